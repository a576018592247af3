"""Prony series of the fractional Zener against its closed form (written here)."""

from __future__ import annotations

import numpy as np
import pytest
from rigsim.materials import prony_series
from rigsim.rigfile import FractionalMaterial


def fractional_zener(k0, kinf, tau, alpha, f):
    z = (2j * np.pi * f * tau) ** alpha
    return (k0 + kinf * z) / (1 + z)


@pytest.mark.parametrize(
    ("k0", "kinf", "tau", "alpha"),
    [
        (1.25e5, 4.7e5, 8e-5, 0.5),
        (1.0e5, 1.0e8, 1.6e-6, 0.3),
        (1.0e6, 1.8e6, 1e-2, 0.9),
        (0.0, 1.0e6, 1e-3, 0.15),
        (2.0e5, 3.0e5, 1.0, 0.6),
    ],
)
def test_prony_series_within_half_percent(k0, kinf, tau, alpha) -> None:
    series = prony_series(FractionalMaterial(k0, kinf, tau, alpha))
    f = np.logspace(0, 3, 700)
    exact = fractional_zener(k0, kinf, tau, alpha, f)
    approx = series.complex_stiffness(f)
    assert np.max(np.abs(np.abs(approx) / np.abs(exact) - 1)) < 0.005
    eta_exact = exact.imag / exact.real
    eta_approx = approx.imag / approx.real
    assert np.max(np.abs(eta_approx / eta_exact - 1)) < 0.005
    assert np.all(series.arm_stiffness_n_per_m > 0) and np.all(series.arm_damping_ns_per_m > 0)
