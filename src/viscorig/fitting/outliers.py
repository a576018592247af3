"""Outlier points of an FRF: glitches of one to three points far outside the noise.

On the dynamic stiffness ``Z = −ω²/H`` (smooth where ``H`` is not, see
:mod:`~viscorig.fitting.noise_estimation`), the polynomial of degree 5 through the
:data:`NEIGHBOURS` points on each side of a point predicts it; the centred sixth difference is
its departure from that prediction times the centre weight 20. Its power over its expectation
(``|d|²`` of noise is exponential: :data:`OUTLIER_LEVEL` is a chance of ``e^{−30}``), read
against its local level (the running median over a window, over ``ln 2``, at least 1, so that
roughness the white part does not hold, a drift's, does not make ordinary points stand out),
flags a point where it is also larger than on both neighbours: a feature several points wide
(a mode) does not stand out from its neighbours.

A glitch of two points hides itself from that test: each point's difference holds its twin's
error with weight 15 against its own 20, and the pair shows on its two outer neighbours instead
(weights 15 and 6), which the test flags in its place; two glitches a point apart show on the
good point between them, or on the points just outside them. So each cluster of flagged points
(within ``2 SHIFT`` of each other) is explained anew: the fewest points near it that, left out,
leave its window on one polynomial within the noise are taken in its place. Where no such
choice exists (a sharp mode, or more glitches than :data:`GLITCH_POINTS`), the flagged points
stand.

The band's end points have no centred difference; the next two are reached through their
neighbours' (weights 6 and 15 against a centre's 20), the end point is not (weight 1). A glitch
there is found on the end's window as a whole: the window is far off one polynomial, and
leaving out the end point brings it back within the noise.
"""

from __future__ import annotations

import itertools
import math

import numpy as np
from numpy.typing import NDArray
from scipy.ndimage import median_filter

#: Points on each side a point is predicted from (a polynomial of degree ``2·NEIGHBOURS − 1``).
NEIGHBOURS = 3
#: Most points taken for a cluster of flagged points (side by side, or a point apart); a cluster
#: of more flagged points keeps them. (A mode narrower than the sweep's step looks the same: no
#: sweep resolves it, and the diagnosis does not fit one.)
GLITCH_POINTS = 3
#: Points either side of a cluster where the points that explain it are looked for.
SHIFT = 2
#: ... and where they are looked for again when none within :data:`SHIFT` does: two glitches
#: three points apart make one peak of the one-point test between them, which may be a
#: point from either.
WIDE_SHIFT = NEIGHBOURS + 1
#: A point whose centred sixth difference is this many times its expectation is an outlier.
OUTLIER_LEVEL = 30.0
#: Largest ``−log P`` of the deviance a window keeps without its glitch (a chance of 1 in
#: 10,000 that a glitch is taken for a feature).
SMOOTH_LEVEL = 9.2
#: Or, on a feature's flank, the largest share of the window's deviance a glitch leaves.
SMOOTH_SHARE = 0.01
#: Points next to each end of the band on which the end point is judged.
END_POINTS = 4 * NEIGHBOURS
#: ``−log P`` of the end window's deviance above which the end point is a glitch. Two ends are
#: tested, not every point, so a lower level than :data:`OUTLIER_LEVEL` keeps false alarms as
#: rare (``2 e^−20`` a band): beside a glitch on the next point, where the polynomial reaches
#: over the gap and follows the end point part of the way, 89 % of pairs are found (80 % at 30),
#: and no lone end point is taken beside a mode near the end.
END_LEVEL = 20.0


def running_median(values: NDArray[np.float64], window: int) -> NDArray[np.float64]:
    """Median over ``window`` points centred on each point (the band's ends mirrored)."""
    size = min(window, values.size)
    return median_filter(values, size=size | 1, mode="mirror")


