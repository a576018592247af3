"""The shift estimate's batched Jacobian equals scipy's forward differences of its residual, on
a sweep from an independent generator (tests/materialdata.py), at a point away from the fit."""

from __future__ import annotations

import materialdata as gen
import numpy as np
from scipy.optimize._numdiff import approx_derivative

from viscorig.materials import shift
from viscorig.materials.table import ModulusTable


def test_the_batched_jacobian_is_scipys_forward_difference() -> None:
    sweep = gen.dma_sweep([-20.0, 0.0, 20.0, 40.0, 60.0], np.geomspace(0.1, 100.0, 9), seed=4)
    table = ModulusTable(**sweep, modulus="E")
    sets, _ = shift._ordered_sets(table)
    problem = shift._Problem(table, sets, reference=2)
    rng = np.random.default_rng(7)
    free = np.array([2.0, 1.0, -1.0, -2.0]) + 0.3 * rng.standard_normal(4)
    problem.knots = shift._knots(problem.reduced(free), 0.5)
    problem.weights = 1.0 + rng.random(problem.weights.shape)
    expected = approx_derivative(problem.residual, free, method="2-point")
    got = problem.jacobian(free)
    assert got.shape == expected.shape
    # the same differences; only the solves' rounding (divided by a step of 1.5e-8) differs
    np.testing.assert_allclose(got, expected, atol=1e-5 * np.abs(expected).max())
    assert np.abs(expected).max() > 0.1
