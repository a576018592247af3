"""Frequency grids, segment plans and time estimates of a stepped-sine sweep (pure functions).

Test time per point is the settle plus integration cycles at that frequency, plus an optional
fixed overhead (ranging, communication). A run is measured in segments so that data is
committed at least every ``max_segment_s`` seconds of test time; each segment is also one
analyser sweep, so it holds at most the 35670A's 801 points.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import ArrayLike, NDArray

from viscorig.analyser import ANALYSER_MAX_POINTS
from viscorig.errors import InputError

#: The 35670A measures at most this many points in one swept-sine sweep.
#: Default longest test time between two commits of a run.
DEFAULT_SEGMENT_S = 60.0


def point_count(band_hz: tuple[float, float], resolution_hz: float) -> int:
    """Number of grid points from lo to hi inclusive; the band must be whole steps.

    Raises
    ------
    ValueError
        ``hi - lo`` is not a whole number of ``resolution_hz`` steps.
    """
    lo, hi = band_hz
    steps = (hi - lo) / resolution_hz
    if not math.isclose(steps, round(steps), rel_tol=0.0, abs_tol=1e-6 * max(1.0, steps)):
        raise ValueError(
            f"band {lo:g}-{hi:g} Hz is not a whole number of {resolution_hz:g} Hz steps"
        )
    return round(steps) + 1


def sweep_frequencies(
    band_hz: tuple[float, float], resolution_hz: float, direction: str = "up"
) -> NDArray[np.float64]:
    """The sweep's frequency grid in Hz, in measurement order (``"up"`` or ``"down"``)."""
    lo, _ = band_hz
    steps = np.arange(point_count(band_hz, resolution_hz))
    grid = np.asarray(lo + resolution_hz * steps, dtype=np.float64)
    return grid[::-1].copy() if direction == "down" else grid


def point_durations_s(
    frequency_hz: ArrayLike,
    settle_cycles: ArrayLike,
    integrate_cycles: ArrayLike,
    overhead_s_per_point: float = 0.0,
) -> NDArray[np.float64]:
    """Test time of each point: (settle + integrate cycles) / f + overhead, in s (the cycles
    one number for every point, or one per point)."""
    frequency = np.asarray(frequency_hz, dtype=float)
    cycles = np.asarray(settle_cycles, dtype=float) + np.asarray(integrate_cycles, dtype=float)
    return cycles / frequency + overhead_s_per_point


def plan_segments(
    frequency_hz: ArrayLike,
    settle_cycles: int,
    integrate_cycles: int,
    *,
    max_segment_s: float = DEFAULT_SEGMENT_S,
    max_points: int = ANALYSER_MAX_POINTS,
    overhead_s_per_point: float = 0.0,
) -> list[slice]:
    """Split a sweep into consecutive segments of at most ``max_segment_s`` of test time.

    Each segment also holds at most ``max_points`` points (the analyser's per-sweep limit). A
    single point longer than ``max_segment_s`` is a segment of its own.

    Returns
    -------
    list of slice
        Slices into ``frequency_hz``, covering it in order without gaps or overlaps.
    """
    if not 1 <= max_points <= ANALYSER_MAX_POINTS:
        raise ValueError(f"max_points must be in [1, {ANALYSER_MAX_POINTS}], not {max_points}")
    durations = point_durations_s(frequency_hz, settle_cycles, integrate_cycles,
                                  overhead_s_per_point)
    ends = np.cumsum(durations)
    segments: list[slice] = []
    start, count = 0, durations.size
    while start < count:
        before = ends[start - 1] if start else 0.0
        # the last point whose cumulative time stays within the segment budget (at least one)
        stop = int(np.searchsorted(ends, before + max_segment_s * (1 + 1e-12), side="right"))
        stop = min(max(stop, start + 1), start + max_points, count)
        segments.append(slice(start, stop))
        start = stop
    return segments


def time_left_s(
    frequency_hz: ArrayLike,
    done_points: int,
    settle_cycles: int,
    integrate_cycles: int,
    overhead_s_per_point: float = 0.0,
) -> float:
    """Test time still needed after the first ``done_points`` points of a sweep, in s."""
    durations = point_durations_s(frequency_hz, settle_cycles, integrate_cycles,
                                  overhead_s_per_point)
    return float(durations[max(done_points, 0):].sum())


def resume_index(planned_hz: ArrayLike, measured_hz: ArrayLike, *, where: str = "") -> int:
    """Index of the first planned point not yet measured, for continuing a run.

    Raises
    ------
    InputError
        The measured frequencies are not the beginning of the planned ones (the sequence or
        the file changed), so continuing would mix two different sweeps.
    """
    planned = np.asarray(planned_hz, dtype=float)
    measured = np.asarray(measured_hz, dtype=float)
    # the analyser rounds frequencies to 15.625 mHz; half of that tells points apart
    if measured.size > planned.size or not np.allclose(
        measured, planned[: measured.size], rtol=0.0, atol=0.0078125
    ):
        raise InputError(
            f"the {measured.size} measured frequencies are not the start of the planned "
            f"{planned.size}-point sweep; the run cannot be continued",
            where or None,
        )
    return int(measured.size)