def _weights(run: NDArray[np.int_], sides: NDArray[np.int_]) -> NDArray[np.float64]:
    """Lagrange weights (run × sides) of the polynomial through the sides' positions, at the
    run's positions."""
    x, t = sides.astype(float), run.astype(float)
    apart = x[:, None] - x[None, :]
    np.fill_diagonal(apart, 1.0)
    to = t[:, None] - x[None, :]
    return np.prod(to, axis=1)[:, None] / to / np.prod(apart, axis=1)[None, :]


def _tail(t: NDArray[np.float64], k: int) -> NDArray[np.float64]:
    """``−log P(T > t)`` for ``T`` a sum of ``k`` unit exponentials."""
    t = np.maximum(t, 0.0)
    series = sum(t**j / math.factorial(j) for j in range(k))
    return t - np.log(series)


def _departure(z: NDArray[np.complex128], v: NDArray[np.float64], run: NDArray[np.int_],
               sides: NDArray[np.int_]) -> tuple[NDArray, NDArray, NDArray]:
    """For runs of points (rows of ``run``) and their sides (rows of ``sides``, in the same
    relative layout for every row): the departure ``r`` from the sides' polynomial, the sides'
    part of its covariance, and its covariance ``C``."""
    a = _weights(run[0] - run[0, 0], sides[0] - run[0, 0])
    r = z[run] - np.einsum("sj,kj->sk", z[sides], a)
    from_sides = np.einsum("kj,sj,lj->skl", a, v[sides], a)
    covariance = from_sides + v[run][:, :, None] * np.eye(run.shape[1])[None]
    return r, from_sides, covariance


def _sides(start: int, k: int, taken: NDArray[np.bool_]) -> NDArray[np.int_] | None:
    """The :data:`NEIGHBOURS` nearest points not taken on each side of a run; ``None`` where a
    side has fewer."""
    left = np.flatnonzero(~taken[:start])[-NEIGHBOURS:]
    right = start + k + np.flatnonzero(~taken[start + k:])[:NEIGHBOURS]
    if left.size < NEIGHBOURS or right.size < NEIGHBOURS:
        return None
    return np.concatenate([left, right])


def _one_point(z: NDArray[np.complex128], v: NDArray[np.float64]) -> NDArray[np.float64]:
    """Each point's centred sixth difference, its power over its expectation (0 where the band
    leaves no side)."""
    n = z.size
    out = np.zeros(n)
    points = np.arange(NEIGHBOURS, n - NEIGHBOURS)
    if points.size == 0:
        return out
    sides = np.concatenate([np.arange(-NEIGHBOURS, 0), np.arange(1, 1 + NEIGHBOURS)])
    r, _, covariance = _departure(z, v, points[:, None], points[:, None] + sides)
    with np.errstate(all="ignore"):
        out[points] = (r[:, 0].real ** 2 + r[:, 0].imag ** 2) / covariance[:, 0, 0]
    return out


def outlier_points(z: NDArray[np.complex128], white: NDArray[np.float64],
                   window: int) -> NDArray[np.bool_]:
    """Points of glitches far outside the noise (see the module text); ``z`` the dynamic
    stiffness in frequency order, ``white`` each point's white power, ``window`` the points of
    the local level's running median."""
    n = z.size
    flagged = np.zeros(n, dtype=bool)
    if n < 2 * NEIGHBOURS + 1:
        return flagged
    with np.errstate(all="ignore"):  # a value no measurement gives is no outlier's evidence
        v = (z.real**2 + z.imag**2) * white
        raw = _one_point(z, v)
        ratio = raw / np.maximum(running_median(raw, window) / math.log(2.0), 1.0)
        flagged[1:-1] = (ratio[1:-1] > ratio[:-2]) & (ratio[1:-1] > ratio[2:])
        flagged &= ratio > OUTLIER_LEVEL
        out = flagged.copy()
        for cluster in _clusters(np.flatnonzero(flagged)):
            points = _glitch(z, v, cluster, flagged)
            if points is None:
                points = _glitch(z, v, cluster, flagged, WIDE_SHIFT)
            if points is not None:
                out[cluster] = False
                out[points] = True
        for end in (np.arange(n), np.arange(n)[::-1]):
            scale = _end_level(raw[end], out[end], window)
            if _end_glitch(z[end], v[end], out[end], scale):
                out[end[0]] = True
    return out


