"""The noise-weighted (maximum-likelihood) fit a plan needs.

The identification core minimises the design's error measure, the plain mean of
``|H_model/H_measured − 1|²``, in which every point weighs the same, and gives the honest
covariance of that estimate under the noise model. A plan spends its time unevenly on purpose
(long integrations where the targets are learnt, short looks elsewhere), so its points differ in
noise by orders of magnitude, and an unweighted estimate lets the noisiest points set the
parameters: on the paper's own sweep it uses about a twentieth of the information the points
hold, and on a plan far less. The estimate a plan is judged by is the generalised least-squares
one under the core's noise model (:class:`viscorig.fitting.NoiseModel`), ``min ‖L⁻¹ r‖²`` with
``LLᵀ = Σ`` (the residual *whitened* by the noise, drift included), which reaches the Fisher
information of the points (the efficiency the design counts on).

:func:`weighted_fit` starts from the core's own fit (:func:`viscorig.fitting.fit`, same model,
start, bounds and noise model), refines it on the whitened residual, and gives that estimate's
covariance under the same noise, ``(J_wᵀ J_w)⁻¹`` with ``J_w`` the whitened Jacobian, scaled up
by the misfit when the model leaves more than the noise can explain (``χ²/ν`` more than three of
its standard deviations above 1), so a wrong model never reports the precision of a right one.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import replace

import numpy as np
from numpy.typing import NDArray
from scipy.optimize import least_squares

from viscorig.fitting import MISFIT_RATIO, FitResult, FrfData, NoiseModel, fit

__all__ = ["weighted_fit"]


def weighted_fit(
    spec: str,
    data: FrfData,
    noise: NoiseModel,
    *,
    fixed: Mapping[str, float] | None = None,
) -> FitResult:
    """Fit ``spec`` to ``data`` by generalised least squares under ``noise``.

    Parameters
    ----------
    spec
        Model spec.
    data
        The points.
    noise
        The core's noise model of exactly these points (in their order).
    fixed
        Parameters held fixed.
    """
    start = fit(spec, data, fixed=dict(fixed or {}), noise=noise)
    model, free, frfs = start.model, start.free, start.frfs
    if not free:
        return start
    ctx = data.context()
    measured = {name: data.frf(name) for name in frfs}
    parameters = [model.by_name[name] for name in free]
    log = np.array([p.log for p in parameters])
    lower = np.array([np.log(p.lower) if p.log else p.lower for p in parameters])
    upper = np.array([np.log(p.upper) if p.log else p.upper for p in parameters])
    values = dict(start.values)

    def to_values(x: NDArray[np.float64]) -> NDArray[np.float64]:
        return np.where(log, np.exp(np.clip(x, -700, 700)), x)

    def ratio(x: NDArray[np.float64]) -> dict[str, NDArray[np.complex128]]:
        values.update(zip(free, to_values(x), strict=True))
        predicted = model.predict(ctx, values)
        return {name: predicted[name] / measured[name] - 1 for name in frfs}

    def whitened(x: NDArray[np.float64]) -> NDArray[np.float64]:
        return noise.whiten(ratio(x))

    x0 = np.array([start.values[name] for name in free])
    x0 = np.where(log, np.log(np.abs(x0) + 1e-300), x0)
    span = upper - lower
    x0 = np.clip(x0, lower + 1e-9 * span, upper - 1e-9 * span)
    with np.errstate(all="ignore"):
        solution = least_squares(whitened, x0, bounds=(lower, upper), x_scale="jac",
                                 method="trf", ftol=1e-12, xtol=1e-12, gtol=1e-12)  # fmt: skip
    better = solution.cost <= 0.5 * float(np.sum(whitened(x0) ** 2))
    x = solution.x if better else x0
    jac = solution.jac if better else _jacobian(whitened, x)
    fitted = to_values(x)
    values.update(zip(free, fitted, strict=True))
    residuals = ratio(x)
    dof = max(noise.effective_points(frfs) - len(free), 1.0)
    reduced = float(np.sum(whitened(x) ** 2)) / dof
    misfit = reduced if reduced > 1.0 + 3.0 * np.sqrt(2.0 / dof) else 1.0
    derivative = np.where(log, fitted, 1.0)
    noise_only = np.linalg.pinv(jac.T @ jac, hermitian=True) * np.outer(derivative, derivative)
    covariance = noise_only * misfit
    stderr = dict.fromkeys(model.names, 0.0)
    stderr.update(zip(free, np.sqrt(np.abs(np.diag(covariance))), strict=True))
    everything = np.concatenate([residuals[name] for name in frfs])
    rms_error = float(np.sqrt(np.mean(np.abs(everything) ** 2)))
    warnings = list(start.warnings)
    if misfit > 1.0:
        warnings.append(f"the model leaves {misfit:.2g} times the noise: standard errors scaled up")
    return replace(
        start,
        values={name: float(v) for name, v in values.items()},
        stderr=stderr,
        covariance=covariance,
        covariance_names=free,
        joint_covariance=covariance,
        noise_covariance=noise_only,
        misfit_scale=float(misfit),
        fits_noise=rms_error <= MISFIT_RATIO * noise.floor_of(frfs),
        rms_error=rms_error,
        residuals=residuals,
        nfev=start.nfev + int(solution.nfev),
        warnings=warnings,
    )


def _jacobian(function, x: NDArray[np.float64]) -> NDArray[np.float64]:
    """Central-difference Jacobian."""
    columns = []
    for i in range(x.size):
        step = 1e-6 * max(1.0, abs(x[i]))
        up, down = x.copy(), x.copy()
        up[i] += step
        down[i] -= step
        columns.append((function(up) - function(down)) / (2 * step))
    return np.column_stack(columns)
