"""``viscorig check SEQUENCE.toml [--station FILE] [--json]``: every problem of a sequence at once.

::

    viscorig check my-test.toml                    # the sequence, for the embedded simulated rig
    viscorig check my-test.toml --station lab.toml # the sequence and the lab's station file
    viscorig check --fields                        # the reference of every step type and field

Each problem is one line, ``FILE:LINE: FIELD: what is wrong; how to fix it`` (a did-you-mean for
a misspelt name), in the order of the file. Without ``--station``, every sweep is also matched
with the simulated rig its prompts mount. Exit status 0 when nothing is wrong, 2 otherwise;
``run`` makes the same checks before its first prompt.
"""

from __future__ import annotations

import argparse
import sys
from typing import NoReturn

from viscorig import jsontext
from viscorig.acquisition import format_duration
from viscorig.cli import summary_of
from viscorig.errors import InputError
from viscorig.sequences import FileCheckError, Problem
from viscorig.sequences.reference import reference_markdown
from viscorig.stations.checking import Checked, check_files


def register(subparsers: argparse._SubParsersAction) -> None:
    """Add the ``check`` command."""
    parser = subparsers.add_parser(
        "check", help=summary_of("check"),
        description="Check a sequence (and a station file) and list every problem at once, "
        "each with its file, line and field. Without --station, each sweep is also matched "
        "with the simulated rig its prompts mount.")
    parser.add_argument("sequence", metavar="SEQUENCE.toml", nargs="?", help="test sequence")
    parser.add_argument("--station", metavar="STATION.toml", default=None,
                        help="the lab's station file, checked too (the real rig)")
    parser.add_argument("--json", action="store_true",
                        help="print one JSON object: ok, problems (file, line, field, message, "
                        "hint), runs, test_time_s")
    parser.add_argument("--fields", action="store_true",
                        help="print the reference of every step type and field (Markdown)")
    parser.set_defaults(handler=check_command)


def refuse(checked: Checked, check_command: str | None) -> NoReturn:
    """Stop before anything runs: the first problem in one line, with how many more follow and
    the command that lists them all (``check_command``, when one can).

    Raises
    ------
    FileCheckError
        Always.
    """
    raise FileCheckError(checked.problems, check_command)


def check_command(args: argparse.Namespace) -> int:
    """``viscorig check``."""
    if args.fields:
        sys.stdout.write(reference_markdown())
        return 0
    if args.sequence is None:
        raise InputError("give a sequence file to check (or --fields for the reference)",
                         "SEQUENCE.toml")
    try:
        checked = check_files(args.sequence, args.station)
    except InputError as error:
        if not args.json:
            raise
        # a file that cannot be read is one more problem: the answer is still JSON
        checked = Checked(problems=[Problem(error.where or "", None, "", error.detail)])
    sequence = checked.sequence
    runs = [] if sequence is None else list(sequence.run_names)
    test_time_s = None if sequence is None else sequence.duration_s()
    if args.json:
        print(jsontext.dumps({
            "sequence": args.sequence, "station": args.station, "ok": checked.ok,
            "problems": [problem.as_dict() for problem in checked.problems],
            "runs": runs, "test_time_s": test_time_s,
        }, indent=2))
        return 0 if checked.ok else 2
    for problem in checked.problems:
        print(problem)
    if not checked.ok or sequence is None or test_time_s is None:  # ok: both are set
        count = len(checked.problems)
        print(f"{count} problem{'s' if count != 1 else ''}", file=sys.stderr)
        return 2

    where = (f"station {args.station}" if args.station
             else "the embedded simulated rig: every run matches the rig its prompt mounts")
    adaptive = sum(step.adaptive for step in sequence.sweeps)
    plans = (f" and {adaptive} adaptive plan{'s' if adaptive > 1 else ''} (viscorig plan "
             "predicts them)" if adaptive else "")
    print(f"{args.sequence}: OK, {len(sequence.steps)} steps, {len(runs)} runs "
          f"({', '.join(runs)}), {format_duration(test_time_s)} of sweep test time{plans}; "
          f"{where}")
    return 0
