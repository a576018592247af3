"""Shift factors of time-temperature superposition, estimated from the data with standard errors.

Criterion: every isothermal set ``s`` is moved along the log-frequency axis by ``log10 aT_s``
(reduced frequency ``f·aT``; ``aT > 1`` below the reference temperature) so that all sets lie
on one smooth master curve, for the storage and the loss modulus at once. The master curve is a
cubic B-spline in ``log10(f·aT)`` for ``ln E'`` and another for ``ln E''``; for given shifts
its coefficients are a linear least-squares solution, so only the shifts are searched (variable
projection). The residuals of ``ln E'`` and ``ln E''`` are each weighted by their own scatter in
each set (sweeps differ in noise by an order of magnitude), estimated from the fit itself.

Standard errors come from the Jacobian of the projected residuals (the marginal covariance of
the shifts, spline coefficients eliminated), scaled by the weighted residual variance. They are
large where neighbouring sets barely overlap or where the modulus is flat over a set, because
there the criterion hardly changes with the shift.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.interpolate import BSpline
from scipy.optimize import least_squares
from scipy.special import chdtrc, fdtrc

from viscorig.errors import InputError
from viscorig.materials.table import ModulusTable

#: Spacings of the spline's knots along log10 reduced frequency tried (decades).
KNOT_SPACINGS_DECADES = (0.5, 0.35, 0.25)
#: Largest shift searched between neighbouring sets (decades).
MAX_STEP_DECADES = 8.0
#: Chance below which the sweeps' own slopes count as a dependence on frequency: above it, no
#: shift along the frequency axis is determined by the data.
SLOPE_SIGNIFICANCE = 0.01
#: Fewest degrees of freedom of the scatter about the sweeps' lines for that test to be made
#: (two sweeps of three points leave two, and miss a real slope under a few per cent of noise).
SLOPE_TEST_DOF = 10


@dataclass(frozen=True)
class ShiftFactors:
    """Shift factors of each set and the smooth master curve they put the data on.

    Attributes
    ----------
    temperature_c
        Mean temperature of each set (°C), ascending.
    sets
        Set number of each entry.
    log10_at, log10_at_stderr
        Shift factor of each set and its standard error (0 at the reference set).
    covariance
        Covariance matrix of ``log10_at`` (zeros in the reference set's row and column).
    reference
        Index (into the arrays) of the set the shifts are relative to.
    storage_scatter, loss_scatter
        Rms of ``ln(measured / master curve)`` of E' and E'' (the data's own scatter).
    residual_storage, residual_loss
        ``ln(measured / master curve)`` at every point of the table.
    point_offset
        What each point's shift adds to its set's, for its own temperature (0 for most data).
    """

    temperature_c: NDArray[np.float64]
    sets: NDArray[np.int64]
    log10_at: NDArray[np.float64]
    log10_at_stderr: NDArray[np.float64]
    covariance: NDArray[np.float64]
    reference: int
    storage_scatter: float
    loss_scatter: float
    residual_storage: NDArray[np.float64]
    residual_loss: NDArray[np.float64]
    point_offset: NDArray[np.float64]

    def of_points(self, table: ModulusTable) -> NDArray[np.float64]:
        """``log10 aT`` of every point of ``table``: its set's, plus the correction for a point
        measured off its set's mean temperature."""
        lookup = dict(zip(self.sets.tolist(), self.log10_at, strict=True))
        return np.array([lookup[s] for s in table.set_index.tolist()]) + self.point_offset


def _ordered_sets(table: ModulusTable) -> tuple[NDArray[np.int64], NDArray[np.float64]]:
    sets = table.sets
    temperatures = table.set_temperatures_c()
    order = np.argsort(temperatures, kind="stable")
    return sets[order], temperatures[order]


