"""``viscorig summary FILE [--band LO:HI] [--json]``: the paper's Table 1 and Table 2 for every run.

Each specimen run is identified as the paper does (Voigt on ``X_s/F_e`` with the table fixed at the
bare-table run's values, their uncertainty propagated, every point weighted the same), and beside
it by the project's estimate (each point weighted by its noise, as ``identify`` fits); every number
comes with its standard uncertainty, the preloaded runs with their change against the same specimen
without preload, and when the runs carry the paper's names the published values are printed beside
ours, with the places where the paper's own numbers disagree with each other (for the paper's runs
present).
"""

from __future__ import annotations

import argparse
import math
from typing import Any

from viscorig import jsontext
from viscorig.cli import summary_of
from viscorig.cli.arguments import parse_band
from viscorig.compare import Change
from viscorig.errors import InputError
from viscorig.identify import (
    PAPER_BAND_HZ,
    LeftOut,
    RunSummary,
    TableSource,
    Variation,
    preload_variations,
    summarize,
)
from viscorig.materials.dmastore import dma_run_names
from viscorig.numbers import Estimate, with_uncertainty
from viscorig.paper import (
    PAPER_TABLE_1,
    PAPER_TABLE_PARAMETERS,
    consistency_notes,
    paper_values,
    paper_variation,
)
from viscorig.storage import CampaignFile

TABLE_UNITS = {"M_s": "kg", "K_s": "N/m", "C_s": "N·s/m"}


def register(subparsers: argparse._SubParsersAction) -> None:
    """Add the ``summary`` command."""
    parser = subparsers.add_parser("summary", help=summary_of("summary"))
    parser.add_argument("file", help="campaign file (.h5)")
    parser.add_argument(
        "--band", default=None, help="band fitted, LO:HI in Hz (default: the paper's 20:120)"
    )
    parser.add_argument(
        "--table-model",
        default="table",
        help="model of the bare-table run, e.g. 'table+frame(2000)' (default: table)",
    )
    parser.add_argument("--json", action="store_true", help="print one JSON object")
    parser.set_defaults(handler=handler)


def handler(args: argparse.Namespace) -> int:
    """Run ``summary``."""
    band = parse_band(args.band) or PAPER_BAND_HZ
    with CampaignFile.open(args.file) as campaign:
        table, runs, left_out = summarize(campaign, band, args.table_model)
        if not runs and not left_out:
            dma = dma_run_names(campaign)
            raise InputError(
                "holds no sweep run with points: Tables 1 and 2 are of the rig's runs"
                + (f" (its DMA sweeps, {', '.join(dma)}, make a master curve: see viscorig "
                   "master)" if dma else ""), args.file)
    variations = preload_variations(runs)
    if args.json:
        print(jsontext.dumps(summary_json(table, runs, variations, band, left_out)))
    else:
        print(format_summary(table, runs, variations, left_out, band_hz=band))
    return 0


def _pm(value: float, stderr: float) -> str:
    return with_uncertainty(value, stderr)


def _q(quantity: Estimate) -> str:
    return with_uncertainty(quantity.value, quantity.stderr)


def _change(change: Change) -> str:
    return change.percent()


def format_summary(
    table: TableSource | None,
    runs: list[RunSummary],
    variations: list[Variation] | None = None,
    left_out: list[LeftOut] | None = None,
    *,
    band_hz: tuple[float, float] = PAPER_BAND_HZ,
) -> str:
    """Table 1, Table 2 and the preload variations as text, with the paper's values beside,
    and the runs left out of the tables with why; a run fitted over much less of ``band_hz``
    than asked (its points stop short) is marked."""
    variations = preload_variations(runs) if variations is None else variations
    present = [run.run for run in runs]
    paper_names = any(name in PAPER_TABLE_1 for name in present)
    specimen = [run for run in runs if not run.bare]
    lines = _table_lines(table, paper_names)
    lines += _table_1_lines(specimen, paper_names, band_hz)
    lines += _weighted_lines(specimen)
    lines += _table_2_lines(specimen, paper_names)
    lines += _preload_lines(variations, {run.run for run in specimen if not run.covers(band_hz)})
    if left_out:
        lines += ["", "Left out of the tables:"] + [f"  - {run.reason}" for run in left_out]
    if paper_names:
        lines += ["", "Notes on the paper's numbers:"]
        lines += [f"  - {note}" for note in consistency_notes(present)]
    return "\n".join(lines)


