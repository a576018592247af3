"""Sensitivities of a model's predicted FRFs to its parameters, in relative coordinates."""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import numpy as np
from numpy.typing import ArrayLike, NDArray

from viscorig.models import Context, Model

__all__ = ["log_sensitivities"]

#: Relative step of the central differences.
_STEP = 1e-6


def log_sensitivities(
    model: Model,
    values: Mapping[str, float],
    names: Sequence[str],
    frequency_hz: ArrayLike,
    *,
    level_m_per_s2: float = 1.0,
) -> dict[str, NDArray[np.complex128]]:
    """``∂ log H/∂u_k`` per FRF (points × parameters), ``u_k = p_k/p̂_k`` (central differences).

    A parameter whose value is 0 is differentiated in absolute units instead.
    """
    f = np.atleast_1d(np.asarray(frequency_hz, dtype=float))
    ctx = Context(f, np.zeros_like(f), np.full_like(f, level_m_per_s2))
    columns: dict[str, list[NDArray[np.complex128]]] = {}
    for name in names:
        value = float(values[name])
        scale = abs(value) if value != 0.0 else 1.0
        up, down = dict(values), dict(values)
        up[name] = value + _STEP * scale
        down[name] = value - _STEP * scale
        plus, minus = model.predict(ctx, up), model.predict(ctx, down)
        for frf in plus:
            column = np.asarray(np.log(plus[frf] / minus[frf]) / (2 * _STEP), dtype=np.complex128)
            columns.setdefault(frf, []).append(column)
    return {frf: np.column_stack(c) for frf, c in columns.items()}
