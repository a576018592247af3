"""Complex stiffness of the specimens, and its state-space form for the time-domain rig.

Every material is reduced to a *state model*: a static spring ``K_0``, a parallel dashpot
``C`` (Voigt only) and Maxwell arms ``(K_i, C_i)``, each arm carrying its own force as an
internal state. The fractional Zener model has no finite state form; it is replaced by a dense
Prony series (Maxwell arms at log-spaced relaxation times, weights by non-negative least squares)
that matches the closed form to better than 0.5 % in ``|K*|`` and in the loss factor over
1-1000 Hz (checked at construction).
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache

import numpy as np
from scipy.optimize import nnls

from rigsim.rigfile import FractionalMaterial, Material, MaxwellMaterial, VoigtMaterial

__all__ = ["PRONY_BAND_HZ", "StateModel", "complex_stiffness", "prony_series", "state_model"]

#: Band over which the Prony series of a fractional material is guaranteed (Hz).
PRONY_BAND_HZ = (1.0, 1000.0)
#: Guaranteed relative accuracy of the Prony series in |K*| and in the loss factor.
PRONY_TOLERANCE = 0.005


@dataclass(frozen=True)
class StateModel:
    """A material as springs, a dashpot and Maxwell arms (SI units).

    ``K*(ω) = static + i ω damping + Σ i ω K_i C_i / (K_i + i ω C_i)``.
    """

    static_stiffness_n_per_m: float
    damping_ns_per_m: float
    arm_stiffness_n_per_m: np.ndarray
    arm_damping_ns_per_m: np.ndarray

    def complex_stiffness(self, frequency_hz: np.ndarray | float) -> np.ndarray:
        """K* of the state model at the given frequencies."""
        iw = 2j * np.pi * np.asarray(frequency_hz, dtype=float)[..., None]
        k, c = self.arm_stiffness_n_per_m, self.arm_damping_ns_per_m
        arms = np.sum(iw * k * c / (k + iw * c), axis=-1)
        return self.static_stiffness_n_per_m + iw[..., 0] * self.damping_ns_per_m + arms


def complex_stiffness(material: Material, frequency_hz: np.ndarray | float) -> np.ndarray:
    """Closed-form K* (N/m) of a material at the given frequencies (Hz)."""
    f = np.asarray(frequency_hz, dtype=float)
    w = 2.0 * np.pi * f
    if isinstance(material, VoigtMaterial):
        return material.stiffness_n_per_m + 1j * w * material.damping_ns_per_m
    if isinstance(material, MaxwellMaterial):
        total = np.full(f.shape, material.static_stiffness_n_per_m, dtype=complex)
        for k_i, c_i in material.arms:
            total = total + 1j * w * k_i * c_i / (k_i + 1j * w * c_i)
        return total
    if isinstance(material, FractionalMaterial):
        z = (1j * w * material.tau_s) ** material.alpha
        k0, kinf = material.static_stiffness_n_per_m, material.high_stiffness_n_per_m
        return (k0 + kinf * z) / (1.0 + z)
    raise TypeError(f"unknown material {material!r}")


def state_model(material: Material) -> StateModel:
    """The state-space form of a material (Prony series for the fractional model)."""
    if isinstance(material, VoigtMaterial):
        empty = np.zeros(0)
        return StateModel(material.stiffness_n_per_m, material.damping_ns_per_m, empty, empty)
    if isinstance(material, MaxwellMaterial):
        arms = np.array(material.arms, dtype=float).reshape(-1, 2)
        return StateModel(material.static_stiffness_n_per_m, 0.0, arms[:, 0], arms[:, 1])
    if isinstance(material, FractionalMaterial):
        return prony_series(material)
    raise TypeError(f"unknown material {material!r}")


def prony_series(material: FractionalMaterial, arms_per_decade: int = 4) -> StateModel:
    """Maxwell-arm (Prony) approximation of a fractional Zener material.

    Relaxation frequencies are log-spaced from two decades below to two decades above
    :data:`PRONY_BAND_HZ`; the static stiffness and the arm stiffnesses are fitted by
    non-negative least squares on the relative error of the real and imaginary parts separately
    (so the loss factor is matched, not only ``|K*|``).

    Raises
    ------
    ValueError
        The series misses the closed form by more than :data:`PRONY_TOLERANCE` in the band
        (more arms per decade are then needed).
    """
    return _prony_cached(
        material.static_stiffness_n_per_m,
        material.high_stiffness_n_per_m,
        material.tau_s,
        material.alpha,
        arms_per_decade,
    )


@lru_cache(maxsize=64)
def _prony_cached(k0: float, kinf: float, tau: float, alpha: float, per_decade: int) -> StateModel:
    material = FractionalMaterial(k0, kinf, tau, alpha)
    lo, hi = PRONY_BAND_HZ
    decades = np.log10(hi / lo) + 4.0
    relax_hz = np.logspace(np.log10(lo) - 2.0, np.log10(hi) + 2.0, int(decades * per_decade) + 1)
    taus = 1.0 / (2.0 * np.pi * relax_hz)
    fit_hz = np.logspace(np.log10(lo) - 0.3, np.log10(hi) + 0.3, 300)
    target = complex_stiffness(material, fit_hz)
    iwt = 2j * np.pi * fit_hz[:, None] * taus[None, :]
    basis = np.concatenate([np.ones((fit_hz.size, 1)), iwt / (1.0 + iwt)], axis=1)
    rows = np.concatenate(
        [basis.real / target.real[:, None], basis.imag / target.imag[:, None]], axis=0
    )
    rhs = np.ones(2 * fit_hz.size)
    weights, _ = nnls(rows, rhs, maxiter=50 * rows.shape[1])
    keep = weights[1:] > 0.0
    arm_k = weights[1:][keep]
    model = StateModel(float(weights[0]), 0.0, arm_k, arm_k * taus[keep])
    check_hz = np.logspace(np.log10(lo), np.log10(hi), 400)
    exact = complex_stiffness(material, check_hz)
    approx = model.complex_stiffness(check_hz)
    err_mag = np.max(np.abs(np.abs(approx) / np.abs(exact) - 1.0))
    err_eta = np.max(np.abs((approx.imag / approx.real) / (exact.imag / exact.real) - 1.0))
    if max(err_mag, err_eta) > PRONY_TOLERANCE:
        if per_decade < 16:
            return _prony_cached(k0, kinf, tau, alpha, per_decade * 2)
        raise ValueError(
            f"Prony series of {material} misses the closed form by {max(err_mag, err_eta):.2%}"
        )
    return model
