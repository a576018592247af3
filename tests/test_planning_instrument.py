"""The analyser's facts a plan obeys, and the rig time of points (against the simulator)."""

from __future__ import annotations

import numpy as np
import pytest
from planning_rig import VOIGT_RIG, SimulatedRig

from viscorig.planning import ANALYSER, PointTiming, coverage_grid, coverage_ratio, log_grid


def test_frequencies_round_down_to_the_next_15_625_mhz_step():
    assert ANALYSER.round_down([20.0, 20.01, 26.2599, 0.0156249])[:3].tolist() == [
        20.0, 20.0, 26.25]  # fmt: skip
    assert ANALYSER.round_down([0.015625 * 7])[0] == pytest.approx(0.109375)


def test_the_grid_stays_inside_the_band_on_whole_steps():
    grid = ANALYSER.grid((20.003, 21.0), 0.25)
    assert grid[0] >= 20.003 and grid[-1] <= 21.0
    assert np.allclose(np.diff(grid), 0.25)
    assert np.allclose(grid / 0.015625, np.round(grid / 0.015625))
    with pytest.raises(ValueError, match="no analyser frequency"):
        ANALYSER.grid((20.001, 20.01))


def test_cycles_are_whole_and_within_the_dwell_range():
    assert ANALYSER.integrate_cycles([0.2, 1.0, 1.5, 234.0, 500.0]).tolist() == [1, 1, 2, 234, 234]
    assert ANALYSER.settle_cycles([-1.0, 0.0, 2.2]).tolist() == [0, 0, 3]


def test_point_time_is_what_the_simulated_rig_takes():
    rig = SimulatedRig(VOIGT_RIG, 1.4, seed=1)
    rig.measure([30.0], 200, 10)  # the controller has found its level
    f = np.array([30.0, 30.0, 30.0])
    measured = rig.measure(f, [0, 7, 3], [12, 5, 40])
    predicted = PointTiming().point_s(f, [0, 7, 3], [12, 5, 40])
    assert np.allclose(measured.duration_s, predicted)
    # a large change of the source level costs the controller a second pass
    jump = rig.measure([120.0], 30, 20)
    assert jump.duration_s[0] == pytest.approx(2 * 50 / 120.0)


def test_overhead_is_calibrated_from_measured_times():
    timing = PointTiming().calibrated([50.0, 50.0], [0, 0], [100, 100], [2.3, 2.3])
    assert timing.overhead_s == pytest.approx(0.3)
    assert PointTiming().calibrated([50.0], [0], [100], [1.5]).overhead_s == 0.0


def test_coverage_leaves_no_gap_wider_than_a_narrow_mode():
    full = log_grid((20.0, 120.0), 47)
    look = full[np.round(np.linspace(0, 46, 10)).astype(int)]  # a first look on that grid
    added = coverage_grid((20.0, 120.0), look, narrowest_damping_ratio=0.02)
    every = np.unique(np.concatenate([look, added]))
    assert np.max(every[1:] / every[:-1]) <= coverage_ratio(0.02) * 1.001
    assert every.size == 47  # 20-120 Hz at 4 % (module docstring)
    assert coverage_grid((20.0, 120.0), every).size == 0
