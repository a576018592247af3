"""Comparing two fits: relative changes and their propagated uncertainty.

Checked against closed forms (a parameter compared as is; the Voigt loss factor ``η = ωC/K``)
and against sampling the fits' covariance, which shares nothing with the finite differences of
the code under test.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from viscorig.compare import Change, Estimates, compare_fits, kstar_at, kstar_changes
from viscorig.models import parse_spec
from viscorig.storage import Fit, FitParameter

VOIGT = parse_spec("voigt")


def voigt(k_v: float, c_v: float, covariance: list[list[float]]) -> Estimates:
    values = {"M_s": 3.4, "K_s": 5e4, "C_s": 5.0, "K_v": k_v, "C_v": c_v, "M_v": 0.15}
    return Estimates(VOIGT, values, ("K_v", "C_v"), np.array(covariance, dtype=float))


def test_a_parameter_change_has_the_closed_form_uncertainty():
    before = voigt(150e3, 100.0, [[600.0**2, 0.0], [0.0, 2.0**2]])
    after = voigt(164e3, 110.0, [[700.0**2, 0.0], [0.0, 1.0**2]])
    k_v, c_v = compare_fits(before, after, ["K_v", "C_v", "not_there"])
    ratio = 164e3 / 150e3
    assert k_v.relative == pytest.approx(ratio - 1)
    assert k_v.relative_stderr == pytest.approx(ratio * math.hypot(600 / 150e3, 700 / 164e3),
                                                rel=1e-6)
    assert k_v.unit == "N/m" and k_v.significant
    assert k_v.percent() == "+9.3 ± 0.6 %"
    assert k_v.words() == "K_v rose 9.3 ± 0.6 %"
    assert c_v.relative == pytest.approx(0.1) and c_v.significant
    flat = Change("C_v", "N·s/m", 100.0, 5.0, 101.0, 5.0)
    assert not flat.significant
    assert flat.words() == "C_v did not change beyond its uncertainty (+1 ± 7 %)"


def test_loss_factor_uncertainty_follows_the_correlated_closed_form():
    covariance = [[800.0**2, -0.6 * 800 * 3.0], [-0.6 * 800 * 3.0, 3.0**2]]
    fit = voigt(150e3, 100.0, covariance)
    f = 70.0
    (k, u_k), (eta, u_eta) = kstar_at(fit, f)
    w = 2 * math.pi * f
    assert k == pytest.approx(150e3) and u_k == pytest.approx(800.0, rel=1e-6)
    assert eta == pytest.approx(w * 100 / 150e3)
    gradient = np.array([-w * 100 / 150e3**2, w / 150e3])
    assert u_eta == pytest.approx(math.sqrt(gradient @ np.array(covariance) @ gradient), rel=1e-5)


def test_propagation_agrees_with_sampling_the_covariance():
    rng = np.random.default_rng(7)
    model = parse_spec("maxwell(2)")
    values = {"M_s": 3.4, "K_s": 5e4, "C_s": 5.0, "K_0": 1.2e5, "K_1": 3e4, "C_1": 60.0,
              "K_2": 2e4, "C_2": 4.0, "M_v": 0.15}
    free = ("K_0", "K_1", "C_1", "K_2", "C_2")
    assert set(free) <= set(model.names)
    sigma = np.array([300.0, 400.0, 0.6, 300.0, 0.06])
    correlation = np.eye(5) + 0.3 * (np.ones((5, 5)) - np.eye(5))
    covariance = correlation * np.outer(sigma, sigma)
    fit = Estimates(model, values, free, covariance)
    (k, u_k), (_, u_eta) = kstar_at(fit, 60.0)
    samples = rng.multivariate_normal([values[n] for n in free], covariance, size=4000)
    from viscorig.models import Context

    context = Context(np.array([60.0]))
    kstars = np.array([model.kstar(context, {**values, **dict(zip(free, s, strict=True))})[0]
                       for s in samples])
    assert k == pytest.approx(np.mean(kstars.real), rel=1e-3)
    assert u_k == pytest.approx(np.std(kstars.real), rel=0.06)
    assert u_eta == pytest.approx(np.std(kstars.imag / kstars.real), rel=0.06)


def test_a_stored_fit_is_compared_with_its_standard_errors():
    def stored(k_v: float, stderr: float) -> Fit:
        parameters = {"M_s": FitParameter(3.4, math.nan, "kg"),
                      "K_s": FitParameter(5e4, math.nan, "N/m"),
                      "C_s": FitParameter(5.0, math.nan, "N·s/m"),
                      "K_v": FitParameter(k_v, stderr, "N/m"),
                      "C_v": FitParameter(100.0, 2.0, "N·s/m"),
                      "M_v": FitParameter(0.15, 0.001, "kg")}
        return Fit("0001", "soft-0", "voigt", (20.0, 120.0), 0.08, 3e-4, "", parameters)

    (change,) = compare_fits(stored(150e3, 600.0), stored(165e3, 600.0), ["K_v"])
    assert change.relative == pytest.approx(0.1)
    assert change.relative_stderr == pytest.approx(1.1 * math.hypot(600 / 150e3, 600 / 165e3))
    stiff = kstar_changes(stored(150e3, 600.0), stored(165e3, 600.0), [20.0])[0]
    assert stiff.quantity == "K' at 20 Hz" and stiff.relative == pytest.approx(0.1)
