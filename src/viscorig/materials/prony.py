"""Generalized Maxwell (Prony) series and the fractional model, fitted to a master curve.

Prony series: ``E*(ω) = E_∞ + Σ E_i iωτ_i / (1 + iωτ_i)``, so
``E' = E_∞ + Σ E_i ω²τ_i²/(1+ω²τ_i²)`` and ``E'' = Σ E_i ωτ_i/(1+ω²τ_i²)``. It is fitted to E'
and E'' together, each residual ``ln(model/measured)`` divided by that modulus's own scatter
(its relative error). For ``N = 1, 2, ...`` terms, a non-negative least-squares solve on
log-spaced ``τ_i`` starts a nonlinear fit of every ``E_i, τ_i`` (in logs, so all stay positive),
bounded (:func:`prony_bounds`): every ``τ_i`` within the relaxation times the reduced
frequencies support, ``1/(2 ω_max)`` to a decade beyond ``1/ω_min``, every modulus at most
:data:`MODULUS_CAP` times the largest measured one. (A term much faster than ``1/ω_max`` adds
only ``E_i ω τ_i`` to the loss there: the data fix the product, so the faster the term, the
larger its modulus, and the instantaneous modulus grows without any point asking for it. One
whose loss peak lies within an octave above ``ω_max`` still shows its flank in the data; stopped
at ``1/ω_max``, a series could not follow a spectrum that goes on past the window, and the
shifts, refined with it, took its misfit: on sweeps generated from a 12-term series with 0.1 %
noise every shift but the reference's was off by 0.02 to 0.08 decade, up to 9 standard errors,
and the master curve 11 % (E′) and 14 % (E″) off inside the measured range, where now the shifts
are within 0.003 decade and 1.2 standard errors and the curve within 0.5 %.) Unbounded, a
term the data do not hold runs away (``τ = 1e-77 s``, ``E = 1e71 Pa`` from six sweeps), and
where it stopped depended on overflowing trial steps of the Levenberg-Marquardt solver, whose
next step after one was not repeatable from one process to the next (the same residuals and
Jacobian gave different trial points); bounded (trust-region reflective), no step overflows and
the same data give the same series bit for bit.
The series kept is the first whose rms errors reach the data's scatter (within 10 %), else the
one of lowest BIC, with at most :data:`MAX_TERMS` terms.

Fractional (Zener) model beside it: four parameters (:class:`viscorig.models.modulus.Fractional`,
the same formula as the rig's K* model, here in Pa).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.optimize import least_squares, nnls
from scipy.special import expit

from viscorig.models import Context
from viscorig.models.modulus import Fractional

MAX_TERMS = 24
#: How far (a factor) beyond ``1/ω_min`` of the data a relaxation time may go (slow end) ...
TAU_MARGIN = 10.0
#: ... and below ``1/ω_max`` (fast end): a term whose loss peak lies up to an octave above the
#: fastest reduced frequency still shows the flank of that peak in the data (see the module
#: text).
FAST_MARGIN = 2.0
#: Largest modulus of any term (and the long-term one), times the largest measured ``|E*|``.
MODULUS_CAP = 10.0
#: Smallest, times the same: a floor for the logs (such a term carries nothing).
MODULUS_FLOOR = 1e-9
#: How close (relative) to the data's scatter counts as reaching it.
SCATTER_MARGIN = 1.10


@dataclass(frozen=True)
class PronySeries:
    """A generalized Maxwell series.

    Attributes
    ----------
    long_term_modulus_pa
        ``E_∞`` (Pa).
    moduli_pa, tau_s
        ``E_i`` (Pa) and ``τ_i`` (s) of each term, ``τ`` ascending.
    """

    long_term_modulus_pa: float
    moduli_pa: NDArray[np.float64]
    tau_s: NDArray[np.float64]

    @property
    def terms(self) -> int:
        """Number of terms."""
        return int(self.tau_s.size)

    @property
    def instantaneous_modulus_pa(self) -> float:
        """``E_0 = E_∞ + Σ E_i``."""
        return float(self.long_term_modulus_pa + self.moduli_pa.sum())

    def complex_modulus(self, omega: ArrayLike) -> NDArray[np.complex128]:
        """``E*(ω)`` (Pa) at angular frequencies ``omega`` (rad/s)."""
        with np.errstate(divide="ignore"):  # ω = 0: the long-term modulus
            log_omega = np.log(np.asarray(omega, dtype=float))
        x, _, y = maxwell_parts(log_omega[:, None] + np.log(self.tau_s)[None, :])
        return (self.long_term_modulus_pa + x @ self.moduli_pa) + 1j * (y @ self.moduli_pa)

    def relaxation(self, time_s: ArrayLike) -> NDArray[np.float64]:
        """Relaxation modulus ``E(t) = E_∞ + Σ E_i exp(−t/τ_i)`` (Pa)."""
        t = np.asarray(time_s, dtype=float)[:, None]
        return self.long_term_modulus_pa + (self.moduli_pa * np.exp(-t / self.tau_s)).sum(axis=1)

    def to_json(self) -> dict:
        """``{"long_term_modulus_pa", "instantaneous_modulus_pa", "terms": [...]}``."""
        return {
            "long_term_modulus_pa": self.long_term_modulus_pa,
            "instantaneous_modulus_pa": self.instantaneous_modulus_pa,
            "terms": [{"modulus_pa": float(e), "tau_s": float(t)}
                      for e, t in zip(self.moduli_pa, self.tau_s, strict=True)],
        }


@dataclass(frozen=True)
class ModelFit:
    """How well a model reproduces the master curve: rms of ``ln(model/measured)``."""

    storage_rms_log_error: float
    loss_rms_log_error: float
    chi2: float
    parameters: int

    def bic(self, points: int) -> float:
        """Bayesian information criterion of the weighted fit."""
        return self.chi2 + self.parameters * math.log(points)

    def reaches(self, scatter: tuple[float, float]) -> bool:
        """Both rms errors within :data:`SCATTER_MARGIN` of the data's ``scatter``."""
        return (self.storage_rms_log_error <= SCATTER_MARGIN * scatter[0]
                and self.loss_rms_log_error <= SCATTER_MARGIN * scatter[1])

    def ladder_entry(self, terms: int, points: int, scatter: tuple[float, float]) -> dict:
        """A rung of :func:`fit_prony`'s ladder: this fit of ``terms`` terms to ``points``
        points (E' and E'' counted apart)."""
        return {"terms": terms, "storage_rms_log_error": self.storage_rms_log_error,
                "loss_rms_log_error": self.loss_rms_log_error, "bic": self.bic(points),
                "reaches_scatter": self.reaches(scatter)}


