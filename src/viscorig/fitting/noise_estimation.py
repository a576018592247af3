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
   local mode a few points wide. Outlier points (heavy-tailed noise, glitches of one to three
   points) are found first (:mod:`~viscorig.fitting.outliers`), and every difference they
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
   estimate and the lag-``h`` statistics disagree on. The correlated part is kept only when it
   lowers the weighted misfit by :data:`SIGNIFICANCE` (a χ² with two degrees of freedom under
   white noise: 1 % false alarms). A first look at the shortest and the longest lag alone
   skips the whole analysis when the longest shows no excess over the shortest (two standard
   errors): most runs have no drift, and the look costs a fraction of the analysis.

Irregular grids. Where the file has the analyser's variance, the differences are trusted to scale
it only on a linear sweep's grid (:func:`regular_grid`): a plan's points (a sparse look, clusters
where the information is, repeats at one frequency) leave the FRF's own shape in every difference.
There, the analyser's normalized variance is each point's white noise power as measured, taken at
face value (source ``"analyser variance"``, no correlated part: none can be read from such a grid);
a scatter beyond it still shows in a fit's χ², which scales the fit's covariance. Without the
variance the differences are all there is (source ``"differences (irregular grid)"``): on a dense
graded grid (a logarithmic sweep) they still read the noise.

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

import hashlib
import math
import sys
import threading
from collections import OrderedDict
from collections.abc import Sequence

import numpy as np
from numpy.typing import NDArray

from viscorig.analyser import FREQUENCY_STEP_HZ
from viscorig.fitting import outliers as outlier_search
from viscorig.fitting.data import MIN_POINTS
from viscorig.fitting.noise import FrfNoise, NoiseModel
from viscorig.fitting.outliers import outlier_points, outlier_power, running_median
from viscorig.mains import MAINS_TOLERANCE_HZ, mains_multiples

#: Order of the lag-1 difference that estimates the white part (exact on a quadratic ``Z``).
WHITE_ORDER = 3
#: Order of the lag-1 difference that estimates it without the frequency (``Z`` then the inverse
#: accelerance: smooth, but no polynomial of low degree).
NO_FREQUENCY_ORDER = 6
#: Points of the running median of the white part.
WHITE_WINDOW = 41
#: Order of the differences at several lags that estimate the correlated part.
LAG_ORDER = 3
#: Lags (points) of the correlated part's differences (those with enough points are used).
LAGS = (1, 2, 4, 8, 12)
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
#: Width of the bins (in natural log) of the windows' mean steps along the axis.
_STEP_BIN = 0.05
#: Correlation lengths tried, relative to the data's mean step on the axis.
_TAU_GRID = np.geomspace(0.3, 30.0, 13)
#: Fewest points for an estimate of the correlated part.
MIN_CORRELATION_POINTS = 40
#: The analyser sets frequencies in steps of this (Hz): a linear sweep's steps differ by up to one.


def regular_grid(frequency_hz: NDArray[np.float64]) -> bool:
    """Are the points a linear sweep's grid (distinct frequencies, every step the same within
    the analyser's frequency step and 1 %), where differences of neighbours read the noise?"""
    steps = np.diff(np.sort(np.asarray(frequency_hz, dtype=float)))
    if steps.size == 0 or np.any(steps <= 0):
        return False
    typical = float(np.median(steps))
    return bool(np.all(np.abs(steps - typical) <= FREQUENCY_STEP_HZ + 0.01 * typical))


def _binomial(order: int) -> NDArray[np.float64]:
    return np.array([(-1) ** k * math.comb(order, k) for k in range(order + 1)], dtype=float)


def _lagged(values: NDArray, weights: NDArray[np.float64], lag: int) -> NDArray:
    """``Σ_k weights[k] · values[i + k·lag]`` for every window (slices, no gathering)."""
    order = weights.size - 1
    n = values.size - order * lag
    total = weights[0] * values[:n]
    for k in range(1, order + 1):
        total = total + weights[k] * values[k * lag : k * lag + n]
    return total


