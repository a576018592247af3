"""``viscorig summary FILE [--band LO:HI]``: the paper's Table 1 and Table 2 for every run.

Each specimen run is identified as the paper does (Voigt on ``X_s/F_e`` with the table fixed);
when the runs carry the paper's names, the published values are printed beside ours, and the
places where the paper's own numbers disagree with each other are said.
"""

from __future__ import annotations

import argparse
import math

from viscorig.cli import summary_of
from viscorig.cli.arguments import parse_band
from viscorig.identify import PAPER_BAND_HZ, RunSummary, TableSource, summarize
from viscorig.paper import (
    PAPER_TABLE_1,
    PAPER_TABLE_2,
    PAPER_TABLE_PARAMETERS,
    consistency_notes,
)
from viscorig.storage import Campaign


def register(subparsers: argparse._SubParsersAction) -> None:
    """Add the ``summary`` command."""
    parser = subparsers.add_parser("summary", help=summary_of("summary"))
    parser.add_argument("file", help="campaign file (.h5)")
    parser.add_argument(
        "--band", default=None, help="band fitted, LO:HI in Hz (default: the paper's 20:120)"
    )
    parser.set_defaults(handler=handler)


def handler(args: argparse.Namespace) -> int:
    """Run ``summary``."""
    band = parse_band(args.band) or PAPER_BAND_HZ
    with Campaign.open(args.file) as campaign:
        table, runs = summarize(campaign, band)
    print(format_summary(table, runs))
    return 0


def _pm(value: float, stderr: float, digits: str = ".6g") -> str:
    return f"{value:{digits}} ± {stderr:.2g}"


def format_summary(table: TableSource | None, runs: list[RunSummary]) -> str:
    """Table 1 and Table 2 as text, with the paper's values where the run names match."""
    paper_names = any(run.run in PAPER_TABLE_1 for run in runs)
    lines = []
    if table is not None:
        lines.append(f"Table suspension (from {table.source}):")
        for name, unit in (("M_s", "kg"), ("K_s", "N/m"), ("C_s", "N·s/m")):
            text = f"  {name} = {table.values[name]:.6g} {unit}"
            if table.fit is not None:
                text = f"  {name} = {_pm(table.values[name], table.fit.stderr[name])} {unit}"
            if paper_names:
                text += f"   (paper {PAPER_TABLE_PARAMETERS[name]:g})"
            lines.append(text)
    lines += ["", "Table 1: Voigt fit of X_s/F_e, table fixed"]
    header = (
        f"  {'run':<10} {'K_v [N/m]':>24} {'C_v [N·s/m]':>20} {'M_v [kg]':>18} {'rms/floor':>10}"
    )
    if paper_names:
        header += f" {'paper K_v':>12} {'paper C_v':>10}"
    lines.append(header)
    for run in runs:
        if run.bare:
            continue
        p = run.fit.parameters
        text = (
            f"  {run.run:<10} {_pm(p['K_v'].value, p['K_v'].stderr):>24} "
            f"{_pm(p['C_v'].value, p['C_v'].stderr):>20} "
            f"{_pm(p['M_v'].value, p['M_v'].stderr, '.4g'):>18} "
            f"{run.fit.rms_error / run.fit.noise_floor:>10.2f}"
        )
        if run.run in PAPER_TABLE_1:
            k_v, c_v = PAPER_TABLE_1[run.run]
            text += f" {k_v:>12.2f} {c_v:>10.2f}"
        lines.append(text)
    lines += ["", "Table 2: system natural frequency, damping factor, half-power bandwidth"]
    header = (
        f"  {'run':<10} {'f_r [Hz]':>9} {'ξ':>7} {'2ξf_r [Hz]':>10} {'peak [Hz]':>10} "
        f"{'B_r meas.':>10}"
    )
    if paper_names:
        header += f" {'paper f_r':>10} {'ξ':>6} {'B_r':>7}"
    lines.append(header)
    for run in runs:
        if run.system is None:
            continue
        s, m = run.system, run.measured
        bandwidth = "n/a" if math.isnan(m.bandwidth_hz) else f"{m.bandwidth_hz:.3f}"
        text = (
            f"  {run.run:<10} {s.natural_frequency_hz:>9.2f} {s.damping_factor:>7.4f} "
            f"{s.bandwidth_hz:>10.3f} {m.peak_hz:>10.2f} {bandwidth:>10}"
        )
        if run.run in PAPER_TABLE_2:
            f_r, xi, b_r = PAPER_TABLE_2[run.run]
            text += f" {f_r:>10.2f} {xi:>6.3f} {b_r:>7.3f}"
        lines.append(text)
    if paper_names:
        lines += ["", "Notes on the paper's numbers:"]
        lines += [f"  - {note}" for note in consistency_notes()]
    return "\n".join(lines)
