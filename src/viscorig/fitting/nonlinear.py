"""Bounded nonlinear least squares on the error measure of the design, with honest uncertainties.

Residual: ``H_model/H_measured − 1`` (complex, split into real and imaginary parts) at every
point of every FRF fitted. Positive parameters are fitted as ``log(value)``, the others scaled
to their bounds, and ``scipy.optimize.least_squares`` scales the steps by the Jacobian, so
stiffnesses of 10⁵ N/m and masses of 0.2 kg need no hand tuning.

Weighting (:data:`WEIGHTINGS`). The project's estimate, ``"noise"``, weights
each point's residual by the inverse of its noise standard deviation from the data's noise
model (:mod:`viscorig.fitting.noise`: noise changing along the band by orders of magnitude):
every point counts for the information it holds, and under white noise it is the
maximum-likelihood estimate (:mod:`viscorig.fitting.uncertainty` says why a drift's
correlation enters its covariance but not its weights): from the same linear start, it solves
the weighted problem directly. ``"uniform"`` (the default of :func:`fit`) is the paper's
method, every point weighing the same, which reproduces the paper's Table 1 and minimises the
error measure ``rms_error`` itself (the fits diagnosis reports are these; it compares models by
maximum-likelihood fits of its own, :mod:`viscorig.diagnosis.weighted`).

Standard errors (:mod:`viscorig.fitting.uncertainty`): the covariance of the estimate under
the noise model, scaled up by the misfit when the model does not reach the noise floor, plus
the covariance of parameters held fixed at values identified elsewhere (the table's),
propagated through the fit's sensitivities.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence

import numpy as np
from numpy.typing import NDArray
from scipy.optimize import OptimizeResult, least_squares

from viscorig.errors import InputError
from viscorig.fitting.arms import (
    arm_contributions,
    dead_arms,
    extended_start,
    maxwell_order,
    reduced_start,
)
from viscorig.fitting.data import FrfData
from viscorig.fitting.jacobian import predict_many
from viscorig.fitting.noise import NoiseModel
from viscorig.fitting.noise_estimation import estimate_noise
from viscorig.fitting.result import FitResult
from viscorig.fitting.starts import linear_start
from viscorig.fitting.uncertainty import CORRELATION_WARNING, Known, fit_covariance, si_jacobian
from viscorig.models import Context, Maxwell, Model, parse_spec

__all__ = ["CORRELATION_WARNING", "WEIGHTINGS", "fit", "resolve_frfs"]

#: Relative step of the forward differences where no analytic Jacobian exists (√ε, as
#: scipy's ``"2-point"``).
_STEP = float(np.sqrt(np.finfo(float).eps))
#: How the points of a fit are weighted: by their noise (the project's estimate, generalised
#: least squares under the noise model) or uniformly (the paper's method).
WEIGHTINGS = ("noise", "uniform")


class _Coordinates:
    """Map between parameter values (SI) and the fitter's unknowns."""

    def __init__(self, model: Model, free: Sequence[str]) -> None:
        self.parameters = [model.by_name[name] for name in free]
        self.log = np.array([p.log for p in self.parameters], dtype=bool)
        self.lower = np.array([p.lower for p in self.parameters])
        self.upper = np.array([p.upper for p in self.parameters])
        self.span = np.where(self.log, 1.0, self.upper - self.lower)

    def to_x(self, values: NDArray[np.float64]) -> NDArray[np.float64]:
        linear = (values - self.lower) / self.span
        return np.where(self.log, np.log(np.abs(values) + 1e-300), linear)

    def to_values(self, x: NDArray[np.float64]) -> NDArray[np.float64]:
        return np.where(self.log, np.exp(x), self.lower + x * self.span)

    def derivative(self, values: NDArray[np.float64]) -> NDArray[np.float64]:
        """d value / d x at ``values``."""
        return np.where(self.log, values, self.span)

    def bounds(self) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        return self.to_x(self.lower), self.to_x(self.upper)


