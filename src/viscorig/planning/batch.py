"""From an allocation of integration time to points the analyser can measure.

Each frequency given time gets whole integration cycles, split into repeated points where it
needs more than the analyser's largest ``SWE:DWEL`` (a repeat at the same frequency needs no
settle: the rig is already in its steady state). The points are measured in one direction
(the one that starts nearer to where the rig is), so the source level changes little from
point to point; each point's settle follows the transient model
(:mod:`viscorig.planning.transient`) and each point's rig time the timing model.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from viscorig.models import Context
from viscorig.planning.information import InformationModel
from viscorig.planning.instrument import (
    ANALYSER,
    SIMULATED_TIMING,
    AnalyserLimits,
    PointTiming,
)
from viscorig.planning.noise import model_amplitudes
from viscorig.planning.points import PlannedPoint
from viscorig.planning.transient import Mode, settle_s, step_mismatch

#: A point at least this long always gets a lead-in (a second pass of it would be costly).
LONG_POINT_CYCLES = 20

__all__ = [
    "PointContext",
    "allocation_points",
    "landing_db",
    "merge_neighbours",
    "order_points",
    "point_context",
    "settle_points",
]


@dataclass(frozen=True)
class PointContext:
    """What settling and timing need to know about the rig (from its current model).

    Attributes
    ----------
    modes
        Identified modes.
    response
        ``f -> ẍ_s/F_e`` (complex), for the motion's phase to the source.
    source
        ``f -> |F_e|`` needed at the level (proportional to the source level needed).
    noise_sd
        ``(f, integrate_s) -> relative noise standard deviation`` of a point (largest FRF).
    """

    modes: Sequence[Mode]
    response: Callable[[NDArray[np.float64]], NDArray[np.complex128]]
    source: Callable[[NDArray[np.float64]], NDArray[np.float64]]
    noise_sd: Callable[[NDArray[np.float64], NDArray[np.float64]], NDArray[np.float64]]


def allocation_points(
    frequency_hz: NDArray[np.float64],
    integrate_s: NDArray[np.float64],
    *,
    max_integrate_cycles: int,
    limits: AnalyserLimits = ANALYSER,
) -> list[tuple[float, int]]:
    """``(frequency, integrate cycles)`` of the points that carry an allocation.

    Frequencies with less than half a cycle of time are dropped; the others get at least the
    allocation, in whole cycles, in as few points as the cycle limit allows.
    """
    cap = min(max_integrate_cycles, limits.max_integrate_cycles)
    points: list[tuple[float, int]] = []
    for f, seconds in zip(frequency_hz, integrate_s, strict=True):
        cycles = seconds * f
        if cycles < 0.5:
            continue
        count = max(1, math.ceil(cycles / cap - 1e-9))
        each = int(limits.integrate_cycles(cycles / count))
        points += [(float(f), each)] * count
    return points


def order_points(points: Sequence[tuple], previous_hz: float | None) -> list[tuple]:
    """Points sorted in the direction that starts nearer to ``previous_hz``."""
    ordered = sorted(points, key=lambda p: p[0])
    if (
        previous_hz is not None
        and ordered
        and abs(ordered[-1][0] - previous_hz) < abs(ordered[0][0] - previous_hz)
    ):
        ordered.reverse()
    return ordered


def landing_db(
    points: Sequence[tuple],
    previous_hz: float | None,
    context: PointContext,
    timing: PointTiming = SIMULATED_TIMING,
    start_db: float = 0.0,
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Where the auto level lands at each point (dB from the level asked for), and the
    controller's passes.

    The controller accepts a point whose reference is within its tolerance and otherwise
    corrects the source (exactly, on a linear rig) and measures again. Starting ``start_db``
    from the level (the last point's reference, measured), a change of the needed source level
    by ``x`` dB leaves the reference at ``start − x``: kept when within the tolerance (one
    pass), corrected to 0 otherwise (two passes). From rest the controller always corrects.
    A point measured ``y`` dB from the level carries ``10^(y/10)`` of the information it would
    at the level (the sensors' noise does not follow the signal).
    """
    f = np.array([p[0] for p in points], dtype=float)
    if f.size == 0:
        return np.zeros(0), np.zeros(0)
    frequencies = np.concatenate([[previous_hz if previous_hz else f[0]], f])
    force = context.source(frequencies)
    change = 20.0 * np.log10(force[1:] / force[:-1])
    landing, passes = np.zeros(f.size), np.ones(f.size)
    offset = start_db
    for i in range(f.size):
        error = offset - change[i]
        if (i == 0 and previous_hz is None) or abs(error) > timing.tolerance_db:
            offset, passes[i] = 0.0, 2.0
        else:
            offset = error
        landing[i] = offset
    return landing, passes


