"""The noise floor: the ``rms_error`` a perfect model would reach, estimated from the data alone.

Method (local roughness of the FRF). A perfect model leaves the residual
``H_model/H_measured − 1 ≈ −ε``, where ``ε`` is the relative measurement error of each point.
Write ``L_i = log H_i`` (complex log, so relative errors become additive and a resonance's large
dynamic range does not matter). ``L`` is smooth on the scale of the frequency step (a resonance
half-power width of a few Hz spans many 0.25 Hz steps), so the sixth finite difference
``Δ⁶L_i`` (binomial coefficients 1, −6, 15, −20, 15, −6, 1) removes the smooth part (a quintic
exactly; the remaining bias scales as ``(Δf/B)⁶``, below 1e-5 for a 2 Hz wide resonance at
0.25 Hz steps) and keeps ``924 σ_i²`` of independent noise (``Σ c_k² = C(12, 6)``). The
differences are of ratios ``log(H_{i+1}/H_i)``, so no phase unwrapping is needed.

The noise power changes along the band (with constant acceleration the forces, and so their
relative noise, change by orders of magnitude, and sharply near a resonance where the driving
force dips), so ``σ_i²`` is estimated locally: the running mean, over 21 points, of
``log(|Δ⁶L_i|²/924)``. Working on the log makes the estimate
insensitive to isolated features that are *model* error and not noise (a fixture resonance a few
points wide, a single bad point) and gives every point equal say; ``|d|²`` of complex Gaussian
noise is exponential, and ``E[log X] = log E[X] − γ`` (Euler's γ), so ``γ`` is added back. The
floor is ``sqrt(mean σ_i²)`` over all points of all FRFs fitted, the same pooling as
``rms_error``.

Assumption, stated: neighbouring points have independent errors. The analyser's normalized
variance (``variance_table``, ``variance_support``) measures scatter within one point's
integration only, and misses point-to-point scatter (level control, drift), which a model sees;
that is why the floor is estimated from the FRF itself.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray

#: Order of the finite difference and its noise gain Σ c_k² = C(2·order, order).
_ORDER = 6
_GAIN = float(math.comb(2 * _ORDER, _ORDER))


def local_noise_power(frf: NDArray[np.complex128], window: int = 21) -> NDArray[np.float64]:
    """Estimated ``E|ε_i|²`` at each point of one FRF (relative error power).

    Parameters
    ----------
    frf
        Complex FRF, points in frequency order, at least 10 of them.
    window
        Points of the running mean of ``log |Δ⁶ log H|²`` (odd; shrinks at the band's edges).
    """
    frf = np.asarray(frf, dtype=complex)
    if frf.size < 10:
        raise ValueError("the noise estimate needs at least 10 points")
    steps = np.log(frf[1:] / frf[:-1])  # first difference of log H, no unwrapping needed
    difference = np.diff(steps, n=_ORDER - 1)  # Δ⁶ log H, centred on points 3..n-4
    log_power = np.log(np.abs(difference) ** 2 / _GAIN + 1e-300)
    pad = _ORDER // 2
    log_power = np.concatenate(
        [np.full(pad, log_power[0]), log_power, np.full(pad, log_power[-1])]
    )
    half = min(window, frf.size) // 2
    cumulative = np.concatenate([[0.0], np.cumsum(log_power)])
    index = np.arange(frf.size)
    lo, hi = np.maximum(index - half, 0), np.minimum(index + half + 1, frf.size)
    local_mean = (cumulative[hi] - cumulative[lo]) / (hi - lo)
    # E[log X] = log E[X] - γ for an exponential X: add γ back to get the mean power.
    return np.exp(local_mean + np.euler_gamma)


def noise_floor(frfs: list[NDArray[np.complex128]], window: int = 21) -> float:
    """Noise floor of the error measure: ``sqrt(mean σ_i²)`` over every point of every FRF."""
    power = np.concatenate([local_noise_power(frf, window) for frf in frfs])
    return float(np.sqrt(np.mean(power)))