def resolve_frfs(model: Model, data: FrfData, frfs: Sequence[str] | None) -> tuple[str, ...]:
    """The FRFs to fit: those asked for, or every FRF that both the model and the data have."""
    if frfs is None:
        chosen = tuple(name for name in model.frfs if name in data.available)
        if not chosen:
            raise InputError(
                f"has none of the FRFs model '{model.spec}' predicts ({', '.join(model.frfs)})",
                data.name,
            )
        return chosen
    chosen = tuple(dict.fromkeys(frfs))
    for name in chosen:
        if name not in model.frfs:
            raise InputError(f"model '{model.spec}' does not predict the {name} FRF", "model spec")
        data.frf(name)  # raises if the run does not have it
    return chosen


def fit(
    model: Model | str,
    data: FrfData,
    *,
    frfs: Sequence[str] | None = None,
    band_hz: tuple[float, float] | None = None,
    fixed: Mapping[str, float] | None = None,
    start: Mapping[str, float] | None = None,
    known: Known | None = None,
    noise: NoiseModel | None = None,
    weighting: str = "uniform",
) -> FitResult:
    """Fit a model to measured FRFs; no start needs to be given.

    Parameters
    ----------
    model
        A :class:`~viscorig.models.Model` or a spec string. A spec that leaves a choice open
        (``maxwell``) is expanded into its candidates; each is fitted and the lowest BIC wins.
    data
        The run's FRFs.
    frfs
        FRFs to fit (``"table"``, ``"support"``); default: every one the model predicts and the
        data has.
    band_hz
        ``(lo, hi)`` in Hz; default: every point.
    fixed
        Parameters held at given values (the table's ``M_s, K_s, C_s`` for a specimen run).
    start
        Start values overriding the linear start (rarely needed; for effect terms' own searches).
    known
        Parameters held fixed *with* their uncertainty (the table's, from the bare-table run):
        their values join ``fixed`` and their covariance is propagated into the result's
        (:mod:`viscorig.fitting.uncertainty`).
    noise
        The noise model of the data in the band (default: estimated from them,
        :func:`viscorig.fitting.noise_estimation.estimate_noise`); pass it to fit several
        models to the same data at the cost of one estimate.
    weighting
        ``"noise"`` (each point weighted by its noise: the project's estimate, which
        ``identify``, ``summary`` and the plans use) or ``"uniform"`` (every point the same:
        the paper's method, minimising ``rms_error`` itself); see the module text.

    Raises
    ------
    InputError
        Missing FRF, too few points in the band, NaN in the data, missing table parameters.
    """
    if weighting not in WEIGHTINGS:
        raise ValueError(f"weighting must be one of {WEIGHTINGS}, not {weighting!r}")
    model = parse_spec(model) if isinstance(model, str) else model
    chosen = resolve_frfs(model, data, frfs)
    band = data.checked(chosen, band_hz)
    for needed in model.requires:
        reason = band.lacks(needed)
        if reason is not None:
            raise InputError(f"model '{model.spec}' needs {needed}, which {reason}", data.name)
    fixed = dict(fixed or {})
    if known is not None:
        fixed = {**known.values, **fixed}
    unknown = sorted(set(fixed) - set(model.names)) if not model.is_open else []
    if unknown:
        raise InputError(f"fixed parameters not in '{model.spec}': {', '.join(unknown)}")
    if noise is None:
        noise = estimate_noise(band, chosen)
    elif any(noise.points(name) != band.frequency_hz.size for name in chosen):
        raise ValueError("the noise model given does not describe the points fitted")
    if not model.is_open:
        return _fit_concrete(model, band, chosen, fixed, start, noise, known=known,
                             weighting=weighting)
    return _select_order(model, band, chosen, fixed, start, noise, known, weighting)


