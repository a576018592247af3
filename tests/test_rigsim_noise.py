"""The simulator's sources of noise that is not white: transducer drift and interference bursts.

Each is measured here on the FRFs the time-domain simulator gives, against the same rig without
the source (the seed fixes everything else), so what is tested is the effect in the data.
"""

from __future__ import annotations

import numpy as np
import pytest
from rigsim.rigfile import RigFileError, parse_rig
from simdata import rig_text, simulate_run

VOIGT = {"mass_kg": 0.25, "model": "voigt", "stiffness_n_per_m": 1.5e5, "damping_ns_per_m": 114.59}


def _relative_error(noise: dict, seed: int = 3, **sweep) -> tuple[np.ndarray, np.ndarray]:
    """``H/H_noiseless − 1`` of the table FRF, and the test time of each point."""
    noisy = simulate_run(rig_text(VOIGT, noise=noise), seed=seed, **sweep)
    clean = simulate_run(rig_text(VOIGT), seed=seed, **sweep)
    return noisy.accelerance_table / clean.accelerance_table - 1, noisy.time_s


def test_sensitivity_drift_is_a_gain_error_correlated_in_test_time() -> None:
    sigma, tau = 1e-3, 30.0
    errors = []
    for seed in range(6):
        error, time = _relative_error(
            {"sensitivity_drift_rms": sigma, "sensitivity_drift_time_s": tau}, seed=seed
        )
        errors.append(error)
    error = np.concatenate(errors)
    # Two channels drift independently: their ratio carries √2 σ, on the magnitude only (the
    # phase moves only through the level controller's slightly different force).
    assert np.sqrt(np.mean(error.real**2)) == pytest.approx(np.sqrt(2) * sigma, rel=0.25)
    assert np.sqrt(np.mean(error.imag**2)) < 0.03 * np.sqrt(2) * sigma
    # Correlation between neighbours follows exp(−Δt/τ) (Δt ≈ 3.6 s per point on average).
    a = np.concatenate([e.real[:-1] for e in errors])
    b = np.concatenate([e.real[1:] for e in errors])
    step = np.mean(np.diff(time))
    assert np.corrcoef(a, b)[0, 1] == pytest.approx(np.exp(-step / tau), abs=0.08)


def test_interference_bursts_make_heavy_tails() -> None:
    base = {"excitation_force_n_per_sqrt_hz": 2e-3,
            "table_acceleration_m_per_s2_per_sqrt_hz": 2e-4}
    quiet, _ = _relative_error(base)
    bursty, _ = _relative_error({**base, "burst_probability": 0.05, "burst_factor": 30.0})
    ratio = np.abs(bursty) / np.median(np.abs(quiet))
    struck = np.count_nonzero(ratio > 8)
    assert 0.02 * ratio.size < struck < 0.09 * ratio.size  # about 5 % of the points
    kurtosis = np.mean(np.abs(bursty) ** 4) / np.mean(np.abs(bursty) ** 2) ** 2
    assert kurtosis > 10  # complex Gaussian noise gives 2


def test_the_sources_are_off_unless_given() -> None:
    rig = parse_rig(rig_text(VOIGT, noise={"excitation_force_n_per_sqrt_hz": 2e-3}))
    assert rig.noise.sensitivity_drift_rms == 0.0 and rig.noise.burst_probability == 0.0
    plain = simulate_run(rig_text(VOIGT, noise={"excitation_force_n_per_sqrt_hz": 2e-3}), seed=4)
    zero = simulate_run(
        rig_text(VOIGT, noise={"excitation_force_n_per_sqrt_hz": 2e-3,
                               "sensitivity_drift_rms": 0.0, "burst_probability": 0.0}),
        seed=4,
    )
    assert np.array_equal(plain.accelerance_table, zero.accelerance_table)


@pytest.mark.parametrize(
    ("key", "value", "words"),
    [
        ("sensitivity_drift_rms", -1e-3, "must be >= 0"),
        ("sensitivity_drift_time_s", 0.0, "must be > 0"),
        ("burst_probability", 1.5, "must be <= 1"),
        ("burst_factor", 0.5, "must be >= 1"),
        ("burst_factor", "big", "must be a number"),
    ],
)
def test_bad_noise_values_are_named(key: str, value: object, words: str) -> None:
    with pytest.raises(RigFileError, match=rf"noise\.{key}: {words}"):
        parse_rig(rig_text(VOIGT, noise={key: value}))
