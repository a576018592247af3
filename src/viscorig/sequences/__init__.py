"""Test sequences and station files (TOML): typed, validated steps and lab descriptions.

A sequence is a list of small steps (prompt, wait, sweep, identify_table) with defaults at the
top; a station file says what is attached to the analyser. Both are read against the schema of
:mod:`viscorig.sequences.schema`, which also generates their reference, and every problem of a
file is reported at once (:class:`FileCheckError`, an :class:`viscorig.errors.InputError`), each
naming the file, line and field.
"""

from viscorig.sequences.levels import parse_level
from viscorig.sequences.problems import FileCheckError, Problem
from viscorig.sequences.segments import (
    ANALYSER_MAX_POINTS,
    DEFAULT_SEGMENT_S,
    plan_segments,
    point_count,
    point_durations_s,
    resume_index,
    sweep_frequencies,
    time_left_s,
)
from viscorig.sequences.sequence import load_sequence, parse_sequence
from viscorig.sequences.station import (
    ChamberStation,
    Channels,
    Sensitivities,
    SpecimenGeometry,
    Station,
    TableParameters,
    load_station,
    parse_station,
)
from viscorig.sequences.steps import (
    OVER_LIMIT_CHOICES,
    IdentifyTableStep,
    PromptStep,
    Sequence,
    Step,
    SweepStep,
    TemperatureStep,
    WaitStep,
)

__all__ = [
    "ANALYSER_MAX_POINTS",
    "DEFAULT_SEGMENT_S",
    "OVER_LIMIT_CHOICES",
    "ChamberStation",
    "Channels",
    "FileCheckError",
    "IdentifyTableStep",
    "Problem",
    "PromptStep",
    "Sensitivities",
    "Sequence",
    "SpecimenGeometry",
    "Station",
    "Step",
    "SweepStep",
    "TableParameters",
    "TemperatureStep",
    "WaitStep",
    "load_sequence",
    "load_station",
    "parse_level",
    "parse_sequence",
    "parse_station",
    "plan_segments",
    "point_count",
    "point_durations_s",
    "resume_index",
    "sweep_frequencies",
    "time_left_s",
]