def _select_order(
    model: Model,
    data: FrfData,
    frfs: tuple[str, ...],
    fixed: Mapping[str, float],
    start: Mapping[str, float] | None,
    noise: NoiseModel,
    known: Known | None = None,
    weighting: str = "uniform",
) -> FitResult:
    """Fit the candidates of an open model and return the refined one of lowest BIC.

    Candidates come in order of growing complexity (maxwell(1), (2), ...): forward selection,
    stopping at the first candidate whose BIC does not improve on the best so far. A Maxwell
    order with a dead arm (:mod:`viscorig.fitting.arms`) is the order below in disguise: it is
    never chosen, and the order below is refitted from its surviving arms when that start is
    better than the order's own fit, so that orders are compared between fits that converged.
    Orders are compared by uniform fits; the chosen one is refined with ``weighting``.
    """
    projected = _maxwell_order_search(model, fixed, start)
    by_spec = {candidate.spec: candidate for candidate in model.candidates()}
    by_order = {maxwell_order(candidate): candidate for candidate in by_spec.values()}
    results: dict[str, FitResult] = {}
    degenerate: dict[str, str] = {}

    def search_fit(candidate: Model, values: Mapping[str, float] | None) -> FitResult:
        if projected and values is None:
            lower = [r for r in results.values() if r.spec not in degenerate]
            return _fit_maxwell_candidate(candidate, data, frfs, fixed, noise, lower)
        if projected:
            return _fit_concrete(
                candidate, data, frfs, fixed, values, noise, tolerance=1e-6,
                max_evaluations=ORDER_SEARCH_EVALUATIONS, bounded_fallback=False,
            )  # fmt: skip
        return _fit_concrete(candidate, data, frfs, fixed, values or start, noise, tolerance=1e-6)

    def reduce(result: FitResult) -> None:
        """Refit the order below ``result``'s from its surviving arms; keep the better fit."""
        dead = dead_arms(result)
        if not dead:
            return
        degenerate[result.spec] = "; ".join(dead.values())
        order = maxwell_order(result.model) or 0
        if len(dead) >= order:  # keep the strongest arm: order 1 is the lowest there is
            contributions = arm_contributions(result.model, result.values, result.frequency_hz)
            dead = {i: why for i, why in dead.items() if i != int(np.argmax(contributions)) + 1}
        lower = by_order.get(order - len(dead))
        if lower is None or not dead:
            return
        existing = results.get(lower.spec)
        if existing is not None and existing.rms_error <= result.rms_error:
            return  # the order below already fits better than this order's live arms can
        refitted = search_fit(lower, reduced_start(result, list(dead), lower))
        if existing is None or refitted.bic < existing.bic:
            results[lower.spec] = refitted
            reduce(refitted)

    for candidate in by_spec.values():
        order = maxwell_order(candidate)
        result = search_fit(candidate, None)
        reduce(result)
        below = results.get(by_order[order - 1].spec) if order and order > 1 else None
        if (
            below is not None
            and not projected
            and (result.rms_error >= below.rms_error or result.spec in degenerate)
        ):
            # Order N can represent order N-1 exactly: a worse or degenerate fit is stuck.
            degenerate.pop(result.spec, None)
            warm = search_fit(candidate, extended_start(below.model, below.values,
                                                        below.frequency_hz, candidate))
            if (not dead_arms(warm), -warm.bic) > (not dead_arms(result), -result.bic):
                result = warm
            reduce(result)
        best_so_far = min(
            (r.bic for r in results.values() if r.spec not in degenerate), default=np.inf
        )
        results[candidate.spec] = result
        if result.spec in degenerate or result.bic >= best_so_far:
            break
    eligible = [r for r in results.values() if r.spec not in degenerate]
    chosen_one = min(eligible or list(results.values()), key=lambda result: result.bic)
    best = _refine_chosen(chosen_one, data, frfs, fixed, noise, known, weighting, by_order,
                          results, degenerate)
    ordered = [results[spec] for spec in by_spec if spec in results]
    best.candidates = [(r.spec, r.bic, r.rms_error) for r in ordered]
    best.warnings += [
        f"{spec} not chosen: {why} (it is the order below in disguise)"
        for spec, why in degenerate.items()
        if spec != best.spec
    ]
    return best


