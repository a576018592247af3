"""The paper's way of fitting, kept as a baseline: a direct search from a given start.

The paper fits with a direct-search method and notes that the result depends strongly on the
initial guess. :func:`nelder_mead_fit` does the same (Nelder-Mead on the raw parameter values,
minimising the same ``rms_error`` as :func:`viscorig.fitting.fit`) so that benchmarks and tests
can show the difference the linear start and scaled least squares make.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import numpy as np
from scipy.optimize import minimize

from viscorig.fitting.data import FrfData
from viscorig.models import Model, parse_spec


def nelder_mead_fit(
    model: Model | str,
    data: FrfData,
    start: Mapping[str, float],
    *,
    frfs: Sequence[str],
    fixed: Mapping[str, float] | None = None,
    max_evaluations: int = 4000,
) -> tuple[dict[str, float], float]:
    """Nelder-Mead from ``start`` (every free parameter); returns ``(values, rms_error)``."""
    model = parse_spec(model) if isinstance(model, str) else model
    fixed = dict(fixed or {})
    free = [name for name in model.names if name not in fixed]
    values = {**model.defaults(), **fixed, **{k: start[k] for k in free}}
    ctx = data.context()
    measured = [data.frf(name) for name in frfs]

    def rms(x: np.ndarray) -> float:
        values.update(zip(free, x, strict=True))
        predicted = model.predict(ctx, values)
        ratio = np.concatenate([predicted[n] / h for n, h in zip(frfs, measured, strict=True)])
        value = float(np.sqrt(np.mean(np.abs(ratio - 1.0) ** 2)))
        return value if np.isfinite(value) else 1e300

    x0 = np.array([start[name] for name in free], dtype=float)
    with np.errstate(all="ignore"):
        result = minimize(
            rms,
            x0,
            method="Nelder-Mead",
            options={"maxfev": max_evaluations, "xatol": 1e-10, "fatol": 1e-12},
        )
    values.update(zip(free, result.x, strict=True))
    return dict(values), float(result.fun)
