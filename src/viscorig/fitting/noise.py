"""The noise floor: the ``rms_error`` a perfect model would reach, estimated from the data alone.

Method (local roughness of the FRF). A perfect model leaves the residual
``H_model/H_measured − 1 ≈ −ε``, where ``ε`` is the relative measurement error of each point.
Write ``L_i = log H_i`` (complex log, so relative errors become additive and a resonance's large
dynamic range does not matter). ``L`` is smooth on the scale of the frequency step (a resonance
half-power width of a few Hz spans many 0.25 Hz steps), so the fourth finite difference

    Δ⁴L_i = L_{i−2} − 4 L_{i−1} + 6 L_i − 4 L_{i+1} + L_{i+2}

removes the smooth part (a cubic exactly; the remaining bias scales as ``(Δf/B)⁴``) and keeps
``70 σ_i²`` of independent noise (1 + 16 + 36 + 16 + 1). The differences are of ratios
``log(H_{i+1}/H_i)``, so no phase unwrapping is needed.

The noise power changes along the band (with constant acceleration the forces, and so their
relative noise, change by orders of magnitude, and sharply near a resonance where the driving
force dips), so ``σ_i²`` is estimated locally: the running mean, over 21 points, of
``log(|Δ⁴L_i|²/70)``. Working on the log makes the estimate
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

import numpy as np
from numpy.typing import NDArray

_FOURTH_DIFFERENCE_GAIN = 70.0


def local_noise_power(frf: NDArray[np.complex128], window: int = 21) -> NDArray[np.float64]:
    """Estimated ``E|ε_i|²`` at each point of one FRF (relative error power).

    Parameters
    ----------
    frf
        Complex FRF, points in frequency order, at least 8 of them.
    window
        Points of the running mean of ``log |Δ⁴ log H|²`` (odd; shrinks at the band's edges).
    """
    frf = np.asarray(frf, dtype=complex)
    if frf.size < 8:
        raise ValueError("the noise estimate needs at least 8 points")
    steps = np.log(frf[1:] / frf[:-1])  # first difference of log H, no unwrapping needed
    fourth = np.diff(steps, n=3)  # Δ⁴ log H, centred on points 2..n-3
    log_power = np.log(np.abs(fourth) ** 2 / _FOURTH_DIFFERENCE_GAIN + 1e-300)
    log_power = np.concatenate([np.full(2, log_power[0]), log_power, np.full(2, log_power[-1])])
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
