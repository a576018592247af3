"""Maximum-likelihood fits on the residual whitened by the noise model.

The fitter of ``identify`` (:func:`viscorig.fitting.fit`) minimises, over the stacked real and
imaginary parts ``r`` of ``H_model/H_measured − 1``, either ``Σ (r_i/s_i)²`` with ``s_i²`` the
noise model's variance of that component (``weighting="noise"``, ``identify``'s default: the
drift's correlation enters the ± but not the weights) or the plain ``Σ r_i²`` that
``rms_error`` measures (``weighting="uniform"``, ``identify --weights uniform``, the paper's
estimate; the fits diagnosis reports for a model, :func:`viscorig.diagnosis.findings.refit`,
are these). Neither maximises the likelihood diagnosis compares models by. Comparing models by a
likelihood is only calibrated when each model maximises that likelihood: fitted otherwise, one
more parameter can move the curve at the quiet points by more than noise allows and fake an
improvement. So every model diagnosis compares is fitted here, on the residual whitened by the
whole noise model, drift correlation included (:meth:`DiagnosisData.whiten`), with a Huber
loss (quadratic within :data:`HUBER_SCALE` standard deviations, linear beyond) so that an
outlier point, which heavy-tailed noise makes, neither drives a fit nor fakes a finding, and
with the table's parameters as nuisance parameters (below) where ``identify`` holds them fixed
and propagates their error into the ± (:mod:`viscorig.fitting.uncertainty`).

The statistic is ``χ² = Σ ρ(e_i)`` over the whitened residual ``e`` (``ρ(e) = e²`` inside the
Huber scale): a chi-square with as many degrees of freedom as real residuals, less the
parameters, when the model is right. ``rms_error`` stays the design's measure.

The table's ``M_s, K_s, C_s`` come from another run (the bare-table fit) with an error of their
own. Held as exact, that error is a systematic misfit every test sees: above the system's
resonance ``ẍ_s/F_e ≈ −1/(M_s + M_v)``, so a 0.1 % error of ``M_s`` reads as a 0.1 % gain of the
table accelerometer. When the data carry the covariance the values were found with
(:attr:`DiagnosisData.table_prior`), they are *nuisance parameters*: fitted in every model, with
the prior ``χ²_prior = |W (p − p₀)|²`` (``WᵀW = Σ⁻¹``) added to the statistic, and its rows
``W (p − p₀)`` appended to the residual (:attr:`Likelihood.prior`) and to the Jacobian. Every
``Δχ²`` is then a profile likelihood ratio with the table's error allowed for, and a linear
estimate of an effect (:class:`~viscorig.diagnosis.scan.Residual`) has the table's directions
projected out as far as their prior lets them move. The prior is weighed by the misfit ``φ``
of the model a step diagnoses (:meth:`DiagnosisData.with_prior_scale`, quasi-likelihood): a
model far from the noise cannot drag the table to soak up its misfit.
"""

from __future__ import annotations

from collections.abc import Collection, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray
from scipy.optimize import least_squares

from viscorig.diagnosis.data import DiagnosisData
from viscorig.errors import InputError
from viscorig.fitting import FitResult, linear_start
from viscorig.fitting.jacobian import predict_many
from viscorig.models import Context, Model

#: Whitened residuals beyond this many standard deviations count linearly (Huber loss).
HUBER_SCALE = 3.0
#: A likelihood fit stops when a step lowers its cost by less than this share of it (unless
#: told otherwise: :func:`ml_fit`'s ``tolerance``).
TOLERANCE = 1e-6
#: Relative step of the forward differences of the Jacobian (√ of the double precision).
_STEP = 1.49e-8


def huber(e: NDArray[np.float64]) -> NDArray[np.float64]:
    """``ρ(e)``: ``e²`` within :data:`HUBER_SCALE`, ``2c|e| − c²`` beyond."""
    a = np.abs(e)
    c = HUBER_SCALE
    return np.where(a <= c, e * e, 2 * c * a - c * c)


def winsorized(e: NDArray[np.float64]) -> NDArray[np.float64]:
    """``e`` clipped at ±:data:`HUBER_SCALE` (the Huber loss's ``ψ``): what a linear test sees."""
    return np.clip(e, -HUBER_SCALE, HUBER_SCALE)