def _centred(values: NDArray[np.float64], size: int, order: int) -> NDArray[np.float64]:
    """Values of the lag-1 differences put on the point at each window's centre."""
    pad = order // 2
    return np.concatenate(
        [np.full(pad, values[0]), values, np.full(size - values.size - pad, values[-1])]
    )


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
    order = WHITE_ORDER if frequency_known else NO_FREQUENCY_ORDER
    weights = _binomial(order)
    modulus2 = z.real**2 + z.imag**2
    d = _lagged(z, weights, 1)
    difference = d.real**2 + d.imag**2
    clean = np.ones(difference.size, dtype=bool)
    if skip is not None:
        clean = _lagged(skip.astype(float), np.ones(order + 1), 1) == 0
    if not np.any(clean):
        clean[:] = True
    if variance is not None:
        expected = _lagged(modulus2 * variance, weights**2, 1)
        ratio = (difference / expected)[clean]
        kept = ratio < REJECT * np.median(ratio) / math.log(2.0)
        kappa = float(np.mean(ratio[kept])) / _EXP_TRUNCATED_MEAN
        return variance * kappa, "analyser variance"
    local = _centred(difference / _lagged(modulus2, weights**2, 1), z.size, order)
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
    taus = _TAU_GRID * mean_step
    taus = taus[taus <= resolution]
    modulus2 = z.real**2 + z.imag**2
    noise2 = modulus2 * white
    # A first look at the shortest and the longest lag: white noise shows the same mean there
    # (within 2 standard errors, a loose screen: the full test below decides).
    first_look = _lag_statistics(z, noise2, axis, skip, [lags[0], lags[-1]])
    stats, lag_of, clean = first_look[0], first_look[3], first_look[4]
    drift = False
    for values in stats:
        kept = (values < REJECT) & clean
        count = np.maximum(np.bincount(lag_of[kept], minlength=2), 1)
        means = np.bincount(lag_of[kept], values[kept], 2) / count
        drift |= bool(means[1] - means[0] > 2.0 * np.sqrt(_MEAN_VARIANCE * np.sum(1.0 / count)))
    if not drift:
        return (0.0, 0.0), float(taus[-1]), resolution
    # The lags in between, stacked after the first two (their order does not matter below).
    rest = _lag_statistics(z, noise2, axis, skip, lags[1:-1])
    lags = [lags[0], lags[-1], *lags[1:-1]]
    stats, step, expected, _, clean, modulus_centre2 = (
        np.concatenate([a, b], axis=-1) for a, b in zip(first_look, rest, strict=True)
    )
    lag_of = np.concatenate([first_look[3], rest[3] + 2])
    sizes = [n - LAG_ORDER * h for h in lags]
    step = np.maximum(step / LAG_ORDER, 1e-12)
    level = np.floor(np.log(step) / _STEP_BIN).astype(np.intp)
    lowest = int(level.min())
    step_of = level - lowest
    bins = int(step_of.max()) + 1
    cell = step_of * len(lags) + lag_of  # (step, lag) cell of each window
    scale = modulus_centre2 / expected  # the gain is kernel(φ) times this
    bin_steps = np.exp((lowest + 0.5 + np.arange(bins)) * _STEP_BIN)
    kernel = _kernel(np.exp(-bin_steps[None, :] / taus[:, None]))  # (τ, step)
    weight = np.array(sizes, dtype=float) / _MEAN_VARIANCE  # 1 / variance of each lag's mean

    def pooled(values, expectation):
        """Per τ: the fit of the lags' robust means, and the white-only misfit."""
        kept = (values < REJECT * expectation) & clean
        count = np.maximum(np.bincount(lag_of[kept], minlength=len(lags)), 1)
        means = np.bincount(lag_of[kept], values[kept], len(lags)) / count
        means /= _CHI2_1_TRUNCATED_MEAN
        summed = np.bincount(cell[kept], scale[kept], bins * len(lags)).reshape(bins, -1)
        g = kernel @ summed / count[None, :]  # (τ, lags): mean gain of the kept windows
        a, sigma2, score = _linear_fit(means, g, weight)
        flat = means - (weight @ means) / weight.sum()
        return a, sigma2, score, float(weight @ flat**2)

    first = [pooled(stats[part], 1.0) for part in range(2)]
    total = first[0][2] + first[1][2]
    choice = int(np.argmin(total))
    if first[0][3] + first[1][3] - total[choice] < SIGNIFICANCE:
        return (0.0, 0.0), float(taus[choice]), resolution
    # Redo the robust cut against the expectation of the first fit (a strong drift makes
    # large-lag statistics legitimately large), then choose τ again.
    second = []
    for part in range(2):
        a, sigma2, score, _ = first[part]
        best = int(np.argmin(score))
        if sigma2[best] <= 0.0:  # no drift on this part: the first cut stands
            second.append(first[part])
            continue
        expectation = a[best] + sigma2[best] * kernel[best, step_of] * scale
        second.append(pooled(stats[part], expectation))
    total = second[0][2] + second[1][2]
    choice = int(np.argmin(total))
    found = (float(second[0][1][choice]), float(second[1][1][choice]))
    return found, float(taus[choice]), resolution


