"""The minimum-time design and its certified bound, on problems solved by hand.

Each case is a design problem whose least time follows from a few lines of algebra (written
out in the test), independent of the solver; random problems check that the certified bound
never exceeds the time of any allocation that meets the targets.
"""

from __future__ import annotations

import numpy as np
import pytest

from viscorig.planning import minimum_time_design


def _meets(rate, tau, targets, wanted, prior=None) -> bool:
    information = np.einsum("p,pij->ij", tau, rate)
    if prior is not None:
        information = information + prior
    variance = np.diag(np.linalg.inv(information))[targets]
    return bool(np.all(variance <= np.asarray(wanted) ** 2 * (1 + 1e-6)))


def test_one_parameter_all_time_goes_to_the_best_frequency():
    # Information per second r_f about one parameter: var = 1/(τ r) ≤ t² ⇔ τ ≥ 1/(t² r);
    # the least total puts everything on the largest r: τ* = 1/(t² max r).
    rates = np.array([2.0, 7.0, 5.0, 0.5])
    design = minimum_time_design([10, 20, 30, 40], rates[:, None, None], [0], [0.1])
    expected = 1.0 / (0.1**2 * 7.0)
    assert design.total_s == pytest.approx(expected, rel=1e-6)
    assert design.lower_bound_s == pytest.approx(expected, rel=1e-6)
    assert design.lower_bound_s <= expected * (1 + 1e-9)
    assert design.integrate_s[1] == pytest.approx(expected, rel=1e-6)
    assert design.relative_stderr[0] == pytest.approx(0.1, rel=1e-6)


def test_two_parameters_each_learnt_at_its_own_frequency_add_up():
    # Candidate A informs p1 only (rate a), B informs p2 only (rate b): with the information
    # diagonal, τ_A = 1/(t1² a) and τ_B = 1/(t2² b). Candidate C informs both at rate c; a
    # second there saves c/a + c/b seconds of A and B (the KKT condition), less than one
    # second when c/a + c/b < 1, so C stays empty.
    a, b, c = 4.0, 9.0, 0.2
    rate = np.zeros((3, 2, 2))
    rate[0] = np.diag([a, 0.0])
    rate[1] = np.diag([0.0, b])
    rate[2] = np.diag([c, c])
    t1, t2 = 0.05, 0.02
    design = minimum_time_design([1, 2, 3], rate, [0, 1], [t1, t2])
    expected = 1 / (t1**2 * a) + 1 / (t2**2 * b)
    assert design.total_s == pytest.approx(expected, rel=1e-5)
    assert design.lower_bound_s == pytest.approx(expected, rel=1e-4)
    assert design.integrate_s[2] < 1e-6 * expected


def test_a_nuisance_parameter_is_cancelled_where_it_does_not_matter():
    # Straight line y = p1 + p2 x, unit noise, x ∈ {-1, 0, 1}: information per second
    # [[1, x], [x, x²]]. For the intercept p1 alone, measuring at x = 0 makes the slope
    # irrelevant: var p1 = 1/τ, so τ* = 1/t². Any split between x = ±1 costs the same only
    # if symmetric (var p1 = 1/τ as well); the optimum is 1/t² either way.
    x = np.array([-1.0, 0.0, 1.0])
    rate = np.stack([np.array([[1.0, xi], [xi, xi * xi]]) for xi in x])
    design = minimum_time_design(x, rate, [0], [0.1])
    assert design.total_s == pytest.approx(100.0, rel=1e-5)
    assert design.lower_bound_s == pytest.approx(100.0, rel=1e-4)
    # For the slope: var p2 = 1/(τ_-1 + τ_1 - (τ_1 - τ_-1)²/τ) minimised by x = ±1 only,
    # equal halves: var = 1/τ → τ* = 1/t² again, and nothing at x = 0.
    slope = minimum_time_design(x, rate, [1], [0.1])
    assert slope.total_s == pytest.approx(100.0, rel=1e-5)
    assert slope.integrate_s[1] < 1e-6 * slope.total_s


def test_prior_information_that_already_meets_the_targets_needs_no_time():
    rate = np.stack([np.eye(2), 2 * np.eye(2)])
    design = minimum_time_design([1, 2], rate, [0, 1], [0.1, 0.1], prior=1000.0 * np.eye(2))
    assert design.total_s == 0.0
    assert np.all(design.integrate_s == 0.0)


def test_prior_information_shortens_the_time_by_what_it_holds():
    # One parameter: var = 1/(I0 + τ r) ≤ t² ⇔ τ ≥ (1/t² − I0)/r.
    rates = np.array([1.0, 3.0])[:, None, None]
    design = minimum_time_design([1, 2], rates, [0], [0.1], prior=np.array([[40.0]]))
    assert design.total_s == pytest.approx((100.0 - 40.0) / 3.0, rel=1e-5)


@pytest.mark.parametrize("seed", range(6))
def test_the_certified_bound_is_below_every_feasible_allocation(seed):
    rng = np.random.default_rng(seed)
    count, k = 30, 3
    vectors = rng.normal(size=(count, 2, k))  # rank-2 information per candidate
    rate = np.einsum("pai,paj->pij", vectors, vectors) * rng.uniform(0.1, 3, count)[:, None, None]
    targets, wanted = [0, 2], [0.05, 0.08]
    design = minimum_time_design(np.arange(count), rate, targets, wanted)
    assert _meets(rate, design.integrate_s, targets, wanted)
    assert design.lower_bound_s <= design.total_s * (1 + 1e-9)
    assert design.lower_bound_s >= 0.99 * design.total_s  # the solver converged
    for _ in range(200):  # random allocations scaled until they meet the targets
        tau = rng.exponential(size=count) * (rng.random(count) < 0.3)
        if not tau.any():
            continue
        scale = 1.0
        while not _meets(rate, tau * scale, targets, wanted):
            scale *= 1.05
        assert tau.sum() * scale >= design.lower_bound_s * (1 - 1e-9)