def _pair_step(x_a: NDArray, y_a: NDArray, x_b: NDArray, y_b: NDArray) -> float:
    """Shift (decades) that puts set b on set a, by a grid search on the overlap.

    ``y_*`` hold ``ln E'`` and ``ln E''`` as two columns; each column is compared after
    removing nothing: both moduli must agree where the sets overlap.
    """
    order = np.argsort(x_a)
    x_a, y_a = x_a[order], y_a[order]
    steps = np.arange(-2.0, MAX_STEP_DECADES + 1e-9, 0.01)
    u = x_b[None, :] - steps[:, None]
    inside = (u >= x_a[0]) & (u <= x_a[-1])
    cost = np.zeros(steps.size)
    for k in range(2):
        diff = np.interp(u, x_a, y_a[:, k]) - y_b[None, :, k]
        cost += np.where(inside, diff**2, 0.0).sum(axis=1)
    count = inside.sum(axis=1)
    cost = np.where(count >= 2, cost / np.maximum(count, 1) / (1.0 + 0.05 * count), np.inf)
    best = float(steps[int(np.argmin(cost))]) if np.isfinite(cost).any() else np.nan
    if not np.isfinite(best):
        # no overlap at any shift: continue the curve's slope (a start only; the fit decides)
        slope_a = np.polyfit(x_a, y_a[:, 0], 1)[0] if x_a.size > 1 else 0.0
        best = (y_a[0, 0] - y_b[-1, 0]) / slope_a if slope_a else 0.0
        best = float(np.clip(best, 0.0, MAX_STEP_DECADES))
    return float(best)


def _basis(u: NDArray[np.float64], knots: NDArray[np.float64]) -> NDArray[np.float64]:
    return BSpline.design_matrix(u, knots, 3, extrapolate=True).toarray()


def _knots(u: NDArray[np.float64], spacing: float) -> NDArray[np.float64]:
    lo, hi = float(u.min()) - 1e-6, float(u.max()) + 1e-6
    inner = max(2, int(np.ceil((hi - lo) / spacing)) + 1)
    breaks = np.linspace(lo, hi, inner)
    return np.concatenate([[lo] * 3, breaks, [hi] * 3])


#: Weight of the typical set's scatter in each set's, in points (a set's own scatter is
#: trusted as it gains points).
POOLED_PRIOR_POINTS = 1.0


def _set_scatter(raw: NDArray[np.float64], leverage: NDArray[np.float64],
                 member: NDArray[np.int64], shifts: int) -> NDArray[np.float64]:
    """Each point's scatter of ``ln E'`` and ``ln E''``: its set's, estimated from the
    residuals ``raw`` and drawn a little towards the typical set's
    (:data:`POOLED_PRIOR_POINTS`).

    Sweeps differ in noise by an order of magnitude (a hot rubber's small loss modulus is
    measured far less well than a cold one's), and a shift is only as well known as the sweeps
    it joins: one weight for all would make the noisy sweeps' shifts look better known than they
    are. A set's degrees of freedom are its points less their leverage on the spline (an end
    set alone holds the curve's end) and less its shift. Where Bartlett's test finds no
    difference between the sets (at 1 %), one pooled scatter serves them all.
    """
    sets = int(member.max()) + 1
    counts = np.bincount(member, minlength=sets).astype(float)
    per_set, dof = np.empty((sets, raw.shape[1])), np.empty((sets, raw.shape[1]))
    for k in range(raw.shape[1]):
        per_set[:, k] = np.bincount(member, weights=raw[:, k] ** 2, minlength=sets)
        dof[:, k] = np.bincount(member, weights=1.0 - leverage[:, k], minlength=sets)
    dof = np.maximum(dof - 0.5 * shifts / sets, 0.1 * counts[:, None])
    # the typical set's, so that one noisy set does not make the quiet ones look noisy
    typical = np.median(per_set / dof, axis=0)
    variance = (per_set + POOLED_PRIOR_POINTS * typical) / (dof + POOLED_PRIOR_POINTS)
    for k in range(raw.shape[1]):
        if not _differ(per_set[:, k], dof[:, k]):
            # one scatter for all is the better estimate when nothing says the sets differ
            variance[:, k] = per_set[:, k].sum() / dof[:, k].sum()
    return np.maximum(np.sqrt(variance), 1e-6)[member]


def _differ(squares: NDArray[np.float64], dof: NDArray[np.float64],
            significance: float = 0.01) -> bool:
    """Bartlett's test: do the sets' variances (sums of squares over degrees of freedom)
    differ beyond chance?"""
    own = np.maximum(squares / dof, 1e-300)
    pooled = squares.sum() / dof.sum()
    k = squares.size
    if k < 2 or pooled <= 0:
        return False
    statistic = (dof.sum() * np.log(pooled) - (dof * np.log(own)).sum()) / (
        1.0 + ((1.0 / dof).sum() - 1.0 / dof.sum()) / (3.0 * (k - 1)))
    return bool(chdtrc(k - 1, statistic) < significance)


