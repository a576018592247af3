"""What the analyser allows a plan to ask for, and what each point costs in rig time.

Facts from the 35670A's programming guide (swept-sine option 1D2), chapter on ``[SENSe:]``:

- ``FREQ:MAN`` (manual sweep, ``SWE:MODE MAN``) measures one chosen frequency; in swept sine a
  frequency is rounded to the next *lower* 15.625 mHz step; with four channels the range is
  31.25 mHz to 25.6 kHz, and a manual point must lie within ``FREQ:STAR`` .. ``FREQ:STOP``.
- ``SWE:STIM`` (settle, the wait after each frequency change) takes 0 and up, in cycles or s.
- ``SWE:DWEL`` (integration) takes 1 to 234 cycles as printed (or 250 µs to 32768 s); less than
  one cycle counts as one.
- A linear sweep holds at most 801 points (402-801 measured points display as 801).

A point's rig time is, on the simulated rig and as far as the manual tells on the real one,
``passes × (settle + integrate) / f + overhead``: with auto level on, every controller pass
settles and integrates again, and a pass is repeated when the reference is out of tolerance
(one extra pass after a large change of the source level). ``overhead`` is what the instrument
and the bus add per point (range changes, reading the result); it is 0 on the simulated rig and
is calibrated from measured point times on a real one (:meth:`PointTiming.calibrated`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np
from numpy.typing import ArrayLike, NDArray

from viscorig.analyser import (
    ANALYSER_MAX_POINTS,
    FREQUENCY_STEP_HZ,
    MAX_FREQUENCY_HZ,
    MAX_INTEGRATE_CYCLES,
    MIN_FREQUENCY_HZ,
    MIN_INTEGRATE_CYCLES,
)
from viscorig.sequences.segments import point_durations_s

__all__ = [
    "ANALYSER",
    "SIMULATED_TIMING",
    "AnalyserLimits",
    "PointTiming",
]


@dataclass(frozen=True)
class AnalyserLimits:
    """The swept-sine settings a plan may use.

    Attributes
    ----------
    frequency_step_hz
        Frequency resolution of the source (frequencies are rounded down to it).
    min_frequency_hz, max_frequency_hz
        Four-channel swept-sine range.
    min_integrate_cycles, max_integrate_cycles
        ``SWE:DWEL`` range in cycles.
    max_settle_cycles
        Largest settle a plan asks for (the instrument allows far more).
    max_points_per_sweep
        Points in one linear sweep.
    """

    frequency_step_hz: float = FREQUENCY_STEP_HZ
    min_frequency_hz: float = MIN_FREQUENCY_HZ
    max_frequency_hz: float = MAX_FREQUENCY_HZ
    min_integrate_cycles: int = MIN_INTEGRATE_CYCLES
    max_integrate_cycles: int = MAX_INTEGRATE_CYCLES
    max_settle_cycles: int = 10000
    max_points_per_sweep: int = ANALYSER_MAX_POINTS

    def round_down(self, frequency_hz: ArrayLike) -> NDArray[np.float64]:
        """Frequencies as the analyser sets them: the next lower step (a step itself stays)."""
        f = np.asarray(frequency_hz, dtype=float)
        steps = np.floor(f / self.frequency_step_hz + 1e-9)
        return steps * self.frequency_step_hz

    def grid(self, band_hz: tuple[float, float], resolution_hz: float | None = None) -> NDArray:
        """Frequencies the analyser can set within ``band_hz``, ``resolution_hz`` apart.

        ``resolution_hz`` is rounded to a whole number of steps (at least one); the grid starts
        at the band's lower edge rounded *up* to a step, so that it stays inside the band.
        """
        lo, hi = band_hz
        step = self.frequency_step_hz
        stride = 1 if resolution_hz is None else max(1, round(resolution_hz / step))
        first = math.ceil(max(lo, self.min_frequency_hz) / step - 1e-9)
        last = math.floor(min(hi, self.max_frequency_hz) / step + 1e-9)
        if last < first:
            raise ValueError(f"band {lo:g}..{hi:g} Hz holds no analyser frequency")
        return np.arange(first, last + 1, stride, dtype=float) * step

    def integrate_cycles(self, cycles: ArrayLike) -> NDArray[np.int64]:
        """Whole cycles within the ``SWE:DWEL`` range."""
        c = np.ceil(np.asarray(cycles, dtype=float) - 1e-9)
        return np.clip(c, self.min_integrate_cycles, self.max_integrate_cycles).astype(np.int64)

    def settle_cycles(self, cycles: ArrayLike) -> NDArray[np.int64]:
        """Whole settle cycles within ``0 .. max_settle_cycles``."""
        c = np.ceil(np.asarray(cycles, dtype=float) - 1e-9)
        return np.clip(c, 0, self.max_settle_cycles).astype(np.int64)


#: The 35670A with its four-channel and swept-sine options.
ANALYSER = AnalyserLimits()


@dataclass(frozen=True)
class PointTiming:
    """Rig time of measured points.

    Attributes
    ----------
    overhead_s
        Time the instrument adds per point beyond settle and integration.
    tolerance_db
        The auto-level tolerance (``SOUR:VOLT:REF:TOL``): the controller accepts a reference
        within it and otherwise corrects the source and measures again
        (:func:`~viscorig.planning.batch.landing_db`).
    """

    overhead_s: float = 0.0
    tolerance_db: float = 1.0

    def point_s(
        self,
        frequency_hz: ArrayLike,
        settle_cycles: ArrayLike,
        integrate_cycles: ArrayLike,
        passes: ArrayLike = 1.0,
    ) -> NDArray[np.float64]:
        """Rig time of each point, s."""
        cycles_s = point_durations_s(frequency_hz, settle_cycles, integrate_cycles)
        return np.asarray(passes, dtype=float) * cycles_s + self.overhead_s

    def calibrated(
        self,
        frequency_hz: ArrayLike,
        settle_cycles: ArrayLike,
        integrate_cycles: ArrayLike,
        measured_s: ArrayLike,
    ) -> PointTiming:
        """This timing with ``overhead_s`` set from measured point times (median excess over
        one pass of settle and integration, never negative)."""
        base = self.point_s(frequency_hz, settle_cycles, integrate_cycles) - self.overhead_s
        excess = np.asarray(measured_s, dtype=float) - base
        excess = excess[np.isfinite(excess)]
        if excess.size == 0:
            return self
        return replace(self, overhead_s=max(0.0, float(np.median(excess))))


#: Timing of the simulated rig: no overhead, one extra pass beyond a 1 dB level change.
SIMULATED_TIMING = PointTiming()
