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

The local noise power ``σ_i²`` is the running median of ``|Δ⁴L|²`` over a window (default 15
points) divided by ``70 ln 2`` (``|d|²`` of complex Gaussian noise is exponential, whose median
is ``ln 2`` times its mean). The median makes the estimate blind to isolated features that are
*model* error and not noise (a fixture resonance a few points wide, a single bad point), while
the running window follows noise that changes along the band. The floor is
``sqrt(mean σ_i²)`` over all points of all FRFs fitted, the same pooling as ``rms_error``.

Assumption, stated: neighbouring points have independent errors. The analyser's normalized
variance (``variance_table``, ``variance_support``) measures scatter within one point's
integration only, and misses point-to-point scatter (level control, drift), which a model sees;
that is why the floor is estimated from the FRF itself.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray
from scipy.ndimage import median_filter

_FOURTH_DIFFERENCE_GAIN = 70.0


def local_noise_power(frf: NDArray[np.complex128], window: int = 15) -> NDArray[np.float64]:
    """Estimated ``E|ε_i|²`` at each point of one FRF (relative error power).

    Parameters
    ----------
    frf
        Complex FRF, points in frequency order, at least 5 of them.
    window
        Points of the running median.
    """
    frf = np.asarray(frf, dtype=complex)
    if frf.size < 5:
        raise ValueError("the noise estimate needs at least 5 points")
    steps = np.log(frf[1:] / frf[:-1])  # first difference of log H, no unwrapping needed
    fourth = np.diff(steps, n=3)  # Δ⁴ log H, centred on points 2..n-3
    power = np.abs(fourth) ** 2 / (_FOURTH_DIFFERENCE_GAIN * np.log(2.0))
    size = min(window, power.size)
    local = median_filter(power, size=size, mode="nearest")
    return np.concatenate([np.full(2, local[0]), local, np.full(2, local[-1])])


def noise_floor(frfs: list[NDArray[np.complex128]], window: int = 15) -> float:
    """Noise floor of the error measure: ``sqrt(mean σ_i²)`` over every point of every FRF."""
    power = np.concatenate([local_noise_power(frf, window) for frf in frfs])
    return float(np.sqrt(np.mean(power)))