def frequency_step(table: ModulusTable) -> float:
    """The typical step between a sweep's neighbouring frequencies (decades): the median over the
    sweeps of each sweep's median step.

    Knots closer than this let one sweep, shifted off the others' frequencies, draw a piece of
    master curve of its own through its noise: a shift of a fraction of a step then fits better
    than the right one, and looks better known than it is.
    """
    steps = []
    for value in np.unique(table.set_index):
        x = np.unique(np.log10(table.frequency_hz[table.set_index == value]))
        if x.size > 1:
            steps.append(float(np.median(np.diff(x))))
    return float(np.median(steps)) if steps else 0.0


def frequency_dependence(table: ModulusTable) -> tuple[float, float, float] | None:
    """The chance that no sweep of ``table`` changes with frequency, and the scatter about each
    sweep's own straight line of ``ln E'`` and of ``ln E''`` over ``log10 f``; ``None`` when
    the sweeps are too few to tell.

    Each sweep's slope is tested against zero with the scatter pooled over the sweeps (an F
    test over both moduli). A shift moves a sweep along the frequency axis: where no sweep
    changes along it beyond its scatter, the criterion of :func:`estimate_shift_factors` is
    flat in every shift, and the shifts it finds follow the noise with standard errors that do
    not say so (a spline drawn through pure noise has slopes of its own). Sweeps leaving fewer
    than :data:`SLOPE_TEST_DOF` degrees of freedom for the scatter, or none with two
    frequencies, are too few to tell.
    """
    _, member = np.unique(table.set_index, return_inverse=True)
    x = np.log10(table.frequency_hz)

    def total(values: NDArray[np.float64]) -> NDArray[np.float64]:
        return np.bincount(member, weights=values).astype(float)

    count = total(np.ones(x.size))
    dx = x - (total(x) / count)[member]
    sxx = total(dx * dx)
    sloped = sxx > 1e-12 * np.maximum(count, 1.0)
    dof = x.size - count.size - int(sloped.sum())
    if dof < SLOPE_TEST_DOF or not sloped.any():
        return None
    statistic, scatter = 0.0, []
    for y in (np.log(table.storage_pa), np.log(table.loss_pa)):
        dy = y - (total(y) / count)[member]
        sxy = total(dx * dy)
        slope_squares = np.where(sloped, sxy**2 / np.where(sloped, sxx, 1.0), 0.0)
        variance = max(float((dy @ dy) - slope_squares.sum()) / dof, 1e-300)
        statistic += float(slope_squares.sum()) / variance
        scatter.append(float(np.sqrt(variance)))
    slopes = 2 * int(sloped.sum())
    chance = float(fdtrc(slopes, 2 * dof, statistic / slopes))
    return chance, scatter[0], scatter[1]


#: scipy's relative step of a forward difference (its ``2-point`` Jacobian's).
_DIFF_STEP = float(np.finfo(float).eps) ** 0.5


