"""Acquisition: drive an analyser through a sequence, segment by segment, into a campaign file.

A sequence is a plan of small steps (:mod:`~viscorig.acquisition.plans`,
:mod:`~viscorig.acquisition.stubs`, the adaptive sweep of :mod:`~viscorig.acquisition.adaptive`)
that a run engine executes (:mod:`~viscorig.acquisition.engine`). The core knows analysers only
through :class:`~viscorig.acquisition.protocol.Analyser`, a structural protocol that the 35670A
driver satisfies; the command line wires a driver in.
"""

from viscorig.acquisition.console import Console, NoAnswer, format_duration
from viscorig.acquisition.engine import EngineState, Msg, RunEngine, RunRefused
from viscorig.acquisition.forecast import Floor, StepForecast, forecast_sequence, format_forecast
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
from viscorig.acquisition.plans import SweepMeasurement
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
    SweepSettings,
    Wiring,
    configure,
)

__all__ = [
    "OVER_LIMIT_CHOICES",
    "PROBE_LEVEL_FRACTION",
    "Analyser",
    "Console",
    "EngineState",
    "Floor",
    "ForceEstimate",
    "MeasuredSegment",
    "Msg",
    "NoAnswer",
    "Outcome",
    "PointAnalyser",
    "ProbeReading",
    "RigEstimate",
    "RunEngine",
    "RunRefused",
    "RunResult",
    "RunState",
    "Runner",
    "RunnerOptions",
    "SegmentDone",
    "StepForecast",
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
    "forecast_sequence",
    "format_duration",
    "format_forecast",
    "measure_probe",
    "motion_ratio",
    "point_flags",
    "probe_frequencies_hz",
    "probe_test_time_s",
    "source_limit_v",
    "specimen_from_accelerance",
]
