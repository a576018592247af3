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