@dataclass
class Likelihood:
    """A model fitted by maximum likelihood to the whitened residual.

    Attributes
    ----------
    model
        The fitted (concrete) model.
    values
        Every parameter's value by global name (the table's held fixed).
    free
        Names of the model's free parameters (every one but the table's values held exact;
        the table's nuisance parameters included).
    chi2
        ``Σ ρ(e_i)`` at the optimum, plus the nuisance parameters' prior ``|prior|²``.
    whitened
        The whitened residual ``e`` at the optimum (the data's part).
    jacobian
        ``∂(e, prior)/∂x`` at the optimum, ``x`` the fitted coordinates (logarithms of positive
        parameters, the values of the others), one column per name of ``fitted``; the rows of
        :attr:`prior` follow the data's.
    residuals
        ``H_model/H_measured − 1`` per FRF.
    """

    model: Model
    values: dict[str, float]
    free: tuple[str, ...]
    chi2: float
    whitened: NDArray[np.float64] = field(repr=False)
    jacobian: NDArray[np.float64] = field(repr=False)
    residuals: dict[str, NDArray[np.complex128]] = field(repr=False)
    fitted: tuple[str, ...] = ()
    """Names of the parameters the fit moved (``free`` unless it held some at their start)."""
    prior: NDArray[np.float64] = field(default_factory=lambda: np.zeros(0), repr=False)
    """The nuisance parameters' prior residual ``W (p − p₀)`` (empty without a prior)."""

    def __post_init__(self) -> None:
        if not self.fitted:
            self.fitted = self.free

    @property
    def augmented(self) -> NDArray[np.float64]:
        """The whitened residual with the prior's rows after it (the Jacobian's rows)."""
        return np.concatenate([self.whitened, self.prior])

    @property
    def spec(self) -> str:
        """Canonical spec of the fitted model."""
        return self.model.spec

    @property
    def rms_error(self) -> float:
        """The design's error measure at these values."""
        return float(np.sqrt(np.mean(np.concatenate(
            [np.abs(r) ** 2 for r in self.residuals.values()]))))

    def stderr(self) -> dict[str, float]:
        """Standard error of every fitted parameter (SI), from the whitened Jacobian."""
        if not self.fitted:
            return {}
        jac = self.jacobian
        try:
            inverse = np.linalg.pinv(jac.T @ jac)
        except np.linalg.LinAlgError:
            return dict.fromkeys(self.fitted, float("nan"))
        spread = np.sqrt(np.abs(np.diag(inverse)))
        out = {}
        for name, s in zip(self.fitted, spread, strict=True):
            value = self.values[name]
            out[name] = float(s * abs(value)) if self.model.by_name[name].log else float(s)
        return out


#: Damping ratios of a local mode a diagnosis fits: from the one whose half-power band spans a
#: frequency step (narrower, it would fit a single noisy point) to the broadest the scan tries
#: (broader, it is a smooth trend, not a local mode).
MODE_DAMPING_MAX = 0.1


def resolvable_bounds(
    model: Model, data: DiagnosisData, values: Mapping[str, float]
) -> dict[str, tuple[float, float]]:
    """Bounds of the local modes' damping ratios that these data resolve (see
    :data:`MODE_DAMPING_MAX`)."""
    steps = np.diff(np.unique(data.data.frequency_hz))
    step = float(np.median(steps)) if steps.size else 0.0
    bounds = {}
    for term in model.effects:
        if term.keyword != "fixture":
            continue
        names = model.local_names(term)
        f_n = float(values.get(names["f_n"], term.argument or 100.0))
        bounds[names["zeta"]] = (max(1e-4, step / (2 * f_n)), MODE_DAMPING_MAX)
    return bounds


def _coordinates(
    model: Model,
    free: tuple[str, ...],
    bounds: Mapping[str, tuple[float, float]] | None = None,
):
    parameters = [model.by_name[name] for name in free]
    log = np.array([p.log for p in parameters], dtype=bool)
    limits = [(max(p.lower, (bounds or {}).get(p.name, (p.lower, p.upper))[0]),
               min(p.upper, (bounds or {}).get(p.name, (p.lower, p.upper))[1]))
              for p in parameters]
    lower = np.array([np.log(lo) if p.log else lo for p, (lo, _) in zip(parameters, limits,
                                                                          strict=True)])
    upper = np.array([np.log(hi) if p.log else hi for p, (_, hi) in zip(parameters, limits,
                                                                          strict=True)])
    return log, lower, np.maximum(upper, lower + 1e-12)


