"""Conversions between the frequency-response forms of a rig.

The analyser measures accelerance (acceleration over force, m/s²/N), and that is what campaign
files store. Receptance (displacement over force, m/N) and dynamic stiffness (force over
displacement, N/m) are derived from it: with time dependence e^{iωt}, ``x = ẍ / (−ω²)``.
Frequencies are in Hz here, as at every interface; ω appears only inside the formulas.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

#: Frequencies a measured frequency response may hold (Hz): wide of every vibration analyser's
#: range (the 35670A's runs from 122 µHz resolution to 102.4 kHz), so that only a damaged number
#: falls outside, such as a frequency word whose exponent bits were hit (1e-309 Hz, 2e305 Hz).
FREQUENCY_RANGE_HZ = (1e-6, 1e6)


def frequency_problem(frequency_hz: ArrayLike) -> str | None:
    """What is wrong with the frequencies of a measured response (a number that is not finite
    or lies outside :data:`FREQUENCY_RANGE_HZ`), in words naming the first such point in the
    given order; ``None`` when nothing is."""
    f = np.asarray(frequency_hz, dtype=float).ravel()
    low, high = FREQUENCY_RANGE_HZ
    bad = ~((f >= low) & (f <= high))
    if not bad.any():
        return None
    index = int(np.flatnonzero(bad)[0])
    return (f"{int(bad.sum())} of {f.size} frequencies are not numbers from {low:g} to "
            f"{high:g} Hz (the first, point {index + 1}, is {f[index]:g})")


def angular_frequency(frequency_hz: ArrayLike) -> NDArray[np.float64]:
    """Angular frequency ω = 2πf in rad/s."""
    return 2.0 * np.pi * np.asarray(frequency_hz, dtype=float)


def accelerance_to_receptance(
    frequency_hz: ArrayLike, accelerance_m_per_s2_per_n: ArrayLike
) -> NDArray[np.complex128]:
    """Receptance X/F in m/N from accelerance Ẍ/F in m/s²/N."""
    omega = angular_frequency(frequency_hz)
    return np.asarray(accelerance_m_per_s2_per_n, dtype=np.complex128) / (-(omega**2))


def receptance_to_accelerance(
    frequency_hz: ArrayLike, receptance_m_per_n: ArrayLike
) -> NDArray[np.complex128]:
    """Accelerance Ẍ/F in m/s²/N from receptance X/F in m/N."""
    omega = angular_frequency(frequency_hz)
    return np.asarray(receptance_m_per_n, dtype=np.complex128) * (-(omega**2))


def accelerance_to_dynamic_stiffness(
    frequency_hz: ArrayLike, accelerance_m_per_s2_per_n: ArrayLike
) -> NDArray[np.complex128]:
    """Dynamic stiffness F/X in N/m from accelerance Ẍ/F in m/s²/N."""
    omega = angular_frequency(frequency_hz)
    accelerance = np.asarray(accelerance_m_per_s2_per_n, dtype=np.complex128)
    return np.divide(-(omega**2), accelerance, dtype=np.complex128)


def dynamic_stiffness_to_accelerance(
    frequency_hz: ArrayLike, dynamic_stiffness_n_per_m: ArrayLike
) -> NDArray[np.complex128]:
    """Accelerance Ẍ/F in m/s²/N from dynamic stiffness F/X in N/m."""
    return receptance_to_accelerance(
        frequency_hz, 1.0 / np.asarray(dynamic_stiffness_n_per_m, dtype=complex)
    )