class _Problem:
    """The variable-projection residual of the shifts."""

    def __init__(self, table: ModulusTable, sets: NDArray[np.int64], reference: int) -> None:
        self.x = np.log10(table.frequency_hz)
        self.y = np.stack([np.log(table.storage_pa), np.log(table.loss_pa)], axis=1)
        position = {s: i for i, s in enumerate(sets.tolist())}
        self.member = np.array([position[s] for s in table.set_index.tolist()])
        self.free = np.array([i for i in range(sets.size) if i != reference])
        self.sets = sets.size
        self.weights = np.ones((self.x.size, 2))
        self.knots: NDArray[np.float64] | None = None
        #: per-point correction of the shift where a point's temperature is not its set's
        self.offset = np.zeros(self.x.size)

    def shifts(self, free: NDArray[np.float64]) -> NDArray[np.float64]:
        full = np.zeros(self.sets)
        full[self.free] = free
        return full

    def reduced(self, free: NDArray[np.float64]) -> NDArray[np.float64]:
        return self.x + self.shifts(free)[self.member] + self.offset

    def fitted(self, free: NDArray[np.float64], leverage: bool = False
               ) -> NDArray[np.float64] | tuple[NDArray[np.float64], NDArray[np.float64]]:
        """Master-curve values of ``ln E'``, ``ln E''`` at every point (two columns), and with
        ``leverage`` each point's leverage on them (the weighted fit's hat-matrix diagonal)."""
        assert self.knots is not None, "knots are set before the first fit"
        basis = _basis(self.reduced(free), self.knots)
        out, hat = np.empty_like(self.y), np.empty_like(self.y)
        for k in range(self.y.shape[1]):
            # weighted normal equations; a small ridge keeps knots without data from making
            # them singular
            w2 = self.weights[:, k] ** 2
            weighted = basis * w2[:, None]
            normal = basis.T @ weighted
            normal += 1e-8 * np.trace(normal) / normal.shape[0] * np.eye(basis.shape[1])
            out[:, k] = basis @ np.linalg.solve(normal, weighted.T @ self.y[:, k])
            if leverage:
                hat[:, k] = np.einsum("ij,ji->i", weighted, np.linalg.solve(normal, basis.T))
        return (out, hat) if leverage else out

    def residual(self, free: NDArray[np.float64]) -> NDArray[np.float64]:
        return ((self.y - self.fitted(free)) * self.weights).ravel(order="F")

    def jacobian(self, free: NDArray[np.float64]) -> NDArray[np.float64]:
        """The residual's forward-difference Jacobian, with scipy's steps, all columns at once.

        Moving one set's shift moves only its own points along the spline: their rows of the
        design matrix change, the normal equations by their outer products, and every
        column's spline coefficients come from one batched solve, where evaluating the
        residual once per shift rebuilt the whole fit each time.
        """
        assert self.knots is not None, "knots are set before the first fit"
        sign = np.where(free >= 0, 1.0, -1.0)
        step = (free + _DIFF_STEP * sign * np.maximum(1.0, np.abs(free))) - free
        u = self.reduced(free)
        basis = _basis(u, self.knots)
        moved_step = np.zeros(self.sets)
        moved_step[self.free] = step
        moved = _basis(u + moved_step[self.member], self.knots)
        column = np.full(self.sets, -1)
        column[self.free] = np.arange(self.free.size)
        member = column[self.member]  # each point's column (-1: the reference set's)
        rows = member >= 0
        # each column's points, padded to the largest set (padding weighs nothing)
        order = np.argsort(member, kind="stable")
        order = order[member[order] >= 0]
        counts = np.bincount(member[rows], minlength=self.free.size)
        slot = np.arange(order.size) - np.repeat(np.cumsum(counts) - counts, counts)
        index = np.zeros((self.free.size, max(1, int(counts.max()))), dtype=np.intp)
        present = np.zeros(index.shape, dtype=bool)
        index[member[order], slot] = order
        present[member[order], slot] = True
        jac = np.empty((self.y.size, self.free.size))
        size = basis.shape[1]
        for k in range(self.y.shape[1]):
            w2, y = self.weights[:, k] ** 2, self.y[:, k]
            weighted = basis * w2[:, None]
            normal = basis.T @ weighted
            rhs = weighted.T @ y
            trace = np.trace(normal)
            ridge = 1e-8 * trace / size * np.eye(size)
            base = basis @ np.linalg.solve(normal + ridge, rhs)
            # per column: the normal matrix and right-hand side with its set's rows moved
            w2_sets = np.where(present, w2[index], 0.0)[:, :, None]
            moved_sets, basis_sets = moved[index], basis[index]
            delta = (np.swapaxes(moved_sets, 1, 2) @ (moved_sets * w2_sets)
                     - np.swapaxes(basis_sets, 1, 2) @ (basis_sets * w2_sets))
            normals = normal + delta
            traces = trace + np.trace(delta, axis1=1, axis2=2)
            normals += (1e-8 * traces / size)[:, None, None] * np.eye(size)
            rhss = rhs + np.einsum("pr,pra->pa", w2_sets[:, :, 0] * y[index],
                                   moved_sets - basis_sets)
            coefficients = np.linalg.solve(normals, rhss[:, :, None])[:, :, 0]
            fitted = basis @ coefficients.T  # points x columns
            own = np.einsum("ia,ia->i", moved[rows], coefficients[member[rows]])
            fitted[np.flatnonzero(rows), member[rows]] = own
            weight = self.weights[:, k][:, None]
            jac[k * u.size:(k + 1) * u.size] = (-(fitted - base[:, None]) * weight) / step
        return jac


