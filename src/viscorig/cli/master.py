"""``viscorig master FILE.h5 --run NAME [--run NAME ...] [--reference-temperature C] [--json]``.

Builds the master curve of a material by time-temperature superposition: from a DMA run
(``import --dma``), or from rig runs of one specimen measured at several temperatures (their
K* from the support FRF, Eq. 5, with the disc mass of a stored fit or ``--disc-mass``, and the
shear modulus through the rig's geometry factor). Prints the shift factors with their standard
errors, the WLF and Arrhenius shift functions with ±, whether superposition holds, the points
that fail the Kramers-Kronig check, and the Prony series with the fewest terms that reaches the
data's scatter, beside a four-parameter fractional model. ``--json`` prints one object (the
contract of design.md). The campaign file is only read.
"""

from __future__ import annotations

import argparse
import json
import math

from viscorig.cli import summary_of
from viscorig.cli.arguments import positive_number
from viscorig.materials.master import MasterCurve, build_master
from viscorig.materials.sources import modulus_table
from viscorig.storage import Campaign


def register(subparsers: argparse._SubParsersAction) -> None:
    """Add the ``master`` command."""
    parser = subparsers.add_parser(
        "master", help=summary_of("master"), description=__doc__.split("\n\n")[1],
        formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("file", help="campaign file (.h5)")
    parser.add_argument("--run", action="append", required=True,
                        help="a DMA run, or a rig run (give once per temperature)")
    parser.add_argument("--reference-temperature", type=float, default=None, metavar="C",
                        help="temperature of the master curve, °C (default: the measured "
                        "temperature nearest the middle of the range)")
    parser.add_argument("--disc-mass", type=positive_number, default=None, metavar="KG",
                        help="disc mass M_v for rig runs without a fit that identified it")
    parser.add_argument("--json", action="store_true", help="print one JSON object")
    parser.set_defaults(handler=handler)


def master_of(path: str, runs: list[str], reference_c: float | None = None,
              disc_mass_kg: float | None = None) -> MasterCurve:
    """The master curve of named runs of a campaign file."""
    campaign = Campaign.open(path)
    table = modulus_table(campaign, runs, disc_mass_kg)
    return build_master(table, tuple(runs), reference_c)


def handler(args: argparse.Namespace) -> int:
    """Run ``master``."""
    master = master_of(args.file, args.run, args.reference_temperature, args.disc_mass)
    if args.json:
        print(json.dumps(master.to_json(), allow_nan=False, default=_finite))
        return 0
    print(text_summary(master))
    return 0


def _finite(value: object) -> object:
    raise TypeError(f"not JSON: {value!r}")


def text_summary(master: MasterCurve) -> str:
    """The master curve in a few lines for a person."""
    m = master.table.modulus
    lines = [f"{', '.join(master.runs)}: {master.table.points} points, "
             f"{master.temperature_c.size} temperatures, modulus {m}, reference "
             f"{master.reference_temperature_c:.2f} °C",
             "shift factors (reduced frequency f·aT):"]
    for t, a, e in zip(master.temperature_c, master.log10_at, master.log10_at_stderr,
                       strict=True):
        lines.append(f"  {t:8.2f} °C   log10 aT = {a:+8.3f} ± {e:.3f}")
    for function in master.shift_functions:
        data = function.to_json()
        values = ", ".join(f"{k} = {v['value']:.4g} ± {v['stderr']:.2g} {v['unit']}".rstrip(" 1")
                           for k, v in data["parameters"].items())
        chi = function.reduced_chi2
        fit = "" if math.isnan(chi) else f" (χ²/dof {chi:.2f}"
        fit += ("" if not fit else ", describes the shifts)" if data["describes_shifts"]
                else ", does not describe the shifts within their errors)")
        best = "  <- better" if function is master.shift_function else ""
        lines.append(f"{function.kind}: {values}{fit}{best}")
    lines.append(master.superposition.verdict)
    flagged = master.flagged_points()
    if flagged:
        named = "; ".join(f"{p['modulus']} at {p['temperature_c']:.1f} °C, "
                          f"{p['frequency_hz']:.4g} Hz ({p['log_deviation']:+.2f})"
                          for p in flagged[:8])
        more = f" and {len(flagged) - 8} more" if len(flagged) > 8 else ""
        lines.append(f"Kramers-Kronig: {len(flagged)} point(s) no linear viscoelastic "
                     f"material gives: {named}{more}")
    else:
        lines.append("Kramers-Kronig: every point is consistent with a linear viscoelastic "
                     "material")
    fit = master.prony_fit
    lines.append(f"Prony series: {master.prony.terms} terms, {m}_inf = "
                 f"{master.prony.long_term_modulus_pa:.4g} Pa, {m}_0 = "
                 f"{master.prony.instantaneous_modulus_pa:.4g} Pa; rms log error "
                 f"storage {fit.storage_rms_log_error:.3f}, loss {fit.loss_rms_log_error:.3f} "
                 f"(data scatter {master.shifts.storage_scatter:.3f}, "
                 f"{master.shifts.loss_scatter:.3f})")
    frac = master.fractional_fit
    lines.append(f"fractional model (4 parameters): rms log error storage "
                 f"{frac.storage_rms_log_error:.3f}, loss {frac.loss_rms_log_error:.3f}")
    return "\n".join(lines)
