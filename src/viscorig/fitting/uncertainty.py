"""Standard errors of a fit: the noise model's sandwich, the misfit, and what is inherited.

Three sources enter the covariance of the fitted parameters ``p``.

Noise. ``r`` is the stacked real and imaginary parts of ``H_model/H_measured − 1``, ``J =
∂r/∂p``, and ``Σ`` the noise covariance of ``r`` (:class:`~viscorig.fitting.noise.NoiseModel`:
white along the band, plus a drift correlated in test time). An estimate minimising ``‖V r‖²``
(``V`` diagonal) has, near the solution, ``δp = −A⁻¹ Jᵀ V² ε`` with ``A = Jᵀ V² J``, so
``cov p = A⁻¹ Jᵀ V² Σ V² J A⁻¹`` (the sandwich), whatever the weights.

- The project's estimate (``weighting="noise"``) weights each real component by the inverse of
  its noise standard deviation, ``V = diag(Σ)^{-1/2}``: points that differ in noise by orders
  of magnitude (a plan's long and short integrations, the force dip at a resonance) count for
  what each is worth. Under white noise this is generalised least squares, the
  maximum-likelihood estimate, and the sandwich is ``(J_wᵀ J_w)⁻¹``: the inverse of the Fisher
  information the points hold. A drift correlated along the sweep enters the covariance
  through the sandwich but not the weights: the estimate then stays exactly as good as the
  weights, and its ± honest, however well or badly the drift's correlation was estimated
  (weighting by an estimated correlation structure would let an error in it bias the ±).
- The paper's estimate (``weighting="uniform"``, ``V = 1``) minimises the design's error
  measure ``‖r‖²``, every point weighing the same. It is kept to reproduce the paper's Table
  1 (the simulated rigs were calibrated so that it does); on the paper's own sweep its
  standard errors are several times those of the noise-weighted estimate.

Both count correlated points for what they are worth instead of as independent.

Misfit. What the model leaves beyond the noise is model error, which no noise model describes. Two
guards, the larger standard error of the two wins (the noise model's correlation structure is
kept): the noise covariance multiplied by the misfit ratio (never by less than 1), which spreads a
misfit over the band as if it were noise: ``‖V r‖²/ν`` for the noise-weighted estimate (where it
exceeds 1 by more than three of its standard deviations, ``3√(2/ν)``: below that it is the scatter
of the noise itself), the Birge ratio ``(rms_error / noise_floor)²`` for the uniform one; and, for
the uniform estimate always and for the noise-weighted one when its misfit is significant, the
residuals' own sandwich (White's misspecification-robust covariance, with the Newey-West Bartlett
weights over :data:`HAC_LAGS` neighbouring points so that a misfit spanning several points counts
as one, on the weighted residual), which puts a local misfit (a start transient, a sharp unmodelled
feature) on the parameters it moves. With a model at the noise floor both stay close to the noise
covariance. A result whose ``rms_error`` exceeds :data:`MISFIT_RATIO` times the floor (the
threshold diagnosis also uses for "at the noise floor") says that the model does not fit to the
noise: its ± are those of the model's band-average, not a measurement uncertainty of the specimen.

Inherited parameters (GUM, first order). A specimen fit holds the table's ``q = (M_s, K_s,
C_s)`` at values identified elsewhere (the bare-table run, or a station's or ``/rig``'s values
with a user-given uncertainty). The fitted ``p̂(q)`` follows them with the sensitivity ``G = ∂p̂/∂q
= −A⁻¹ Jᵀ J_q`` (the implicit-function theorem on ``Jᵀ r = 0``, Gauss-Newton term; ``A⁻¹ Jᵀ V²
J_q`` for a weighted estimate), so ``cov p += G C_q Gᵀ`` and ``cov(p, q) = G C_q``. The table run's
noise is independent of the specimen run's, so the two add. A joint fit of both runs would give the
same to first order and cost a refit of the table with every specimen; propagation reuses the
table's covariance as it is stored.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

from viscorig.fitting.noise import NoiseModel
from viscorig.models import Context, Model

#: ``rms_error`` above this multiple of the noise floor: the model does not fit to the noise.
MISFIT_RATIO = 1.25
#: Correlation above which a warning names the pair of parameters.
CORRELATION_WARNING = 0.95
#: Neighbouring points whose residual products enter the residuals' own sandwich.
HAC_LAGS = 5


@dataclass(frozen=True)
class Known:
    """Parameter values taken from elsewhere, held fixed in a fit, with their uncertainty.

    Attributes
    ----------
    values
        ``{name: value}`` (SI).
    names
        The parameters whose covariance is known, in the order of ``covariance``.
    covariance
        Their covariance (SI units); an empty matrix when all are exact.
    source
        Where they come from (``"run 'table'"``, ``"/rig"``, ``"station"``).
    """

    values: dict[str, float]
    names: tuple[str, ...] = ()
    covariance: NDArray[np.float64] = field(default_factory=lambda: np.zeros((0, 0)))
    source: str = ""

    @classmethod
    def exact(cls, values: Mapping[str, float], source: str = "") -> Known:
        """Values without uncertainty."""
        return cls(dict(values), (), np.zeros((0, 0)), source)

    @classmethod
    def from_fit(cls, result, names: Sequence[str], source: str = "") -> Known:
        """Some of a fit's values, with their joint covariance (fitted or themselves
        inherited), as another fit inherits them (the table's from the bare-table run)."""
        names = tuple(names)
        known = [name for name in names if name in result.covariance_names]
        index = [result.covariance_names.index(name) for name in known]
        covariance = np.asarray(result.joint_covariance)[np.ix_(index, index)]
        return cls({name: float(result.values[name]) for name in names}, tuple(known),
                   covariance, source)

    @classmethod
    def with_stderr(
        cls, values: Mapping[str, float], stderr: Mapping[str, float], source: str = ""
    ) -> Known:
        """Values with independent standard uncertainties (a user's or a station's)."""
        names = tuple(name for name in values if stderr.get(name, 0.0) > 0.0)
        covariance = np.diag([float(stderr[name]) ** 2 for name in names])
        return cls(dict(values), names, covariance.reshape(len(names), len(names)), source)

    def stderr(self, name: str) -> float | None:
        """Standard uncertainty of one value, ``None`` when it is exact."""
        if name not in self.names:
            return None
        i = self.names.index(name)
        return float(np.sqrt(self.covariance[i, i]))


def si_jacobian(
    model: Model,
    ctx: Context,
    values: Mapping[str, float],
    names: Sequence[str],
    frfs: Sequence[str],
    measured: Sequence[NDArray[np.complex128]],
) -> NDArray[np.float64]:
    """``∂r/∂p`` in SI units for the parameters ``names``, stacked real then imaginary.

    Analytic where the model gives derivatives (:meth:`~viscorig.models.Model.derivatives`),
    else central differences with a relative step of 1e-6.
    """
    names = tuple(names)
    if not names:
        return np.zeros((2 * sum(h.size for h in measured), 0))
    derivatives = model.derivatives(ctx, values, names)
    if derivatives is not None:
        jac = np.concatenate([derivatives[n] / h[:, None]
                              for n, h in zip(frfs, measured, strict=True)])
        return np.concatenate([jac.real, jac.imag])
    columns = []
    for name in names:
        value = float(values[name])
        step = 1e-6 * max(abs(value), 1e-12)
        shifted = []
        for sign in (1.0, -1.0):
            trial = dict(values)
            trial[name] = value + sign * step
            out = model.predict(ctx, trial)
            shifted.append(np.concatenate([out[n] / h for n, h in zip(frfs, measured,
                                                                       strict=True)]))
        column = (shifted[0] - shifted[1]) / (2 * step)
        columns.append(np.concatenate([column.real, column.imag]))
    return np.stack(columns, axis=1)


@dataclass
class Uncertainty:
    """The covariance of a fit and what went into it.

    Attributes
    ----------
    names
        Parameters of ``covariance``: the fitted ones, then the inherited ones with an
        uncertainty.
    covariance
        Their joint covariance (SI units).
    noise_covariance
        Of the fitted parameters, from the noise alone (before the misfit scale).
    misfit_scale
        Factor applied to the noise part for the misfit (1 when the model fits to the noise).
    fits_noise
        ``rms_error ≤ MISFIT_RATIO · noise_floor``.
    warnings
        Rank deficiency, strongly correlated pairs.
    influence
        ``∂p/∂ε`` of the fitted parameters (SI) with respect to the stacked residual
        (``fitted parameters × 2N``, first order: ``δp = −influence @ ε``), from which the
        covariance of two fits whose residuals share a misfit is built
        (:mod:`viscorig.compare`).
    """

    names: tuple[str, ...]
    covariance: NDArray[np.float64]
    noise_covariance: NDArray[np.float64]
    misfit_scale: float
    fits_noise: bool
    warnings: list[str]
    influence: NDArray[np.float64] | None = None


def _inverse(jac: NDArray[np.float64]) -> tuple[NDArray[np.float64], bool]:
    """``(JᵀJ)⁻¹`` from the Gram matrix of unit-norm columns (a small eigen decomposition; an
    SVD of the tall ``J`` would call threaded LAPACK, slow on a busy machine). Directions below
    1e-7 of the largest singular value count as not identified (second value False)."""
    if not np.all(np.isfinite(jac)):
        return np.full((jac.shape[1], jac.shape[1]), np.nan), False
    norms = np.sqrt(np.einsum("ij,ij->j", jac, jac))
    norms[norms == 0] = 1.0
    scaled = jac / norms
    eigenvalues, vectors = np.linalg.eigh(scaled.T @ scaled)
    keep = eigenvalues > eigenvalues.max() * 1e-14
    inverse = ((vectors[:, keep] / eigenvalues[keep]) @ vectors[:, keep].T) / np.outer(norms, norms)
    return inverse, bool(np.all(keep))


def bartlett_meat(g: NDArray[np.float64], blocks: Sequence[int]) -> NDArray[np.float64]:
    """``Σ_l w_l Σ_i g_i g_{i+l}ᵀ`` over the rows ``g_i``, Bartlett weights ``w_l = 1 −
    l/(L+1)`` over ``|l| ≤ L`` (:data:`HAC_LAGS`), never across the boundary of two blocks
    (sizes ``blocks``, in the stacked order: parts and FRFs). Positive semi-definite."""
    meat = g.T @ g
    block_of = np.repeat(np.arange(len(blocks)), blocks)
    for lag in range(1, HAC_LAGS + 1):
        same = block_of[lag:] == block_of[:-lag]
        cross = (g[lag:] * same[:, None]).T @ g[:-lag]
        meat += (1.0 - lag / (HAC_LAGS + 1)) * (cross + cross.T)
    return meat


def residual_meat(
    jac: NDArray[np.float64], residual: NDArray[np.float64], blocks: Sequence[int]
) -> NDArray[np.float64]:
    """:func:`bartlett_meat` of ``g_i = J_i r_i``, with the small-sample factor ``n/(n−k)``."""
    n, k = jac.shape
    return bartlett_meat(jac * residual[:, None], blocks) * (n / max(n - k, 1))


def fit_covariance(
    jac: NDArray[np.float64],
    scale: NDArray[np.float64],
    free: tuple[str, ...],
    noise: NoiseModel,
    frfs: Sequence[str],
    rms_error: float,
    residual: NDArray[np.float64],
    inherited_jac: NDArray[np.float64] | None = None,
    known: Known | None = None,
    weights: NDArray[np.float64] | None = None,
) -> Uncertainty:
    """The covariance of a least-squares fit (see the module text).

    Parameters
    ----------
    jac
        ``∂r/∂x`` at the solution, stacked real (points × fitted unknowns ``x``).
    scale
        ``∂p/∂x`` of each fitted parameter (the fitter's coordinates to SI).
    free
        Names of the fitted parameters.
    noise
        The noise model of the data fitted.
    frfs
        FRFs fitted, in the order of the stacked residual.
    rms_error
        The fit's error measure.
    residual
        The stacked real residual at the solution.
    inherited_jac
        ``∂r/∂q`` in SI for the inherited parameters ``known.names``.
    known
        The inherited values and their covariance.
    weights
        ``diag V`` of a weighted fit (``‖V r‖²`` minimised), in the stacked layout; ``None``
        for the uniform fit.
    """
    warnings: list[str] = []
    k = len(free)
    floor = noise.floor_of(frfs)
    fits_noise = bool(rms_error <= MISFIT_RATIO * floor)
    if weights is not None:
        jac = jac * weights[:, None]
        residual = residual * weights
        if inherited_jac is not None:
            inherited_jac = inherited_jac * weights[:, None]
        dof = max(residual.size - k, 1)
        ratio2 = float(residual @ residual) / dof
        significant = ratio2 > 1.0 + 3.0 * math.sqrt(2.0 / dof)
        ratio2 = ratio2 if significant else 1.0
    else:
        significant = True
        ratio2 = (rms_error / floor) ** 2 if floor > 0 else np.inf
    misfit_scale = float(max(1.0, ratio2)) if np.isfinite(ratio2) else 1.0
    inherited = tuple(known.names) if known is not None else ()
    names = free + inherited
    if k == 0:
        cov_q = known.covariance if known is not None else np.zeros((0, 0))
        return Uncertainty(names, cov_q, np.zeros((0, 0)), misfit_scale, fits_noise, warnings)
    inverse, full_rank = _inverse(jac)
    if not full_rank:
        warnings.append("the parameters are not all identifiable from these data (rank deficient)")
    if weights is not None:
        meat = jac.T @ (weights[:, None] * noise.apply_covariance(weights[:, None] * jac, frfs))
    else:
        meat = jac.T @ noise.apply_covariance(jac, frfs)
    noise_cov = (inverse @ meat @ inverse) * np.outer(scale, scale)
    blocks = [block.size for _ in range(2) for frf in frfs for block in noise.blocks[frf]]
    influence = (inverse @ jac.T) * scale[:, None]  # of the (weighted) residual
    if weights is not None:
        influence = influence * weights[None, :]  # of the residual itself
    noise_sigma = np.sqrt(np.abs(np.diag(noise_cov)))
    sigma = noise_sigma * np.sqrt(misfit_scale)
    if significant:
        robust = inverse @ residual_meat(jac, residual, blocks) @ inverse * np.outer(scale, scale)
        sigma = np.maximum(sigma, np.sqrt(np.abs(np.diag(robust))))
    with np.errstate(invalid="ignore", divide="ignore"):
        stretch = np.where(noise_sigma > 0, sigma / noise_sigma, 1.0)
    covariance = np.zeros((len(names), len(names)))
    covariance[:k, :k] = noise_cov * np.outer(stretch, stretch)
    if inherited and inherited_jac is not None and known is not None:
        sensitivity = -(inverse @ (jac.T @ inherited_jac)) * scale[:, None]  # ∂p/∂q, SI
        c_q = known.covariance
        covariance[:k, :k] += sensitivity @ c_q @ sensitivity.T
        covariance[:k, k:] = sensitivity @ c_q
        covariance[k:, :k] = covariance[:k, k:].T
        covariance[k:, k:] = c_q
    sigma = np.sqrt(np.abs(np.diag(covariance)))
    with np.errstate(invalid="ignore", divide="ignore"):
        rho = covariance / np.outer(sigma, sigma)
    for i in range(k):
        for j in range(i + 1, k):
            if abs(rho[i, j]) > CORRELATION_WARNING:
                warnings.append(
                    f"{names[i]} and {names[j]} are strongly correlated (ρ = {rho[i, j]:+.3f})"
                )
    return Uncertainty(names, covariance, noise_cov, misfit_scale, fits_noise, warnings,
                       influence)
