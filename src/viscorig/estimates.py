"""Direct estimates (no model fitting): K* from Eq. (4) and (5), E' and η, C_v, Table 2; and
the same quantities of one fit with their uncertainty (first-order propagation through the
fit's joint covariance). Changes between two fits are in :mod:`viscorig.compare`.

Signs and conventions of ``shared/docs/physics.md``: time dependence e^{iωt}, accelerances as
stored, frequencies in Hz at the interface.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from viscorig.frf import accelerance_to_dynamic_stiffness, accelerance_to_receptance
from viscorig.models import Context, table_dynamic_stiffness
from viscorig.numbers import Estimate


def kstar_from_table(
    frequency_hz: ArrayLike,
    accelerance_table: ArrayLike,
    table: dict[str, float],
    disc_mass_kg: float,
) -> NDArray[np.complex128]:
    """Eq. (4) with the table's damping kept: ``K* = F_e/X_s − (K_s − (M_s+M_v) ω² + iω C_s)``.

    Rests on a rigid load cell (``x_s ≈ x_v``); its disagreement with :func:`kstar_from_support`
    is a diagnostic of that assumption.
    """
    omega = 2 * np.pi * np.asarray(frequency_hz, dtype=float)
    z = accelerance_to_dynamic_stiffness(frequency_hz, accelerance_table)
    return z - table_dynamic_stiffness(omega, table) + disc_mass_kg * omega**2


def kstar_from_support(
    frequency_hz: ArrayLike, accelerance_support: ArrayLike, disc_mass_kg: float
) -> NDArray[np.complex128]:
    """Eq. (5): ``K* = F_v/X_v + ω² M_v``; exact whatever the load cell's stiffness."""
    omega = 2 * np.pi * np.asarray(frequency_hz, dtype=float)
    return accelerance_to_dynamic_stiffness(frequency_hz, accelerance_support) + omega**2 * (
        disc_mass_kg
    )


def storage_modulus(kstar: ArrayLike, theta_m: float) -> NDArray[np.float64]:
    """Eq. (7)/(8): ``E' = Re K* / θ`` in Pa (θ in metres, :mod:`viscorig.rig`)."""
    return np.real(np.asarray(kstar, dtype=complex)) / theta_m


def loss_factor(kstar: ArrayLike) -> NDArray[np.float64]:
    """Eq. (7)/(8): ``η = Im K* / Re K*`` (independent of θ)."""
    kstar = np.asarray(kstar, dtype=complex)
    return kstar.imag / kstar.real


def equivalent_damping(frequency_hz: ArrayLike, kstar: ArrayLike) -> NDArray[np.float64]:
    """Eq. (12): ``C_v = η θ E'/ω = Im K*/ω`` in N·s/m, the viscous damper equivalent at ω."""
    omega = 2 * np.pi * np.asarray(frequency_hz, dtype=float)
    return np.imag(np.asarray(kstar, dtype=complex)) / omega


@dataclass(frozen=True)
class SystemProperties:
    """Table 2 of the paper for one run.

    Attributes
    ----------
    natural_frequency_hz
        ``f_r = √((K_s+K_v)/(M_s+M_v)) / 2π`` of the Voigt system.
    damping_factor
        ``ξ = (C_s+C_v) / (2 √((K_s+K_v)(M_s+M_v)))``.
    bandwidth_hz
        ``B_r = 2 ξ f_r`` (the paper's formula, valid for light damping).
    """

    natural_frequency_hz: float
    damping_factor: float
    bandwidth_hz: float


def system_properties(values: Mapping[str, float]) -> SystemProperties:
    """Table 2 quantities from table and Voigt parameters (``M_s K_s C_s K_v C_v M_v``)."""
    stiffness = values["K_s"] + values["K_v"]
    mass = values["M_s"] + values["M_v"]
    damping = values["C_s"] + values["C_v"]
    f_r = float(np.sqrt(stiffness / mass) / (2 * np.pi))
    xi = float(damping / (2 * np.sqrt(stiffness * mass)))
    return SystemProperties(f_r, xi, 2 * xi * f_r)


@dataclass(frozen=True)
class MeasuredResonance:
    """Resonance read off a measured FRF (receptance magnitude).

    Attributes
    ----------
    peak_hz
        Frequency of the largest ``|X/F|`` (parabolic interpolation on ``log|X/F|``); NaN,
        and so are the others, when that is the first or last point: the resonance is then
        outside the data, and the edge is no peak.
    bandwidth_hz
        Half-power bandwidth: distance between the frequencies where ``|X/F|`` falls to
        ``peak/√2`` (linear interpolation), NaN if the band does not hold both.
    damping_factor
        ``bandwidth / (2 peak)``.
    """

    peak_hz: float
    bandwidth_hz: float
    damping_factor: float


