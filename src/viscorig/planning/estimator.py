"""The noise-weighted (maximum-likelihood) fit a plan needs.

The identification core minimises the design's error measure, the plain mean of
``|H_model/H_measured − 1|²``, in which every point weighs the same. A plan spends its time
unevenly on purpose (long integrations where the targets are learnt, short looks elsewhere), so
its points differ in noise by orders of magnitude, and an unweighted estimate lets the noisiest
points set the parameters: on the paper's own sweep it already uses about a twentieth of the
information the points hold, and on a plan far less. The estimate a plan is judged by is the
weighted one, ``min Σ |r_i|²/σ_i²`` with ``σ_i²`` each point's noise power, which reaches the
Fisher information of the points (the efficiency the design counts on).

:func:`weighted_fit` starts from the core's own fit (:func:`viscorig.fitting.fit`: same model,
same start, same bounds), refines it on the residual divided by each point's noise standard
deviation, and gives the covariance of that estimate under the same noise, ``(JᵀWJ)⁻¹ JᵀWΣWJ
(JᵀWJ)⁻¹`` with ``W = Σ⁻¹``, scaled up by the misfit when the model leaves more than the noise
can explain (``χ²/ν`` more than three of its standard deviations above 1), so a wrong model
never reports the precision of a right one.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import replace

import numpy as np
from numpy.typing import NDArray
from scipy.optimize import least_squares

from viscorig.fitting import FitResult, FrfData, fit

__all__ = ["weighted_fit"]


def weighted_fit(
    spec: str,
    data: FrfData,
    noise_power: Mapping[str, NDArray[np.float64]],
    *,
    fixed: Mapping[str, float] | None = None,
) -> FitResult:
    """Fit ``spec`` to ``data`` weighting each point by its noise.

    Parameters
    ----------
    spec
        Model spec.
    data
        The points (any order).
    noise_power
        ``{frf: E|ε_i|²}`` of every point of ``data``, in its order.
    fixed
        Parameters held fixed.
    """
    start = fit(spec, data, fixed=dict(fixed or {}))
    model, free, frfs = start.model, start.free, start.frfs
    if not free:
        return start
    ctx = data.context()
    measured = [data.frf(name) for name in frfs]
    power = np.concatenate([np.asarray(noise_power[name], dtype=float) for name in frfs])
    sigma = np.sqrt(np.maximum(power / 2.0, 1e-300))  # each of Re, Im carries half
    parameters = [model.by_name[name] for name in free]
    log = np.array([p.log for p in parameters])
    lower = np.array([np.log(p.lower) if p.log else p.lower for p in parameters])
    upper = np.array([np.log(p.upper) if p.log else p.upper for p in parameters])
    values = dict(start.values)

    def to_values(x: NDArray[np.float64]) -> NDArray[np.float64]:
        return np.where(log, np.exp(np.clip(x, -700, 700)), x)

    def ratio(x: NDArray[np.float64]) -> NDArray[np.complex128]:
        values.update(zip(free, to_values(x), strict=True))
        predicted = model.predict(ctx, values)
        return np.concatenate([predicted[n] / h for n, h in zip(frfs, measured, strict=True)]) - 1

    def whitened(x: NDArray[np.float64]) -> NDArray[np.float64]:
        r = ratio(x)
        return np.concatenate([r.real / sigma, r.imag / sigma])

    x0 = np.array([start.values[name] for name in free])
    x0 = np.where(log, np.log(np.abs(x0) + 1e-300), x0)
    span = upper - lower
    x0 = np.clip(x0, lower + 1e-9 * span, upper - 1e-9 * span)
    with np.errstate(all="ignore"):
        solution = least_squares(whitened, x0, bounds=(lower, upper), x_scale="jac",
                                 method="trf", ftol=1e-12, xtol=1e-12, gtol=1e-12)  # fmt: skip
    x = solution.x if solution.cost <= 0.5 * float(np.sum(whitened(x0) ** 2)) else x0
    fitted = to_values(x)
    values.update(zip(free, fitted, strict=True))
    r = ratio(x)
    jac = solution.jac if x is solution.x else _jacobian(whitened, x)
    n, k = jac.shape
    dof = max(n - k, 1)
    reduced = float(np.sum(whitened(x) ** 2)) / dof
    # scaled only by a misfit the noise cannot explain (χ²/ν beyond 3 of its standard
    # deviations, sqrt(2/ν)): a model at the noise floor keeps the noise's own covariance
    misfit = reduced if reduced > 1.0 + 3.0 * np.sqrt(2.0 / dof) else 1.0
    inverse = np.linalg.pinv(jac.T @ jac)
    derivative = np.where(log, fitted, 1.0)
    covariance = inverse * misfit * np.outer(derivative, derivative)
    stderr = dict.fromkeys(model.names, 0.0)
    stderr.update(zip(free, np.sqrt(np.abs(np.diag(covariance))), strict=True))
    points = data.frequency_hz.size
    return replace(
        start,
        values={name: float(v) for name, v in values.items()},
        stderr=stderr,
        covariance=covariance,
        rms_error=float(np.sqrt(np.mean(np.abs(r) ** 2))),
        residuals={name: r[i * points : (i + 1) * points] for i, name in enumerate(frfs)},
        nfev=start.nfev + int(solution.nfev),
        warnings=[*start.warnings, *(
            [f"the model leaves {misfit:.2g} times the noise: standard errors scaled up"]
            if misfit > 1.5 else []
        )],
    )  # fmt: skip


def _jacobian(function, x: NDArray[np.float64]) -> NDArray[np.float64]:
    """Central-difference Jacobian."""
    base = function(x)
    columns = []
    for i in range(x.size):
        step = 1e-6 * max(1.0, abs(x[i]))
        up, down = x.copy(), x.copy()
        up[i] += step
        down[i] -= step
        columns.append((function(up) - function(down)) / (2 * step))
    return np.column_stack(columns) if columns else np.zeros((base.size, 0))
