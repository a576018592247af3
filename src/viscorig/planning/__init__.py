"""Rig-time planning: how long a swept-sine test must be, and which points to measure.

A pure core (no transport, no simulator): the noise of a point from the physics of the
measurement (:mod:`~viscorig.planning.noise`), the Fisher information of points about a model's
parameters (:mod:`~viscorig.planning.information`), the minimum-time optimal design and its
certified floor (:mod:`~viscorig.planning.design`, :mod:`~viscorig.planning.bound`), the settle
a transient needs (:mod:`~viscorig.planning.transient`), and the adaptive plan that looks, fits
and chooses points until the wanted uncertainties are reached
(:mod:`~viscorig.planning.adaptive`). A plan reaches a rig only through a *measure* callable
(:mod:`~viscorig.planning.points`).
"""

from viscorig.planning.adaptive import (
    AdaptivePlan,
    AdaptiveSettings,
    NextPoints,
    PlanOutcome,
    PlanStep,
    State,
    expected_time_s,
    weighted_fit_function,
)
from viscorig.planning.bound import DesignBound, design_bound
from viscorig.planning.coverage import coverage_grid, coverage_ratio, log_grid
from viscorig.planning.design import Design, minimum_time_design
from viscorig.planning.information import InformationModel, log_sensitivities
from viscorig.planning.instrument import ANALYSER, AnalyserLimits, PointTiming
from viscorig.planning.noise import (
    ChannelAmplitudes,
    FrfNoiseForecast,
    NoiseForecast,
    fit_noise_forecast,
    measured_amplitudes,
    model_amplitudes,
    point_noise_power,
    shared_noise,
)
from viscorig.planning.points import (
    MeasuredPoints,
    MeasureFunction,
    PlannedPoint,
    SweepSegment,
    sweep_segments,
)
from viscorig.planning.transient import Mode, identified_modes, settle_s, step_mismatch

__all__ = [
    "ANALYSER",
    "AdaptivePlan",
    "AdaptiveSettings",
    "AnalyserLimits",
    "ChannelAmplitudes",
    "Design",
    "DesignBound",
    "FrfNoiseForecast",
    "InformationModel",
    "MeasureFunction",
    "MeasuredPoints",
    "Mode",
    "NextPoints",
    "NoiseForecast",
    "PlanOutcome",
    "PlanStep",
    "PlannedPoint",
    "PointTiming",
    "State",
    "SweepSegment",
    "coverage_grid",
    "coverage_ratio",
    "design_bound",
    "expected_time_s",
    "fit_noise_forecast",
    "identified_modes",
    "log_grid",
    "log_sensitivities",
    "measured_amplitudes",
    "minimum_time_design",
    "model_amplitudes",
    "point_noise_power",
    "settle_s",
    "shared_noise",
    "step_mismatch",
    "sweep_segments",
    "weighted_fit_function",
]