def measured_resonance(frequency_hz: ArrayLike, accelerance: ArrayLike) -> MeasuredResonance:
    """Peak and half-power bandwidth of ``|X/F|`` measured directly on the FRF."""
    f = np.asarray(frequency_hz, dtype=float)
    magnitude = np.abs(accelerance_to_receptance(f, accelerance))
    i = int(np.nanargmax(magnitude))
    if i in (0, f.size - 1):
        return MeasuredResonance(float("nan"), float("nan"), float("nan"))
    peak_hz = f[i]
    peak = magnitude[i]
    y = np.log(magnitude[i - 1 : i + 2])  # parabola through the three top points' log-magnitudes
    denominator = y[0] - 2 * y[1] + y[2]
    if denominator < 0:
        shift = 0.5 * (y[0] - y[2]) / denominator
        peak_hz = f[i] + shift * 0.5 * (f[i + 1] - f[i - 1])
        peak = float(np.exp(y[1] - 0.25 * (y[0] - y[2]) * shift))
    level = peak / np.sqrt(2.0)
    below = np.nonzero(magnitude[:i] < level)[0]
    above = np.nonzero(magnitude[i:] < level)[0]
    if below.size == 0 or above.size == 0:
        return MeasuredResonance(float(peak_hz), float("nan"), float("nan"))
    j = below[-1]
    k = i + above[0]
    lower = np.interp(level, [magnitude[j], magnitude[j + 1]], [f[j], f[j + 1]])
    upper = np.interp(level, [magnitude[k], magnitude[k - 1]], [f[k], f[k - 1]])
    bandwidth = float(upper - lower)
    return MeasuredResonance(float(peak_hz), bandwidth, bandwidth / (2 * float(peak_hz)))


# -- the same quantities with their uncertainty -------------------------------------------------


def gradient(function, values: dict[str, float], names: list[str]) -> NDArray[np.float64]:
    """Central differences of a scalar or array ``function(values)`` by the named values
    (relative step 1e-6); the last axis runs over ``names``."""
    columns = []
    for name in names:
        step = 1e-6 * max(abs(values[name]), 1e-30)
        up, down = dict(values), dict(values)
        up[name] += step
        down[name] -= step
        columns.append((np.asarray(function(up)) - np.asarray(function(down))) / (2 * step))
    return np.stack(columns, axis=-1) if columns else np.zeros((0,))


def derived(result, function, unit: str = "") -> Estimate:
    """A function of a fit's parameters, with its uncertainty (first order, every parameter with
    a standard error: fitted and inherited, with their correlations)."""
    names = list(result.covariance_names)
    value = float(function(result.values))
    if not names:
        return Estimate(value, 0.0, unit)
    g = gradient(function, dict(result.values), names)
    variance = float(g @ np.asarray(result.joint_covariance) @ g)
    return Estimate(value, float(np.sqrt(max(variance, 0.0))), unit)


def natural_frequency(values: Mapping[str, float]) -> float:
    """``f_r`` (Hz) of the Voigt system, Table 2."""
    return system_properties(values).natural_frequency_hz


def damping_factor(values: Mapping[str, float]) -> float:
    """``ξ`` of the Voigt system, Table 2."""
    return system_properties(values).damping_factor


def bandwidth(values: Mapping[str, float]) -> float:
    """``B_r = 2 ξ f_r`` (Hz), Table 2."""
    return system_properties(values).bandwidth_hz


#: Table 2's quantities: name -> (function of the parameters, unit).
TABLE_2_QUANTITIES = {
    "f_r": (natural_frequency, "Hz"),
    "xi": (damping_factor, ""),
    "B_r": (bandwidth, "Hz"),
}


def system_properties_with_uncertainty(result) -> dict[str, Estimate]:
    """Table 2 (``f_r``, ``xi``, ``B_r``) of a Voigt fit, each with its uncertainty."""
    return {name: derived(result, function, unit)
            for name, (function, unit) in TABLE_2_QUANTITIES.items()}


@dataclass(frozen=True)
class ModulusBand:
    """``E'(f)`` and ``η(f)`` of a fitted model with their standard uncertainties.

    Attributes
    ----------
    frequency_hz
        Where they are evaluated.
    storage_modulus, storage_modulus_stderr
        ``E' = Re K*/θ`` and its uncertainty (Pa).
    loss_factor, loss_factor_stderr
        ``η = Im K*/Re K*`` and its uncertainty.
    """

    frequency_hz: NDArray[np.float64]
    storage_modulus: NDArray[np.float64]
    storage_modulus_stderr: NDArray[np.float64]
    loss_factor: NDArray[np.float64]
    loss_factor_stderr: NDArray[np.float64]


def modulus_band(result, frequency_hz: ArrayLike, theta_m: float) -> ModulusBand:
    """``E'`` and ``η`` of a fit's ``K*`` on any grid, with uncertainty bands (first order,
    through every parameter with a standard error; θ taken as exact)."""
    f = np.asarray(frequency_hz, dtype=float)
    names = list(result.covariance_names)

    def parts(values: dict[str, float]) -> NDArray[np.float64]:
        kstar = result.model.kstar(Context(f), values)
        return np.concatenate([kstar.real / theta_m, kstar.imag / kstar.real])

    centre = parts(dict(result.values))
    if names:
        g = gradient(parts, dict(result.values), names)
        variance = np.einsum("ij,jk,ik->i", g, np.asarray(result.joint_covariance), g)
    else:
        variance = np.zeros_like(centre)
    sigma = np.sqrt(np.maximum(variance, 0.0))
    n = f.size
    return ModulusBand(f, centre[:n], sigma[:n], centre[n:], sigma[n:])


