"""``viscorig report FILE [--out DIR]``: the campaign as one self-contained HTML page.

Writes ``DIR/index.html`` (figures embedded, no script, nothing fetched: it opens offline) and
every figure as PNG beside it (and as SVG with --svg). The page leads with the answer: per run
the best model the diagnosis ladder reaches, its error against the noise floor, the main
parameters with their ±, where it still fails and the finding in one sentence, then what
preload changed (with ±).
Then Tables 1 and 2 beside the paper's values, E' and η against frequency, and per run the
FRFs with the bands where the model shown still fails, the residual and the ladder.

The ladder costs seconds per specimen run; runs are climbed in parallel (--jobs).
--no-ladder diagnoses each run once (about a second for the paper's campaign) and shows what is
most likely missing; --no-diagnosis leaves diagnosis out. A run's latest stored fit is where its
diagnosis starts.
"""

from __future__ import annotations

import argparse
from pathlib import Path

from viscorig.cli import summary_of
from viscorig.cli.arguments import job_count, parse_band
from viscorig.executor import check_scheduler
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
    parser.add_argument("--no-ladder", action="store_true",
                        help="diagnose each run once instead of climbing the ladder of effects "
                        "to the best model (faster; shows the most likely missing effect)")
    parser.add_argument("--ladder", action="store_true", help=argparse.SUPPRESS)  # the default
    parser.add_argument("--jobs", type=job_count, default=None,
                        help="processes climbing ladders at once (default: one per core)")
    parser.add_argument("--svg", action="store_true",
                        help="also write every figure as SVG, for print (draws each figure a "
                        "second time)")
    parser.add_argument("--scheduler", default=None, metavar="tcp://HOST:PORT",
                        help="climb the ladders on the workers of this Dask cluster (optional "
                        "extra viscorig[dask]; the workers must see FILE at the same path)")
    parser.set_defaults(handler=handler)


def handler(args: argparse.Namespace) -> int:
    """Run ``report``."""
    band = parse_band(args.band) or PAPER_BAND_HZ
    if args.scheduler is not None:
        check_scheduler(args.scheduler)
    path = Path(args.file)
    out = Path(args.out) if args.out else path.with_name(path.stem + "-report")
    page = build_report(path, out, band_hz=band, diagnosis=not args.no_diagnosis,
                        ladder=not args.no_ladder, jobs=args.jobs, scheduler=args.scheduler,
                        svg=args.svg)
    figures = len(list(out.glob("*.png")))
    formats = "PNG and SVG" if args.svg else "PNG"
    print(f"{page}  ({figures} figures as {formats} in {out})")
    return 0
