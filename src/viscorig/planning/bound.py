"""The physical floor: the least rig time any plan needs for the wanted uncertainties.

For a rig whose model, noise and level are known, :func:`design_bound` solves the minimum-time
design over every frequency the analyser can set in the band (no prior information: the plan
knows nothing before it starts) and reports

- ``integration_floor_s``: a certified lower bound on the integration time of *any* plan that
  reaches the targets (:mod:`viscorig.planning.design`);
- ``plan``: that optimal design as points the analyser can measure (whole cycles, at most the
  largest integration per point, repeats at one frequency unsettled), settled from rest by the
  transient model, and ``plan_time_s``, its rig time, settle included. A plan that must first
  learn the rig can approach this figure but not beat it by more than the rounding to cycles.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np

from viscorig.models import Model
from viscorig.planning.batch import (
    allocation_points,
    merge_neighbours,
    order_points,
    point_context,
    settle_points,
)
from viscorig.planning.design import Design, minimum_time_design
from viscorig.planning.information import InformationModel
from viscorig.planning.instrument import (
    ANALYSER,
    SIMULATED_TIMING,
    AnalyserLimits,
    PointTiming,
)
from viscorig.planning.noise import NoiseForecast
from viscorig.planning.points import PlannedPoint
from viscorig.planning.transient import identified_modes
from viscorig.sequences.schema import LONGEST_S

__all__ = ["DesignBound", "design_bound"]


#: Integration floor beyond which no plan is laid out (the longest dwell a step may have); the
#: bound is then its floor alone.
PLAN_LIMIT_S = LONGEST_S


@dataclass(frozen=True)
class DesignBound:
    """The least rig time for the targets on a known rig.

    Attributes
    ----------
    integration_floor_s
        Certified lower bound on the integration time of any plan.
    design
        The optimal allocation over every candidate frequency.
    plan
        The design as analyser points, in measurement order (none when the floor is beyond
        :data:`PLAN_LIMIT_S`).
    plan_time_s
        Rig time of ``plan``, settle and controller passes included (the integration floor
        where no plan is laid out).
    relative_stderr
        Predicted relative standard error of each target with ``plan``.
    """

    integration_floor_s: float
    design: Design
    plan: tuple[PlannedPoint, ...]
    plan_time_s: float
    relative_stderr: dict[str, float]

    @property
    def settle_s(self) -> float:
        """Rig time of ``plan`` beyond its integration."""
        integration = sum(p.integrate_cycles / p.frequency_hz for p in self.plan)
        return self.plan_time_s - integration


def design_bound(
    model: Model,
    values: Mapping[str, float],
    names: tuple[str, ...],
    noise: NoiseForecast,
    level_m_per_s2: float,
    band_hz: tuple[float, float],
    targets: Mapping[str, float],
    *,
    resolution_hz: float | None = None,
    force_limit_n: float | None = None,
    timing: PointTiming = SIMULATED_TIMING,
    limits: AnalyserLimits = ANALYSER,
    bias_fraction: float = 0.3,
    max_integrate_cycles: int | None = None,
) -> DesignBound:
    """The floor and the optimal plan for ``targets`` (relative standard errors by name).

    Parameters
    ----------
    model, values
        The rig's model and its parameter values (fixed ones included).
    names
        The parameters a fit would estimate (targets and nuisance parameters).
    noise, level_m_per_s2, force_limit_n
        The noise model, the level held and the shaker's limit.
    band_hz
        Frequencies allowed.
    resolution_hz
        Candidate spacing (default: every analyser frequency in the band).
    """
    info = InformationModel(model, dict(values), tuple(names), noise, level_m_per_s2,
                            force_limit_n)  # fmt: skip
    candidates = limits.grid(band_hz, resolution_hz)
    index = [names.index(name) for name in targets]
    wanted = np.array([targets[name] for name in targets])
    design = minimum_time_design(candidates, info.rate(candidates), index, wanted)
    if not design.lower_bound_s <= PLAN_LIMIT_S:
        # no plan to lay out point by point (a target of 1e-7 made tens of millions of them)
        floor = float(design.lower_bound_s) if np.isfinite(design.lower_bound_s) else PLAN_LIMIT_S
        return DesignBound(integration_floor_s=floor, design=design, plan=(),
                           plan_time_s=floor, relative_stderr={})
    support = design.support(1e-4)
    step = resolution_hz or limits.frequency_step_hz
    merged = merge_neighbours(
        candidates[support], design.integrate_s[support], max(2.5 * step, 0.1), limits
    )
    exact = minimum_time_design(merged, info.rate(merged), index, wanted)
    cap = limits.max_integrate_cycles if max_integrate_cycles is None else max_integrate_cycles
    allocated = allocation_points(merged, exact.integrate_s, max_integrate_cycles=cap,
                                  limits=limits)  # fmt: skip
    points = order_points([(f, c, "refine") for f, c in allocated], None)
    modes = identified_modes(model, values, band_hz)
    plan, seconds = settle_points(
        points, None, point_context(info, modes), bias_fraction=bias_fraction, timing=timing,
        limits=limits,
    )  # fmt: skip
    f = np.array([p.frequency_hz for p in plan])
    integrate = np.array([p.integrate_cycles for p in plan]) / f
    # a design for one target may leave a nuisance direction unlearnt: the target's variance
    # is then that of the pseudo-inverse (it is estimable, the design says so)
    covariance = np.linalg.pinv(info.of_points(f, integrate), rcond=1e-13)
    stderr = np.sqrt(np.abs(np.diag(covariance)))
    return DesignBound(
        integration_floor_s=design.lower_bound_s,
        design=design,
        plan=tuple(plan),
        plan_time_s=float(seconds.sum()),
        relative_stderr={name: float(stderr[i]) for name, i in zip(targets, index, strict=True)},
    )
