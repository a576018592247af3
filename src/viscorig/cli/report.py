"""``viscorig report FILE [--out DIR]``: the campaign as one self-contained HTML page.

Writes ``DIR/index.html`` (figures embedded, no script, nothing fetched: it opens offline) and
every figure as PNG and SVG beside it: per run the measured and model FRFs with the failure
bands and flagged points, the residual with the noise floor, the diagnosis ladder; E' and η
against frequency per rubber and the preload effect; Tables 1 and 2 beside the paper's values.
"""

from __future__ import annotations

import argparse
from pathlib import Path

from viscorig.cli import summary_of
from viscorig.cli.arguments import parse_band
from viscorig.identify import PAPER_BAND_HZ
from viscorig.report import build_report


def register(subparsers: argparse._SubParsersAction) -> None:
    """Add the ``report`` command."""
    parser = subparsers.add_parser(
        "report", help=summary_of("report"),
        description=(__doc__ or "").split("\n\n", 1)[1].replace("``", ""),
        formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("file", help="campaign file (.h5)")
    parser.add_argument("--out", default=None,
                        help="report folder (default: FILE without .h5, plus '-report')")
    parser.add_argument("--band", default=None,
                        help="identification band LO:HI in Hz (default: the paper's 20:120)")
    parser.add_argument("--no-diagnosis", action="store_true",
                        help="leave out the diagnosis (failure bands, findings, ladder)")
    parser.add_argument("--ladder", action="store_true",
                        help="climb the whole ladder of effects for each run (adds the best "
                        "effect and refits until the noise floor; tens of seconds per run); "
                        "without it each run is diagnosed once and its candidates shown")
    parser.set_defaults(handler=handler)


def handler(args: argparse.Namespace) -> int:
    """Run ``report``."""
    band = parse_band(args.band) or PAPER_BAND_HZ
    path = Path(args.file)
    out = Path(args.out) if args.out else path.with_name(path.stem + "-report")
    page = build_report(path, out, band_hz=band, diagnosis=not args.no_diagnosis,
                        ladder=args.ladder)
    figures = len(list(out.glob("*.png")))
    print(f"{page}  ({figures} figures as PNG and SVG in {out})")
    return 0