def ratio_derivatives(
    model: Model,
    ctx: Context,
    values: Mapping[str, float],
    free: Sequence[str],
    log: NDArray[np.bool_],
    inverse: Mapping[str, NDArray[np.complex128]],
    predicted: Mapping[str, NDArray[np.complex128]] | None = None,
) -> dict[str, NDArray[np.complex128]] | None:
    """``∂(H/H_measured)/∂x`` per FRF of ``inverse`` (``1/H_measured``; points × ``free``),
    ``x`` the fitted coordinates (``log p`` where ``log``), from the model's analytic
    derivatives (:meth:`~viscorig.models.Model.derivatives`; ``predicted``: the model's
    prediction at ``values``, when at hand); ``None`` where it has none."""
    derivatives = model.derivatives(ctx, values, free, predicted)
    if derivatives is None:
        return None
    by_x = np.array([values[name] if is_log else 1.0
                     for name, is_log in zip(free, log, strict=True)])
    with np.errstate(all="ignore"):
        return {frf: derivatives[frf] * (h[:, None] * by_x) for frf, h in inverse.items()}


class _Objective:
    """The robust whitened residual of a model's fit and its Jacobian, as the solver asks for
    them, over the fitted coordinates ``x`` (logarithms of positive parameters)."""

    def __init__(self, model: Model, data: DiagnosisData, values: dict[str, float],
                 free: tuple[str, ...], log: NDArray[np.bool_], upper: NDArray[np.float64]
                 ) -> None:
        self.model, self.data, self.values, self.free = model, data, values, free
        self.log, self.upper = log, upper
        self.ctx = data.data.context()
        with np.errstate(all="ignore"):  # (a product is a fraction of a division's time)
            self.inverse = {name: 1.0 / data.data.frf(name) for name in data.frfs}
        self.nuisance = data.nuisance
        self.prior_at = [free.index(name) for name in self.nuisance]
        # With a prior, the Huber loss is applied here to the data's rows only (r = sign(e)·√ρ(e),
        # a plain least-squares fit of r minimises Σρ(e) + |prior|²): the prior is a Gaussian,
        # never down-weighted as an outlier would be. Without one, the solver's own Huber loss.
        self.robust_here = bool(self.nuisance)
        # The last point evaluated: its x, residual ratio and whitened residual (the solver asks
        # for the Jacobian where it just evaluated the residual).
        self.last: dict[str, Any] = {}

    def to_values(self, x: NDArray[np.float64]) -> NDArray[np.float64]:
        return np.where(self.log, np.exp(np.clip(x, -700, 700)), x)

    def current(self, x: NDArray[np.float64]) -> dict[str, float]:
        current = dict(self.values)
        current.update(zip(self.free, self.to_values(x), strict=True))
        return current

    def ratio(self, x: NDArray[np.float64]) -> dict[str, NDArray[np.complex128]]:
        """``H_model/H_measured − 1`` per FRF at ``x``."""
        with np.errstate(all="ignore"):
            return self._ratio(self.model.predict(self.ctx, self.current(x)))

    def _ratio(self, predicted: dict[str, NDArray[np.complex128]]
               ) -> dict[str, NDArray[np.complex128]]:
        return {name: predicted[name] * self.inverse[name] - 1.0 for name in self.data.frfs}

    def _cached_ratio(self, x: NDArray[np.float64]) -> dict[str, NDArray[np.complex128]]:
        last = self.last
        if "x" not in last or not np.array_equal(last["x"], x):
            last.clear()
            with np.errstate(all="ignore"):
                predicted = self.model.predict(self.ctx, self.current(x))
                last.update(x=x.copy(), predicted=predicted, ratio=self._ratio(predicted))
        return last["ratio"]

    def _cached_whitened(self, x: NDArray[np.float64]) -> NDArray[np.float64]:
        base = self._cached_ratio(x)
        if "whitened" not in self.last:
            self.last["whitened"] = self.data.whiten(base)
        return self.last["whitened"]

    def residual(self, x: NDArray[np.float64]) -> NDArray[np.float64]:
        e = self._cached_whitened(x)
        if self.robust_here:
            e = np.sign(e) * np.sqrt(huber(e))
        e = np.concatenate([e, self.data.prior_residual(self.current(x))])
        return np.where(np.isfinite(e), e, 1e6)

    def jacobian(self, x: NDArray[np.float64]) -> NDArray[np.float64]:
        # The raw residual's derivatives, whitened once for all columns.
        base = self._cached_ratio(x)
        columns = ratio_derivatives(self.model, self.ctx, self.current(x), self.free, self.log,
                                    self.inverse, self.last["predicted"])
        if columns is None:  # forward differences, every column in one evaluation
            steps = _STEP * np.maximum(1.0, np.abs(x))
            steps = np.where(x + steps > self.upper, -steps, steps)
            moved = x[None, :] + np.diag(steps)
            shifted = predict_many(self.model, self.ctx, self.values, self.free,
                                   self.to_values(moved))
            columns = {}
            with np.errstate(all="ignore"):
                for frf in base:
                    change = shifted[frf] * self.inverse[frf]
                    change -= 1.0 + base[frf]
                    change /= steps[:, None]
                    columns[frf] = change.T
        matrix = self.data.whiten(columns)
        if self.robust_here:  # d(sign(e)√ρ(e))/de: 1 within the Huber scale, c/√ρ(e) beyond
            e = np.abs(self._cached_whitened(x))
            slope = np.where(e <= HUBER_SCALE, 1.0,
                             HUBER_SCALE / np.sqrt(np.maximum(huber(e), 1e-300)))
            matrix *= slope[:, None]
        if self.nuisance:
            rows = np.zeros((len(self.nuisance), x.size))
            rows[:, self.prior_at] = self.data.prior_jacobian(self.current(x),
                                                              self.log[self.prior_at])
            matrix = np.vstack([matrix, rows])
        if not np.isfinite(matrix).all():
            matrix[~np.isfinite(matrix)] = 0.0
        return matrix


