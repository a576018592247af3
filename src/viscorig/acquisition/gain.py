"""The amplifier-and-shaker gain, measured on the rig: the shaker's force per source volt.

An adaptive plan starts each point's auto-level controller at the source level the point needs,
the force it needs over this gain, so that the rig is steady when the plan comes back to a
frequency. A technician seldom knows the gain (the station file gives ``[shaker]
gain_n_per_v`` only "if known"); the rig does. The 35670A does not report the source level of
a point measured under auto level, so before each adaptive run the gain is measured at the
probe's frequencies (the band's edges) with the controller off and the source held at a tenth
of the run's start level (:data:`GAIN_SOURCE_V`, as safe as the probe's own start): force read
over volts sent. The value, its standard error and how it was measured are stored with the run
(:meth:`GainEstimate.attributes`); a station value is then a check, with a warning when the
two disagree by more than :data:`DISAGREE_STDERRS` standard errors.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike

from viscorig.acquisition.limits import PROBE_LEVEL_FRACTION
from viscorig.acquisition.sweep import START_LEVEL_V
from viscorig.numbers import with_uncertainty

__all__ = ["DISAGREE_STDERRS", "GAIN_SOURCE_V", "GainEstimate", "disagreement", "estimate_gain"]

#: Source level of the gain points, V peak: the probe's start level.
GAIN_SOURCE_V = START_LEVEL_V * PROBE_LEVEL_FRACTION
#: A station gain this many standard errors from the measured one is reported as disagreeing.
DISAGREE_STDERRS = 3.0


@dataclass(frozen=True)
class GainEstimate:
    """Force per source volt as measured, N/V.

    Attributes
    ----------
    value_n_per_v
        Mean of the points' force over source level.
    stderr_n_per_v
        Its standard error: the larger of the analyser's noise on the force (its normalized
        variance) and the points' scatter (a real shaker's gain varies over the band).
    frequency_hz
        Where it was measured.
    source_v
        The source level held, V peak.
    """

    value_n_per_v: float
    stderr_n_per_v: float
    frequency_hz: tuple[float, ...]
    source_v: float

    @property
    def basis(self) -> str:
        """How it was measured, in words."""
        where = " and ".join(f"{f:g}" for f in self.frequency_hz)
        return (f"measured at {where} Hz with the source held at {self.source_v:.3g} Vpk "
                "(auto level off)")

    def text(self) -> str:
        """``50.02 ± 0.03 N/V``."""
        return with_uncertainty(self.value_n_per_v, self.stderr_n_per_v, "N/V")

    def attributes(self) -> dict[str, object]:
        """The run attributes that keep it (units in the names)."""
        return {"shaker_gain_n_per_v": self.value_n_per_v,
                "shaker_gain_stderr_n_per_v": self.stderr_n_per_v,
                "shaker_gain_basis": self.basis}


def estimate_gain(frequency_hz: ArrayLike, force_n: ArrayLike, source_v: float,
                  force_variance: ArrayLike | None = None) -> GainEstimate | None:
    """The gain from points measured at a source level held at ``source_v``.

    ``force_variance`` is the analyser's normalized variance of the force channel (variance of
    the amplitude over its square; NaN or absent: unknown). Points whose force is not finite
    and positive are left out; ``None`` when none is left (no force: the amplifier is off or
    the force transducer not connected).
    """
    frequency = np.asarray(frequency_hz, dtype=float)
    force = np.asarray(force_n, dtype=float)
    usable = np.isfinite(force) & (force > 0) & np.isfinite(frequency)
    if not (math.isfinite(source_v) and source_v > 0) or not usable.any():
        return None
    gains = force[usable] / source_v
    value = float(gains.mean())
    noise = 0.0
    if force_variance is not None:
        variance = np.asarray(force_variance, dtype=float)[usable]
        known = np.isfinite(variance) & (variance >= 0)
        if known.any():
            noise = float(np.sqrt(np.sum(gains[known] ** 2 * variance[known]))) / gains.size
    scatter = float(gains.std(ddof=1) / math.sqrt(gains.size)) if gains.size > 1 else 0.0
    return GainEstimate(value, max(noise, scatter), tuple(float(f) for f in frequency[usable]),
                        float(source_v))


def disagreement(measured: GainEstimate, station_n_per_v: float | None) -> float | None:
    """How many standard errors the station's gain lies from the measured one (``None``: the
    station gives none); ``inf`` for a difference where the measurement saw no noise."""
    if station_n_per_v is None:
        return None
    difference = abs(float(station_n_per_v) - measured.value_n_per_v)
    if measured.stderr_n_per_v > 0:
        return difference / measured.stderr_n_per_v
    return 0.0 if difference == 0 else math.inf