def _refine_chosen(chosen: FitResult, data: FrfData, frfs: tuple[str, ...],
                   fixed: Mapping[str, float], noise: NoiseModel, known: Known | None,
                   weighting: str, by_order: Mapping[int | None, Model],
                   results: dict[str, FitResult], degenerate: dict[str, str]) -> FitResult:
    """The order search's choice refitted to full convergence with ``weighting``, and reduced
    while the refined fit leaves an arm dead (``results`` and ``degenerate`` updated)."""
    best = _fit_concrete(chosen.model, data, frfs, fixed, chosen.values, noise,
                         known=known, weighting=weighting)
    while (dead := dead_arms(best)) and (maxwell_order(best.model) or 0) > len(dead):
        degenerate[best.spec] = "; ".join(dead.values())
        lower = by_order[(maxwell_order(best.model) or 0) - len(dead)]
        start_values = reduced_start(best, list(dead), lower)
        best = _fit_concrete(lower, data, frfs, fixed, start_values, noise, known=known,
                             weighting=weighting)
        if lower.spec not in results or best.bic < results[lower.spec].bic:
            results[lower.spec] = best
    return best


#: Nonlinear evaluations a Maxwell order gets while orders are compared (it starts at the
#: solution of the projected problem, so a well-posed order converges in a few).
ORDER_SEARCH_EVALUATIONS = 12


def _maxwell_order_search(
    model: Model, fixed: Mapping[str, float], start: Mapping[str, float] | None
) -> bool:
    """Orders of a plain open ``maxwell`` can be compared from their projected starts.

    :meth:`Maxwell.start` solves the linearised problem (variable projection over ``log τ``,
    weighted by ``1/|Z|``, which is the error measure to first order), so each order needs only
    a few nonlinear steps. Effect terms, fixed ``K*`` parameters or a given start change that
    problem: those take the general path (a full fit of every order).
    """
    return (
        isinstance(model.modulus_term, Maxwell)
        and not model.effects
        and start is None
        and set(fixed) <= {"M_s", "K_s", "C_s"}
    )


def _fit_maxwell_candidate(
    candidate: Model,
    data: FrfData,
    frfs: tuple[str, ...],
    fixed: Mapping[str, float],
    noise: NoiseModel,
    lower_orders: Sequence[FitResult],
) -> FitResult:
    """One Maxwell order during the order search: a few nonlinear steps from the better of its
    projected start and the previous order's fit with one more, idle, arm (so that an order
    whose projected start failed is never shown worse than the order below it)."""
    starts = [linear_start(candidate, data, frfs, fixed)]
    if lower_orders:
        previous = lower_orders[-1].values
        order = len([name for name in candidate.names if name.startswith("C_")]) - 1
        omega = 2 * np.pi * data.frequency_hz
        idle = candidate.by_name[f"K_{order}"].clip(0.0)
        tau = 1.0 / np.sqrt(omega.min() * omega.max())
        starts.append({**starts[0], **previous, f"K_{order}": idle, f"C_{order}": idle * tau})
    ctx = data.context()
    measured = [data.frf(name) for name in frfs]

    def error(values: Mapping[str, float]) -> float:
        predicted = candidate.predict(ctx, values)
        with np.errstate(all="ignore"):
            ratio = np.concatenate([predicted[n] / h for n, h in zip(frfs, measured, strict=True)])
        value = float(np.sum(np.abs(ratio - 1.0) ** 2))
        return value if np.isfinite(value) else np.inf

    best = min(starts, key=error)
    return _fit_concrete(
        candidate, data, frfs, fixed, best, noise, tolerance=1e-6,
        max_evaluations=ORDER_SEARCH_EVALUATIONS, bounded_fallback=False,
    )  # fmt: skip


