"""The physical floor on a simulated Voigt rig: its scaling laws and its plan."""

from __future__ import annotations

import numpy as np
import pytest
from planning_rig import TABLE, VOIGT_RIG, SimulatedRig, paper_sweep

from viscorig.fitting import fit
from viscorig.planning import InformationModel, design_bound, fit_noise_forecast, point_noise_power


@pytest.fixture(scope="module")
def rig_model():
    points = paper_sweep(SimulatedRig(VOIGT_RIG, 1.4, seed=2), step_hz=1.0)
    result = fit("voigt", points.frf_data(), fixed=TABLE)
    power, source = point_noise_power(points)
    return result, fit_noise_forecast(points, power, source)


def _bound(rig_model, targets, **options):
    result, noise = rig_model
    return design_bound(result.model, result.values, result.free, noise, 1.4, (20.0, 120.0),
                        targets, force_limit_n=100.0, **options)  # fmt: skip


def test_the_floor_falls_as_the_square_of_the_wanted_uncertainty(rig_model):
    tight = _bound(rig_model, {"K_v": 2e-6, "C_v": 1e-5})
    loose = _bound(rig_model, {"K_v": 4e-6, "C_v": 2e-5})
    assert loose.integration_floor_s == pytest.approx(tight.integration_floor_s / 4, rel=1e-3)


def test_one_target_needs_no_more_than_two(rig_model):
    both = _bound(rig_model, {"K_v": 2e-6, "C_v": 1e-5})
    for name, target in {"K_v": 2e-6, "C_v": 1e-5}.items():
        one = _bound(rig_model, {name: target})
        assert one.integration_floor_s <= both.integration_floor_s * (1 + 1e-6)


def test_the_plan_reaches_the_targets_within_the_instruments_limits(rig_model):
    targets = {"K_v": 2e-6, "C_v": 1e-5}
    bound = _bound(rig_model, targets)
    assert bound.integration_floor_s <= bound.design.total_s * (1 + 1e-9)
    integration = sum(p.integrate_cycles / p.frequency_hz for p in bound.plan)
    assert bound.design.total_s <= integration * (1 + 1e-9) <= bound.plan_time_s
    for name, target in targets.items():
        assert bound.relative_stderr[name] <= target * (1 + 1e-9)
    f = np.array([p.frequency_hz for p in bound.plan])
    assert np.all((f >= 20.0) & (f <= 120.0))
    assert all(1 <= p.integrate_cycles <= 234 and p.settle_cycles >= 0 for p in bound.plan)
    # the information is at the low end of the band (the force signal is small at the top)
    low = sum(p.integrate_cycles / p.frequency_hz for p in bound.plan if p.frequency_hz < 40)
    assert low > 0.7 * integration
    # predicted with the same information model as the plan
    result, noise = rig_model
    info = InformationModel(result.model, result.values, result.free, noise, 1.4, 100.0)
    covariance = np.linalg.inv(info.of_points(f, [p.integrate_cycles / p.frequency_hz
                                                  for p in bound.plan]))  # fmt: skip
    assert np.sqrt(covariance[0, 0]) == pytest.approx(bound.relative_stderr["K_v"], rel=1e-6)


def test_a_floor_beyond_a_day_lays_out_no_plan(rig_model):
    """A target of 1e-8 made the forecast lay out the plan point by point: tens of millions of
    points, and `viscorig plan` did not come back within minutes."""
    import time

    start = time.perf_counter()
    bound = _bound(rig_model, {"K_v": 1e-8, "C_v": 1e-8})
    assert time.perf_counter() - start < 10.0
    assert bound.integration_floor_s > 86_400.0
    assert bound.plan == () and bound.plan_time_s == bound.integration_floor_s
