"""Shift functions ``log10 aT(T)``: WLF and Arrhenius, fitted to estimated shift factors with ±.

- WLF: ``log10 aT = −C1 (T − T_ref) / (C2 + T − T_ref)`` (``C1`` dimensionless, ``C2`` in K).
- Arrhenius: ``log10 aT = E_a / (R ln 10) · (1/T − 1/T_ref)`` (``T`` in K, ``E_a`` in J/mol).

Both give ``aT > 1`` below the reference temperature. Each is fitted by generalised least
squares with the full covariance of the shift factors (they are correlated through the master
curve they share). Where the weighted residual ``χ²/dof`` exceeds 1 the function does not
describe the shifts within their errors; its parameter errors are then scaled by
``sqrt(χ²/dof)`` and the result says so. A parameter that ends at a bound of its fit (WLF's
``C1`` at 1000) was not found by the shifts, only stopped: the function names it
(:attr:`ShiftFunction.at_bound`); its curve over the measured temperatures still stands. The
better function is the one of lower AIC (``χ² + 2k``), at a bound or not (on the real DMA file
WLF with ``C1`` at 1000 is a straight line in T that follows the shifts better than Arrhenius:
the card it gives misses the loss modulus by 0.60 in rms ln, Arrhenius's by 2.1); where it is at
a bound, everything that calls it better says so.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.optimize import curve_fit

from viscorig.numbers import Estimate, with_uncertainty

GAS_CONSTANT_J_PER_MOL_K = 8.314462618
KELVIN = 273.15
#: A parameter this close to a bound of its fit (relative to the bound's size) is at it.
BOUND_TOLERANCE = 1e-6


def wlf(temperature_c: ArrayLike, reference_c: float, c1: float, c2_k: float) -> NDArray:
    """WLF ``log10 aT`` at ``temperature_c``."""
    dt = np.asarray(temperature_c, dtype=float) - reference_c
    return -c1 * dt / (c2_k + dt)


def arrhenius(temperature_c: ArrayLike, reference_c: float, ea_j_per_mol: float) -> NDArray:
    """Arrhenius ``log10 aT`` at ``temperature_c``."""
    t = np.asarray(temperature_c, dtype=float) + KELVIN
    return ea_j_per_mol / (GAS_CONSTANT_J_PER_MOL_K * math.log(10.0)) * (
        1.0 / t - 1.0 / (reference_c + KELVIN))


#: name -> (parameter names, units)
PARAMETERS = {"wlf": (("C1", "C2_K"), ("1", "K")), "arrhenius": (("Ea_J_per_mol",), ("J/mol",))}


@dataclass(frozen=True)
class ShiftFunction:
    """One fitted shift function.

    Attributes
    ----------
    kind
        ``"wlf"`` or ``"arrhenius"``.
    reference_temperature_c
        Where ``log10 aT = 0``.
    values, stderr
        Parameter values and standard errors, in the order of :data:`PARAMETERS` (by name
        with their units: :attr:`parameters`).
    covariance
        Their covariance.
    chi2, dof
        Weighted residual sum of squares of the shifts and its degrees of freedom.
    at_bound
        Names of the parameters that ended at a bound of the fit (their values and errors say
        nothing of the data).
    """

    kind: str
    reference_temperature_c: float
    values: tuple[float, ...]
    stderr: tuple[float, ...]
    covariance: NDArray[np.float64] = field(repr=False)
    chi2: float
    dof: int
    at_bound: tuple[str, ...] = ()

    @property
    def parameters(self) -> dict[str, Estimate]:
        """``{name: Estimate(value, stderr, unit)}`` in the order of :data:`PARAMETERS`."""
        names, units = PARAMETERS[self.kind]
        return {name: Estimate(float(value), float(error), unit) for name, value, error, unit
                in zip(names, self.values, self.stderr, units, strict=True)}

    @property
    def aic(self) -> float:
        """``χ² + 2k``."""
        return self.chi2 + 2 * len(self.values)

    @property
    def reduced_chi2(self) -> float:
        """``χ²/dof`` (NaN without degrees of freedom)."""
        return self.chi2 / self.dof if self.dof > 0 else math.nan

    def __call__(self, temperature_c: ArrayLike) -> NDArray[np.float64]:
        """``log10 aT`` at ``temperature_c``."""
        return _function(self.kind)(temperature_c, self.reference_temperature_c, *self.values)

    def stderr_at(self, temperature_c: float) -> float:
        """Standard error of ``log10 aT`` at one temperature, from the parameters' covariance."""
        gradient = _gradient(lambda p: float(
            _function(self.kind)(temperature_c, self.reference_temperature_c, *p)), self.values)
        return float(np.sqrt(max(0.0, gradient @ self.covariance @ gradient)))

    def reaches(self, temperature_c: float) -> bool:
        """The function is finite at ``temperature_c``: WLF above its Vogel temperature
        ``T_ref − C2`` (where ``log10 aT`` goes to infinity), Arrhenius above 0 K."""
        if self.kind == "arrhenius":
            return temperature_c > -KELVIN
        return temperature_c > self.reference_temperature_c - self.values[1]

    def rereferenced(self, reference_c: float) -> ShiftFunction:
        """The same function with ``log10 aT = 0`` at ``reference_c`` (WLF: ``C1' = C1 C2 /
        (C2 + ΔT)``, ``C2' = C2 + ΔT``; Arrhenius: same ``E_a``), errors propagated."""
        if self.kind == "arrhenius":
            return ShiftFunction("arrhenius", reference_c, self.values, self.stderr,
                                 self.covariance, self.chi2, self.dof, self.at_bound)
        shift = reference_c - self.reference_temperature_c

        def moved(p: NDArray) -> NDArray:
            return np.array([p[0] * p[1] / (p[1] + shift), p[1] + shift])

        def component(k: int) -> Callable[[NDArray], float]:
            return lambda p: float(moved(np.asarray(p))[k])

        jac = np.stack([_gradient(component(k), self.values) for k in range(2)])
        covariance = jac @ self.covariance @ jac.T
        values = tuple(float(v) for v in moved(np.asarray(self.values)))
        return ShiftFunction("wlf", reference_c, values,
                             tuple(float(v) for v in np.sqrt(np.diag(covariance))),
                             covariance, self.chi2, self.dof, self.at_bound)

    def parameters_text(self) -> str:
        """``C1 = 13.5 ± 1.1, C2_K = 101 ± 7 K``; a parameter at a bound of the fit as
        ``C1 = 1000 (at the bound of its fit, not found by the shifts)``."""
        out = []
        for name, estimate in self.parameters.items():
            unit = "" if estimate.unit == "1" else estimate.unit
            if name in self.at_bound:
                out.append(f"{name} = {estimate.value:.4g}{' ' + unit if unit else ''} (at the "
                           "bound of its fit, not found by the shifts)")
            else:
                out.append(f"{name} = "
                           + with_uncertainty(estimate.value, estimate.stderr, unit))
        return ", ".join(out)

    def to_json(self) -> dict:
        """``{"kind", "parameters": {name: {"value", "stderr", "unit"}}, ..., "at_bound":
        [names]}``."""
        return {
            "kind": self.kind,
            "reference_temperature_c": self.reference_temperature_c,
            "parameters": {name: p.to_json() for name, p in self.parameters.items()},
            "chi2_per_dof": None if math.isnan(self.reduced_chi2) else self.reduced_chi2,
            "describes_shifts": bool(not self.reduced_chi2 > 2.0),
            "at_bound": list(self.at_bound),
        }