def _fit_concrete(
    model: Model,
    data: FrfData,
    frfs: tuple[str, ...],
    fixed: Mapping[str, float],
    start: Mapping[str, float] | None,
    noise: NoiseModel,
    tolerance: float = 1e-9,
    max_evaluations: int | None = None,
    bounded_fallback: bool = True,
    known: Known | None = None,
    weighting: str = "uniform",
) -> FitResult:
    free = tuple(name for name in model.names if name not in fixed)
    values = _start_values(model, data, frfs, fixed, start, free)
    coordinates = _Coordinates(model, free)
    ctx = data.context()
    measured = [data.frf(name) for name in frfs]
    current = dict(values)
    last: list[tuple[NDArray[np.float64], dict[str, NDArray[np.complex128]]]] = []

    def predict(x: NDArray[np.float64]) -> dict[str, NDArray[np.complex128]]:
        if last and np.array_equal(last[0][0], x):
            return last[0][1]
        current.update(zip(free, coordinates.to_values(x), strict=True))
        last[:] = [(x.copy(), model.predict(ctx, current))]
        return last[0][1]

    def residual(x: NDArray[np.float64]) -> NDArray[np.float64]:
        predicted = predict(x)
        ratio = np.concatenate([predicted[n] / h for n, h in zip(frfs, measured, strict=True)])
        ratio -= 1.0
        return np.concatenate([ratio.real, ratio.imag])

    def jacobian(x: NDArray[np.float64], *_: object) -> NDArray[np.float64]:
        # r = H/H_measured − 1: ∂r/∂p = (∂H/∂p)/H_measured.
        predicted = predict(x)  # current now holds x's values
        derivatives = model.derivatives(ctx, current, free, predicted)
        assert derivatives is not None
        blocks = [derivatives[n] / h[:, None] for n, h in zip(frfs, measured, strict=True)]
        complex_jacobian = np.concatenate(blocks) * coordinates.derivative(
            np.array([current[name] for name in free])
        )
        return np.concatenate([complex_jacobian.real, complex_jacobian.imag])

    def differences(x: NDArray[np.float64], *_: object) -> NDArray[np.float64]:
        # Forward differences, every column from one evaluation of the model (predict_many),
        # with the steps of scipy's "2-point" (√ε relative, turned back at a bound).
        base = residual(x)
        if not x.size:
            return np.zeros((base.size, 0))
        steps = _STEP * np.where(x >= 0, 1.0, -1.0) * np.maximum(1.0, np.abs(x))
        outside = (x + steps < lower) | (x + steps > upper)
        steps = np.where(outside, -steps, steps)
        steps = (x + steps) - x
        rows = coordinates.to_values(x[None, :] + np.diag(steps))
        shifted = predict_many(model, ctx, current, free, rows)
        with np.errstate(all="ignore"):
            ratio = np.concatenate([shifted[n] / h for n, h in zip(frfs, measured, strict=True)],
                                   axis=1) - 1.0
        moved = np.concatenate([ratio.real, ratio.imag], axis=1)
        return ((moved - base[None, :]) / steps[:, None]).T

    analytic = model.derivatives(ctx, values, free) is not None

    x0 = coordinates.to_x(np.array([values[name] for name in free]))
    lower, upper = coordinates.bounds()
    x0 = np.clip(x0, lower + 1e-12 * (upper - lower), upper - 1e-12 * (upper - lower))
    derivative = jacobian if analytic else differences
    weighted = weighting == "noise" and bool(free)
    weights = None
    if weighted:  # each point by its noise, from the same start
        weights = 1.0 / np.sqrt(noise.stacked_variance(frfs))

        def weighted_residual(x: NDArray[np.float64]) -> NDArray[np.float64]:
            return residual(x) * weights

        def weighted_jacobian(x: NDArray[np.float64], *_: object) -> NDArray[np.float64]:
            return derivative(x) * weights[:, None]

        solution = _least_squares(
            weighted_residual, weighted_jacobian, x0, (lower, upper),
            tolerance, max_evaluations or 50 + 20 * len(free), bounded_fallback, analytic,
        )  # fmt: skip
        solution.jac = solution.jac / weights[:, None]  # back to ∂r/∂x
    else:
        solution = _least_squares(
            residual, derivative, x0, (lower, upper), tolerance,
            max_evaluations or 50 + 20 * len(free), bounded_fallback, analytic,
        )  # fmt: skip
    fitted = coordinates.to_values(solution.x)
    values.update(zip(free, fitted, strict=True))
    return _result(model, data, frfs, values, free, coordinates, solution, (lower, upper),
                   residual(solution.x), noise, known, weights, ctx, measured)