def _table_lines(table: TableSource | None, paper_names: bool) -> list[str]:
    """The table suspension's M_s, K_s, C_s and where they came from."""
    if table is None:
        return []
    lines = [f"Table suspension (from {table.source}):"]
    known = table.known
    for name, unit in TABLE_UNITS.items():
        stderr = known.stderr(name)
        text = f"  {name} = {_pm(table.values[name], stderr or math.nan)} {unit}"
        if stderr is None:
            text += "   (given, no uncertainty)"
        if paper_names:
            text += f"   (paper {PAPER_TABLE_PARAMETERS[name]:g})"
        lines.append(text)
    return lines


def _table_1_lines(specimen: list[RunSummary], paper_names: bool,
                   band_hz: tuple[float, float] = PAPER_BAND_HZ) -> list[str]:
    """Table 1: the paper's Voigt fit of each specimen run, its error against the floor."""
    lines = ["", "Table 1: Voigt fit of X_s/F_e, table fixed, every point weighted the same as "
             "in the paper (± one standard uncertainty)"]
    header = (
        f"  {'run':<10} {'K_v [N/m]':>22} {'C_v [N·s/m]':>18} {'M_v [kg]':>18} "
        f"{'rms/floor':>9}"
    )
    if paper_names:
        header += f" {'paper K_v':>12} {'paper C_v':>10}"
    lines.append(header)
    if not specimen:
        lines.append("  no specimen run in this campaign")
    misfits: list[str] = []
    short: list[str] = []
    for run in specimen:
        p = run.fit.parameters
        ratio = run.fit.rms_error / run.fit.noise_floor
        text = (
            f"  {run.run:<10} {_pm(p['K_v'].value, p['K_v'].stderr):>22} "
            f"{_pm(p['C_v'].value, p['C_v'].stderr):>18} "
            f"{_pm(p['M_v'].value, p['M_v'].stderr):>18} {ratio:>9.2f}"
        )
        if not run.fit.fits_noise:
            text += "*"
            misfits.append(run.run)
        if not run.covers(band_hz):
            text += "†"
            short.append(f"{run.run} {run.fit.band_hz[0]:g}–{run.fit.band_hz[1]:g} Hz")
        if run.run in PAPER_TABLE_1:
            k_v, c_v = PAPER_TABLE_1[run.run]
            text += f" {k_v:>12.2f} {c_v:>10.2f}"
        lines.append(text)
    if misfits:
        lines.append(
            "  * the Voigt model does not fit these runs to the noise: their ± are those of the "
            "model's band-average (scaled by the misfit), not of the specimen"
        )
    if short:
        lines.append(f"  † fitted over part of the {band_hz[0]:g}–{band_hz[1]:g} Hz band only, "
                     f"where the run has points ({'; '.join(short)}): an interrupted run, or "
                     "one measured over a narrower band; not comparable with the others")
    return lines


def _weighted_lines(specimen: list[RunSummary]) -> list[str]:
    """The same fits weighted by the noise, as ``identify`` fits."""
    weighted = [(run.run, run.weighted) for run in specimen if run.weighted is not None]
    if not weighted:
        return []
    lines = ["", "The same fits by the project's estimate, each point weighted by its "
             "noise (as identify fits)"]
    lines.append(f"  {'run':<10} {'K_v [N/m]':>22} {'C_v [N·s/m]':>18} {'M_v [kg]':>18}")
    for name, fitted in weighted:
        p = fitted.parameters
        lines.append(
            f"  {name:<10} {_pm(p['K_v'].value, p['K_v'].stderr):>22} "
            f"{_pm(p['C_v'].value, p['C_v'].stderr):>18} "
            f"{_pm(p['M_v'].value, p['M_v'].stderr):>18}"
            + ("" if fitted.fits_noise else "*")
        )
    return lines


def _table_2_lines(specimen: list[RunSummary], paper_names: bool) -> list[str]:
    """Table 2: natural frequency, damping factor and bandwidth, fitted and measured."""
    lines = ["", "Table 2: system natural frequency, damping factor, half-power bandwidth"]
    header = (
        f"  {'run':<10} {'f_r [Hz]':>16} {'ξ':>18} {'B_r = 2ξf_r [Hz]':>17} "
        f"{'peak [Hz]':>9} {'B_r meas.':>9}"
    )
    if paper_names:
        header += f" {'paper f_r':>9} {'ξ':>6} {'B_r':>6}"
    lines.append(header)
    for run in specimen:
        if run.system_uncertain is None:
            continue
        s, m = run.system_uncertain, run.measured
        bandwidth = "n/a" if math.isnan(m.bandwidth_hz) else f"{m.bandwidth_hz:.3f}"
        peak = "n/a" if math.isnan(m.peak_hz) else f"{m.peak_hz:.2f}"
        text = (
            f"  {run.run:<10} {_q(s['f_r']):>16} {_q(s['xi']):>18} "
            f"{_q(s['B_r']):>17} {peak:>9} {bandwidth:>9}"
        )
        paper = paper_values(run.run)
        if paper is not None:
            text += f" {paper['f_r']:>9.2f} {paper['xi']:>6.3f} {paper['B_r']:>6.3f}"
        lines.append(text)
    return lines