def ml_fit(
    model: Model,
    data: DiagnosisData,
    start: Mapping[str, float],
    *,
    only: Collection[str] | None = None,
    max_steps: int = 200,
    tolerance: float = TOLERANCE,
) -> Likelihood:
    """Fit ``model``'s free parameters (every one but the table's, or those of them in
    ``only``, the others held at their start) from ``start`` to minimise ``Σ ρ(e_i)``, ``e`` the
    whitened residual; ``start`` holds a value for every parameter. Local modes keep a damping
    ratio the data resolve (:func:`resolvable_bounds`).

    ``tolerance``: the fit stops when a step lowers the cost by less than this share of it."""
    fixed = data.exact_table
    every = tuple(name for name in model.names if name not in fixed)
    free = every if only is None else tuple(
        name for name in every if name in only or name in data.nuisance)
    values = _resolved_start(model, data,
                             {**model.defaults(), **(data.table or {}), **dict(start), **fixed},
                             free)
    log, lower, upper = _coordinates(model, free, resolvable_bounds(model, data, values))
    objective = _Objective(model, data, values, free, log, upper)
    start_values = np.array([values[name] for name in free], dtype=float)
    x0 = np.where(log, np.log(np.abs(start_values) + 1e-300), start_values)
    span = upper - lower
    x0 = np.clip(x0, lower + 1e-9 * span, upper - 1e-9 * span)
    if free:
        with np.errstate(all="ignore"):
            solution = least_squares(
                objective.residual, x0, jac=objective.jacobian, bounds=(lower, upper),
                x_scale="jac", method="trf",
                loss="linear" if objective.robust_here else "huber", f_scale=HUBER_SCALE,
                ftol=tolerance, xtol=1e-8, gtol=1e-8, max_nfev=max_steps,
            )
        x = solution.x
        jacobian = np.asarray(solution.jac, dtype=float)
    else:
        x = x0
        jacobian = np.zeros((objective.residual(x0).size, 0))
    fitted = dict(values)
    fitted.update(zip(free, (float(v) for v in objective.to_values(x)), strict=True))
    residuals = objective.ratio(x)
    whitened = data.whiten(residuals)
    prior = data.prior_residual(fitted)
    return Likelihood(
        model, fitted, every, float(np.sum(huber(whitened)) + prior @ prior), whitened,
        jacobian, residuals, free, prior,
    )


