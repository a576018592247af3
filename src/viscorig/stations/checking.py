"""Checking a sequence (and a station file) before anything runs: every problem at once.

``viscorig check``, ``run``, ``plan`` and the bench's queue all check through
:func:`check_files` (or :func:`check_texts` for texts a campaign file holds); without a
station, each sweep is also matched with the simulated rig its prompts mount.
"""

from __future__ import annotations

import re
from dataclasses import dataclass, field

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
from viscorig.sequences.sequence import read_text
from viscorig.sequences.setpoints import set_point_problems
from viscorig.stations.opening import embedded_chamber_station, simulated_rig_problems

__all__ = ["Checked", "check_files", "check_texts"]

_TOML_LINE = re.compile(r"\(at line (\d+), column \d+\)")


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
