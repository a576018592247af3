"""Predictions for many parameter sets at once, for the fitters' finite-difference Jacobians.

A model whose terms all give derivatives of their stages is differentiated analytically
(:meth:`~viscorig.models.Model.derivatives`: the chain ``∂H/∂p`` through ``K*``, the disc's
added stiffness, the coupling and the measuring chain). One with a term that gives none (the
frame, a modifier of ``K*``, a user's term) is differentiated by forward differences, every
column from one evaluation of the model (:func:`predict_many`).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np
from numpy.typing import NDArray

from viscorig.models import Context, Model

#: Models whose terms were found to evaluate with per-point parameter arrays (id -> verdict).
#: A term written for scalars only (``float(p["x"])``) is found out once and then evaluated
#: one parameter set at a time.
_BATCHABLE: dict[int, tuple[Model, bool]] = {}


def predict_many(
    model: Model,
    ctx: Context,
    values: Mapping[str, float],
    names: Sequence[str],
    rows: NDArray[np.float64],
) -> dict[str, NDArray[np.complex128]]:
    """The model's predictions for several parameter sets at once (a finite-difference
    Jacobian's, say): ``values`` with ``names`` set to each row of ``rows`` (sets × names).

    Returns FRF name -> sets × points (read-only where the sets share a value). The sets are
    evaluated in one pass of the pipeline, each parameter of ``names`` a column of one value per
    set broadcast against the points, so that a term none of whose parameters moves is
    evaluated once for all sets, and any other once on sets × points. A model with a term that
    does not take such parameters falls back to one pass per set (found once per model, by
    comparing the first set with a plain evaluation).
    """
    rows = np.atleast_2d(np.asarray(rows, dtype=float))
    count, points = rows.shape[0], ctx.frequency_hz.size
    known = _BATCHABLE.get(id(model))
    batchable = None if known is None or known[0] is not model else known[1]
    if batchable is not False and count > 1:
        batch: dict[str, Any] = dict(values)  # a parameter may be a column, one per set
        for j, name in enumerate(names):
            batch[name] = rows[:, j, None]
        try:
            with np.errstate(all="ignore"):
                joined = model.predict(ctx, batch)
            out = {frf: np.broadcast_to(h, (count, points)) for frf, h in joined.items()}
        except (TypeError, ValueError, IndexError):
            out = None
        if batchable is None:
            batchable = out is not None and _agrees(model, ctx, values, names, rows[0], out)
            if len(_BATCHABLE) > 4096:
                _BATCHABLE.clear()
            _BATCHABLE[id(model)] = (model, batchable)
        if batchable and out is not None:
            return out
    single = []
    for row in rows:
        current = dict(values)
        current.update(zip(names, (float(v) for v in row), strict=True))
        with np.errstate(all="ignore"):
            single.append(model.predict(ctx, current))
    return {frf: np.stack([s[frf] for s in single]) for frf in single[0]}


def _agrees(model: Model, ctx: Context, values: Mapping[str, float], names: Sequence[str],
            row: NDArray[np.float64], out: Mapping[str, NDArray[np.complex128]]) -> bool:
    current = dict(values)
    current.update(zip(names, (float(v) for v in row), strict=True))
    with np.errstate(all="ignore"):
        plain = model.predict(ctx, current)
    return set(plain) == set(out) and all(
        np.allclose(out[frf][0], plain[frf], rtol=1e-12, atol=0.0, equal_nan=True)
        for frf in plain
    )
