"""Maximum-likelihood polish of a fit: least squares on the residual whitened by the noise.

The fitter minimises the design's error measure, the plain mean of ``|H_model/H_measured − 1|²``,
in which the noisiest points (high frequency, where the force is small) weigh most. Comparing
models by a noise-whitened χ² is only calibrated when each model minimises that χ²: fitted
otherwise, one more parameter can move the curve at the quiet points by more than noise allows
and fake an improvement. So every fit diagnosis compares is polished here, from the fitter's
solution, on ``(H_model/H_measured − 1)/σ_i``; ``rms_error`` stays the design's measure.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
from scipy.optimize import least_squares

from viscorig.diagnosis.data import DiagnosisData
from viscorig.fitting import FitResult


def polish(result: FitResult, data: DiagnosisData) -> FitResult:
    """``result`` refitted to minimise ``Σ |r_i|²/σ_i²`` (its free parameters, same model)."""
    model, free, frfs = result.model, result.free, result.frfs
    if not free:
        return result
    ctx = data.data.context()
    measured = [data.data.frf(name) for name in frfs]
    weight = np.concatenate([1.0 / np.sqrt(data.noise_power[name]) for name in frfs])
    parameters = [model.by_name[name] for name in free]
    log = np.array([p.log for p in parameters])
    lower = np.array([np.log(p.lower) if p.log else p.lower for p in parameters])
    upper = np.array([np.log(p.upper) if p.log else p.upper for p in parameters])
    values = dict(result.values)

    def to_values(x: np.ndarray) -> np.ndarray:
        return np.where(log, np.exp(np.clip(x, -700, 700)), x)

    def ratio(x: np.ndarray) -> np.ndarray:
        values.update(zip(free, to_values(x), strict=True))
        predicted = model.predict(ctx, values)
        return np.concatenate([predicted[n] / h for n, h in zip(frfs, measured, strict=True)]) - 1

    def residual(x: np.ndarray) -> np.ndarray:
        r = ratio(x) * weight
        return np.concatenate([r.real, r.imag])

    start = np.array([result.values[name] for name in free])
    x0 = np.where(log, np.log(np.abs(start) + 1e-300), start)
    span = upper - lower
    x0 = np.clip(x0, lower + 1e-9 * span, upper - 1e-9 * span)
    with np.errstate(all="ignore"):
        solution = least_squares(
            residual, x0, bounds=(lower, upper), x_scale="jac", method="trf",
            ftol=1e-6, xtol=1e-8, gtol=1e-8, max_nfev=10 + 2 * len(free),
        )
    if not solution.cost * 2 <= float(np.sum(residual(x0) ** 2)):
        values.update(zip(free, start, strict=True))
        return result
    fitted = to_values(solution.x)
    values.update(zip(free, fitted, strict=True))
    r = ratio(solution.x)
    points = data.data.frequency_hz.size
    return replace(
        result,
        values={name: float(v) for name, v in values.items()},
        rms_error=float(np.sqrt(np.mean(np.abs(r) ** 2))),
        residuals={name: r[i * points : (i + 1) * points] for i, name in enumerate(frfs)},
        nfev=result.nfev + int(solution.nfev),
    )
