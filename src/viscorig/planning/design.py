"""Optimal experimental design with rig time as the resource.

Problem. Candidate frequencies ``f`` each give information ``τ_f · R_f`` for ``τ_f`` seconds of
integration (:class:`~viscorig.planning.information.InformationModel`); ``I_0`` is what is
known already (points measured so far, or nothing). The least integration time that brings the
relative standard error of every target parameter ``k`` to ``t_k`` is ::

    minimise  Σ_f τ_f   subject to   g_k(τ) = [(I_0 + Σ_f τ_f R_f)⁻¹]_kk / t_k² ≤ 1,   τ ≥ 0

a convex problem (each constraint is convex in ``τ``): c-optimal design for each target with
per-parameter constraints, every other estimated parameter a nuisance.

Optimality (KKT). With ``C = (I_0 + Σ τ R)⁻¹`` and ``h_kf = e_kᵀ C R_f C e_k / t_k²`` (the
decrease of ``g_k`` per second at ``f``), ``τ`` is optimal when multipliers ``λ ≥ 0`` exist with
``d_f = Σ_k λ_k h_kf ≤ 1`` at every candidate and ``= 1`` where ``τ_f > 0`` (the equivalence
theorem of optimal design in this form).

Solution (column generation). A few multiplicative-algorithm steps (Silvey, Titterington &
Torsney 1978) on the simplex pick a first support; the problem restricted to the support is
small and solved exactly (SLSQP with analytic gradients); the multipliers follow from the KKT
equations on the support; every candidate whose ``d_f`` exceeds 1 joins the support; repeat.

Certificate. For any ``λ ≥ 0`` and any design ``τ̄``, convexity of the Lagrangian gives ::

    least time ≥ Σ_f τ̄_f d'_f + Σ_k λ'_k (g_k(τ̄) − 1),    λ' = λ / max(1, max_f d_f)

:attr:`Design.lower_bound_s` is that number: a true lower bound over every allocation on the
candidate frequencies, whatever the solver's convergence.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.optimize import minimize, nnls

__all__ = ["Design", "minimum_time_design"]

#: Ridge (relative to the information's scale) that keeps a sparse design invertible.
_RIDGE = 1e-12
#: Candidates of the first support (the best of a few multiplicative steps).
_FIRST_SUPPORT = 24


@dataclass(frozen=True)
class Design:
    """An optimal allocation of integration time over candidate frequencies.

    Attributes
    ----------
    frequency_hz
        The candidates.
    integrate_s
        Integration time given to each candidate (most are 0).
    total_s
        ``Σ integrate_s``: the least integration time found that meets every target.
    lower_bound_s
        Certified lower bound on the least time over every allocation of the candidates.
    relative_stderr
        Predicted relative standard error of every target with this design.
    multipliers
        Weight of each target's constraint at the optimum (0: not binding).
    """

    frequency_hz: NDArray[np.float64]
    integrate_s: NDArray[np.float64]
    total_s: float
    lower_bound_s: float
    relative_stderr: NDArray[np.float64]
    multipliers: NDArray[np.float64]

    def support(self, fraction: float = 1e-3) -> NDArray[np.int64]:
        """Indices of the candidates holding more than ``fraction`` of the time."""
        if self.total_s <= 0:
            return np.zeros(0, dtype=np.int64)
        return np.nonzero(self.integrate_s > fraction * self.total_s)[0]


class _Problem:
    """The constraint functions and their derivatives for one set of candidates."""

    def __init__(self, rate, prior, targets, squared) -> None:
        self.rate = rate
        self.prior = prior
        self.targets = targets
        self.squared = squared
        k = rate.shape[1]
        scale = float(np.mean(np.trace(rate, axis1=1, axis2=2))) / k
        self.ridge = _RIDGE * max(scale, 1e-300) * np.eye(k)

    def covariance(self, tau: NDArray[np.float64], index: NDArray[np.int64]) -> NDArray:
        information = self.prior + np.einsum("p,pij->ij", tau, self.rate[index])
        try:
            return np.linalg.inv(information + self.ridge)
        except np.linalg.LinAlgError:
            return np.full_like(information, np.inf)

    def ratios(self, covariance: NDArray) -> NDArray[np.float64]:
        """``g_k``."""
        return np.diag(covariance)[self.targets] / self.squared

    def decrease(self, covariance: NDArray, index: NDArray[np.int64] | None = None) -> NDArray:
        """``h_kf`` (targets × candidates)."""
        rate = self.rate if index is None else self.rate[index]
        rows = covariance[self.targets]  # e_kᵀ C
        return np.einsum("ki,pij,kj->kp", rows, rate, rows) / self.squared[:, None]


def _solve_support(problem: _Problem, index: NDArray[np.int64], start: NDArray) -> NDArray:
    """Least ``Σ τ`` on the candidates ``index`` (exact, SLSQP), from a feasible ``start``."""
    scale = max(float(start.sum()), 1e-12)

    def constraints(x):
        return 1.0 - problem.ratios(problem.covariance(x * scale, index))

    def jacobian(x):
        covariance = problem.covariance(x * scale, index)
        return problem.decrease(covariance, index) * scale

    result = minimize(
        lambda x: float(np.sum(x)),
        start / scale,
        jac=lambda x: np.ones_like(x),
        bounds=[(0.0, None)] * index.size,
        constraints=[{"type": "ineq", "fun": constraints, "jac": jacobian}],
        method="SLSQP",
        options={"maxiter": 500, "ftol": 1e-12},
    )
    x = np.maximum(result.x, 0.0)
    ratios = problem.ratios(problem.covariance(x * scale, index))
    if not np.all(np.isfinite(ratios)):
        return start
    # SLSQP may end a hair infeasible: scale up to meet every target (feasible by monotonicity).
    factor = 1.0
    while np.max(problem.ratios(problem.covariance(x * scale * factor, index))) > 1.0 + 1e-9:
        factor *= 1.0 + max(float(np.max(ratios)) - 1.0, 1e-6)
        if factor > 1e6:
            return start
    return x * scale * factor


def _feasible_start(
    problem: _Problem, weights: NDArray[np.float64]
) -> NDArray[np.float64] | None:
    """``Θ w`` with the least ``Θ`` that meets every target (bisection on ``Θ``); ``None``
    when no ``Θ`` does."""
    all_index = np.arange(weights.size)
    high = 1.0
    while not np.max(problem.ratios(problem.covariance(high * weights, all_index))) <= 1.0:
        high *= 4.0
        if high > 1e30:
            return None
    low = 0.0
    for _ in range(80):
        middle = 0.5 * (low + high)
        if np.max(problem.ratios(problem.covariance(middle * weights, all_index))) <= 1.0:
            high = middle
        else:
            low = middle
        if high - low <= 1e-9 * high:
            break
    return high * weights


def _multiplicative(problem: _Problem, iterations: int) -> NDArray[np.float64]:
    """A first allocation on the simplex: multiplicative steps for equal target weights."""
    count = problem.rate.shape[0]
    w = np.full(count, 1.0 / count)
    all_index = np.arange(count)
    for _ in range(iterations):
        covariance = problem.covariance(_feasible_scale(problem, w) * w, all_index)
        d = problem.decrease(covariance).sum(axis=0)
        w = w * d / float(w @ d)
        w /= w.sum()
    return w


def _feasible_scale(problem: _Problem, w: NDArray[np.float64]) -> float:
    per_second = np.einsum("p,pij->ij", w, problem.rate)
    if np.any(problem.prior):
        return 1.0  # only the shape matters for the first support
    return float(np.max(problem.ratios(np.linalg.inv(per_second + problem.ridge))))


def minimum_time_design(
    frequency_hz: ArrayLike,
    rate: NDArray[np.float64],
    targets: ArrayLike,
    relative_stderr: ArrayLike,
    *,
    prior: NDArray[np.float64] | None = None,
    tolerance: float = 1e-4,
    max_rounds: int = 40,
) -> Design:
    """The least integration time over ``frequency_hz`` that meets every target.

    Parameters
    ----------
    frequency_hz
        Candidate frequencies (P).
    rate
        Information per second of integration at each candidate, (P, k, k), in relative
        coordinates of the k estimated parameters.
    targets
        Indices (into the k parameters) of the targets.
    relative_stderr
        Wanted relative standard error of each target.
    prior
        Information already held, (k, k).
    tolerance
        Optimal when no candidate's ``d_f`` exceeds 1 by more than this.
    max_rounds
        Rounds of column generation at most.
    """
    f = np.asarray(frequency_hz, dtype=float)
    rate = np.asarray(rate, dtype=float)
    targets = np.atleast_1d(np.asarray(targets, dtype=np.int64))
    squared = np.atleast_1d(np.asarray(relative_stderr, dtype=float)) ** 2
    k = rate.shape[1]
    prior = np.zeros((k, k)) if prior is None else np.asarray(prior, dtype=float)
    problem = _Problem(rate, prior, targets, squared)
    all_index = np.arange(f.size)

    if np.any(prior) and np.all(problem.ratios(problem.covariance(np.zeros(0), all_index[:0]))
                                <= 1.0):  # fmt: skip
        covariance = problem.covariance(np.zeros(0), all_index[:0])
        return Design(f, np.zeros(f.size), 0.0, 0.0, np.sqrt(np.diag(covariance)[targets]),
                      np.zeros(targets.size))  # fmt: skip

    w = _multiplicative(problem, 60)
    first = np.argsort(w)[::-1][:_FIRST_SUPPORT]
    first = first[w[first] > 1e-3 * w.max()]
    uniform = _feasible_start(problem, np.full(f.size, 1.0 / f.size))
    if uniform is None:
        raise ValueError("the candidates carry no information about the targets")
    best_each = problem.decrease(problem.covariance(uniform, all_index)).argmax(axis=1)
    first = np.union1d(first, best_each)
    start = np.zeros(f.size)
    start[first] = 1.0 / first.size
    feasible = _feasible_start(problem, start)
    if feasible is None:
        first, start = all_index, uniform
    else:
        start = feasible
    tau = np.zeros(f.size)
    tau[first] = _solve_support(problem, first, start[first])
    lam = np.full(targets.size, 1.0 / targets.size)
    for _ in range(max_rounds):
        covariance = problem.covariance(tau, all_index)
        h = problem.decrease(covariance)
        support = np.nonzero(tau > 1e-9 * tau.sum())[0]
        lam, _ = nnls(h[:, support].T, np.ones(support.size))
        d = lam @ h
        if d.max() <= 1.0 + tolerance:
            break
        joining = np.nonzero(d > 1.0 + tolerance)[0]
        joining = joining[np.argsort(d[joining])[::-1][:8]]
        index = np.union1d(support, joining)
        reduced = _solve_support(problem, index, tau[index] + 1e-3 * tau.sum() / index.size)
        tau = np.zeros(f.size)
        tau[index] = reduced
    covariance = problem.covariance(tau, all_index)
    h = problem.decrease(covariance)
    d = lam @ h
    scaled = lam / max(1.0, float(d.max()))
    bound = float(tau @ (scaled @ h) + scaled @ (problem.ratios(covariance) - 1.0))
    return Design(
        frequency_hz=f,
        integrate_s=tau,
        total_s=float(tau.sum()),
        lower_bound_s=max(bound, 0.0),
        relative_stderr=np.sqrt(np.diag(covariance)[targets]),
        multipliers=lam,
    )
