"""The adaptive plan on the time-domain simulator: it stops at the target, stays within the
band and the analyser's limits, respects the dwell limit, and shows its states."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest
from planning_rig import TABLE, VOIGT_RIG, VOIGT_TRUTH, SimulatedRig

from viscorig.errors import InputError
from viscorig.fitting import fit
from viscorig.planning import (
    ANALYSER,
    AdaptivePlan,
    AdaptiveSettings,
    NextPoints,
    State,
    shared_noise,
    sweep_segments,
)


def _settings(**changes) -> AdaptiveSettings:
    values = dict(spec="voigt", targets={"K_v": 2e-5, "C_v": 1e-4}, band_hz=(20.0, 120.0),
                  level_m_per_s2=1.4, fixed=TABLE, force_limit_n=100.0)  # fmt: skip
    values.update(changes)
    return AdaptiveSettings(**values)


def test_the_plan_stops_as_soon_as_the_targets_are_met():
    rig = SimulatedRig(VOIGT_RIG, 1.4, seed=3)
    targets = {"K_v": 5e-6, "C_v": 2.5e-5}
    outcome = AdaptivePlan(_settings(targets=targets)).run(rig)
    assert outcome.targets_met
    for name, target in targets.items():
        stderr = outcome.fit.stderr[name] / outcome.fit.values[name]
        assert stderr <= target
        assert outcome.relative_stderr[name] == pytest.approx(stderr)
        assert abs(outcome.fit.values[name] - VOIGT_TRUTH[name]) < 4 * outcome.fit.stderr[name]
    # it stopped at the first fit that met them: the fit before did not
    fits = [step for step in outcome.history if step.state == State.FIT]
    assert any(fits[-2].relative_stderr[name] > t for name, t in targets.items())
    assert outcome.test_time_s == pytest.approx(rig.simulator.clock_s)


def test_a_loose_target_needs_only_the_first_look_and_the_coverage():
    rig = SimulatedRig(VOIGT_RIG, 1.4, seed=4)
    plan = AdaptivePlan(_settings(targets={"K_v": 2e-3, "C_v": 2e-3}))
    outcome = plan.run(rig)
    assert outcome.targets_met
    assert {point.purpose for point in plan.planned} == {"look", "cover"}
    assert outcome.test_time_s < 120.0
    # the band is covered for diagnosis all the same: one point per 4 % of frequency
    f = np.unique(outcome.points.frequency_hz)
    assert np.max(f[1:] / f[:-1]) < 1.045 and f.min() == 20.0 and f.max() == 120.0


@pytest.mark.parametrize("seed", range(4))
def test_points_stay_in_the_band_and_within_the_instruments_limits(seed):
    rng = np.random.default_rng(seed)
    lo = float(rng.uniform(15.0, 40.0))
    hi = float(rng.uniform(lo + 30.0, 150.0))
    max_settle = int(rng.integers(5, 60))
    max_integrate = int(rng.integers(3, 300))
    settings = _settings(
        band_hz=(lo, hi), resolution_hz=float(rng.choice([0.1, 0.25, 1.0])),
        max_settle_cycles=max_settle, max_integrate_cycles=max_integrate,
        level_m_per_s2=float(rng.uniform(0.5, 2.0)), dwell_limit_s=150.0,
        targets={"K_v": 1e-6, "C_v": 1e-6},
    )  # fmt: skip
    plan = AdaptivePlan(settings)
    rig = SimulatedRig(VOIGT_RIG, settings.level_m_per_s2, seed=seed)
    requested = []
    while plan.request is not None:
        requested += plan.request.points
        plan.deliver(rig(plan.request.points))
    f = np.array([p.frequency_hz for p in requested])
    assert np.all((f >= lo) & (f <= hi))
    steps = f / ANALYSER.frequency_step_hz
    assert np.allclose(steps, np.round(steps), atol=1e-9)  # on the analyser's 15.625 mHz grid
    integrate = np.array([p.integrate_cycles for p in requested])
    settle = np.array([p.settle_cycles for p in requested])
    assert np.all((integrate >= 1) & (integrate <= min(234, max_integrate)))
    assert np.all((settle >= 0) & (settle <= max_settle))
    # a settle capped below what the transient needs leaves bias: the data then misfit
    assert plan.outcome is not None
    assert plan.outcome.reason in {"dwell limit", "batch limit", "model misfit"}
    # the limit is kept to the accuracy of the time prediction (a few per cent)
    assert plan.outcome.test_time_s <= 150.0 * 1.1


def test_the_plan_requests_points_and_is_delivered_them():
    rig = SimulatedRig(VOIGT_RIG, 1.4, seed=5)
    plan = AdaptivePlan(_settings(targets={"K_v": 1e-4, "C_v": 5e-4}))
    request = plan.request
    assert isinstance(request, NextPoints) and request.state == State.LOOK
    assert {p.purpose for p in request.points} == {"look"}
    while plan.request is not None:
        plan.deliver(rig(plan.request.points))
    outcome = plan.outcome
    assert outcome is not None
    assert outcome.targets_met
    states = [step.state for step in outcome.history]
    assert states[0] == State.LOOK and states[-1] == State.DONE
    assert State.FIT in states and State.DECIDE in states
    assert all(step.test_time_s >= 0 for step in outcome.history)


def test_the_plan_refuses_wrong_deliveries_and_wrong_targets():
    plan = AdaptivePlan(_settings())
    rig = SimulatedRig(VOIGT_RIG, 1.4)
    assert plan.request is not None
    with pytest.raises(ValueError, match="points delivered"):
        plan.deliver(rig(plan.request.points[:3]))
    with pytest.raises(InputError, match="not fitted parameters"):
        _settings(targets={"K_s": 1e-3})
    with pytest.raises(InputError, match="must be > 0"):
        _settings(targets={"K_v": 0.0})


def test_a_custom_fit_function_is_what_the_targets_are_judged_by():
    rig = SimulatedRig(VOIGT_RIG, 1.4, seed=6)
    calls = []

    def core_fit(points):  # the core's own estimate, under the points' measured noise
        calls.append(len(points))
        return fit("voigt", points.frf_data(), fixed=TABLE, noise=shared_noise(points))

    outcome = AdaptivePlan(_settings(targets={"K_v": 3e-3, "C_v": 3e-3}), core_fit).run(rig)
    assert outcome.targets_met and calls and calls[-1] == len(outcome.points)


def test_linear_runs_become_sweeps_and_the_rest_manual_points():
    from viscorig.planning import PlannedPoint

    points = [PlannedPoint(20.0 + 0.25 * i, 10, 20) for i in range(6)]
    points += [PlannedPoint(40.0, 5, 100), PlannedPoint(40.0, 0, 100), PlannedPoint(60.0, 7, 3)]
    segments = sweep_segments(points)
    assert [s.kind for s in segments] == ["linear", "manual"]
    assert segments[0].start_hz == 20.0 and segments[0].stop_hz == 21.25
    assert segments[0].resolution_hz == pytest.approx(0.25)
    assert len(segments[1].points) == 3


def _first_batch(seed: int):
    plan = AdaptivePlan(_settings(targets={"K_v": 2e-6, "C_v": 1e-5}))
    rig = SimulatedRig(VOIGT_RIG, 1.4, seed=seed)
    plan.deliver(rig(plan.request.points))
    request = plan.request
    return plan, request, rig(request.points)


def test_a_transient_left_in_the_first_long_point_of_a_visit_lengthens_later_settles():
    plan, _, measured = _first_batch(7)
    long = np.nonzero(measured.integrate_cycles > 1)[0]
    visit = long[measured.frequency_hz[long] == measured.frequency_hz[long[0]]]
    assert visit.size >= 3
    first = visit[0]
    bumped = measured.accelerance_table.copy()
    bumped[first] *= 1 + 6 * np.sqrt(measured.variance_table[first])  # what a transient leaves
    plan.deliver(replace(measured, accelerance_table=bumped))
    assert any("transient left" in step.note for step in plan.history)
    assert plan.request is not None
    assert plan._settle_factor == 2.0


def test_repeats_within_their_noise_leave_the_settles_alone():
    plan, _, measured = _first_batch(7)
    plan.deliver(measured)
    assert not any("transient left" in step.note for step in plan.history)


def test_repeats_join_into_one_point_per_frequency():
    rig = SimulatedRig(VOIGT_RIG, 1.4, seed=9)
    points = rig.measure([30.0, 30.0, 30.0, 40.0], [200, 0, 0, 100], [10, 20, 30, 10])
    merged = points.merged()
    assert merged.frequency_hz.tolist() == [30.0, 40.0]
    assert merged.integrate_cycles.tolist() == [60, 10]
    assert merged.duration_s.sum() == pytest.approx(points.duration_s.sum())
    v = points.variance_table[:3]
    assert merged.variance_table[0] == pytest.approx(1 / np.sum(1 / v))
    weights = (1 / v) / np.sum(1 / v)
    expected = np.sum(weights * points.accelerance_table[:3])
    assert merged.accelerance_table[0] == pytest.approx(expected)


def test_the_plan_predicts_where_the_auto_level_lands():
    from viscorig.planning.batch import landing_db, point_context

    plan, request, measured = _first_batch(3)
    points = [(p.frequency_hz, p.integrate_cycles, p.purpose) for p in request.points]
    previous = float(plan.points.frequency_hz[-1])
    landing, passes = landing_db(points, previous, point_context(plan._info, plan._modes),
                                 plan._timing, plan._reference_db())  # fmt: skip
    achieved = 20 * np.log10(measured.reference_amplitude / 1.4)
    assert np.allclose(landing, achieved, atol=0.05)
    # a second controller pass costs a second settle and integration
    single = (measured.settle_cycles + measured.integrate_cycles) / measured.frequency_hz
    assert np.allclose(measured.duration_s, passes * single)


def test_a_model_that_misfits_stops_once_the_band_is_covered():
    plan = AdaptivePlan(_settings(targets={"K_v": 2e-5, "C_v": 2e-4}))
    outcome = plan.run(SimulatedRig("hard-10", 1.4, seed=2))  # a fractional rubber, K_c, fixtures
    assert outcome.reason == "model misfit"
    assert {p.purpose for p in plan.planned} == {"look", "cover"}
    assert outcome.fit.misfit_scale > 4.0


def test_the_expected_time_brackets_what_the_plan_takes():
    from planning_rig import paper_sweep

    from viscorig.planning import (
        design_bound,
        expected_time_s,
        fit_noise_forecast,
        point_noise_power,
    )

    targets = {"K_v": 2e-6, "C_v": 1e-5}
    settings = _settings(targets=targets)
    # the floor of a similar specimen, known from an earlier sweep of it
    earlier = paper_sweep(SimulatedRig(VOIGT_RIG, 1.4, seed=10), step_hz=1.0)
    result = fit("voigt", earlier.frf_data(), fixed=TABLE)
    power, source = point_noise_power(earlier)
    bound = design_bound(result.model, result.values, result.free,
                         fit_noise_forecast(earlier, power, source), 1.4, (20.0, 120.0), targets,
                         force_limit_n=100.0)  # fmt: skip
    low, high = expected_time_s(settings, bound.plan_time_s)
    outcome = AdaptivePlan(settings).run(SimulatedRig(VOIGT_RIG, 1.4, seed=11))
    assert low <= outcome.test_time_s <= high
    loose = _settings(targets={"K_v": 2e-3, "C_v": 2e-3})
    low, high = expected_time_s(loose)
    outcome = AdaptivePlan(loose).run(SimulatedRig(VOIGT_RIG, 1.4, seed=12))
    assert low <= outcome.test_time_s and high == np.inf
    assert expected_time_s(_settings(dwell_limit_s=30.0))[1] <= 30.0