def _end_level(ratio: NDArray[np.float64], out: NDArray[np.bool_], window: int) -> float:
    """The local level at the band's start (as the one-point test's, over ``window`` points)
    from the points no glitch reaches: a point's difference holds its neighbours' errors, and
    glitches close together near the end made the running median there theirs (10⁷ on a band
    with five glitches among its first 22 points)."""
    reached = np.convolve(out.astype(float), np.ones(2 * NEIGHBOURS + 1), mode="same") > 0
    reached[:2 * NEIGHBOURS] = True  # the end point's own reach, and the points without one
    clean = np.flatnonzero(~reached)[:window]
    if clean.size < 2 * NEIGHBOURS:
        return 1.0
    return max(float(np.median(ratio[clean])) / math.log(2.0), 1.0)


def _end_glitch(z: NDArray[np.complex128], v: NDArray[np.float64], out: NDArray[np.bool_],
                scale: float) -> bool:
    """The band's end point is a glitch, which no centred difference reaches (one there
    weighs it by 1 against a centre's 20): with the next :data:`END_POINTS` points not taken
    (``out``), it is not on one polynomial of degree ``2·NEIGHBOURS − 1`` (``−log P`` of their
    deviance, over the local level ``scale``, above :data:`END_LEVEL`), and they are without
    it (below :data:`SMOOTH_LEVEL`)."""
    if out[0]:
        return False
    window = np.flatnonzero(~out)[:END_POINTS + 1]
    if window.size <= END_POINTS:
        return False
    whole = _deviance(z, v, window) / scale
    rest = _deviance(z, v, window[1:]) / scale
    return bool(_tail(np.array([whole]), window.size - 2 * NEIGHBOURS)[0] > END_LEVEL
                and _tail(np.array([rest]), END_POINTS - 2 * NEIGHBOURS)[0] < SMOOTH_LEVEL)


def _clusters(points: NDArray[np.int_]) -> list[list[int]]:
    """Points grouped where they are within ``2 SHIFT`` of each other: the two points a pair of
    glitches a point apart shows on are four apart."""
    clusters: list[list[int]] = []
    for point in points.tolist():
        if clusters and point - clusters[-1][-1] <= 2 * SHIFT:
            clusters[-1].append(point)
        else:
            clusters.append([point])
    return clusters


def _glitch(z: NDArray[np.complex128], v: NDArray[np.float64], cluster: list[int],
            flagged: NDArray[np.bool_], shift: int = SHIFT) -> list[int] | None:
    """The points that explain a cluster of flagged points: the fewest (up to
    :data:`GLITCH_POINTS`) within ``shift`` points of it (or of the band's end, where the
    end is within ``NEIGHBOURS`` of them) that, left out, leave the window
    (the candidates' span and ``NEIGHBOURS + 1`` points each side not flagged elsewhere)
    smooth: the rest on one polynomial of degree ``2·NEIGHBOURS − 1`` within the noise
    (``−log P`` of its deviance below :data:`SMOOTH_LEVEL`), or, on a feature's flank, with
    less than :data:`SMOOTH_SHARE` of the window's deviance left. ``None`` where none does
    (a feature, or more glitches than that): the flagged points stand."""
    if len(cluster) > GLITCH_POINTS:
        return None
    n = z.size
    low, high = max(cluster[0] - shift, 0), min(cluster[-1] + shift, n - 1)
    # within a difference's reach of an end, the glitch may sit on the points it cannot centre
    low = 0 if low <= NEIGHBOURS else low
    high = n - 1 if high >= n - 1 - NEIGHBOURS else high
    candidates = list(range(low, high + 1))
    elsewhere = flagged.copy()
    elsewhere[low:high + 1] = True
    left = np.flatnonzero(~elsewhere[:low])[-(NEIGHBOURS + 1):]
    right = high + 1 + np.flatnonzero(~elsewhere[high + 1:])[:NEIGHBOURS + 1]
    window = np.concatenate([left, candidates, right]).astype(int)
    whole = _deviance(z, v, window)
    at = {point: i for i, point in enumerate(window.tolist())}
    for size in range(1, GLITCH_POINTS + 1):
        if window.size - size <= 2 * NEIGHBOURS:
            break
        choices = list(itertools.combinations(candidates, size))
        left_out = np.zeros((len(choices), window.size), dtype=bool)
        for row, choice in enumerate(choices):
            left_out[row, [at[point] for point in choice]] = True
        deviance = _deviances(z, v, window, left_out)
        with np.errstate(invalid="ignore"):
            smooth = ((_tail(deviance, window.size - size - 2 * NEIGHBOURS) < SMOOTH_LEVEL)
                      | (deviance < SMOOTH_SHARE * whole))
        if smooth.any():
            return list(choices[int(np.argmin(np.where(smooth, deviance, np.inf)))])
    return None


