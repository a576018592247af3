"""``viscorig show FILE``: what a campaign file holds, run by run, with flagged points and fits
(a run's own, and the fits of several runs together under ``/fits``, such as the Payne effect's).

Works on a file that is still being written or whose writer crashed (its last run stays
"running" with every committed segment). A run that cannot be read is listed with the reason,
the others are still shown, and the exit status is 2. ``--json`` prints the same as one JSON
object (units in the key names, ``null`` for unknown numbers), for scripts.
"""

from __future__ import annotations

import argparse
import dataclasses
import math
from pathlib import Path
from typing import Any

import numpy as np

from viscorig import jsontext
from viscorig.acquisition import format_duration
from viscorig.cli import summary_of
from viscorig.errors import InputError
from viscorig.materials.dmastore import dma_run_names, dma_specimen, read_dma
from viscorig.numbers import with_uncertainty
from viscorig.storage import (
    FLAG_NAMES,
    CampaignFile,
    FitRecord,
    JointFitRecord,
    RunRecord,
    count_flags,
)
from viscorig.storage.journal import JournalEntry


def register(subparsers: argparse._SubParsersAction) -> None:
    """Add the ``show`` command."""
    parser = subparsers.add_parser("show", help=summary_of("show"))
    parser.add_argument("file", help="campaign file (.h5)")
    parser.add_argument("--plot", metavar="RUN", default=None,
                        help="write the FRF figure of RUN (measured so far) as a PNG instead")
    parser.add_argument("--out", default=None,
                        help="PNG written by --plot (default: FILE-RUN.png beside FILE)")
    parser.add_argument("--json", action="store_true",
                        help="print one JSON object: the file, its runs and their fits")
    parser.set_defaults(handler=handler)


def _number(value: float, digits: int = 3) -> str:
    return "-" if math.isnan(value) else f"{value:.{digits}g}"


def _flag_summary(run: RunRecord) -> str:
    if not run.points:
        return "-"
    flagged = int(run.flagged().sum())
    if not flagged:
        return "0"
    counts = ", ".join(
        f"{FLAG_NAMES[flag]} {count}" for flag, count in count_flags(run.flags).items() if count
    )
    return f"{flagged} ({counts})"


def run_row(run: RunRecord) -> list[str]:
    """The listing's cells for one run."""
    metadata = run.metadata
    band = f"{run.frequency_hz.min():.2f}-{run.frequency_hz.max():.2f}" if run.points else "-"
    return [
        run.name,
        metadata.status,
        str(run.points),
        band,
        _number(metadata.level_m_per_s2),
        metadata.specimen + ("" if math.isnan(metadata.hardness_shore_a)
                             else f" ({metadata.hardness_shore_a:g} Shore A)"),
        _number(metadata.preload_strain),
        _flag_summary(run),
    ]


def fit_lines(fit: FitRecord) -> list[str]:
    """The listing's lines for one fit."""
    lo, hi = fit.band_hz
    lines = [
        f"  {fit.run}/{fit.id}  {fit.model}  {lo:g}-{hi:g} Hz  rms_error {_number(fit.rms_error)}"
        f"  noise_floor {_number(fit.noise_floor)}  {fit.created}"
        + (f"  weighted by {fit.weighting}" if fit.weighting else "")
    ]
    for name, parameter in fit.parameters.items():
        shown = with_uncertainty(parameter.value, parameter.stderr)
        lines.append(f"      {name} = {shown} {parameter.unit}".rstrip())
    return lines


def joint_fit_lines(fit: JointFitRecord) -> list[str]:
    """The listing's lines for one fit of several runs together."""
    lo, hi = fit.band_hz
    lines = [
        f"  /fits/{fit.id}  {fit.model}  runs {', '.join(fit.runs)}  {lo:g}-{hi:g} Hz  "
        f"{fit.points} points  reduced chi-square {_number(fit.reduced_chi_square)}  "
        f"{fit.created}"
    ]
    for name, parameter in fit.parameters.items():
        shown = with_uncertainty(parameter.value, parameter.stderr)
        lines.append(f"      {name} = {shown} {parameter.unit}".rstrip())
    return lines


def joint_fits(campaign: CampaignFile, problems: list[str]) -> list[JointFitRecord]:
    """The fits of several runs together (``/fits``); a file where they cannot be read puts
    its reason in problems."""
    try:
        return campaign.joint_fits()
    except InputError as error:
        problems.append(str(error))
        return []


