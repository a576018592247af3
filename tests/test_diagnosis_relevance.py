"""A significant finding must also matter: it removes a real share of the χ² the noise leaves
unexplained, and it is judged against the misfit of the larger model (an F test)."""

from __future__ import annotations

import pytest
from scipy.stats import chi2

from viscorig.diagnosis.significance import (
    MIN_EXCESS_FRACTION,
    dispersion,
    removes_enough,
    scan_threshold,
    threshold,
)


def test_a_sliver_of_the_excess_is_not_enough() -> None:
    # χ² 1.66 n for n = 3208 (a model 1.29 x the floor), improved by 0.8 %
    n = 3208
    before = 1.66 * n
    assert not removes_enough(before, before * 0.992, before - n)


def test_a_real_effect_removes_most_of_the_excess() -> None:
    assert removes_enough(1.0e6, 2.0e5, 1.0e6 - 3208)


def test_at_the_noise_any_drop_will_do() -> None:
    assert removes_enough(3200.0, 3170.0, -8.0)


def test_threshold_is_a_share_of_the_excess() -> None:
    excess = 1000.0
    assert removes_enough(5000.0, 5000.0 - MIN_EXCESS_FRACTION * excess, excess)
    assert not removes_enough(5000.0, 5000.0 - 0.99 * MIN_EXCESS_FRACTION * excess, excess)


def test_thresholds_are_chi_square_quantiles() -> None:
    assert threshold(1, 1e-3) == pytest.approx(chi2.isf(1e-3, 1))
    assert threshold(3, 1e-3) > threshold(1, 1e-3)
    # a scan over more correlation lengths needs more
    assert scan_threshold(5000, 1e-3) > scan_threshold(500, 1e-3) > threshold(1, 1e-3)


@pytest.mark.slow
def test_scan_threshold_meets_its_false_alarm_rate() -> None:
    """The Rice upcrossing formula against a brute-force maximum of a smooth Gaussian process."""
    import numpy as np

    rng = np.random.default_rng(1)
    points, width = 4000, 8.0  # process: white noise smoothed by a Gaussian of `width` points
    kernel = np.exp(-0.5 * (np.arange(-40, 41) / width) ** 2)
    kernel /= np.sqrt(np.sum(kernel**2))
    length = (points - 80) / (np.sqrt(2.0) * width)  # arc length: sqrt(Var(Ż)) = 1/(√2 width)
    level = scan_threshold(length, alpha=0.05)
    trials = 2000
    noise = rng.standard_normal((trials, points))
    z = np.apply_along_axis(lambda row: np.convolve(row, kernel, mode="valid"), 1, noise)
    exceed = np.mean(np.max(np.where(z > 0, z * z, 0.0), axis=1) > level)
    assert 0.02 < exceed < 0.07


def test_misfit_inflates_the_test() -> None:
    assert dispersion(3000.0, 3208, 5) == 1.0
    assert dispersion(2 * 3203.0, 3208, 5) == pytest.approx(2.0)


def test_diagnosis_whitens_as_the_shared_noise_model_does() -> None:
    """Formed once per block, the whitening matrices give the noise model's own whitening."""
    import numpy as np
    from simdata import rig_text, simulate_run

    from viscorig.diagnosis.data import combine

    extra = "[noise]\nsensitivity_drift_rms = 2e-3\nsensitivity_drift_time_s = 60.0\n"
    device = {"mass_kg": 0.25, "model": "voigt", "stiffness_n_per_m": 1.5e5,
              "damping_ns_per_m": 114.59}  # fmt: skip
    text = rig_text(device, noise={"device_force_n_per_sqrt_hz": 2e-3,
                                   "disc_acceleration_m_per_s2_per_sqrt_hz": 2e-4,
                                   "excitation_force_n_per_sqrt_hz": 2e-3,
                                   "table_acceleration_m_per_s2_per_sqrt_hz": 2e-4})
    text = text.replace("[noise]\n", extra)
    run = simulate_run(text, seed=4, step_hz=0.5)
    data = combine([("run", run.frf_data("run"))], table={"M_s": 3.4, "K_s": 50194.0,
                                                          "C_s": 5.05})
    assert data.noise.correlated
    rng = np.random.default_rng(0)
    n = data.data.frequency_hz.size
    vector = {f: rng.standard_normal(n) + 1j * rng.standard_normal(n) for f in data.frfs}
    matrix = {f: rng.standard_normal((n, 3)) + 1j * rng.standard_normal((n, 3))
              for f in data.frfs}
    kept = {f: ~data.outliers[f] for f in data.frfs}
    expected = data.noise.whiten({f: np.where(kept[f], vector[f], 0) for f in data.frfs})
    np.testing.assert_allclose(data.whiten(vector), expected, rtol=1e-9, atol=1e-9)
    expected = data.noise.whiten_jacobian(
        {f: np.where(kept[f][:, None], matrix[f], 0) for f in data.frfs})
    np.testing.assert_allclose(data.whiten(matrix), expected, rtol=1e-9, atol=1e-6)
    # a residual that cannot be computed at one point spoils that point's block alone
    spoiled = {f: v.copy() for f, v in vector.items()}
    spoiled["table"][5] = np.nan
    whitened, clean = data.whiten(spoiled), data.whiten(vector)
    half = whitened.size // 2
    assert np.isnan(whitened[5]) and np.isfinite(whitened[half:]).all()
    np.testing.assert_array_equal(whitened[n:half], clean[n:half])
    # the per-point stand-in keeps each point's power and drops the correlation
    power = data.whitened_power(vector)
    assert set(power) == set(data.frfs) and all(p.shape == (n,) for p in power.values())