def _lag_statistics(
    z: NDArray[np.complex128],
    noise2: NDArray[np.float64],
    axis: NDArray[np.float64],
    skip: NDArray[np.bool_],
    lags: list[int],
) -> tuple[NDArray, NDArray, NDArray, NDArray, NDArray | bool, NDArray]:
    """For every window of every lag (stacked): the two parts' statistics ``s`` (real and
    imaginary projections of the third difference over their white expectation), the window's
    span along the axis, its white expectation, its lag (position in ``lags``), whether it
    holds no outlier, and ``|Z|²`` at its centre."""
    n = z.size
    weights = _binomial(LAG_ORDER)
    bad = skip.astype(float) if np.any(skip) else None
    parts: dict[str, list] = {"d": [], "centre": [], "expected": [], "clean": [], "step": []}
    for h in lags:
        size = n - LAG_ORDER * h
        parts["d"].append(_lagged(z, weights, h))
        parts["centre"].append(0.5 * (z[h : h + size] + z[2 * h : 2 * h + size]))
        parts["expected"].append(_lagged(noise2, weights**2, h) / 2.0)
        if bad is not None:
            parts["clean"].append(_lagged(bad, np.ones(LAG_ORDER + 1), h) == 0)
        parts["step"].append(np.abs(axis[LAG_ORDER * h :] - axis[:size]))
    d, centre, expected, step = (np.concatenate(parts[key]) for key in
                                 ("d", "centre", "expected", "step"))
    clean = np.concatenate(parts["clean"]) if bad is not None else np.ones(d.size, dtype=bool)
    lag_of = np.repeat(np.arange(len(lags)), [n - LAG_ORDER * h for h in lags])
    modulus_centre2 = centre.real**2 + centre.imag**2
    rotated = d * centre.conj() / np.sqrt(np.maximum(modulus_centre2, 1e-300))
    stats = np.stack([rotated.real**2, rotated.imag**2]) / expected  # (part, window)
    return stats, step, expected, lag_of, clean, modulus_centre2


def _kernel(phi: NDArray[np.float64]) -> NDArray[np.float64]:
    """``Σ_jk b_j b_k φ^|j−k|`` for the weights ``1, −3, 3, −1``."""
    c = _LAG_AUTOCOVARIANCE
    return c[0] + phi * (c[1] + phi * (c[2] + phi * c[3]))


def _linear_fit(
    means: NDArray[np.float64], g: NDArray[np.float64], weight: NDArray[np.float64]
) -> tuple[NDArray, NDArray, NDArray]:
    """For every ``τ`` (rows of ``g``): ``means ≈ a + σ² g`` by weighted least squares with
    ``σ² ≥ 0``; returns ``a, σ², weighted misfit``."""
    sw, sy = weight.sum(), weight @ means
    sg, sgg, sgy = g @ weight, (g * g) @ weight, g @ (weight * means)
    det = sw * sgg - sg**2
    safe = np.where(det > 0, det, 1.0)
    sigma2 = np.where(det > 0, np.maximum((sw * sgy - sg * sy) / safe, 0.0), 0.0)
    a = (sy - sigma2 * sg) / sw
    residual = means[None, :] - a[:, None] - sigma2[:, None] * g
    return a, sigma2, (residual**2) @ weight


#: Noise estimates kept, by the points they were made from: a report estimates a run's noise for
#: its residual figures, for its fits and for its diagnosis, from the same points. (An estimate
#: whose drift runs along an axis out of the points' order is not kept: the dense Cholesky
#: factors its whitening builds would stay with it, n² numbers a part.)
KEPT_ESTIMATES = 256
_estimates: OrderedDict[bytes, FrfNoise] = OrderedDict()
_estimates_lock = threading.Lock()


def forget_estimates() -> None:
    """Drop the noise estimates kept (:func:`estimate_frf_noise`): the next of each is made
    again, as in a new process (a benchmark timing a command)."""
    with _estimates_lock:
        _estimates.clear()


