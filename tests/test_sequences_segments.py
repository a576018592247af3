"""Frequency grids, segment plans, time left and resume positions."""

from __future__ import annotations

import itertools

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from viscorig.errors import InputError
from viscorig.sequences import (
    ANALYSER_MAX_POINTS,
    plan_segments,
    point_count,
    point_durations_s,
    resume_index,
    sweep_frequencies,
    time_left_s,
)


def test_grid_is_inclusive_and_ordered() -> None:
    grid = sweep_frequencies((20.0, 120.0), 0.25)
    assert grid.size == point_count((20.0, 120.0), 0.25) == 401
    assert grid[0] == 20.0 and grid[-1] == 120.0
    np.testing.assert_array_equal(sweep_frequencies((20.0, 120.0), 0.25, "down"), grid[::-1])
    with pytest.raises(ValueError, match="whole number"):
        point_count((20.0, 120.1), 0.25)


def test_paper_sweep_plan() -> None:
    grid = sweep_frequencies((20.0, 120.0), 0.25)
    durations = point_durations_s(grid, 100, 100)
    assert durations[0] == pytest.approx(10.0) and durations[-1] == pytest.approx(200 / 120)
    segments = plan_segments(grid, 100, 100)
    assert [s.stop - s.start for s in segments[:2]] == [6, 6]  # 10 s per point at 20 Hz
    assert len(segments) == 25
    assert all(durations[s].sum() <= 60.0 + 1e-9 for s in segments)
    total = durations.sum()
    assert total == pytest.approx(1439.25, abs=0.01)  # 24 min of dwell
    assert time_left_s(grid, 0, 100, 100) == pytest.approx(total)
    assert time_left_s(grid, 6, 100, 100) == pytest.approx(total - durations[:6].sum())
    assert time_left_s(grid, 401, 100, 100) == 0.0


def test_point_cap_and_long_points() -> None:
    fast = np.linspace(10_000.0, 11_000.0, 2000)
    segments = plan_segments(fast, 0, 1, max_segment_s=3600.0)
    assert max(s.stop - s.start for s in segments) == ANALYSER_MAX_POINTS
    slow = np.array([0.5, 0.5, 0.5])  # 400 s per point, longer than a segment
    assert plan_segments(slow, 100, 100) == [slice(0, 1), slice(1, 2), slice(2, 3)]
    with pytest.raises(ValueError):
        plan_segments(fast, 0, 1, max_points=900)


@given(
    frequency=st.lists(st.floats(0.1, 25_600.0), min_size=1, max_size=300),
    settle=st.integers(0, 500),
    integrate=st.integers(1, 500),
    budget=st.floats(1.0, 600.0),
    max_points=st.integers(1, ANALYSER_MAX_POINTS),
)
def test_plan_covers_every_point_once_within_limits(
    frequency: list[float], settle: int, integrate: int, budget: float, max_points: int
) -> None:
    segments = plan_segments(frequency, settle, integrate, max_segment_s=budget,
                             max_points=max_points)
    assert segments[0].start == 0 and segments[-1].stop == len(frequency)
    assert all(a.stop == b.start for a, b in itertools.pairwise(segments))
    durations = point_durations_s(frequency, settle, integrate)
    for part in segments:
        count = part.stop - part.start
        assert 1 <= count <= max_points
        assert count == 1 or durations[part].sum() <= budget * (1 + 1e-9)


def test_resume_continues_after_the_measured_prefix() -> None:
    planned = sweep_frequencies((20.0, 30.0), 0.25)
    measured = planned[:7] + 0.003  # the analyser rounds to 15.625 mHz
    assert resume_index(planned, measured) == 7
    assert resume_index(planned, []) == 0
    with pytest.raises(InputError, match="cannot be continued"):
        resume_index(planned, planned[1:8], where="c.h5: /runs/soft-0")