def _deviance(z: NDArray[np.complex128], v: NDArray[np.float64], points: NDArray[np.int_]
              ) -> float:
    """Weighted residual power of the best polynomial of degree ``2·NEIGHBOURS − 1`` through
    the points."""
    return float(_deviances(z, v, points, np.zeros((1, points.size), dtype=bool))[0])


def _deviances(z: NDArray[np.complex128], v: NDArray[np.float64], points: NDArray[np.int_],
               left_out: NDArray[np.bool_]) -> NDArray[np.float64]:
    """:func:`_deviance` of ``points`` less those of each row of ``left_out`` (a mask over
    ``points``), all rows in one batched QR: a point left out weighs nothing. Infinite where a
    point kept has no finite value."""
    x = points.astype(float)
    x = (x - x.mean()) / max(np.ptp(x), 1.0)  # (the polynomials are the same in any affine x)
    with np.errstate(all="ignore"):
        weight = 1.0 / np.sqrt(v[points])
        design = np.vander(x, 2 * NEIGHBOURS) * weight[:, None]
        target = z[points] * weight
    bad = ~(np.isfinite(design).all(axis=1) & np.isfinite(target))
    keep = ~left_out
    rows = np.where(keep[:, :, None], np.where(bad[:, None], 0.0, design)[None], 0.0)
    values = np.where(keep, np.where(bad, 0.0, target)[None], 0.0)
    q, _ = np.linalg.qr(rows)
    residual = values - np.einsum("spk,sk->sp", q, np.einsum("spk,sp->sk", q, values))
    power = np.sum(residual.real**2 + residual.imag**2, axis=1)
    return np.where((keep & bad[None]).any(axis=1), np.inf, power)


def outlier_power(z: NDArray[np.complex128], white: NDArray[np.float64],
                  outliers: NDArray[np.bool_]) -> NDArray[np.float64]:
    """Each outlier point's own error power, relative as ``white`` (0 elsewhere): what its
    departure from the prediction of its run's sides holds beyond the sides' noise,
    ``(|r_j|² − (A V_sides Aᵀ)_jj) / |Z_j|²``."""
    own = np.zeros(z.size)
    if not outliers.any():
        return own
    with np.errstate(all="ignore"):
        v = (z.real**2 + z.imag**2) * white
    edges = np.flatnonzero(np.diff(np.concatenate([[0], outliers.astype(np.int8), [0]])))
    for start, stop in zip(edges[::2], edges[1::2], strict=True):
        sides = _sides(int(start), int(stop - start), outliers)
        if sides is None:
            continue
        run = np.arange(start, stop)
        with np.errstate(all="ignore"):
            r, from_sides, _ = _departure(z, v, run[None], sides[None])
            power = np.abs(r[0]) ** 2 - np.diagonal(from_sides[0])
            own[run] = power / (z[run].real ** 2 + z[run].imag ** 2)
    return own