def _settings() -> str:
    """The constants of this module and of the outlier search as they stand: one changed at
    run time (by a study, or a test) makes a new estimate."""
    return repr([(name, value.tobytes() if isinstance(value, np.ndarray) else value)
                 for module in (sys.modules[__name__], outlier_search)
                 for name, value in sorted(vars(module).items())
                 if name.lstrip("_").isupper() and name != "KEPT_ESTIMATES"
                 and isinstance(value, int | float | tuple | np.ndarray)])


def _fingerprint(*parts: object) -> bytes:
    digest = hashlib.blake2b(digest_size=20)
    for part in parts:
        if part is None or isinstance(part, (str, int, bool)):
            digest.update(repr(part).encode())
        else:
            array = np.ascontiguousarray(part)
            digest.update(f"{array.dtype.str}{array.shape}".encode())
            digest.update(array.tobytes())
    return digest.digest()


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

    The same points give the same model, made once: the last :data:`KEPT_ESTIMATES` are kept
    (those whose drift is whitened in O(n)), their arrays read-only, each with the constants
    of this module and of the outlier search it was made with.

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
    key = _fingerprint(np.asarray(frf, dtype=complex), frequency_hz, time_s, variance, name,
                       window, correlated, _settings())
    with _estimates_lock:
        kept = _estimates.get(key)
        if kept is not None:
            _estimates.move_to_end(key)
            return kept
    noise = _estimated(frf, frequency_hz, time_s, variance, name, window, correlated)
    if noise.dense:
        return noise
    for array in (noise.white_power, noise.axis, noise.outliers):
        if array is not None:
            array.flags.writeable = False
    with _estimates_lock:
        _estimates[key] = noise
        while len(_estimates) > KEPT_ESTIMATES:
            _estimates.popitem(last=False)
    return noise


def _estimated(frf: NDArray[np.complex128], frequency_hz: NDArray[np.float64] | None,
               time_s: NDArray[np.float64] | None, variance: NDArray[np.float64] | None,
               name: str, window: int, correlated: bool) -> FrfNoise:
    frf = np.asarray(frf, dtype=complex)
    if frf.size < MIN_POINTS:
        raise ValueError(f"the noise estimate needs at least {MIN_POINTS} points")
    if frequency_hz is None:
        order = np.arange(frf.size)
        z = 1.0 / frf
    else:
        frequency = np.asarray(frequency_hz, dtype=float)
        steps = np.diff(frequency)
        order = (np.arange(frf.size) if np.all(steps > 0)
                 else np.argsort(frequency, kind="stable"))
        omega = 2 * np.pi * frequency[order]
        z = -(omega**2) / frf[order]
    var = None
    if variance is not None:
        var = np.asarray(variance, dtype=float)[order]
        if not np.all(np.isfinite(var) & (var > 0)):
            var = None
    known = frequency_hz is not None
    irregular = frequency_hz is not None and not regular_grid(frequency_hz)
    if irregular and var is not None:
        white = np.empty_like(var)
        white[order] = var
        axis, unit = np.arange(frf.size, dtype=float), "point"
        if time_s is not None and np.all(np.isfinite(time_s)):
            axis, unit = np.asarray(time_s, dtype=float), "s"
        return FrfNoise(name, white, axis=axis, axis_unit=unit, source="analyser variance",
                        outliers=np.zeros(frf.size, dtype=bool))
    white_sorted, source = white_power(z, var, window, None, known)
    skip = outlier_points(z, white_sorted, WHITE_WINDOW)
    if np.any(skip):
        white_sorted, source = white_power(z, var, window, skip, known)
    axis_unit = "point"
    axis_sorted = np.arange(frf.size, dtype=float)
    if time_s is not None:
        time = np.asarray(time_s, dtype=float)[order]
        steps = np.diff(time)
        if np.all(np.isfinite(time)) and (np.all(steps > 0) or np.all(steps < 0)
                                          or np.unique(time).size == time.size):
            axis_sorted, axis_unit = time, "s"
    powers, tau, resolution = (0.0, 0.0), 1.0, math.inf
    if correlated and frequency_hz is not None:
        powers, tau, resolution = _correlated_part(z, white_sorted, axis_sorted, skip)
        if powers[0] + powers[1] > 0:
            white_sorted = _without_leak(white_sorted, powers[0] + powers[1], tau, axis_sorted)
    interference = () if frequency_hz is None else mains_interference(
        np.asarray(frequency_hz, dtype=float)[order][~skip], white_sorted[~skip])
    if np.any(skip):
        # An outlier carries its own error: the floor a perfect model reaches includes it.
        own = outlier_power(z, white_sorted, skip)
        white_sorted = np.where(skip, np.maximum(white_sorted, own), white_sorted)
    if irregular:
        source += " (irregular grid)"
    white = np.empty_like(white_sorted)
    white[order] = white_sorted
    outliers = np.empty_like(skip)
    outliers[order] = skip
    axis = np.empty_like(axis_sorted)
    axis[order] = axis_sorted
    return FrfNoise(name, white, powers, tau, axis, axis_unit, resolution, source, outliers,
                    interference)