def table(rows: list[list[str]]) -> list[str]:
    """Rows as left-aligned columns."""
    widths = [max(len(row[i]) for row in rows if i < len(row)) for i in range(len(rows[0]))]
    return [
        "  ".join(cell.ljust(widths[i]) for i, cell in enumerate(row)).rstrip() for row in rows
    ]


def listing(path: Path) -> tuple[list[str], list[str]]:
    """The listing of a campaign file, and the problems met on the way (one line each)."""
    campaign = CampaignFile.open(path)
    attributes = campaign.attributes
    lines = [
        f"{path}: viscorig campaign, format {attributes.get('format_version')}, created "
        f"{attributes.get('created', '?')} by {attributes.get('software', '?')}"
    ]
    files = campaign.setup_files
    sequence = files.get("sequence_file") or ("stored" if campaign.sequence_text else "none")
    station = files.get("station_file") or ("stored" if campaign.station_text else
                                             "none (simulated rig)")
    lines.append(f"sequence: {sequence}; station: {station}")
    rig = campaign.rig
    if rig:
        lines.append("rig: " + ", ".join(f"{key} {value:g}" for key, value in rig.items()))
    rows = [["run", "status", "points", "band [Hz]", "level [m/s^2]", "specimen", "preload",
             "flagged"]]
    problems: list[str] = []
    fits: list[str] = []
    plans: list[str] = []
    for name in campaign.run_names:
        try:
            run = campaign.run(name)
            rows.append(run_row(run))
            plan = plan_line(run, campaign.run_attributes(name))
            if plan:
                plans.append(plan)
        except InputError as error:
            rows.append([name, f"cannot be read: {error.detail}"])
            problems.append(str(error))
            continue
        try:
            for fit in campaign.fits(name):
                fits.extend(fit_lines(fit))
        except InputError as error:
            fits.append(f"  {name}: fits cannot be read: {error.detail}")
            problems.append(str(error))
    dma = dma_runs(campaign, problems)
    for joint in joint_fits(campaign, problems):
        fits.extend(joint_fit_lines(joint))
    if len(rows) == 1 and not dma:
        lines.append("no runs")
    elif len(rows) > 1:
        lines.append("")
        lines.extend(table(rows))
    if dma:
        lines.extend(["", *table([["DMA run", "points", "temperatures", "°C", "Hz", "modulus",
                                   "specimen", "source"]] + [
            [d["name"], str(d["points"]), str(d["temperatures"]),
             f"{d['temperature_c'][0]:.1f}..{d['temperature_c'][1]:.1f}",
             f"{d['frequency_hz'][0]:.3g}..{d['frequency_hz'][1]:.3g}", d["modulus"],
             d["specimen"] or "-", d["source"]] for d in dma])])
    if plans:
        lines.extend(["", *plans])
    if fits:
        lines.extend(["", "fits", *fits])
    entries = journal(campaign, problems)
    if entries:
        lines.extend(["", "journal", *table([[entry.time_utc, entry.run or "-", entry.kind,
                                              entry.text.replace("\n", " / ")]
                                             for entry in entries])])
    return lines, problems


def journal(campaign: CampaignFile, problems: list[str]) -> list[JournalEntry]:
    """The notes and run events of the bench (``/journal``); a journal that cannot be read
    puts its reason in problems."""
    try:
        return campaign.journal
    except InputError as error:
        problems.append(str(error))
        return []


def plan_line(run: RunRecord, attributes: dict[str, Any]) -> str:
    """One line on a run an adaptive plan measured (``""`` for a full sweep)."""
    if attributes.get("plan") != "adaptive":
        return ""

    reason = attributes.get("plan_reason") or f"stopped while {attributes.get('plan_state')}"
    frequencies = np.unique(run.frequency_hz).size
    rig_time = attributes.get("test_time_s")
    text = (f"{run.name}: adaptive plan for {attributes.get('plan_model', '?')} "
            f"({attributes.get('plan_targets', '')}): {reason}; {run.points} points at "
            f"{frequencies} frequencies")
    if isinstance(rig_time, int | float) and math.isfinite(rig_time):
        text += f", rig time {format_duration(float(rig_time))}"
    return text


def fit_json(fit: FitRecord) -> dict[str, Any]:
    """One stored fit as JSON (the ``identify --json`` parameter layout)."""
    return {
        "id": fit.id,
        "model": fit.model,
        "band_hz": [float(fit.band_hz[0]), float(fit.band_hz[1])],
        "rms_error": float(fit.rms_error),
        "noise_floor": float(fit.noise_floor),
        "weighting": fit.weighting or None,
        "created": fit.created,
        "parameters": {name: p.to_json() for name, p in fit.parameters.items()},
    }


