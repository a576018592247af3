"""``viscorig master FILE.h5 --run NAME [--run NAME ...] [--reference-temperature C] [--json]``.

Builds the master curve of a material by time-temperature superposition: from a DMA run
(``import --dma``), or from rig runs of one specimen measured at several temperatures (their
K* from the support FRF, Eq. 5, with the disc mass of a stored fit or ``--disc-mass``, or with
``--kstar fit`` from the newest stored fit's model; the shear modulus through the rig's
geometry factor). Prints the shift factors with their standard errors, the WLF and Arrhenius
shift functions with ±, whether superposition holds, the points that fail the Kramers-Kronig
check, and the Prony series with the fewest terms that reaches the data's scatter, beside a
four-parameter fractional model. ``--json`` prints one object (the contract of design.md). The
campaign file is only read.
"""

from __future__ import annotations

import argparse

from viscorig import jsontext
from viscorig.cli import summary_of
from viscorig.cli.arguments import add_vertical_shift, positive_number
from viscorig.materials.master import MasterCurve
from viscorig.materials.sources import master_curve
from viscorig.storage import CampaignFile


def register(subparsers: argparse._SubParsersAction) -> None:
    """Add the ``master`` command."""
    parser = subparsers.add_parser(
        "master", help=summary_of("master"), description=__doc__.split("\n\n")[1].replace("``", ""),
        formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("file", help="campaign file (.h5)")
    parser.add_argument("--run", action="append", required=True,
                        help="a DMA run, or a rig run (give once per temperature)")
    parser.add_argument("--reference-temperature", type=float, default=None, metavar="C",
                        help="temperature of the master curve, °C (default: the measured "
                        "temperature nearest the middle of the range)")
    parser.add_argument("--disc-mass", type=positive_number, default=None, metavar="KG",
                        help="disc mass M_v for rig runs without a fit that identified it")
    parser.add_argument("--kstar", choices=("support", "fit"), default="support",
                        help="rig runs: K* from the support FRF by Eq. 5 (default) or from "
                        "the newest stored fit of a specimen model")
    add_vertical_shift(parser)
    parser.add_argument("--json", action="store_true", help="print one JSON object")
    parser.set_defaults(handler=handler)


def master_of(path: str, runs: list[str], reference_c: float | None = None,
              disc_mass_kg: float | None = None, kstar_source: str = "support",
              vertical: str = "none", expansion_per_k: float = 0.0) -> MasterCurve:
    """The master curve of named runs of a campaign file."""
    return master_curve(CampaignFile.open(path), runs, reference_c, disc_mass_kg, kstar_source,
                        vertical, expansion_per_k)


def handler(args: argparse.Namespace) -> int:
    """Run ``master``."""
    master = master_of(args.file, args.run, args.reference_temperature, args.disc_mass,
                       args.kstar, args.vertical_shift, args.thermal_expansion)
    if args.json:
        print(jsontext.dumps(master.to_json()))
        return 0
    print(master.text())
    return 0