def _function(kind: str) -> Callable[..., NDArray]:
    functions: dict[str, Callable[..., NDArray]] = {"wlf": wlf, "arrhenius": arrhenius}
    return functions[kind]


def _gradient(function: Callable[[NDArray], float], values: tuple[float, ...]) -> NDArray:
    values_array = np.asarray(values, dtype=float)
    gradient = np.empty(values_array.size)
    for k in range(values_array.size):
        step = 1e-6 * max(abs(values_array[k]), 1e-3)
        up, down = values_array.copy(), values_array.copy()
        up[k] += step
        down[k] -= step
        gradient[k] = (function(up) - function(down)) / (2 * step)
    return gradient


def fit_shift_function(
    kind: str, temperature_c: NDArray[np.float64], log10_at: NDArray[np.float64],
    covariance: NDArray[np.float64], reference_c: float,
) -> ShiftFunction | None:
    """Fit ``kind`` to shift factors whose reference (zero-variance) entry is at ``reference_c``.

    Returns ``None`` when there are fewer shifts than parameters or the fit fails.
    """
    keep = np.diag(covariance) > 0
    t, y = temperature_c[keep], log10_at[keep]
    cov = covariance[np.ix_(keep, keep)]
    names, _ = PARAMETERS[kind]
    if t.size < len(names):
        return None
    if kind == "wlf":
        low = reference_c - float(np.min(temperature_c))
        start = [17.44, max(51.6, low + 20.0)]
        bounds = ([1e-3, max(low, 0.0) + 1e-3], [1e3, 1e5])
    else:
        start, bounds = [2e5], ([1e2], [5e6])

    def model(temperature: NDArray, *p: float) -> NDArray:
        return _function(kind)(temperature, reference_c, *p)

    try:
        values, pcov = curve_fit(model, t, y, p0=start, sigma=cov, absolute_sigma=True,
                                 bounds=bounds, maxfev=5000)
    except (RuntimeError, ValueError, np.linalg.LinAlgError):
        return None
    residual = y - model(t, *values)
    try:
        chi2 = float(residual @ np.linalg.solve(cov, residual))
    except np.linalg.LinAlgError:
        return None
    dof = t.size - len(names)
    if dof > 0 and chi2 / dof > 1.0:
        pcov = pcov * (chi2 / dof)
    at_bound = tuple(name for name, value, low, high in zip(names, values, *bounds, strict=True)
                     if min(abs(value - low), abs(value - high))
                     <= BOUND_TOLERANCE * max(abs(low), abs(high), 1.0))
    return ShiftFunction(kind, reference_c, tuple(float(v) for v in values),
                         tuple(float(v) for v in np.sqrt(np.clip(np.diag(pcov), 0, None))),
                         pcov, chi2, dof, at_bound)


def best_shift_function(functions: Sequence[ShiftFunction | None]) -> ShiftFunction | None:
    """The fitted function of lowest AIC, or ``None`` if none was fitted (one at a bound of its
    fit included: see the module text)."""
    fitted = [f for f in functions if f is not None]
    return min(fitted, key=lambda f: f.aic) if fitted else None