def estimate_shift_factors(
    table: ModulusTable, reference_set: int | None = None,
    knot_spacing: float | None = None,
) -> ShiftFactors:
    """Estimate the shift factor of every set of ``table`` (see the module text).

    Parameters
    ----------
    table
        At least two sets of at least two points each.
    reference_set
        Set number whose shift is 0; default the set nearest the middle temperature.
    knot_spacing
        Spline knot spacing in decades of reduced frequency; default the one of
        :data:`KNOT_SPACINGS_DECADES` with the lowest BIC (a curve the data follow to a tenth
        of a per cent needs closer knots than a noisy one, or the spline's own error biases
        the shifts).

    Raises
    ------
    InputError
        Fewer than two sets, a set at a single frequency, or sweeps that do not change with
        frequency beyond their scatter (:func:`frequency_dependence`).
    """
    sets, temperatures = _ordered_sets(table)
    where = table.source or "modulus table"
    if sets.size < 2:
        raise InputError("one temperature only; a master curve needs isothermal sweeps at two "
                         "or more (sweeps saved one file per temperature: import each with one "
                         "--specimen and give them all, --run A --run B; a curve already "
                         "shifted to one reference temperature, as a DMA program's master export "
                         "is, cannot be shifted again: import the raw sweeps)", where)
    frequencies = [np.unique(table.frequency_hz[table.set_index == s]) for s in sets]
    single = next((i for i, f in enumerate(frequencies) if f.size < 2), None)
    if single is not None:
        points = int((table.set_index == sets[single]).sum())
        measured = "a single point" if points == 1 else (
            f"its {points} points at one frequency, {frequencies[single][0]:.4g} Hz")
        raise InputError(f"the sweep at {float(temperatures[single]):.1f} °C has {measured}; a "
                         "set needs two or more frequencies", where)
    tested = frequency_dependence(table)
    if tested is not None and tested[0] > SLOPE_SIGNIFICANCE:
        chance, storage_scatter, loss_scatter = tested
        raise InputError(
            "no sweep changes with frequency beyond its scatter (rms "
            f"{storage_scatter:.2g} of ln E', {loss_scatter:.2g} of ln E'' about each sweep's "
            f"line; chance {chance:.2f} that the slopes are noise): no shift along the frequency "
            "axis is determined by these data", where)
    if reference_set is None:
        middle = 0.5 * (temperatures[0] + temperatures[-1])
        reference = int(np.argmin(np.abs(temperatures - middle)))
    else:
        reference = int(np.flatnonzero(sets == reference_set)[0])
    # start: neighbour by neighbour, colder to warmer, then relative to the reference
    probe = _Problem(table, sets, reference)
    start = np.zeros(sets.size)
    for i in range(1, sets.size):
        a, b = table.set_index == sets[i - 1], table.set_index == sets[i]
        start[i] = start[i - 1] - _pair_step(probe.x[a], probe.y[a], probe.x[b], probe.y[b])
    start -= start[reference]
    if knot_spacing is None:
        floor = frequency_step(table)
        spacings = tuple(sorted({max(spacing, floor) for spacing in KNOT_SPACINGS_DECADES},
                                reverse=True))
    else:
        spacings = (knot_spacing,)
    # and from every set unshifted, with the widest knots: under noise the neighbour-by-neighbour
    # steps add up like a random walk, and a sweep started far from the others stays there on a
    # piece of curve of its own
    fits = [_fit(table, sets, temperatures, reference, start, spacing) for spacing in spacings]
    fits.append(_fit(table, sets, temperatures, reference, np.zeros(sets.size), spacings[0]))
    problem, solution, _ = min(fits, key=lambda fit: fit[2])
    free = solution.x
    residual = problem.residual(free)
    jac = solution.jac
    parameters = free.size + 2 * (problem.knots.size - 4)
    # the weights are each set's own scatter already: only a misfit beyond it scales the errors
    variance = max(1.0, float(residual @ residual) / max(1, residual.size - parameters))
    try:
        cov_free = np.linalg.pinv(jac.T @ jac) * variance
    except np.linalg.LinAlgError:
        cov_free = np.full((free.size, free.size), np.inf)
    covariance = np.zeros((sets.size, sets.size))
    covariance[np.ix_(problem.free, problem.free)] = cov_free
    raw = problem.y - problem.fitted(free)
    shifts = problem.shifts(free)
    return ShiftFactors(
        temperature_c=temperatures, sets=sets, log10_at=shifts,
        log10_at_stderr=np.sqrt(np.clip(np.diag(covariance), 0.0, None)),
        covariance=covariance, reference=reference,
        storage_scatter=float(np.sqrt(np.mean(raw[:, 0] ** 2))),
        loss_scatter=float(np.sqrt(np.mean(raw[:, 1] ** 2))),
        residual_storage=raw[:, 0], residual_loss=raw[:, 1], point_offset=problem.offset,
    )


