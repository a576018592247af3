"""Maxwell arms during the order search: which contribute nothing, and starts across orders.

An order whose fit leaves an arm *dead* is the order below in disguise, and its BIC compared
with the order below is meaningless unless that lower order was fitted at least as well. An
arm is dead when

- its largest contribution ``|iω K_i C_i / (K_i + iω C_i)|`` over the band fitted is below
  :data:`DEAD_ARM_CONTRIBUTION` of ``|K*|`` at the same frequency, or
- its stiffness or damping is not identified: a standard error above
  :data:`DEAD_ARM_STDERR` times the value (an arm relaxing far outside the band acts as a
  spring or a dashpot, and only a combination of ``K_i`` and ``C_i`` is seen).

The order search uses :func:`reduced_start` (the fit of order ``N`` without its dead arms) to
start order ``N − k`` and :func:`extended_start` (the fit of order ``N − 1`` plus one new arm)
to start order ``N``, so that every order is compared from a start at least as good as the
neighbouring order's solution.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import numpy as np
from numpy.typing import NDArray

from viscorig.fitting.result import FitResult
from viscorig.models import Context, Maxwell, Model
from viscorig.numbers import with_uncertainty

#: An arm whose contribution to ``K*`` stays below this fraction of ``|K*|`` over the band is
#: dead (0.1 %: far below what a damper characterisation can use).
DEAD_ARM_CONTRIBUTION = 1e-3
#: An arm whose ``K_i`` or ``C_i`` has a standard error above this multiple of its value is
#: dead (not identified: two orders of magnitude).
DEAD_ARM_STDERR = 100.0
#: Stiffness of the new arm of :func:`extended_start`, relative to ``|K*|`` at the band centre:
#: large enough for the fitter to see it, small enough to start near the lower order's optimum.
NEW_ARM_FRACTION = 0.02


def maxwell_order(model: Model) -> int | None:
    """Number of arms of a concrete Maxwell model; ``None`` for any other model."""
    term = model.modulus_term
    return term.order if isinstance(term, Maxwell) else None


def _arm_values(
    model: Model, values: Mapping[str, float]
) -> tuple[Maxwell, NDArray, NDArray, dict[str, float]]:
    term = model.modulus_term
    assert isinstance(term, Maxwell)
    local = model.local_values(term, values)
    k, c = term.arms(local)
    return term, k, c, local


def arm_contributions(
    model: Model, values: Mapping[str, float], frequency_hz: NDArray[np.float64]
) -> NDArray[np.float64]:
    """Largest ``|arm_i / K*|`` over ``frequency_hz``, one value per arm (arm 1 first)."""
    term, k, c, local = _arm_values(model, values)
    omega = 2 * np.pi * np.asarray(frequency_hz, dtype=float)
    iwc = 1j * omega[:, None] * c[None, :]
    with np.errstate(all="ignore"):
        arms = k[None, :] * iwc / (k[None, :] + iwc)
        kstar = np.asarray(term.modulus(Context(frequency_hz), local))
        ratio = np.abs(arms) / np.abs(kstar)[:, None]
    return np.nan_to_num(ratio, nan=0.0, posinf=np.inf).max(axis=0)


def dead_arms(result: FitResult) -> dict[int, str]:
    """The dead arms of a Maxwell fit (see the module text): ``{arm number: why}``."""
    order = maxwell_order(result.model)
    if not order:
        return {}
    model, values = result.model, result.values
    contributions = arm_contributions(model, values, result.frequency_hz)
    dead: dict[int, str] = {}
    for i in range(1, order + 1):
        if contributions[i - 1] < DEAD_ARM_CONTRIBUTION:
            dead[i] = f"arm {i} adds at most {contributions[i - 1]:.1e} of |K*| over the band"
            continue
        for name in (f"K_{i}", f"C_{i}"):
            value, stderr = values[name], result.stderr.get(name, 0.0)
            bounds = model.by_name[name]
            if name not in result.free:
                continue
            if min(value / bounds.lower, bounds.upper / value) < 1.01:
                dead[i] = f"arm {i} is not identified ({name} = {value:.3g}, at its bound)"
                break
            if not stderr <= DEAD_ARM_STDERR * abs(value):
                dead[i] = f"arm {i} is not identified ({name} = {with_uncertainty(value, stderr)})"
                break
    kstar = np.abs(model.kstar(Context(result.frequency_hz), values))
    if order > 1 and values["K_0"] < DEAD_ARM_CONTRIBUTION * kstar.min():
        # No static stiffness: the arm relaxing slowest stands in for it (a spring in the band).
        _, k, c, _ = _arm_values(model, values)
        slowest = int(np.argmax(c / k)) + 1
        dead.setdefault(
            slowest, f"K_0 adds nothing and arm {slowest} stands in for it (a spring in the band)"
        )
    return dead


def reduced_start(result: FitResult, dead: Sequence[int], lower: Model) -> dict[str, float]:
    """Start of ``lower`` (a Maxwell model with ``len(dead)`` arms fewer and the same effect
    terms): ``result``'s values without the dead arms. A dead arm's storage stiffness at the
    band centre goes into ``K_0`` (an arm relaxing above the band acts as a spring there)."""
    _, k, c, _ = _arm_values(result.model, result.values)
    keep = [i for i in range(k.size) if i + 1 not in dead]
    start = {name: value for name, value in result.values.items() if name in lower.by_name}
    omega = 2 * np.pi * np.sqrt(result.frequency_hz.min() * result.frequency_hz.max())
    folded = 0.0
    for i in sorted(set(range(k.size)) - set(keep)):
        wt = omega * c[i] / k[i]
        folded += k[i] * wt**2 / (1 + wt**2)
    start["K_0"] = result.values["K_0"] + folded
    for new, old in enumerate(keep, start=1):
        start[f"K_{new}"], start[f"C_{new}"] = float(k[old]), float(c[old])
    return {name: lower.by_name[name].clip(value) for name, value in start.items()}


def extended_start(
    model: Model, values: Mapping[str, float], frequency_hz: NDArray[np.float64], higher: Model
) -> dict[str, float]:
    """Start of ``higher`` (one arm more than the Maxwell ``model``, same effect terms), from
    ``model``'s fitted ``values`` over the band ``frequency_hz``: those values plus a new arm
    of :data:`NEW_ARM_FRACTION` of ``|K*|``, relaxing where the existing arms leave the widest
    gap in ``log τ`` within the band. The arms are numbered by increasing relaxation time, as
    the linear start numbers them."""
    term, k, c, local = _arm_values(model, values)
    f = np.asarray(frequency_hz, dtype=float)
    omega_lo, omega_hi = 2 * np.pi * f.min(), 2 * np.pi * f.max()
    edges = np.log([1.0 / omega_hi, 1.0 / omega_lo])
    log_tau = np.sort(np.clip(np.log(c / k), *edges))
    points = np.concatenate([edges[:1], log_tau, edges[1:]])
    gap = int(np.argmax(np.diff(points)))
    tau = float(np.exp(0.5 * (points[gap] + points[gap + 1])))
    centre = Context(np.array([np.sqrt(f.min() * f.max())]))
    gain = NEW_ARM_FRACTION * float(np.abs(term.modulus(centre, local))[0])
    start = {name: value for name, value in values.items() if name in higher.by_name}
    stiffness, damping = np.append(k, gain), np.append(c, gain * tau)
    for i, arm in enumerate(np.argsort(damping / stiffness, kind="stable"), start=1):
        start[f"K_{i}"], start[f"C_{i}"] = float(stiffness[arm]), float(damping[arm])
    return {name: higher.by_name[name].clip(value) for name, value in start.items()}
