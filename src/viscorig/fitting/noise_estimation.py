"""Estimating the noise model of an FRF from the data alone (:mod:`viscorig.fitting.noise`).

Work on the dynamic stiffness. With ``ω`` the angular frequency, ``Z = −ω²/H`` is the force per
displacement the point measured: ``Z = K_s + K* − ω² M + iω C`` on the table FRF with a rigid
link, ``K* − ω² M_v`` on the support FRF. A resonance of ``H`` is a zero crossing of ``Re Z``,
so ``Z`` is smooth where ``H`` is not (the bare table's 0.1 Hz wide resonance included), and
for a Voigt rubber it is a quadratic in ``ω``. Its relative error is that of ``H``:
``Z_measured ≈ Z (1 − ε)``, so the noise of ``Z`` is ``δZ_i = −Z_i ε_i``.

Finite differences. The m-th difference at lag ``h``, ``d_i = Σ_k b_k Z_{i+kh}`` with binomial
weights ``b_k = (−1)^k C(m, k)``, removes any polynomial of degree below ``m`` in the point
index (the grid is uniform or smoothly graded), and keeps of the noise
``E|d_i|² = Σ_k b_k² |Z_{i+kh}|² w_{i+kh} + (correlated terms)``.

1. White part, lag 1, ``m = 3``. ``e_i = |d_i|² / Σ_k b_k² |Z_{i+kh}|²`` estimates the local
   ``w`` (``Σ b_k² = C(6, 3) = 20``); the smooth part left is ``(Δω)³`` times the third
   derivative of ``Z``, far below any noise for a dynamic stiffness that is close to a
   quadratic over 4 steps. (A higher order keeps less of the smooth part but averages fewer
   independent looks at the noise: the mean of ``e_i`` is worth ``n/2.3`` independent points
   at ``m = 3``, ``n/3.2`` at ``m = 6``.) ``|d|²`` of complex Gaussian noise is exponential,
   whose median is ``ln 2`` times its mean: the running median of ``e_i`` over
   :data:`WHITE_WINDOW` points, divided by ``ln 2``, is the local ``w_i``. The median ignores a
   local mode a few points wide. Outlier points (heavy-tailed noise) are found first, by the
   sixth difference centred on each point (:func:`outlier_points`), and every difference they
   enter is left out of every statistic: they neither inflate nor collapse the estimate.
   Where the file has the analyser's normalized variance ``v_i`` (the sum of both channels'),
   it gives the shape along the band, point by point, and the differences its scale:
   ``w_i = κ v_i`` with ``κ`` the robust mean of ``|d_i|² / Σ b_k² |Z|² v`` (``κ ≈ 1``
   when the variance tells the whole truth; above 1 when the points scatter more than each
   point's integration shows).

2. Correlated part, lags ``h`` of :data:`LAGS`, ``m = 3`` (exact on the quadratic ``Z`` of a
   Voigt rig). A drift that is slow on the scale of one step cancels in a lag-1 difference; at
   the lag of its correlation length it shows in full. Project ``d_i`` on the phase of ``Z`` at
   the window's centre: its real part carries the magnitude error ``Re ε``, its imaginary part
   the phase error ``Im ε``. For each part, ``s_i(h) = (proj d_i)² / W_i(h)`` with
   ``W_i(h) = Σ b_k² |Z|² w / 2`` the white expectation; it is ``χ²₁``-distributed with mean
   ``a + σ² g_i(h; τ)``, where, with ``φ = e^{−Δt/τ}`` for the window's mean step ``Δt``,
   ``g_i = |Z_c|² (20 − 30φ + 12φ² − 2φ³) / W_i`` (the autocovariances of the binomial weights
   ``1, −3, 3, −1`` against the Gauss-Markov correlation). For each ``τ`` of a grid spanning the
   lags' time scales, the pooled means over the points (after dropping those above 9 times their
   expectation, a robust cut that removes outliers and local modes and is corrected for, the
   mean of ``χ²₁`` below 9 being 0.973) are fitted by weighted least squares, ``a`` and ``σ²``
   being linear unknowns; the ``τ`` of least misfit wins. ``a`` absorbs what the lag-1 white
   estimate and the lag-``h`` statistics disagree on.

What the data cannot tell. A drift slower than the longest lag looks like a smooth change of
the FRF: only its rate ``σ²/τ`` shows. Its correlation length is then set at the resolution
limit (:attr:`FrfNoise.resolution`, about twice the longest lag's time span), which keeps the
drift's variance within that span and leaves out a constant gain offset, which no single sweep
can see (a transducer's calibration uncertainty, to be given by the user). Near sharp features
(a resonance a few steps wide in ``Z``, such as a fixture mode) the large-lag differences see
the feature, not the noise; the robust cut drops them as long as they cover well under half of
the band.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from functools import lru_cache

import numpy as np
from numpy.typing import NDArray
from scipy.ndimage import median_filter

from viscorig.fitting.noise import FrfNoise, NoiseModel

#: Order of the lag-1 difference that estimates the white part (exact on a quadratic ``Z``).
WHITE_ORDER = 3
#: Order of the lag-1 difference that finds outlier points (centred on the point).
OUTLIER_ORDER = 6
#: Points of the running median of the white part.
WHITE_WINDOW = 41
#: A point whose centred lag-1 difference is this many times its expectation is an outlier.
OUTLIER_LEVEL = 30.0
#: Order of the differences at several lags that estimate the correlated part.
LAG_ORDER = 3
#: Lags (points) of the correlated part's differences (those with enough points are used).
LAGS = (1, 2, 3, 4, 6, 8, 12)
#: A statistic above this multiple of its expectation is left out (χ²₁: 0.27 % of pure noise).
REJECT = 9.0
#: Mean of an exponential variable below :data:`REJECT` times its mean, relative to its mean.
_EXP_TRUNCATED_MEAN = 0.9988891746764844
#: Mean of χ²₁ below :data:`REJECT`, relative to its full mean.
_CHI2_1_TRUNCATED_MEAN = 0.9733369246698526
#: Autocovariances of the weights 1, −3, 3, −1 at offsets 0..3 (doubled beyond 0).
_LAG_AUTOCOVARIANCE = np.array([20.0, -30.0, 12.0, -2.0])
#: Variance of a lag's pooled mean of χ²₁ statistics times the number of windows: ``2 (1 + 2 Σ
#: ρ_k²)``, the windows overlapping with correlations −0.75, 0.3, −0.05 at offsets 1 to 3 lags.
_MEAN_VARIANCE = 4.62
#: Least drop of the weighted misfit (a χ² with two degrees of freedom under white noise) for a
#: correlated part to be kept: 1 % false alarms.
SIGNIFICANCE = 9.2
#: Correlation lengths tried, relative to the data's mean step on the axis.
_TAU_GRID = np.geomspace(0.3, 60.0, 24)
#: Fewest points for an estimate of the correlated part.
MIN_CORRELATION_POINTS = 40


def _binomial(order: int) -> NDArray[np.float64]:
    return np.array([(-1) ** k * math.comb(order, k) for k in range(order + 1)], dtype=float)


def _combine(windows: NDArray[np.complex128], weights: NDArray[np.float64]) -> NDArray:
    """``windows @ weights`` for complex windows (numpy's mixed-type product is slow)."""
    return windows.real @ weights + 1j * (windows.imag @ weights)


@lru_cache(maxsize=64)
def _windows(size: int, order: int, lag: int) -> NDArray[np.intp]:
    """Index of every window ``i, i+h, …, i+m·h`` (rows)."""
    return np.arange(size - order * lag)[:, None] + lag * np.arange(order + 1)[None, :]


def running_median(values: NDArray[np.float64], window: int) -> NDArray[np.float64]:
    """Median over ``window`` points centred on each point (the band's ends mirrored)."""
    size = min(window, values.size)
    return median_filter(values, size=size | 1, mode="mirror")


def _centred(values: NDArray[np.float64], size: int, order: int) -> NDArray[np.float64]:
    """Values of the lag-1 differences put on the point at each window's centre."""
    pad = order // 2
    return np.concatenate(
        [np.full(pad, values[0]), values, np.full(size - values.size - pad, values[-1])]
    )


def _outlier_statistic(
    z: NDArray[np.complex128], white: NDArray[np.float64]
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Centred sixth differences: their ratio to the white expectation, and the power of the
    centre point's own error they imply, ``(|d|² − Σ_{k≠c} b_k² |Z_k|² w_k) / (b_c² |Z_c|²)``,
    both put on the centre points (zero at the ends)."""
    weights = _binomial(OUTLIER_ORDER)
    index = _windows(z.size, OUTLIER_ORDER, 1)
    window_z = z[index]
    power = np.abs(window_z) ** 2 * white[index]
    difference = np.abs(_combine(window_z, weights)) ** 2
    expected = power @ weights**2
    centre = OUTLIER_ORDER // 2
    others = expected - weights[centre] ** 2 * power[:, centre]
    own = (difference - others) / (weights[centre] ** 2 * np.abs(window_z[:, centre]) ** 2)
    ratio, own_power = np.zeros(z.size), np.zeros(z.size)
    ratio[centre : centre + index.shape[0]] = difference / expected
    own_power[centre : centre + index.shape[0]] = own
    return ratio, own_power


def outlier_points(z: NDArray[np.complex128], white: NDArray[np.float64]) -> NDArray[np.bool_]:
    """Points that stand alone far outside the noise (heavy-tailed noise, a glitch).

    The lag-1 sixth difference centred on a point weighs it by 20 and its neighbours by at most
    15: a point whose centred difference exceeds :data:`OUTLIER_LEVEL` times its expectation
    (``|d|²`` of noise is exponential: a chance of ``e^{−30}``) and exceeds those centred on
    both neighbours is an outlier. A feature several points wide (a mode) is not: its
    neighbours' differences are as large.
    """
    centred, _ = _outlier_statistic(z, white)
    peak = np.zeros(z.size, dtype=bool)
    peak[1:-1] = (centred[1:-1] > centred[:-2]) & (centred[1:-1] > centred[2:])
    return peak & (centred > OUTLIER_LEVEL)


def _difference_statistic(
    z: NDArray[np.complex128], order: int
) -> tuple[NDArray[np.intp], NDArray[np.complex128], NDArray[np.float64]]:
    """Windows of the lag-1 differences of ``order``, ``|Z|²`` in them, and ``|d|²``."""
    weights = _binomial(order)
    index = _windows(z.size, order, 1)
    window_z = z[index]
    return index, np.abs(window_z) ** 2, np.abs(_combine(window_z, weights)) ** 2


def white_power(
    z: NDArray[np.complex128],
    variance: NDArray[np.float64] | None = None,
    window: int = WHITE_WINDOW,
    skip: NDArray[np.bool_] | None = None,
    frequency_known: bool = True,
) -> tuple[NDArray[np.float64], str]:
    """Local white power ``w_i`` of ``ε`` from the dynamic stiffness ``z`` (frequency order).

    ``skip`` marks outlier points: the differences they enter are left out (replaced by the
    local median, which leaves it unchanged). Without the frequency (``z`` then the inverse
    accelerance, smooth but not a polynomial) the sixth difference is used. Returns the power
    and its source (``"differences"`` or ``"analyser variance"``).
    """
    order = WHITE_ORDER if frequency_known else OUTLIER_ORDER
    weights2 = _binomial(order) ** 2
    index, modulus2, difference = _difference_statistic(z, order)
    clean = np.ones(index.shape[0], dtype=bool) if skip is None else ~skip[index].any(axis=1)
    if not np.any(clean):
        clean[:] = True
    if variance is not None:
        expected = (modulus2 * variance[index]) @ weights2
        ratio = (difference / expected)[clean]
        kept = ratio < REJECT * np.median(ratio) / math.log(2.0)
        kappa = float(np.mean(ratio[kept])) / _EXP_TRUNCATED_MEAN
        return variance * kappa, "analyser variance"
    local = _centred(difference / (modulus2 @ weights2), z.size, order)
    median = running_median(local, window)
    if not np.all(clean):
        dirty = _centred((~clean).astype(float), z.size, order) > 0
        local = np.where(dirty, median, local)
        median = running_median(local, window)
    return median / math.log(2.0), "differences"


def _without_leak(
    white: NDArray[np.float64], power: float, tau: float, axis: NDArray[np.float64]
) -> NDArray[np.float64]:
    """The white part without what the correlated part adds to the lag-1 differences:
    ``σ² Σ_l (−1)^l C(2m, m+l) φ^|l| / C(2m, m)`` with ``φ = e^{−Δt/τ}`` for the local step
    (never below a tenth of the estimate)."""
    step = np.gradient(axis) if axis.size > 1 else np.ones_like(axis)
    phi = np.exp(-np.abs(step) / tau)
    m = WHITE_ORDER
    leak = sum((-1) ** abs(k) * math.comb(2 * m, m + k) * phi ** abs(k) for k in range(-m, m + 1))
    leak = leak / math.comb(2 * m, m)
    return np.maximum(white - power * leak, 0.1 * white)


def _correlated_part(
    z: NDArray[np.complex128],
    white: NDArray[np.float64],
    axis: NDArray[np.float64],
    skip: NDArray[np.bool_],
) -> tuple[tuple[float, float], float, float]:
    """``((σ_re², σ_im²), τ, resolution)`` of the correlated part (see the module text)."""
    n = z.size
    steps = np.abs(np.diff(axis))
    mean_step = float(np.mean(steps)) if steps.size else 1.0
    lags = [h for h in LAGS if n - LAG_ORDER * h >= MIN_CORRELATION_POINTS // 2]
    resolution = 2.0 * mean_step * (lags[-1] if lags else 1)
    if n < MIN_CORRELATION_POINTS or len(lags) < 3 or not mean_step > 0:
        return (0.0, 0.0), mean_step, resolution
    weights = _binomial(LAG_ORDER)
    taus = _TAU_GRID * mean_step
    taus = taus[taus <= resolution]
    # Every window of every lag at once, each labelled with its lag and with its mean step
    # along the axis rounded to 5 % (the correlation enters through that step alone).
    index, lag_of = _lag_windows(n, tuple(lags))
    sizes = [n - LAG_ORDER * h for h in lags]
    clean = ~skip[index].any(axis=1)
    window_z = z[index]
    centre = 0.5 * (window_z[:, 1] + window_z[:, 2])
    modulus_centre = np.abs(centre)
    rotated = _combine(window_z, weights) * centre.conj() / np.maximum(modulus_centre, 1e-300)
    expected = (np.abs(window_z) ** 2 * white[index]) @ weights**2 / 2.0
    stats = np.stack([rotated.real**2, rotated.imag**2]) / expected  # (part, window)
    step = np.maximum(np.abs(axis[index[:, -1]] - axis[index[:, 0]]) / LAG_ORDER, 1e-12)
    steps, step_of = np.unique(np.round(np.log(step) / 0.05), return_inverse=True)
    cell = step_of * len(lags) + lag_of  # (step, lag) cell of each window
    cells = steps.size * len(lags)
    scale = modulus_centre**2 / expected  # the gain is kernel(φ) times this
    kernel = _kernel(np.exp(-np.exp(steps * 0.05)[None, :] / taus[:, None]))  # (τ, step)
    weight = np.array(sizes, dtype=float) / _MEAN_VARIANCE  # 1 / variance of each lag's mean
    scores, powers, white_only = [], [], []
    for part in range(2):
        values = stats[part]
        expectation = np.ones_like(values)  # the robust cut is redone against the first fit
        for _ in range(2):
            kept = (values < REJECT * expectation) & clean
            count = np.maximum(np.bincount(lag_of[kept], minlength=len(lags)), 1)
            means = np.bincount(lag_of[kept], values[kept], len(lags)) / count
            means /= _CHI2_1_TRUNCATED_MEAN
            summed = np.bincount(cell[kept], scale[kept], cells).reshape(steps.size, -1)
            g = kernel @ summed / count[None, :]  # (τ, lags): mean gain of the kept windows
            a, sigma2, score = _linear_fit(means, g, weight)
            choice = int(np.argmin(score))
            expectation = a[choice] + sigma2[choice] * kernel[choice, step_of] * scale
        scores.append(score)
        powers.append(sigma2)
        white_only.append(float(np.sum(weight * (means - np.sum(weight * means) / np.sum(weight))
                                       ** 2)))
    total = scores[0] + scores[1]
    choice = int(np.argmin(total))
    found = [float(powers[part][choice]) for part in range(2)]
    if white_only[0] + white_only[1] - total[choice] < SIGNIFICANCE:
        found = [0.0, 0.0]
    return (found[0], found[1]), float(taus[choice]), resolution


@lru_cache(maxsize=32)
def _lag_windows(size: int, lags: tuple[int, ...]) -> tuple[NDArray[np.intp], NDArray[np.intp]]:
    """Windows of every lag, stacked, and the lag (position in ``lags``) of each."""
    index = np.concatenate([_windows(size, LAG_ORDER, h) for h in lags])
    sizes = [size - LAG_ORDER * h for h in lags]
    return index, np.repeat(np.arange(len(lags)), sizes)


def _kernel(phi: NDArray[np.float64]) -> NDArray[np.float64]:
    """``Σ_jk b_j b_k φ^|j−k|`` for the weights ``1, −3, 3, −1``."""
    c = _LAG_AUTOCOVARIANCE
    return c[0] + phi * (c[1] + phi * (c[2] + phi * c[3]))


def _linear_fit(
    means: NDArray[np.float64], g: NDArray[np.float64], weight: NDArray[np.float64]
) -> tuple[NDArray, NDArray, NDArray]:
    """For every ``τ`` (rows of ``g``): ``means ≈ a + σ² g`` by weighted least squares with
    ``σ² ≥ 0``; returns ``a, σ², weighted misfit``."""
    w = weight[None, :]
    sw, sg, sgg = np.sum(w), np.sum(w * g, axis=1), np.sum(w * g * g, axis=1)
    sy, sgy = np.sum(w * means), np.sum(w * g * means, axis=1)
    det = sw * sgg - sg**2
    with np.errstate(divide="ignore", invalid="ignore"):
        sigma2 = np.where(det > 0, (sw * sgy - sg * sy) / det, 0.0)
    sigma2 = np.maximum(np.nan_to_num(sigma2), 0.0)
    a = (sy - sigma2 * sg) / sw
    residual = means[None, :] - a[:, None] - sigma2[:, None] * g
    score = np.sum(w * residual**2, axis=1)
    return a, sigma2, score


def estimate_frf_noise(
    frf: NDArray[np.complex128],
    frequency_hz: NDArray[np.float64] | None = None,
    time_s: NDArray[np.float64] | None = None,
    variance: NDArray[np.float64] | None = None,
    *,
    name: str = "frf",
    window: int = WHITE_WINDOW,
    correlated: bool = True,
) -> FrfNoise:
    """The noise model of one FRF (see the module text).

    Parameters
    ----------
    frf
        Measured accelerance, one value per point (any point order; at least 10 points).
    frequency_hz
        Frequency of each point. Without it the points are taken as equally spaced in
        frequency order, the inverse accelerance stands in for the dynamic stiffness, and only
        the white part is estimated (the larger lags need the dynamic stiffness).
    time_s
        Test time of each point: the axis of the correlated part (default: the point index).
    variance
        The analyser's normalized variance of the FRF at each point (relative power), if known.
    name
        FRF name stored in the result.
    window
        Points of the running median of the white part.
    correlated
        Estimate the correlated part (``False``: white only).
    """
    frf = np.asarray(frf, dtype=complex)
    if frf.size < 10:
        raise ValueError("the noise estimate needs at least 10 points")
    if frequency_hz is None:
        order = np.arange(frf.size)
        z = 1.0 / frf
    else:
        frequency = np.asarray(frequency_hz, dtype=float)
        order = np.argsort(frequency, kind="stable")
        omega = 2 * np.pi * frequency[order]
        z = -(omega**2) / frf[order]
    var = None
    if variance is not None:
        var = np.asarray(variance, dtype=float)[order]
        if not np.all(np.isfinite(var) & (var > 0)):
            var = None
    known = frequency_hz is not None
    white_sorted, source = white_power(z, var, window, None, known)
    skip = outlier_points(z, white_sorted)
    if np.any(skip):
        white_sorted, source = white_power(z, var, window, skip, known)
    axis_unit = "point"
    axis_sorted = np.arange(frf.size, dtype=float)
    if time_s is not None:
        time = np.asarray(time_s, dtype=float)[order]
        if np.all(np.isfinite(time)) and np.unique(time).size == time.size:
            axis_sorted, axis_unit = time, "s"
    powers, tau, resolution = (0.0, 0.0), 1.0, math.inf
    if correlated and frequency_hz is not None:
        powers, tau, resolution = _correlated_part(z, white_sorted, axis_sorted, skip)
        if powers[0] + powers[1] > 0:
            white_sorted = _without_leak(white_sorted, powers[0] + powers[1], tau, axis_sorted)
    if np.any(skip):
        # An outlier carries its own error: the floor a perfect model reaches includes it.
        _, own = _outlier_statistic(z, white_sorted)
        white_sorted = np.where(skip, np.maximum(white_sorted, own), white_sorted)
    white = np.empty_like(white_sorted)
    white[order] = white_sorted
    outliers = np.empty_like(skip)
    outliers[order] = skip
    axis = np.empty_like(axis_sorted)
    axis[order] = axis_sorted
    return FrfNoise(name, white, powers, tau, axis, axis_unit, resolution, source, outliers)


def estimate_noise(data, frfs: Sequence[str] | None = None, *, correlated: bool = True):
    """The :class:`~viscorig.fitting.noise.NoiseModel` of a run's FRFs (an
    :class:`~viscorig.fitting.FrfData`), from its points alone (and the analyser's variance
    where the data carry it)."""
    frfs = data.available if frfs is None else tuple(frfs)
    noises = []
    for name in frfs:
        noises.append(
            estimate_frf_noise(
                data.frf(name),
                data.frequency_hz,
                data.time_s,
                data.variance(name),
                name=name,
                correlated=correlated,
            )
        )
    return NoiseModel.of(*noises)