def _start_values(model: Model, data: FrfData, frfs: tuple[str, ...],
                  fixed: Mapping[str, float], start: Mapping[str, float] | None,
                  free: tuple[str, ...]) -> dict[str, float]:
    """Every parameter's start: a complete ``start`` as given (clipped to the bounds), else
    the linear start with what ``start`` gives over it."""
    if start and all(name in start for name in free):  # a complete start: no linear start
        values = {**model.defaults(), **fixed}
        values.update({name: model.by_name[name].clip(float(start[name])) for name in free})
        return values
    values = linear_start(model, data, frfs, fixed)
    if start:
        values.update({k: v for k, v in start.items() if k in values and k not in fixed})
    return values


#: Share of a uniform fit's squared error its outlier points may hold before they are said to
#: pull it off the other points.
OUTLIER_PULL = 0.1


def outlier_share(residual: NDArray[np.complex128], outliers: NDArray[np.bool_]) -> float:
    """The share of ``Σ|r|²`` the outlier points hold (0 without any)."""
    power = residual.real**2 + residual.imag**2
    total = float(np.sum(power))
    if not outliers.any() or not total > 0:
        return 0.0
    return float(np.sum(power[outliers])) / total


def outlier_heavy(result: FitResult) -> bool:
    """A fit weighing every point alike whose noise model's outlier points hold more than
    :data:`OUTLIER_PULL` of what it minimises: they pull its values off the other points."""
    frfs, noise = result.frfs, result.noise
    if noise is None:
        return False
    return outlier_share(np.concatenate([result.residuals[name] for name in frfs]),
                         np.concatenate([noise.outliers(name) for name in frfs])
                         ) > OUTLIER_PULL


def _outlier_pull(residual: NDArray[np.complex128], outliers: NDArray[np.bool_]) -> list[str]:
    """A warning where the noise model's outlier points hold more than :data:`OUTLIER_PULL` of
    what a fit weighing every point alike minimises: they pull its values off the others."""
    share = outlier_share(residual, outliers)
    if share <= OUTLIER_PULL:
        return []
    count = int(np.count_nonzero(outliers))
    return [f"{count} outlier point{'s' if count > 1 else ''} (far outside the noise) hold "
            f"{share:.0%} of the error this fit minimises, every point weighted the same: they "
            "pull its values off the other points; weighted by its noise (identify's default), "
            "each counts as its own error allows"]