#: Temperature resolution: sets whose mean temperatures, in order, lie less than this apart are
#: at one temperature (repeated sweeps, strain steps); a thermocouple and a chamber's control
#: tell no finer.
TEMPERATURE_RESOLUTION_K = 0.1


def temperature_groups(temperatures: ArrayLike) -> NDArray[np.int64]:
    """Which temperature each of ``temperatures`` (°C) is at, numbered from the coldest: values
    that, in order, lie less than :data:`TEMPERATURE_RESOLUTION_K` apart are one temperature
    (grouped by the gaps between them, not rounded to a grid: 24.99 and 25.01 °C are one
    temperature however a grid falls)."""
    values = np.asarray(temperatures, dtype=float).ravel()
    order = np.argsort(values, kind="stable")
    # (a resolution's worth less its rounding: 10.1 − 10.0 is 0.0999999999999996)
    gaps = np.diff(values[order]) >= TEMPERATURE_RESOLUTION_K * (1 - 1e-9)
    groups = np.empty(values.size, dtype=np.int64)
    groups[order] = np.concatenate([[0], np.cumsum(gaps)]).astype(np.int64)
    return groups


def _temperature_slope(shifts: NDArray[np.float64],
                       temperatures: NDArray[np.float64]) -> NDArray[np.float64]:
    """``d(log10 aT)/dT`` at each set's temperature: the gradient of the shifts averaged over the
    sets at one temperature (:func:`temperature_groups`), 0 with one temperature. A gradient
    taken across two sets at the same temperature divided by zero."""
    inverse = temperature_groups(temperatures)
    if not inverse.any():
        return np.zeros(temperatures.size)
    count = np.bincount(inverse)
    mean_shift = np.bincount(inverse, weights=shifts) / count
    mean_temperature = np.bincount(inverse, weights=temperatures) / count
    return np.gradient(mean_shift, mean_temperature)[inverse]


def _fit(table: ModulusTable, sets: NDArray[np.int64], temperatures: NDArray[np.float64],
         reference: int, start: NDArray[np.float64], spacing: float) -> tuple:
    """The shifts with knots ``spacing`` decades apart: (problem, solution, BIC)."""
    problem = _Problem(table, sets, reference)
    free = start[problem.free]
    for _ in range(3):  # knots follow the span; weights follow the scatter
        problem.knots = _knots(problem.reduced(free), spacing)
        solution = least_squares(problem.residual, free, jac=problem.jacobian, method="trf",
                                 x_scale=1.0,
                                 max_nfev=40, xtol=1e-6, ftol=1e-8)
        free = solution.x
        values, leverage = problem.fitted(free, leverage=True)
        problem.weights = 1.0 / _set_scatter(problem.y - values, leverage, problem.member,
                                             free.size)
    solution = least_squares(problem.residual, free, jac=problem.jacobian, method="trf",
                             max_nfev=60, xtol=1e-8,
                             ftol=1e-10)
    deviation = table.temperature_c - temperatures[problem.member]
    if np.abs(deviation).max() > 0.01:
        # points measured off their set's mean temperature (a specimen warming during a sweep):
        # each is moved by the local slope d(log10 aT)/dT of the shifts found, then refitted
        slope = _temperature_slope(problem.shifts(solution.x), temperatures)
        problem.offset = slope[problem.member] * deviation
        solution = least_squares(problem.residual, solution.x, jac=problem.jacobian,
                                 method="trf", max_nfev=60,
                                 xtol=1e-8, ftol=1e-10)
    # Gaussian likelihood with each set's own variance (the weights), so that fits with
    # different knots compare whatever scatter each leaves
    residual = solution.fun
    assert problem.knots is not None
    parameters = solution.x.size + 2 * (problem.knots.size - 4)
    bic = float(residual @ residual - 2.0 * np.log(problem.weights).sum()
                + parameters * np.log(residual.size))
    return problem, solution, bic