def joint_fit_json(fit: JointFitRecord) -> dict[str, Any]:
    """One fit of several runs together as JSON (the parameter layout of ``identify --json``)."""
    return {
        "id": fit.id,
        "model": fit.model,
        "runs": list(fit.runs),
        "band_hz": [float(fit.band_hz[0]), float(fit.band_hz[1])],
        "points": int(fit.points),
        "reduced_chi_square": float(fit.reduced_chi_square),
        "weighting": fit.weighting or None,
        "created": fit.created,
        "parameters": {name: p.to_json() for name, p in fit.parameters.items()},
    }


def run_json(run: RunRecord, fits: list[FitRecord]) -> dict[str, Any]:
    """One run as JSON: metadata, points, band, flag counts and fits."""
    m = run.metadata
    counts = count_flags(run.flags) if run.points else {}
    return {
        "name": run.name,
        "status": m.status,
        "points": run.points,
        "band_hz": ([float(run.frequency_hz.min()), float(run.frequency_hz.max())]
                    if run.points else None),
        "level_m_per_s2": float(m.level_m_per_s2),
        "direction": m.direction,
        "specimen": m.specimen,
        "hardness_shore_a": float(m.hardness_shore_a),
        "preload_strain": float(m.preload_strain),
        "temperature_c": float(m.temperature_c),
        "simulated": bool(m.simulated),
        "started": m.started,
        "finished": m.finished,
        "flagged_points": int(run.flagged().sum()) if run.points else 0,
        "flags": {FLAG_NAMES[flag]: int(n) for flag, n in counts.items()},
        "frequencies": int(np.unique(run.frequency_hz).size),
        "fits": [fit_json(fit) for fit in fits],
    }


def dma_runs(campaign: CampaignFile, problems: list[str]) -> list[dict[str, Any]]:
    """The DMA runs of the file (``/dma``), each summarised; unreadable ones go to problems."""
    out: list[dict[str, Any]] = []
    try:
        names = dma_run_names(campaign)
    except InputError as error:
        problems.append(str(error))
        return out
    for name in names:
        try:
            table_ = read_dma(campaign, name)
            specimen = dma_specimen(campaign, name)
        except InputError as error:
            problems.append(str(error))
            continue
        out.append({"name": name, "points": table_.points,
                    "temperatures": int(table_.sets.size),
                    "temperature_c": [float(table_.temperature_c.min()),
                                      float(table_.temperature_c.max())],
                    "frequency_hz": [float(table_.frequency_hz.min()),
                                     float(table_.frequency_hz.max())],
                    "modulus": table_.modulus, "specimen": specimen, "source": table_.source})
    return out


def describe_json(path: Path) -> tuple[dict[str, Any], list[str]]:
    """The ``show --json`` object of a campaign file, and the problems met on the way."""
    campaign = CampaignFile.open(path)
    attributes = campaign.attributes
    files = campaign.setup_files
    document: dict[str, Any] = {
        "file": str(path),
        "format": attributes.get("format"),
        "format_version": attributes.get("format_version"),
        "created": attributes.get("created"),
        "software": attributes.get("software"),
        "sequence_file": files.get("sequence_file") or None,
        "station_file": files.get("station_file") or None,
        "simulated_rig": campaign.station_text is None,
        "rig": {key: value if isinstance(value, int) else float(value)
                for key, value in campaign.rig.items()},
        "runs": [],
    }
    problems: list[str] = []
    for name in campaign.run_names:
        try:
            document["runs"].append(run_json(campaign.run(name), campaign.fits(name)))
        except InputError as error:
            document["runs"].append({"name": name, "error": error.detail})
            problems.append(str(error))
    document["dma_runs"] = dma_runs(campaign, problems)
    document["joint_fits"] = [joint_fit_json(fit) for fit in joint_fits(campaign, problems)]
    document["journal"] = [dataclasses.asdict(entry) for entry in journal(campaign, problems)]
    return document, problems


def handler(args: argparse.Namespace) -> int:
    """Print the listing; exit status 2 if a run could not be read."""
    if args.plot is not None:
        # keeps the command's start fast: matplotlib loads only for --plot
        from viscorig.report.quicklook import default_png, plot_run

        path = Path(args.file)
        print(plot_run(path, args.plot, default_png(path, args.plot, args.out)))
        return 0
    if args.json:
        document, problems = describe_json(Path(args.file))
        print(jsontext.dumps(document))
    else:
        lines, problems = listing(Path(args.file))
        print("\n".join(lines))
    if problems:
        more = f" (and {len(problems) - 1} more)" if len(problems) > 1 else ""
        raise InputError(problems[0] + more)
    return 0
