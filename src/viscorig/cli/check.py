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
import json
import re
import sys
from dataclasses import dataclass, field
from typing import NoReturn

from viscorig.acquisition import format_duration
from viscorig.cli import summary_of
from viscorig.cli.stations import embedded_chamber_station, simulated_rig_problems
from viscorig.errors import InputError
from viscorig.sequences import (
    ChamberStation,
    FileCheckError,
    Problem,
    Sequence,
    Station,
    parse_sequence,
    parse_station,
)
from viscorig.sequences.reference import reference_markdown
from viscorig.sequences.sequence import read_text
from viscorig.sequences.setpoints import set_point_problems

_TOML_LINE = re.compile(r"\(at line (\d+), column \d+\)")


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


@dataclass
class Checked:
    """What checking a sequence (and station) found."""

    sequence: Sequence | None = None
    sequence_text: str = ""
    station: Station | None = None
    station_text: str | None = None
    problems: list[Problem] = field(default_factory=list)

    @property
    def ok(self) -> bool:
        return not self.problems and self.sequence is not None

    def passed(self) -> Sequence:
        """The sequence of a check that found no problem (:attr:`ok`); ``ValueError`` else."""
        if not self.ok or self.sequence is None:
            raise ValueError("the sequence did not pass its check")
        return self.sequence


def _problems_of(error: InputError, source: str) -> list[Problem]:
    if isinstance(error, FileCheckError):
        return error.problems
    found = _TOML_LINE.search(error.detail)
    line = int(found.group(1)) if found else None
    return [Problem(source, line, "", error.detail)]


def check_texts(sequence_text: str, sequence_source: str, station_text: str | None = None,
                station_source: str = "") -> Checked:
    """Check a sequence and optional station given as texts; nothing raises for bad content.

    Without a station, each sweep is matched with the simulated rig its prompts mount.
    """
    checked = Checked(sequence_text=sequence_text, station_text=station_text)
    try:
        checked.sequence = parse_sequence(sequence_text, source=sequence_source)
    except InputError as error:
        checked.problems += _problems_of(error, sequence_source)
    if station_text is not None:
        try:
            checked.station = parse_station(station_text, source=station_source)
        except InputError as error:
            checked.problems += _problems_of(error, station_source)
    elif checked.sequence is not None:
        checked.problems += simulated_rig_problems(checked.sequence, sequence_text)
    if checked.sequence is not None and checked.sequence.soaks and (
            station_text is None or checked.station is not None):
        chamber: ChamberStation | None
        if checked.station is None:
            chamber, name = embedded_chamber_station(checked.sequence), "the embedded rig"
        else:
            chamber, name = checked.station.chamber, station_source
        checked.problems += set_point_problems(checked.sequence, chamber, sequence_text, name)
    return checked


def check_files(sequence_path: str, station_path: str | None) -> Checked:
    """Read and check the files ``run`` and ``check`` are given.

    Raises
    ------
    InputError
        A file cannot be read.
    """
    sequence_text = read_text(sequence_path)
    station_text = None if station_path is None else read_text(station_path)
    return check_texts(sequence_text, sequence_path, station_text, station_path or "")


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
    checked = check_files(args.sequence, args.station)
    sequence = checked.sequence
    runs = [] if sequence is None else list(sequence.run_names)
    test_time_s = None if sequence is None else sequence.duration_s()
    if args.json:
        print(json.dumps({
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
