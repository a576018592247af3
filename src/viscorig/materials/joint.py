"""Shift factors and Prony series refined together: the master curve as a linear viscoelastic
material.

The spline master curve of :mod:`viscorig.materials.shift` puts the sets on one smooth curve of
E' and one of E'', each free of the other. A Prony series ties them (Kramers-Kronig): refining
the shifts together with the series makes them the shifts under which the data are one linear
viscoelastic material, which is what an FE card assumes. Residuals and weights are those of the
Prony fit (``ln(model/measured)`` over each modulus's scatter); the shifts' covariance is the
marginal one from the Jacobian of the joint problem, scaled by the weighted residual variance.
The series' moduli and relaxation times keep the bounds of the Prony fit
(:func:`viscorig.materials.prony.prony_bounds`) at the reduced frequencies of the shifts, which
are free: where the shifts moved the data away from the series' fastest or slowest term, the
refinement is repeated with the bounds of the shifts it found.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray
from scipy.optimize import least_squares

from viscorig.materials.prony import (
    ModelFit,
    PronySeries,
    maxwell_parts,
    model_fit,
    prony_bounds,
)

LN10 = math.log(10.0)
#: Most refinements, each with the series' bounds at the reduced frequencies the last one left.
JOINT_PASSES = 3
#: How far (natural log) past the bounds of its own reduced frequencies a refined series may end
#: without another pass.
BOUND_SLACK = math.log(2.0)


@dataclass(frozen=True)
class JointFit:
    """Result of :func:`refine_jointly`."""

    series: PronySeries
    fit: ModelFit
    log10_at: NDArray[np.float64]
    covariance: NDArray[np.float64]


def refine_jointly(
    frequency_hz: NDArray[np.float64], member: NDArray[np.int64],
    point_offset: NDArray[np.float64], storage: NDArray[np.float64],
    loss: NDArray[np.float64], scatter: tuple, series: PronySeries,
    log10_at: NDArray[np.float64], reference: int, evaluations: int = 60,
) -> JointFit:
    """Refine a Prony series and the shift factors of every set but ``reference`` together.

    Parameters
    ----------
    frequency_hz, member, point_offset
        Each point's frequency, the index of its set, and its own shift correction (decades).
    storage, loss
        Measured moduli (Pa).
    scatter
        The weights: rms ``ln`` scatter of E' and E'', two numbers or two arrays of one value
        per point (each sweep's own noise).
    series, log10_at
        The start: a Prony series and every set's shift (0 at ``reference``).
    """
    size = frequency_hz.size
    ws = np.broadcast_to(np.maximum(np.asarray(scatter[0], float), 1e-4), (size,))
    wl = np.broadcast_to(np.maximum(np.asarray(scatter[1], float), 1e-4), (size,))
    sets = log10_at.size
    free = np.array([i for i in range(sets) if i != reference], dtype=int)
    n = series.terms
    ls, ll = np.log(storage), np.log(loss)
    indicator = (member[:, None] == free[None, :]).astype(float)

    log_frequency = np.log(2 * np.pi * frequency_hz) + LN10 * point_offset

    def shifts_of(p: NDArray) -> NDArray:
        shifts = np.zeros(sets)
        shifts[free] = p[2 * n + 1:]
        return shifts

    def unpack(p: NDArray) -> tuple[NDArray, ...]:
        e_inf, e = np.exp(p[0]), np.exp(p[1:n + 1])
        log_wt = (log_frequency + LN10 * shifts_of(p)[member])[:, None] + p[None, n + 1:2 * n + 1]
        x, x_complement, y = maxwell_parts(log_wt)
        return e_inf, e, x, x_complement, y

    def residual(p: NDArray) -> NDArray:
        e_inf, e, x, _, y = unpack(p)
        return np.concatenate([(np.log(e_inf + x @ e) - ls) / ws, (np.log(y @ e) - ll) / wl])

    def jacobian(p: NDArray) -> NDArray:
        e_inf, e, x, x_complement, y = unpack(p)
        es, el = e_inf + x @ e, y @ e
        dx = 2 * x * x_complement * e
        dy = y * (x_complement - x) * e
        top = np.hstack([np.full((size, 1), e_inf), x * e, dx,
                         LN10 * dx.sum(axis=1)[:, None] * indicator]) / es[:, None]
        bottom = np.hstack([np.zeros((size, 1)), y * e, dy,
                            LN10 * dy.sum(axis=1)[:, None] * indicator]) / el[:, None]
        return np.vstack([top / ws[:, None], bottom / wl[:, None]])

    start = np.concatenate([[np.log(series.long_term_modulus_pa)], np.log(series.moduli_pa),
                            np.log(series.tau_s), log10_at[free]])
    shifts_now = log10_at
    for _ in range(JOINT_PASSES):
        # the series' bounds follow the reduced frequencies, which move with the shifts: a pass
        # whose shifts moved them away from a relaxation time is done again from there
        omega_now = 2 * np.pi * frequency_hz * 10.0 ** (shifts_now[member] + point_offset)
        lower, upper = prony_bounds(omega_now, storage, loss, n)
        lower = np.concatenate([lower, np.full(free.size, -np.inf)])
        upper = np.concatenate([upper, np.full(free.size, np.inf)])
        margin = np.zeros(start.size)
        margin[:2 * n + 1] = 1e-9 * (upper[:2 * n + 1] - lower[:2 * n + 1])
        solution = least_squares(residual, np.clip(start, lower + margin, upper - margin),
                                 jac=jacobian, method="trf", bounds=(lower, upper),
                                 max_nfev=evaluations * start.size, x_scale="jac")
        shifts_now = shifts_of(solution.x)
        omega_end = 2 * np.pi * frequency_hz * 10.0 ** (shifts_now[member] + point_offset)
        lower_end, upper_end = prony_bounds(omega_end, storage, loss, n)
        inside = solution.x[:2 * n + 1]
        if np.all((inside >= lower_end - BOUND_SLACK) & (inside <= upper_end + BOUND_SLACK)):
            break
        start = solution.x
    e_inf, e = np.exp(solution.x[0]), np.exp(solution.x[1:n + 1])
    shifts = shifts_of(solution.x)
    tau = np.exp(solution.x[n + 1:2 * n + 1])
    order = np.argsort(tau)
    refined = PronySeries(float(e_inf), e[order], tau[order])
    r = solution.fun
    variance = float(r @ r) / max(1, r.size - start.size)
    jac = jacobian(solution.x)
    covariance_all = np.linalg.pinv(jac.T @ jac) * variance
    covariance = np.zeros((sets, sets))
    covariance[np.ix_(free, free)] = covariance_all[2 * n + 1:, 2 * n + 1:]
    omega = 2 * np.pi * frequency_hz * 10.0 ** (shifts[member] + point_offset)
    fit = model_fit(refined.complex_modulus(omega), storage, loss,
                    (float(np.sqrt(np.mean(ws**2))), float(np.sqrt(np.mean(wl**2)))), 2 * n + 1)
    return JointFit(refined, fit, shifts, covariance)