#: Mains interference: the white noise's peak within ``MAINS_TOLERANCE_HZ`` of a mains multiple
#: stands this many times above its median farther than :data:`MAINS_REACH_HZ` (a clean run's
#: white power peaks at most 11 times its median within 1 Hz of 50, 60, 100 or 120 Hz on the
#: paper campaign, where a table resonance is near) ...
MAINS_RATIO = 100.0
#: ... and is the largest within this distance of it.
MAINS_REACH_HZ = 5.0


def mains_interference(frequency_hz: NDArray[np.float64], white: NDArray[np.float64]
                       ) -> tuple[tuple[float, float], ...]:
    """The multiples of the mains frequency (:mod:`viscorig.mains`) where the white noise
    peaks (``(Hz, peak over median elsewhere)``): a hum picked up by an input (a ground loop, a
    cable beside a mains lead) is not locked to the source, so the points a sweep measures
    near its frequency scatter by its power through the integration window, and nowhere
    else. Outlier points (a glitch on one to three points, which carries its own error) are
    not given."""
    found = []
    for target in mains_multiples(float(np.max(frequency_hz))):
        distance = np.abs(frequency_hz - target)
        near, local = distance <= MAINS_TOLERANCE_HZ, distance < MAINS_REACH_HZ
        if not near.any() or np.count_nonzero(~local) < 2 * WHITE_WINDOW:
            continue
        peak = float(np.max(white[near]))
        base = float(np.median(white[~local]))
        if peak >= np.max(white[local]) and base > 0 and peak >= MAINS_RATIO * base:
            found.append((target, peak / base))
    return tuple(found)


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
    return NoiseModel.of(*shared_drift(noises))


def shared_drift(noises: Sequence[FrfNoise]) -> list[FrfNoise]:
    """The FRFs of one run with the drift found on any of them given to those where none was
    found (the strongest, on the same axis).

    The transducers of a run share the room and the conditioning: a slow drift of their
    sensitivity affects every FRF. It shows where an FRF's white noise is low all along the
    band (the table FRF), and hides in an FRF whose white noise varies by orders of magnitude
    (the support FRF, whose force falls with frequency): its few quiet points carry the drift,
    the many noisy ones dilute the statistic. Left out, the drift would make an FRF look far
    more precise than it is at exactly the points a noise-weighted fit leans on.
    """
    found = [n for n in noises if n.correlated and n.axis_unit == "s"]
    if not found:
        return list(noises)
    strongest = max(found, key=lambda n: sum(n.correlated_power))
    out = []
    for noise in noises:
        if noise.correlated or noise.axis_unit != strongest.axis_unit:
            out.append(noise)
            continue
        out.append(FrfNoise(noise.frf, noise.white_power, strongest.correlated_power,
                            strongest.correlation_length, noise.axis, noise.axis_unit,
                            noise.resolution, noise.source, noise.outliers,
                            noise.interference))
    return out


def local_noise_power(
    frf: NDArray[np.complex128],
    window: int = 31,
    frequency_hz: NDArray[np.float64] | None = None,
    time_s: NDArray[np.float64] | None = None,
) -> NDArray[np.float64]:
    """``E|ε_i|²`` at each point of one FRF (white plus correlated), from the data alone.

    For callers that hold one FRF as an array; :func:`estimate_frf_noise` is the model
    behind it.
    """
    return estimate_frf_noise(frf, frequency_hz, time_s, window=window).power()


def noise_floor(frfs: list[NDArray[np.complex128]], window: int = 31) -> float:
    """Noise floor of the error measure: ``sqrt(mean σ_i²)`` over every point of every FRF."""
    power = np.concatenate([local_noise_power(frf, window) for frf in frfs])
    return float(np.sqrt(np.mean(power)))
