"""Starts that need no user guess: linear (or non-negative) least squares on dynamic stiffness.

The table alone: ``F_e/X_s = K_s − ω² M_s + iω C_s`` is linear in ``M_s, K_s, C_s``.
With a specimen, both FRFs give samples of the disc's dynamic stiffness ``D_v = K* − ω² M_v``:
``F_v/X_v`` directly (Eq. 5 before adding ``ω² M_v``), and ``F_e/X_s − D_table`` with the table
known (Eq. 4 before removing ``M_v``). The modulus term turns those samples into a start
(:meth:`viscorig.models.ModulusTerm.start`). Each sample is weighted by ``1/|Z|`` of the
dynamic stiffness it came from, which makes the linear problem approximate the relative error
measure of the nonlinear fit (``δH/H = −δZ/Z``).
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np
from numpy.typing import NDArray

from viscorig.errors import InputError
from viscorig.fitting.data import FrfData
from viscorig.frf import accelerance_to_dynamic_stiffness
from viscorig.models import Model, Voigt, table_dynamic_stiffness


def table_linear_fit(data: FrfData) -> dict[str, float]:
    """``M_s, K_s, C_s`` by weighted linear least squares on the table's dynamic stiffness."""
    omega = 2 * np.pi * data.frequency_hz
    z = accelerance_to_dynamic_stiffness(data.frequency_hz, data.frf("table"))
    voigt = Voigt().start(omega, z, 1.0 / np.abs(z))
    return {"M_s": voigt["M_v"], "K_s": voigt["K_v"], "C_s": voigt["C_v"]}


def disc_stiffness_samples(
    data: FrfData, frfs: tuple[str, ...], table: Mapping[str, float]
) -> tuple[NDArray[np.float64], NDArray[np.complex128], NDArray[np.float64]]:
    """Samples ``(ω, D_v, weight)`` of the disc's dynamic stiffness from the FRFs fitted."""
    omega = 2 * np.pi * data.frequency_hz
    parts = []
    for name in frfs:
        z = accelerance_to_dynamic_stiffness(data.frequency_hz, data.frf(name))
        if name == "table":
            parts.append((omega, z - table_dynamic_stiffness(omega, table), 1.0 / np.abs(z)))
        else:
            parts.append((omega, z, 1.0 / np.abs(z)))
    return tuple(np.concatenate(column) for column in zip(*parts, strict=True))  # type: ignore[return-value]


def linear_start(
    model: Model, data: FrfData, frfs: tuple[str, ...], fixed: Mapping[str, float]
) -> dict[str, float]:
    """Start values of every parameter of a concrete model, from the data alone.

    ``fixed`` values are kept as they are. The table's ``M_s, K_s, C_s`` must be among them
    when a specimen model is fitted to the table FRF.
    """
    values = model.defaults()
    values.update(fixed)
    term = model.modulus_term
    if term is None:
        raise InputError(f"'{model.spec}' has no K* term", "model spec")
    if not term.has_disc:
        values.update({k: v for k, v in table_linear_fit(data).items() if k not in fixed})
    else:
        missing = [name for name in ("M_s", "K_s", "C_s") if name not in fixed]
        if "table" in frfs and missing:
            raise InputError(
                f"fitting '{model.spec}' to the table FRF needs the table's {', '.join(missing)} "
                "(identify a bare-table run first, or give them in /rig)",
                data.name,
            )
        omega, d_disc, weight = disc_stiffness_samples(data, frfs, values)
        own = term.start(omega, d_disc, weight)
        names = model.local_names(term)
        names["M_v"] = "M_v"
        values.update({names[k]: float(v) for k, v in own.items() if names[k] not in fixed})
    ctx = data.context()
    for effect in model.effects:
        names = model.local_names(effect)
        for local, value in effect.initial(ctx, values).items():
            if names[local] not in fixed:
                values[names[local]] = float(value)
    measured = {name: data.frf(name) for name in frfs}
    for effect in model.effects:  # after every initial(): a data start sees the whole model
        names = model.local_names(effect)
        for local, value in effect.start_from_data(model, ctx, values, measured).items():
            if names[local] not in fixed and np.isfinite(value):
                values[names[local]] = model.by_name[names[local]].clip(float(value))
    for parameter in model.parameters:
        if parameter.name not in fixed:
            value = values[parameter.name]
            if not np.isfinite(value):
                value = parameter.default
            values[parameter.name] = parameter.clip(value)
    return values