def _result(model: Model, data: FrfData, frfs: tuple[str, ...], values: dict[str, float],
            free: tuple[str, ...], coordinates: _Coordinates, solution: OptimizeResult,
            bounds: tuple[NDArray[np.float64], NDArray[np.float64]], r: NDArray[np.float64],
            noise: NoiseModel, known: Known | None, weights: NDArray[np.float64] | None,
            ctx: Context, measured: list[NDArray[np.complex128]]) -> FitResult:
    """The :class:`FitResult` of a solved fit: error measures, uncertainty (with what was
    inherited), warnings, residuals."""
    fitted = coordinates.to_values(solution.x)
    lower, upper = bounds
    weighted = weights is not None
    n, k = r.size, len(free)
    rss = float(r @ r)
    half = r.size // 2
    complex_residual = r[:half] + 1j * r[half:]
    rms_error = float(np.sqrt(np.mean(np.abs(complex_residual) ** 2)))
    inherited = tuple(name for name in (known.names if known else ()) if name in model.by_name)
    inherited_jac = None
    if inherited:
        inherited_jac = si_jacobian(model, ctx, values, inherited, frfs, measured)
    if known is not None and inherited != tuple(known.names):
        keep = [known.names.index(name) for name in inherited]
        known = Known(known.values, inherited, known.covariance[np.ix_(keep, keep)],
                      known.source)
    uncertainty = fit_covariance(
        solution.jac, coordinates.derivative(fitted), free, noise, frfs, rms_error, r,
        inherited_jac, known, weights,
    )  # fmt: skip
    warnings = list(uncertainty.warnings)
    stderr = dict.fromkeys(model.names, 0.0)
    stderr.update(zip(uncertainty.names, np.sqrt(np.abs(np.diag(uncertainty.covariance))),
                      strict=True))
    for name, x, lo, hi in zip(free, solution.x, lower, upper, strict=True):
        if min(x - lo, hi - x) < 1e-6 * (hi - lo):
            warnings.append(f"{name} is at a bound; its standard error is not meaningful")
    if not weighted:
        warnings += _outlier_pull(complex_residual, np.concatenate(
            [noise.outliers(name) for name in frfs]))
    points = data.frequency_hz.size
    return FitResult(
        model=model,
        values={name: float(v) for name, v in values.items()},
        stderr=stderr,
        free=free,
        covariance=uncertainty.covariance[:k, :k],
        rms_error=rms_error,
        noise_floor=noise.floor_of(frfs),
        band_hz=(float(data.frequency_hz.min()), float(data.frequency_hz.max())),
        points=points,
        frfs=frfs,
        frequency_hz=data.frequency_hz,
        residuals={
            name: complex_residual[i * points : (i + 1) * points] for i, name in enumerate(frfs)
        },
        bic=float(n * np.log(max(rss, 1e-300) / n) + k * np.log(n)),
        nfev=int(solution.nfev),
        warnings=warnings,
        noise=noise,
        covariance_names=uncertainty.names,
        joint_covariance=uncertainty.covariance,
        noise_covariance=uncertainty.noise_covariance,
        misfit_scale=uncertainty.misfit_scale,
        fits_noise=uncertainty.fits_noise,
        influence=uncertainty.influence,
        inherited_from=known.source if known is not None and inherited else "",
        weighting="noise" if weighted else "uniform",
    )


def _least_squares(
    residual: Callable[[NDArray[np.float64]], NDArray[np.float64]],
    jacobian: Callable[..., NDArray[np.float64]] | None,
    x0: NDArray[np.float64],
    bounds: tuple[NDArray[np.float64], NDArray[np.float64]],
    tolerance: float,
    max_evaluations: int,
    bounded_fallback: bool = True,
    analytic: bool = True,
) -> OptimizeResult:
    """Minimise ``|residual|²`` from ``x0`` within ``bounds``.

    With an analytic Jacobian, Levenberg-Marquardt (MINPACK) goes first: in the fitted
    coordinates (logarithms of positive parameters) the bounds are far from any sensible
    solution, and MINPACK's own small QR avoids the threaded LAPACK calls on the tall Jacobian
    that make the trust-region method slow on a busy machine. If it leaves the bounds or ends
    worse than it began, the bounded trust-region method (``trf``) solves from ``x0``; without
    ``bounded_fallback`` the start is kept instead (the Maxwell order search, where an order
    that does not converge quickly is a degenerate one). A Jacobian of finite differences
    (``analytic`` false) goes to ``trf`` directly.
    """
    lower, upper = bounds
    options = {"x_scale": "jac", "ftol": tolerance, "xtol": tolerance, "gtol": tolerance}
    with np.errstate(all="ignore"):
        if jacobian is not None and analytic and x0.size <= residual(x0).size:
            start_cost = 0.5 * float(np.sum(residual(x0) ** 2))
            solution = least_squares(
                residual, x0, jac=jacobian, method="lm", max_nfev=max_evaluations, **options
            )
            x = solution.x
            if (
                np.all(np.isfinite(x))
                and np.all((lower < x) & (x < upper))
                and solution.cost <= start_cost
            ):
                return solution
            if not bounded_fallback:
                return OptimizeResult(x=x0, jac=jacobian(x0), nfev=solution.nfev, cost=start_cost)
        return least_squares(
            residual,
            x0,
            jac=jacobian if jacobian is not None else "2-point",
            bounds=(lower, upper),
            method="trf",
            max_nfev=max_evaluations,
            **options,
        )
