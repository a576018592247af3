"""``viscorig diagnose FILE --run RUN [--model SPEC] [--auto] [--band LO:HI] [--json] [--jobs N]``.

Fits the model (default ``voigt`` on both FRFs, the table held at the file's bare-table run or
``/rig`` values), shows where it departs from the measurements, which effect is most likely
missing and why, and the exact ``identify`` command with that effect added. ``--auto`` adds the
best significant effect (and the local modes, the load cell and a K* in place of the current
one significant next to it) and refits until nothing
significant is left, and prints the ladder, each rung as it is reached: the diagnosis of the
model given is printed first, while the ladder is climbed. Runs of the same specimen at other
levels or in the other sweep direction are diagnosed jointly (``--alone`` to diagnose the run
by itself).
The file is only read, before anything is fitted; each step's candidate fits run on ``--jobs``
worker processes, one per core by default (:mod:`viscorig.diagnosis.workers`): the same numbers
as in one process, sooner.
"""

from __future__ import annotations

import argparse
import shlex
from collections.abc import Iterable, Iterator

from viscorig import jsontext
from viscorig.cli import summary_of
from viscorig.cli.arguments import job_count, parse_band
from viscorig.cli.identify import FRF_CHOICES
from viscorig.diagnosis import DEFAULT_MODEL, DiagnosisResult, diagnose, from_campaign
from viscorig.diagnosis.workers import fitting_on
from viscorig.executor import executor
from viscorig.storage import CampaignFile


def register(subparsers: argparse._SubParsersAction) -> None:
    """Add the ``diagnose`` command."""
    parser = subparsers.add_parser("diagnose", help=summary_of("diagnose"))
    parser.add_argument("file", help="campaign file (.h5)")
    parser.add_argument("--run", required=True, help="run name, e.g. hard-10")
    parser.add_argument(
        "--model", default=None, help=f"model spec diagnosed (default: {DEFAULT_MODEL})"
    )
    parser.add_argument(
        "--auto", action="store_true",
        help="add the best significant effect and refit until nothing significant is left",
    )
    parser.add_argument("--band", default=None, help="band, LO:HI in Hz (default: all points)")
    parser.add_argument(
        "--frf", choices=sorted(FRF_CHOICES), default=None,
        help="FRFs diagnosed (default: both when the table is known)",
    )
    parser.add_argument(
        "--alone", action="store_true",
        help="leave out the specimen's runs at other levels or directions",
    )
    parser.add_argument("--json", action="store_true", help="print one JSON object")
    parser.add_argument("--jobs", type=job_count, default=None,
                        help="worker processes for each step's candidate fits (default: one "
                             "per core; 1: all in this process)")
    parser.set_defaults(handler=handler)


def handler(args: argparse.Namespace) -> int:
    """Run ``diagnose``."""
    band = parse_band(args.band)
    frfs = FRF_CHOICES[args.frf] if args.frf else None
    with CampaignFile.open(args.file, "r") as campaign:
        data = from_campaign(campaign, args.run, band_hz=band, frfs=frfs,
                             with_companions=not args.alone)
    with executor(jobs=args.jobs) as workers, fitting_on(workers):
        diagnosis = diagnose(data, args.model)
        if args.json:
            ladder = diagnosis.auto() if args.auto else None
            document = diagnosis.to_json(ladder)
            if ladder is not None:
                document["final"] = ladder[-1].to_json()
            print(jsontext.dumps(document))
            return 0
        # the first diagnosis is the first answer: shown while the ladder is climbed
        rungs = diagnosis.climb() if args.auto else None
        for line in diagnosis_text(diagnosis, args.file, rungs, band):
            print(line, flush=True)
    return 0


def next_command(file: str, run: str, spec: str, band: tuple[float, float] | None,
                 weights: str = "uniform") -> str:
    """The ``identify`` command line that fits ``spec`` as the diagnosis reported it: weighting
    every point alike, the fit whose ``rms_error`` the ladder shows (``identify``'s default
    weighs by the noise and ends a few percent higher on that measure); ``weights="noise"``
    where outliers pull that fit off (``DiagnosisResult.pulled_by_outliers``)."""
    words = ["viscorig", "identify", file, "--run", run, "--model", spec, "--weights", weights]
    if band is not None:
        words += ["--band", f"{band[0]:g}:{band[1]:g}"]
    return shlex.join(words)


#: The line above the ladder's rungs.
LADDER_HEADING = "ladder (model -> rms_error):"


def format_diagnosis(
    d: DiagnosisResult,
    file: str,
    ladder: list[DiagnosisResult] | None = None,
    band_hz: tuple[float, float] | None = None,
) -> str:
    """Human-readable diagnosis: where it fails, what is missing, what to run next, and the
    ladder climbed from it when given."""
    return "\n".join(diagnosis_text(d, file, ladder, band_hz))


def diagnosis_text(
    d: DiagnosisResult,
    file: str,
    ladder: Iterable[DiagnosisResult] | None = None,
    band_hz: tuple[float, float] | None = None,
) -> Iterator[str]:
    """The lines of :func:`format_diagnosis`, the ladder's as its rungs come (``ladder`` may be
    :meth:`~viscorig.diagnosis.DiagnosisResult.climb`, climbed as the lines are read)."""
    yield from diagnosis_lines(d, file, band_hz)
    last = None
    for step in ladder or ():
        if last is None:
            yield LADDER_HEADING
        yield rung_line(step)
        last = step
    if last is not None and last is not d:
        yield "next: " + next_command(file, d.data.run, last.model, band_hz,
                                      "noise" if last.pulled_by_outliers else "uniform")