def model_fit(model: NDArray[np.complex128], storage: NDArray, loss: NDArray,
              scatter: tuple[float, float], parameters: int) -> ModelFit:
    """Errors of modelled moduli against measured ones (weights: the scatter of each)."""
    rs = np.log(np.maximum(model.real, 1e-300) / storage)
    rl = np.log(np.maximum(model.imag, 1e-300) / loss)
    chi2 = float(((rs / scatter[0]) ** 2).sum() + ((rl / scatter[1]) ** 2).sum())
    return ModelFit(float(np.sqrt(np.mean(rs**2))), float(np.sqrt(np.mean(rl**2))), chi2,
                    parameters)


def tau_span(omega: ArrayLike) -> tuple[float, float]:
    """The relaxation times a series fitted at angular frequencies ``omega`` may take (s):
    ``1/ω_max`` to ``1/ω_min`` widened by :data:`TAU_MARGIN`."""
    omega = np.asarray(omega, dtype=float)
    return 1.0 / (FAST_MARGIN * float(omega.max())), TAU_MARGIN / float(omega.min())


def prony_bounds(omega: ArrayLike, storage: ArrayLike, loss: ArrayLike,
                 terms: int) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Lower and upper bounds of ``ln E_∞, ln E_i, ln τ_i`` (see the module text)."""
    largest = float(np.hypot(np.asarray(storage, dtype=float), np.asarray(loss, dtype=float))
                    .max())
    lo_tau, hi_tau = tau_span(omega)
    lower = np.concatenate([np.full(terms + 1, math.log(MODULUS_FLOOR * largest)),
                            np.full(terms, math.log(lo_tau))])
    upper = np.concatenate([np.full(terms + 1, math.log(MODULUS_CAP * largest)),
                            np.full(terms, math.log(hi_tau))])
    return lower, upper


def _inside(start: NDArray, bounds: tuple[NDArray, NDArray]) -> NDArray[np.float64]:
    """``start`` moved just inside ``bounds``."""
    lower, upper = bounds
    margin = 1e-9 * (upper - lower)
    return np.clip(start, lower + margin, upper - margin)


def maxwell_parts(log_wt: NDArray) -> tuple[NDArray, NDArray, NDArray]:
    """A Maxwell term's shares ``ω²τ²/(1+ω²τ²)`` (of E'), ``1/(1+ω²τ²)`` and ``ωτ/(1+ω²τ²)``
    (of E''), from ``ln ωτ`` without forming ``ωτ``: over a master curve of a few dozen decades
    ``(1+ω²τ²)²`` is beyond a double.

    The derivatives by ``ln τ`` follow: ``2 x x_c`` for the first, ``y (x_c − x)`` for the
    third (``x, x_c, y`` the three shares).
    """
    decay = np.exp(-np.abs(log_wt))  # ωτ or 1/ωτ, whichever is at most 1
    return expit(2 * log_wt), expit(-2 * log_wt), decay / (1 + decay * decay)


def _start(omega: NDArray, storage: NDArray, loss: NDArray, scatter: tuple[float, float],
           terms: int) -> NDArray[np.float64]:
    """ln E_∞, ln E_i, ln τ_i from NNLS on ``terms`` log-spaced relaxation times."""
    lo, hi = 1.0 / omega.max(), 1.0 / omega.min()
    tau = np.array([math.sqrt(lo * hi)]) if terms == 1 else np.geomspace(lo, hi, terms)
    x, _, y = maxwell_parts(np.log(omega)[:, None] + np.log(tau)[None, :])
    a = np.vstack([
        np.hstack([np.ones((omega.size, 1)), x]) / (storage[:, None] * scatter[0]),
        np.hstack([np.zeros((omega.size, 1)), y]) / (loss[:, None] * scatter[1]),
    ])
    b = np.concatenate([np.full(omega.size, 1 / scatter[0]), np.full(omega.size, 1 / scatter[1])])
    x = nnls(a, b, maxiter=50 * a.shape[1])[0]
    floor = 1e-6 * max(float(x.max()), float(storage.min()))
    x = np.maximum(x, floor)
    return np.concatenate([np.log(x), np.log(tau)])


def _refine(omega: NDArray, storage: NDArray, loss: NDArray, scatter: tuple[float, float],
            start: NDArray, evaluations: int = 40) -> PronySeries:
    n = (start.size - 1) // 2
    ls, ll = np.log(storage), np.log(loss)

    log_omega = np.log(omega)[:, None]

    def parts(p: NDArray) -> tuple[NDArray, ...]:
        e_inf, e = np.exp(p[0]), np.exp(p[1:n + 1])
        x, x_complement, y = maxwell_parts(log_omega + p[None, n + 1:])
        return e_inf, e, x, x_complement, y

    def residual(p: NDArray) -> NDArray:
        e_inf, e, x, _, y = parts(p)
        return np.concatenate([(np.log(e_inf + x @ e) - ls) / scatter[0],
                               (np.log(y @ e) - ll) / scatter[1]])

    def jacobian(p: NDArray) -> NDArray:
        e_inf, e, x, x_complement, y = parts(p)
        es, el = e_inf + x @ e, y @ e
        dx = 2 * x * x_complement  # d/d ln τ of ω²τ²/(1+ω²τ²) and of ωτ/(1+ω²τ²)
        dy = y * (x_complement - x)
        top = np.hstack([np.full((omega.size, 1), e_inf), x * e, dx * e]) / es[:, None]
        bottom = np.hstack([np.zeros((omega.size, 1)), y * e, dy * e]) / el[:, None]
        return np.vstack([top / scatter[0], bottom / scatter[1]])

    bounds = prony_bounds(omega, storage, loss, n)
    solution = least_squares(residual, _inside(start, bounds), jac=jacobian, method="trf",
                             bounds=bounds, max_nfev=evaluations, x_scale="jac")
    e_inf, e, _, _, _ = parts(solution.x)
    tau = np.exp(solution.x[n + 1:])
    order = np.argsort(tau)
    return PronySeries(float(e_inf), e[order], tau[order])


def fit_prony(
    omega: ArrayLike, storage_pa: ArrayLike, loss_pa: ArrayLike, scatter: tuple[float, float],
    max_terms: int = MAX_TERMS,
) -> tuple[PronySeries, ModelFit, list[dict]]:
    """The Prony series with the fewest terms that reaches the data's scatter.

    Parameters
    ----------
    omega
        Reduced angular frequency of each point (rad/s).
    storage_pa, loss_pa
        Measured E' and E'' (Pa).
    scatter
        Rms of ``ln`` residual of E' and E'' about a smooth curve (the target).
    max_terms
        Most terms tried.

    Returns
    -------
    series, fit, ladder
        The series kept, its errors, and for each number of terms tried its errors and BIC.
    """
    omega, storage, loss = (np.asarray(v, dtype=float) for v in (omega, storage_pa, loss_pa))
    scatter = (max(scatter[0], 1e-4), max(scatter[1], 1e-4))
    ladder, best = [], None
    for terms in range(1, max_terms + 1):
        series = _refine(omega, storage, loss, scatter, _start(omega, storage, loss, scatter,
                                                              terms))
        fit = model_fit(series.complex_modulus(omega), storage, loss, scatter, 2 * terms + 1)
        ladder.append(fit.ladder_entry(terms, 2 * omega.size, scatter))
        if best is None or fit.bic(2 * omega.size) < best[1].bic(2 * omega.size):
            best = (series, fit)
        if fit.reaches(scatter):
            break
        # stop once BIC has not improved for four more terms: the data says no more
        if terms - best[0].terms >= 4:
            break
    assert best is not None, "the ladder tries one number of terms at least"
    series = best[0]
    start = np.concatenate([[np.log(series.long_term_modulus_pa)], np.log(series.moduli_pa),
                            np.log(series.tau_s)])
    polished = _refine(omega, storage, loss, scatter, start, evaluations=400)
    fit = model_fit(polished.complex_modulus(omega), storage, loss, scatter, 2 * series.terms + 1)
    if fit.chi2 > best[1].chi2:
        polished, fit = series, best[1]
    return polished, fit, ladder


def fit_prony_terms(omega: ArrayLike, storage_pa: ArrayLike, loss_pa: ArrayLike,
                    scatter: tuple[float, float], terms: int) -> tuple[PronySeries, ModelFit]:
    """The best Prony series of exactly ``terms`` terms (same weighting as :func:`fit_prony`)."""
    omega, storage, loss = (np.asarray(v, dtype=float) for v in (omega, storage_pa, loss_pa))
    scatter = (max(scatter[0], 1e-4), max(scatter[1], 1e-4))
    series = _refine(omega, storage, loss, scatter,
                     _start(omega, storage, loss, scatter, terms), evaluations=400)
    return series, model_fit(series.complex_modulus(omega), storage, loss, scatter, 2 * terms + 1)


@dataclass(frozen=True)
class FractionalModel:
    """Fractional Zener ``E* = (E_0 + E_∞ (iωτ)^α) / (1 + (iωτ)^α)``."""

    relaxed_modulus_pa: float
    unrelaxed_modulus_pa: float
    tau_s: float
    alpha: float

    def complex_modulus(self, omega: ArrayLike) -> NDArray[np.complex128]:
        """``E*(ω)`` (Pa) at angular frequencies ``omega`` (rad/s)."""
        frequency_hz = np.asarray(omega, dtype=float) / (2 * np.pi)
        return Fractional().modulus(Context(frequency_hz=frequency_hz), {
            "K_0": self.relaxed_modulus_pa, "K_inf": self.unrelaxed_modulus_pa,
            "tau": self.tau_s, "alpha": self.alpha})

    def to_json(self) -> dict:
        """Parameters with units."""
        return {"relaxed_modulus_pa": self.relaxed_modulus_pa,
                "unrelaxed_modulus_pa": self.unrelaxed_modulus_pa,
                "tau_s": self.tau_s, "alpha": self.alpha}


def fit_fractional(omega: ArrayLike, storage_pa: ArrayLike, loss_pa: ArrayLike,
                   scatter: tuple[float, float]) -> tuple[FractionalModel, ModelFit]:
    """Fit the four-parameter fractional model to E' and E'' (same weighting as the Prony fit)."""
    omega, storage, loss = (np.asarray(v, dtype=float) for v in (omega, storage_pa, loss_pa))
    scatter = (max(scatter[0], 1e-4), max(scatter[1], 1e-4))

    def model(p: NDArray) -> FractionalModel:
        return FractionalModel(float(np.exp(p[0])), float(np.exp(p[0]) + np.exp(p[1])),
                               float(np.exp(p[2])), float(p[3]))

    def residual(p: NDArray) -> NDArray:
        value = model(p).complex_modulus(omega)
        return np.concatenate([
            np.log(np.maximum(value.real, 1e-300) / storage) / scatter[0],
            np.log(np.maximum(value.imag, 1e-300) / loss) / scatter[1]])

    peak = float(omega[np.argmax(loss)])
    best = None
    for alpha in (0.2, 0.4, 0.6):
        start = np.array([np.log(storage.min()), np.log(max(storage.max() - storage.min(),
                                                            1e-3 * storage.max())),
                          np.log(1 / peak), alpha])
        solution = least_squares(residual, start, method="trf",
                                 bounds=([-np.inf, -np.inf, -np.inf, 0.01],
                                         [np.inf, np.inf, np.inf, 1.0]), max_nfev=400)
        if best is None or solution.cost < best.cost:
            best = solution
    assert best is not None
    fitted = model(best.x)
    return fitted, model_fit(fitted.complex_modulus(omega), storage, loss, scatter, 4)