def settle_points(
    points: Sequence[tuple[float, int, str]],
    previous_hz: float | None,
    context: PointContext,
    *,
    bias_fraction: float = 0.3,
    max_settle_cycles: int | None = None,
    timing: PointTiming = SIMULATED_TIMING,
    limits: AnalyserLimits = ANALYSER,
    lead_cycles: int = 1,
    settle_factor: float = 1.0,
    start_db: float = 0.0,
) -> tuple[list[PlannedPoint], NDArray[np.float64]]:
    """Planned points with their settle cycles, in the given order, and each one's rig time.

    ``points`` holds ``(frequency, integrate cycles, purpose)``.

    Where the source level must change by more than the auto-level tolerance, the controller
    measures a point twice (settle and integration each time); where the last level was near
    the tolerance's edge a small change does it too. So before a long point, or where the level
    moves by more than half the tolerance, a short *lead-in* point at the same frequency
    (``lead_cycles`` of integration, the settle the next point needs) takes the controller's
    passes, and the point follows in one pass without settling (the rig is in its steady state
    at a level within tolerance): one cycle more than without it, and never a second pass of a
    long point. ``settle_factor`` lengthens
    every settle (a transient seen in the data decays slower than the identified modes say);
    ``start_db`` is where the last point's reference stands from the level (:func:`landing_db`).
    """
    if not points:
        return [], np.zeros(0)
    f = np.array([p[0] for p in points])
    cycles = np.array([p[1] for p in points], dtype=float)
    purposes = [p[2] for p in points]
    integrate = cycles / f
    noise = context.noise_sd(f, integrate)
    frequencies = np.concatenate([[previous_hz if previous_hz else f[0]], f])
    force = context.source(frequencies)
    source_ratio = force[1:] / force[:-1]
    _, passes = landing_db(points, previous_hz, context, timing, start_db)
    planned: list[PlannedPoint] = []
    seconds: list[float] = []
    cap = limits.max_settle_cycles if max_settle_cycles is None else max_settle_cycles
    last = previous_hz
    for i in range(f.size):
        purpose = purposes[i]
        if last is not None and abs(f[i] - last) < 1e-12 and passes[i] == 1.0:
            planned.append(PlannedPoint(float(f[i]), 0, int(cycles[i]), purpose))
            seconds.append(float(timing.point_s(f[i], 0, cycles[i])))
            continue
        ratio = source_ratio[i] if np.isfinite(source_ratio[i]) else 1.0
        mismatch = step_mismatch(f[i], last, context.response, ratio, timing.tolerance_db)
        # a lead-in costs one cycle more; it pays where a second pass is expected or would be
        # costly (a long point: the prediction may be off by the reference's own scatter)
        lead = cycles[i] > 2 * lead_cycles and (passes[i] > 1 or cycles[i] >= LONG_POINT_CYCLES)
        wait = settle_s(
            f[i], last, list(context.modes), mismatch=mismatch, noise_sd=float(noise[i]),
            integrate_s=float(integrate[i]), bias_fraction=bias_fraction,
        )  # fmt: skip
        if lead:  # the lead-in is a point of its own: short, so noisier but less averaged
            lead_s = lead_cycles / f[i]
            lead_noise = float(context.noise_sd(f[i : i + 1], np.array([lead_s]))[0])
            wait = max(wait, settle_s(
                f[i], last, list(context.modes), mismatch=mismatch, noise_sd=lead_noise,
                integrate_s=lead_s, bias_fraction=bias_fraction,
            ))  # fmt: skip
        settle_cycles = min(int(limits.settle_cycles(settle_factor * wait * f[i])), int(cap))
        if lead:
            planned.append(PlannedPoint(float(f[i]), settle_cycles, lead_cycles, purpose))
            seconds.append(float(timing.point_s(f[i], settle_cycles, lead_cycles, passes[i])))
            planned.append(PlannedPoint(float(f[i]), 0, int(cycles[i]), purpose))
            seconds.append(float(timing.point_s(f[i], 0, cycles[i])))
        else:
            planned.append(PlannedPoint(float(f[i]), settle_cycles, int(cycles[i]), purpose))
            seconds.append(float(timing.point_s(f[i], settle_cycles, cycles[i], passes[i])))
        last = f[i]
    return planned, np.array(seconds)


def point_context(info: InformationModel, modes: list[Mode]) -> PointContext:
    """What settling and timing need, from the current model of the rig."""
    def response(f: NDArray[np.float64]) -> NDArray[np.complex128]:
        f = np.atleast_1d(f)
        ctx = Context(f, np.zeros_like(f), np.full_like(f, info.level_m_per_s2))
        return info.model.predict(ctx, info.values)["table"]

    def source(f: NDArray[np.float64]) -> NDArray[np.float64]:
        amplitudes = model_amplitudes(
            info.model, info.values, f, info.level_m_per_s2, force_limit_n=info.force_limit_n
        )
        return amplitudes.excitation_force

    def noise_sd(f: NDArray[np.float64], integrate_s: NDArray[np.float64]) -> NDArray:
        power = info.noise_power(f, integrate_s)
        return np.sqrt(np.max(np.vstack(list(power.values())), axis=0))

    return PointContext(modes, response, source, noise_sd)


def merge_neighbours(
    frequency: NDArray[np.float64],
    seconds: NDArray[np.float64],
    distance_hz: float,
    limits: AnalyserLimits,
) -> NDArray[np.float64]:
    """Support frequencies closer than ``distance_hz`` merged into their time-weighted mean,
    set on the analyser's grid (fewer frequencies: fewer settles)."""
    order = np.argsort(frequency)
    frequency, seconds = frequency[order], seconds[order]
    groups: list[list[int]] = [[0]]
    for i in range(1, frequency.size):
        if frequency[i] - frequency[groups[-1][-1]] <= distance_hz:
            groups[-1].append(i)
        else:
            groups.append([i])
    merged = [
        float(limits.round_down(np.average(frequency[g], weights=seconds[g] + 1e-300)))
        for g in groups
    ]
    return np.unique(np.array(merged))
