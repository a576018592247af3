"""``viscorig plan SEQUENCE.toml [--station FILE] [--json]``: how long a sequence will hold the rig.

Per step the predicted test time (a full sweep's exactly, with the probe before a newly mounted
specimen; an adaptive plan's as a range, with its floor beside it: the least rig time any plan
needs for its targets), and the total. Nothing is measured and no instrument is opened. On the
embedded simulated rig (no ``--station``) the floor of each adaptive step is that of the rig
preset its prompt mounts, found by simulating that rig; with a station the specimen is not
known before it is measured, so an adaptive step's range has no upper end but its dwell limit.
``viscorig run`` prints the same before its first prompt.
"""

from __future__ import annotations

import argparse

from viscorig import jsontext
from viscorig.acquisition.forecast import format_forecast
from viscorig.cli import summary_of
from viscorig.cli.check import refuse
from viscorig.stations.checking import check_files
from viscorig.stations.forecasting import sequence_forecast


def register(subparsers: argparse._SubParsersAction) -> None:
    """Add the ``plan`` command."""
    parser = subparsers.add_parser(
        "plan", help=summary_of("plan"),
        description="Predict each step's test time and the total without touching any "
        "instrument: a full sweep's exactly, an adaptive plan's as a range with its floor "
        "beside it (on the embedded simulated rig, from the rig preset each prompt mounts).")
    parser.add_argument("sequence", metavar="SEQUENCE.toml", help="test sequence")
    parser.add_argument("--station", metavar="STATION.toml", default=None,
                        help="the lab's station file (default: the embedded simulated rig)")
    parser.add_argument("--json", action="store_true", help="print one JSON object")
    parser.set_defaults(handler=plan_command)


def plan_command(args: argparse.Namespace) -> int:
    """``viscorig plan``."""
    checked = check_files(args.sequence, args.station)
    if not checked.ok:
        option = f" --station {args.station}" if args.station else ""
        refuse(checked, f"viscorig check {args.sequence}{option}")
    sequence, station = checked.passed(), checked.station
    forecasts = sequence_forecast(sequence, station)
    if args.json:
        low = sum(item.low_s for item in forecasts)
        high = sum(item.high_s for item in forecasts)
        print(jsontext.dumps({
            "sequence": args.sequence, "station": args.station,
            "steps": [item.to_json() for item in forecasts if item.kind not in (
                "prompt", "identify_table")],
            "total_low_s": low, "total_high_s": high,  # unbounded: null
            "soaks": sum(item.kind == "soak" for item in forecasts),
            "soak_s": sum(item.low_s for item in forecasts if item.kind == "soak"),
        }, indent=2))
        return 0
    where = f"station {args.station}" if args.station else "the embedded simulated rig"
    print(format_forecast(forecasts, f"{args.sequence} on {where}: predicted test time"))
    return 0