#: The ratio to the floor without the outlier points is shown beside the whole one when the two
#: differ by more than this share.
OUTLIERS_SHOWN = 0.1


def floor_ratio(d: DiagnosisResult) -> str:
    """``rms_error / noise_floor``, and beside it the same without the outlier points where
    they make a difference: a few points off by tens of per cent are their own floor, and the
    whole ratio then hides how far the model is from the noise of the others."""
    whole = d.rms_error / d.noise_floor
    text = f"{whole:.2f} x floor"
    if d.outlier_points:
        clean = d.rms_error_without_outliers / d.noise_floor_without_outliers
        if abs(clean - whole) > OUTLIERS_SHOWN * whole:
            text += f"; {clean:.2f} x without its {d.outlier_points} outlier points"
    return text


def rung_line(step: DiagnosisResult) -> str:
    """One rung of the ladder: model, rms error, its ratio to the noise floor."""
    mark = ("  at the noise floor" if step.at_noise_floor
            else "  at the noise floor weighed by its noise" if step.pulled_by_outliers else "")
    return f"  {step.model:<44} {step.rms_error:.3e}  ({floor_ratio(step)}){mark}"


def diagnosis_lines(
    d: DiagnosisResult, file: str, band_hz: tuple[float, float] | None = None
) -> list[str]:
    """The diagnosis of one model: where it fails, what is missing, what to run next."""
    lines = [
        f"run {d.data.run}: model {d.model}, FRFs {', '.join(d.data.frfs)}"
        + (f", with runs {', '.join(d.data.runs[1:])}" if len(d.data.runs) > 1 else ""),
        f"rms_error {d.rms_error:.3e}   noise_floor {d.noise_floor:.3e}   ({floor_ratio(d)}"
        + (", at the noise floor)" if d.at_noise_floor else ")"),
        "noise: " + "; ".join(d.data.noise.describe()),
    ]
    if d.pulled_by_outliers:
        floor = d.noise_floor_without_outliers
        lines.append(
            f"outliers: its {d.outlier_points} outlier points pull the uniform fit (the paper's) "
            f"off the other points ({d.rms_error_without_outliers / floor:.2f} x their noise); "
            f"weighed by its noise, the model leaves "
            f"{d.likelihood_rms_error_without_outliers / floor:.2f} x: "
            + next_command(file, d.data.run, d.model, band_hz, "noise"))
    prior = d.data.table_prior
    if prior is not None and d.data.nuisance:
        lines.append(f"table: {', '.join(d.data.nuisance)} from {prior.source or 'elsewhere'}, "
                     "fitted within their uncertainty in every test")
    weighed = " (weighed by its noise)" if d.pulled_by_outliers else ""
    if not d.failures:
        lines.append(f"where it fails{weighed}: nowhere"
                     + (" (at the noise floor: what is left is noise)" if d.at_noise_floor
                        else ": no band stands out of the noise"))
    else:
        lines.append(f"where it fails{weighed}:")
        for band in d.failures[:6]:
            run = f" [{band.run}]" if band.run != d.data.run else ""
            lines.append(
                f"  {band.band_hz[0]:7.2f}-{band.band_hz[1]:<7.2f} Hz  {band.frf:<8}{run} "
                f"{band.what}"
            )
    if d.findings:
        lines.append(
            "candidate effects (* significant: its χ² drop, in units of the misfit φ it leaves, "
            "beyond its threshold, next to the ones before it):"
        )
        for finding in d.findings:
            mark = "*" if finding.significant else " "
            per_misfit = finding.delta_chi2 / finding.dispersion
            lines.append(
                f" {mark} {finding.effect:<28} {finding.model:<36} rms {finding.rms_error:.3e}"
                f"  ΔBIC {finding.delta_bic:+.4g}  Δχ²/φ {per_misfit:.4g}"
                f" (needs {finding.threshold:.3g})"
            )
    if d.scan is not None:
        lines.append(
            f"scan for local modes: {d.scan.templates} frequencies and widths, "
            f"{d.scan.length:.0f} correlation lengths; a mode needs Δχ² > {d.scan.threshold:.1f} "
            f"({d.scan.threshold ** 0.5:.1f} standard errors) after looking everywhere"
        )
    best = d.significant[0] if d.significant else None
    if best is None:
        lines.append(
            "nothing significant is missing: what is left is noise."
            if d.at_noise_floor
            else "nothing significant is missing: weighed by its noise, what is left is noise."
            if d.pulled_by_outliers
            else "no candidate effect explains what is left beyond noise."
        )
    else:
        lines.append(f"most likely missing: {best.effect}")
        lines.append(f"  {best.explanation}")
        lines.append("next: " + next_command(file, d.data.run, best.model, band_hz,
                                             "noise" if d.pulled_by_outliers else "uniform"))
    for text in d.advice:
        lines.append(f"to tell them apart: {text}")
    return lines
