"""The source's ramp down (``SOUR:VOLT:SLEW``) when a swept sine stops.

With a slew rate set, the analyser does not cut the source when a swept sine ends or is aborted
(``ABOR``): it ramps it from the level it was driving down to 0 at that rate (0 V/s, the preset:
at once). The simulated analyser models this twice:

- what the source outputs in time (:meth:`SourceOutput.level_vpk`): the level of the point
  being measured while the sweep runs, then a linear fall at the slew rate, on the wall clock
  scaled by the pace (unpaced, the fall takes no wall time);
- what the rig sees, when ``ABOR`` stopped the sweep (a pause, a hold, an abort): the ramp's
  test time passes on the rig simulator, driven at the last frequency by a staircase of
  :data:`RAMP_STEPS` falling levels (:func:`ramp_requests`), so the rig's state and clock carry
  the ramp into the next sweep. At a sweep's own end the rig is not driven through the ramp:
  the simulator takes consecutive sweeps as one continuous excitation, as it always has (what
  the real analyser does between the points of a manual sweep is an open question, see
  ``docs/bench.md``).

The ramp up at the start of a sweep is not modelled: the first point's settling covers it.
That the real 35670A ramps on ``ABOR`` as at the end of a measurement is inferred
(``drivers/agilent35670a/running.py``).
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, replace

import numpy as np

from rigsim.measurement import SourceControl, SweepRequest

__all__ = ["RAMP_STEPS", "SourceOutput", "ramp_requests"]

#: Levels of the staircase that stands for the ramp on the rig simulator.
RAMP_STEPS = 8


@dataclass
class SourceOutput:
    """The source's output level in time: driving, or ramping down.

    Times are ``time.monotonic()`` seconds; rates are volts per simulated second.
    """

    driving_vpk: float = 0.0
    frequency_hz: float = 0.0
    _ramp_from_vpk: float = 0.0
    _ramp_started: float = 0.0
    _ramp_wall_s: float = 0.0

    def drive(self, level_vpk: float, frequency_hz: float) -> None:
        """The sweep drives the source at ``level_vpk`` (a ramp in progress ends)."""
        self.driving_vpk = float(level_vpk)
        self.frequency_hz = float(frequency_hz)
        self._ramp_wall_s = 0.0
        self._ramp_from_vpk = 0.0

    def stop(self, slew_v_per_s: float, pace: float | None) -> float:
        """The sweep stops: ramp from the level driven down to 0 at ``slew_v_per_s``. Returns
        the ramp's duration in simulated seconds (0 without a slew rate or a level)."""
        level, self.driving_vpk = self.driving_vpk, 0.0
        if level <= 0.0 or slew_v_per_s <= 0.0:
            self._ramp_from_vpk, self._ramp_wall_s = 0.0, 0.0
            return 0.0
        duration_s = level / slew_v_per_s
        self._ramp_from_vpk = level
        self._ramp_started = time.monotonic()
        self._ramp_wall_s = 0.0 if pace is None else duration_s / pace
        return duration_s

    def level_vpk(self, now: float | None = None) -> float:
        """The source's output level (volts peak) at ``now`` (default: now)."""
        if self.driving_vpk > 0.0:
            return self.driving_vpk
        if self._ramp_wall_s <= 0.0:
            return 0.0
        elapsed = (time.monotonic() if now is None else now) - self._ramp_started
        return self._ramp_from_vpk * max(0.0, 1.0 - elapsed / self._ramp_wall_s)


def ramp_requests(frequency_hz: float, from_vpk: float, duration_s: float,
                  control: SourceControl, ranges: tuple[float | None, ...]
                  ) -> list[SweepRequest]:
    """The rig simulator's requests that stand for a ramp from ``from_vpk`` to 0 over
    ``duration_s`` at ``frequency_hz``: :data:`RAMP_STEPS` equal steps of falling fixed level
    (auto level off), the mean level of each step's part of the ramp."""
    if not (duration_s > 0.0 and from_vpk > 0.0 and frequency_hz > 0.0
            and math.isfinite(duration_s)):
        return []
    step_s = duration_s / RAMP_STEPS
    levels = from_vpk * (1.0 - (np.arange(RAMP_STEPS) + 0.5) / RAMP_STEPS)
    fixed = replace(control, auto_level=False)
    return [SweepRequest(frequency_hz=np.array([frequency_hz]), settle_s=np.array([0.0]),
                         integrate_s=np.array([step_s]),
                         control=replace(fixed, source_vpk=float(level)),
                         input_range_vpk=ranges)
            for level in levels]
