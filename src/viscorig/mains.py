"""The mains frequencies whose hum a rig's inputs pick up (a ground loop, a cable beside a mains
lead): the noise model looks for it in the data, the bench check in the inputs' noise."""

from __future__ import annotations

#: Mains frequencies (Hz).
MAINS_HZ = (50.0, 60.0)
#: Multiples of each looked at (the fundamental and its harmonics).
MAINS_HARMONICS = 4
#: How close (Hz) a frequency must lie to a multiple to be at it: the main lobe of the
#: analyser's integration window at the paper's 100 cycles (±0.5 Hz at 50 Hz).
MAINS_TOLERANCE_HZ = 0.5


def mains_multiple(frequency_hz: float) -> float | None:
    """The multiple of a mains frequency within :data:`MAINS_TOLERANCE_HZ` of
    ``frequency_hz``, or ``None``."""
    for mains in MAINS_HZ:
        k = round(frequency_hz / mains)
        if 1 <= k <= MAINS_HARMONICS and abs(frequency_hz - k * mains) <= MAINS_TOLERANCE_HZ:
            return k * mains
    return None


def mains_multiples(top_hz: float) -> list[float]:
    """Every multiple looked at up to ``top_hz``, ascending."""
    return sorted({k * mains for mains in MAINS_HZ for k in range(1, MAINS_HARMONICS + 1)
                   if k * mains <= top_hz})
