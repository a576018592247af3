"""Acquisition: drive an analyser through a sequence, segment by segment, into a campaign file.

The core knows analysers only through :class:`~viscorig.acquisition.protocol.Analyser`, a
structural protocol that the 35670A driver satisfies; the command line wires a driver in.
"""

from viscorig.acquisition.console import Console, NoAnswer, format_duration
from viscorig.acquisition.limits import (
    PROBE_LEVEL_FRACTION,
    ForceEstimate,
    ProbeReading,
    RigEstimate,
    estimate_force,
    estimate_force_from_probe,
    motion_ratio,
    point_flags,
    source_limit_v,
    specimen_from_accelerance,
)
from viscorig.acquisition.probe import measure_probe, probe_frequencies_hz, probe_test_time_s
from viscorig.acquisition.protocol import (
    Analyser,
    MeasuredSegment,
    PointAnalyser,
    SweepProgressReport,
)
from viscorig.acquisition.runner import (
    OVER_LIMIT_CHOICES,
    Outcome,
    Runner,
    RunnerOptions,
    RunResult,
    RunState,
    StepRecord,
)
from viscorig.acquisition.sweep import (
    SegmentDone,
    SweepHooks,
    SweepInterrupted,
    SweepMeasurement,
    SweepSettings,
    Wiring,
    configure,
)

__all__ = [
    "OVER_LIMIT_CHOICES",
    "PROBE_LEVEL_FRACTION",
    "Analyser",
    "Console",
    "ForceEstimate",
    "MeasuredSegment",
    "NoAnswer",
    "Outcome",
    "PointAnalyser",
    "ProbeReading",
    "RigEstimate",
    "RunResult",
    "RunState",
    "Runner",
    "RunnerOptions",
    "SegmentDone",
    "StepRecord",
    "SweepHooks",
    "SweepInterrupted",
    "SweepMeasurement",
    "SweepProgressReport",
    "SweepSettings",
    "Wiring",
    "configure",
    "estimate_force",
    "estimate_force_from_probe",
    "format_duration",
    "measure_probe",
    "motion_ratio",
    "point_flags",
    "probe_frequencies_hz",
    "probe_test_time_s",
    "source_limit_v",
    "specimen_from_accelerance",
]
