"""Analytic derivatives of the predicted accelerances, for the fitter's Jacobian.

With the rigid link (physics.md) every predicted accelerance is ``H = −ω²/D`` with ``D`` a dynamic
stiffness: ``D_t + D_v`` for the table FRF, ``D_v`` for the support FRF, where
``D_t = K_s − ω² M_s + iω C_s`` and ``D_v = K* − ω² M_v``. So ``∂H/∂p = (H²/ω²) ∂D/∂p``, and
``∂D/∂p`` is ``∂K*/∂p`` (:meth:`~viscorig.models.ModulusTerm.modulus_derivatives`) or one of
``−ω², 1, iω`` for the masses, ``K_s`` and ``C_s``.

A model with effect terms, or whose modulus term gives no derivatives, gets ``None`` here and
the fitter falls back to finite differences: the effect stages may change the chain anywhere.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np
from numpy.typing import NDArray

from viscorig.models import Context, Model


def stiffness_derivatives(
    model: Model, ctx: Context, values: Mapping[str, float], names: Sequence[str]
) -> dict[str, NDArray[np.complex128]] | None:
    """``∂D/∂p`` per FRF (points × ``len(names)``, complex), ``H = −ω²/D``; ``None`` if unknown.

    Parameters
    ----------
    model
        A concrete model.
    ctx
        The measurement points.
    values
        Every parameter's value, by global name.
    names
        The global names of the parameters to differentiate by, in column order.
    """
    term = model.modulus_term
    if term is None or model.effects:
        return None
    d_kstar = term.modulus_derivatives(ctx, model.local_values(term, values))
    if d_kstar is None:
        return None
    w = ctx.omega
    to_global = model.local_names(term)
    disc: dict[str, NDArray | float] = {to_global[name]: d for name, d in d_kstar.items()}
    if term.has_disc:
        disc["M_v"] = -(w**2)
    table: dict[str, NDArray | float] = {"M_s": -(w**2), "K_s": 1.0, "C_s": 1j * w, **disc}
    columns = {"table": table, "support": disc}
    result = {}
    for frf in model.frfs:
        matrix = np.zeros((w.size, len(names)), dtype=complex)
        for j, name in enumerate(names):
            if name in columns[frf]:
                matrix[:, j] = columns[frf][name]
        result[frf] = matrix
    return result


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