def _preload_lines(variations: list[Variation], short: set[str] | None = None) -> list[str]:
    """Each preloaded run's change against its base, with the paper's where it has one; a
    pair with a run in ``short`` (fitted over part of the band, Table 1's †) marked so."""
    if not variations:
        return []
    lines = ["", "Preload: change against the same specimen without preload"]
    header = f"  {'run':<22}" + "".join(f" {name:>16}" for name in variations[0].changes)
    lines.append(header)
    for variation in variations:
        label = f"{variation.base} → {variation.run}"
        if {variation.base, variation.run} & (short or set()):
            label += " †"
        lines.append(
            f"  {label:<22}"
            + "".join(f" {_change(q):>16}" for q in variation.changes.values())
        )
        paper = paper_variation(variation.run, variation.base)
        if paper is not None:
            lines.append(
                f"  {'  paper':<22}"
                + "".join(f" {paper[name]:>+14.2f} %" for name in variation.changes)
            )
    bases = dict.fromkeys(phrase for v in variations for phrase in v.basis)
    lines.append(f"  ± of a change: {'; '.join(bases)}")
    return lines


def summary_json(
    table: TableSource | None,
    runs: list[RunSummary],
    variations: list[Variation],
    band_hz: tuple[float, float],
    left_out: list[LeftOut] | None = None,
) -> dict[str, Any]:
    """The summary as one JSON object: every number as ``{value, stderr, unit}``; the runs
    left out of the tables under ``left_out``, each with its ``reason``."""
    present = [run.run for run in runs]
    document: dict[str, Any] = {"band_hz": [float(band_hz[0]), float(band_hz[1])]}
    if table is not None:
        known = table.known
        document["table"] = {
            "source": table.source,
            "parameters": {  # stderr null: a value held exact
                name: {"value": float(table.values[name]), "stderr": known.stderr(name),
                       "unit": unit}
                for name, unit in TABLE_UNITS.items()
            },
            "paper": dict(PAPER_TABLE_PARAMETERS) if any(
                name in PAPER_TABLE_1 for name in present) else None,
        }
    entries = []
    for run in runs:
        if run.bare:
            continue
        fit = run.fit.to_json(run.run)
        entry = {
            "run": run.run,
            "model": fit["model"],
            "band_hz": fit["band_hz"],
            "rms_error": fit["rms_error"],
            "noise_floor": fit["noise_floor"],
            "fits_noise": fit["fits_noise"],
            "weighting": fit["weighting"],
            "parameters": {name: fit["parameters"][name] for name in ("K_v", "C_v", "M_v")},
            "noise_weighted": None if run.weighted is None else {
                "parameters": {name: run.weighted.to_json(run.run)["parameters"][name]
                               for name in ("K_v", "C_v", "M_v")},
                "rms_error": float(run.weighted.rms_error),
                "fits_noise": bool(run.weighted.fits_noise),
            },
            "system": {name: q.to_json() for name, q in (run.system_uncertain or {}).items()},
            "measured": {
                "peak_hz": None if math.isnan(run.measured.peak_hz)
                else float(run.measured.peak_hz),
                "bandwidth_hz": None if math.isnan(run.measured.bandwidth_hz)
                else float(run.measured.bandwidth_hz),
            },
            "paper": paper_values(run.run),
        }
        entries.append(entry)
    document["runs"] = entries
    document["variations"] = [
        {
            "run": v.run,
            "base": v.base,
            "changes": {name: q.to_json() for name, q in v.changes.items()},
            "statements": v.statements(),
            "basis": list(v.basis),
            "paper": paper_variation(v.run, v.base),
        }
        for v in variations
    ]
    document["left_out"] = [{"run": run.run, "reason": run.reason} for run in left_out or []]
    document["notes"] = (
        consistency_notes(present) if any(name in PAPER_TABLE_1 for name in present) else []
    )
    return document