def _resolved_start(model: Model, data: DiagnosisData, values: dict[str, float],
                    free: tuple[str, ...]) -> dict[str, float]:
    """``values`` with the K* and disc mass started from the data (``identify``'s linear start,
    :func:`~viscorig.fitting.linear_start`, every other value held) where the fit frees all of
    them and the band does not resolve the K* given
    (:meth:`~viscorig.models.ModulusTerm.resolved`). Carried from a model that lacked a term, a
    fractional K* can sit decades past the band, where following its valley back took a hundred
    solver steps; from the data's start, a third to a quarter of that, to the same optimum."""
    term = model.modulus_term
    if term is None or not term.has_disc:
        return values
    restarted = {*model.local_names(term).values(), "M_v"}
    if not restarted <= set(free):
        return values
    omega = 2 * np.pi * data.data.frequency_hz
    if term.resolved(omega, model.local_values(term, values)):
        return values
    held = {name: value for name, value in values.items() if name not in restarted}
    try:
        return linear_start(model, data.data, data.frfs, held)
    except (InputError, ValueError, np.linalg.LinAlgError):
        return values


def ml_refit(result: FitResult | Likelihood, data: DiagnosisData) -> Likelihood:
    """The maximum-likelihood fit of a fitted model, started from its values."""
    return ml_fit(result.model, data, result.values)


def evaluate(model: Model, data: DiagnosisData, values: Mapping[str, float]) -> Likelihood:
    """The likelihood of ``model`` at ``values`` (no fit), with a finite-difference Jacobian
    weighted as the Huber loss weighs each residual."""
    fixed = data.exact_table
    free = tuple(name for name in model.names if name not in fixed)
    values = {**(data.table or {}), **dict(values), **fixed}
    ctx = data.data.context()
    measured = {name: data.data.frf(name) for name in data.frfs}
    log, _, _ = _coordinates(model, free)

    def ratio(current: Mapping[str, float]) -> dict[str, NDArray[np.complex128]]:
        with np.errstate(all="ignore"):
            predicted = model.predict(ctx, current)
            return {name: predicted[name] / measured[name] - 1.0 for name in data.frfs}

    residuals = ratio(values)
    whitened = data.whiten(residuals)
    with np.errstate(all="ignore"):
        inverse = {frf: 1.0 / measured[frf] for frf in data.frfs}
    columns = ratio_derivatives(model, ctx, values, free, log, inverse) if free else None
    if free and columns is None:
        current = np.array([values[name] for name in free], dtype=float)
        steps = np.array([1e-6 if is_log else
                          1e-6 * max(abs(value), model.by_name[name].upper * 1e-6)
                          for name, is_log, value in zip(free, log, current, strict=True)])
        moved = np.where(log, current * np.exp(steps), current + steps)
        rows = np.where(np.eye(len(free), dtype=bool), moved[None, :], current[None, :])
        shifted = predict_many(model, ctx, values, free, rows)
        with np.errstate(all="ignore"):
            columns = {frf: ((shifted[frf] / measured[frf] - 1.0) - residuals[frf]).T / steps
                       for frf in data.frfs}
    jacobian = data.whiten(columns) if columns is not None else np.zeros((whitened.size, 0))
    jacobian = np.where(np.isfinite(jacobian), jacobian, 0.0)
    weight = np.sqrt(np.minimum(1.0, HUBER_SCALE / np.maximum(np.abs(whitened), 1e-300)))
    prior = data.prior_residual(values)
    rows = np.zeros((prior.size, len(free)))
    if prior.size:
        at = [free.index(name) for name in data.nuisance]
        rows[:, at] = data.prior_jacobian(values, log[at])
    return Likelihood(model, dict(values), free, float(np.sum(huber(whitened)) + prior @ prior),
                      whitened, np.vstack([jacobian * weight[:, None], rows]), residuals,
                      prior=prior)

