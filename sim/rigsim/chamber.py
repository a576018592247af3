"""The simulated temperature chamber: air heated and cooled at limited rates towards a set
point that ramps, and specimens that follow the air with a thermal lag.

State, all in °C and seconds of test time:

- the controller's *target* set point and its set-point rate limit (K/min, 0: none) give the
  *working* set point, which moves towards the target at that rate;
- the air follows the working set point as a first-order lag of time constant
  ``air_time_constant_s``, its rate of change clipped to ``heating_rate_k_per_min`` and
  ``cooling_rate_k_per_min`` (the heater's and the refrigeration's power);
- the specimens follow the air as a first-order lag of time constant
  ``specimen_time_constant_s`` (rubber blocks warm through slowly: soaking takes time).

The controller's output (%, +100 full heat, -100 full cooling) is the air's rate of change as
a fraction of the rate available in that direction.

:meth:`Chamber.advance` lets test time pass (the rig simulator calls it for every settle and
integration window it measures, and for idle time); it integrates the equations in steps of
at most :data:`MAX_STEP_S`. A thermocouple can be broken (:meth:`Chamber.break_thermocouple`):
its reading is then unavailable and the controller reports a sensor break.
"""

from __future__ import annotations

import math
import threading
from dataclasses import dataclass

__all__ = ["MAX_STEP_S", "Chamber", "ChamberParameters"]

#: Longest integration step of the thermal model, s.
MAX_STEP_S = 2.0


@dataclass(frozen=True)
class ChamberParameters:
    """What the chamber and its specimens are made of (rig file ``[chamber]``)."""

    heating_rate_k_per_min: float = 5.0
    cooling_rate_k_per_min: float = 3.0
    air_time_constant_s: float = 60.0
    specimen_time_constant_s: float = 420.0
    start_temperature_c: float = 25.0
    low_limit_c: float = -70.0
    """The controller's range (RNG.LO): the lowest set point it accepts."""
    high_limit_c: float = 180.0
    """The controller's range (RNG.HI)."""


class Chamber:
    """A chamber and its specimens (module text); thread-safe.

    Parameters
    ----------
    parameters
        Rates, lags, start temperature and the controller's range.
    """

    def __init__(self, parameters: ChamberParameters | None = None) -> None:
        self.parameters = parameters or ChamberParameters()
        start = self.parameters.start_temperature_c
        self._lock = threading.Lock()
        self._time_s = 0.0
        self._air_c = start
        self._specimen_c = start
        self._target_c = start
        self._working_c = start
        self._rate_k_per_min = 0.0
        self._output_percent = 0.0
        self._broken: set[str] = set()

    # ------------------------------------------------------------------ readings

    @property
    def time_s(self) -> float:
        """Test time the chamber has lived, s."""
        with self._lock:
            return self._time_s

    @property
    def air_c(self) -> float:
        """Air temperature (the controller's own thermocouple), °C."""
        with self._lock:
            return self._air_c

    @property
    def specimen_c(self) -> float:
        """Temperature of the specimens, °C (the physics uses it whatever the sensors say)."""
        with self._lock:
            return self._specimen_c

    @property
    def target_c(self) -> float:
        with self._lock:
            return self._target_c

    @property
    def working_c(self) -> float:
        with self._lock:
            return self._working_c

    @property
    def rate_k_per_min(self) -> float:
        with self._lock:
            return self._rate_k_per_min

    @property
    def output_percent(self) -> float:
        with self._lock:
            return self._output_percent

    def broken(self, sensor: str) -> bool:
        """Is ``sensor`` (``"air"`` or ``"specimen"``) broken?"""
        with self._lock:
            return sensor in self._broken

    # ------------------------------------------------------------------ commands

    def set_target(self, temperature_c: float) -> None:
        """Write the target set point (clamped to the controller's range, as it does)."""
        low, high = self.parameters.low_limit_c, self.parameters.high_limit_c
        with self._lock:
            self._target_c = min(max(float(temperature_c), low), high)
            if self._rate_k_per_min <= 0.0:
                self._working_c = self._target_c

    def set_rate(self, rate_k_per_min: float) -> None:
        """Write the set-point rate limit, K/min (0: the working set point jumps)."""
        with self._lock:
            self._rate_k_per_min = max(float(rate_k_per_min), 0.0)
            if self._rate_k_per_min <= 0.0:
                self._working_c = self._target_c

    def break_thermocouple(self, sensor: str = "air") -> None:
        """Break a thermocouple (``"air"``: the controller's; ``"specimen"``)."""
        if sensor not in ("air", "specimen"):
            raise ValueError(f"sensor must be 'air' or 'specimen', not {sensor!r}")
        with self._lock:
            self._broken.add(sensor)

    def repair(self) -> None:
        with self._lock:
            self._broken.clear()

    # ------------------------------------------------------------------ time

    def advance(self, duration_s: float) -> None:
        """Let ``duration_s`` seconds of test time pass."""
        if not duration_s >= 0.0 or not math.isfinite(duration_s):
            raise ValueError(f"duration_s must be finite and >= 0, not {duration_s}")
        with self._lock:
            left = float(duration_s)
            while left > 0.0:
                step = min(left, MAX_STEP_S)
                self._step(step)
                left -= step
            self._time_s += float(duration_s)

    def _step(self, dt: float) -> None:
        p = self.parameters
        if self._rate_k_per_min > 0.0:
            move = self._rate_k_per_min / 60.0 * dt
            gap = self._target_c - self._working_c
            self._working_c += max(-move, min(move, gap))
        if "air" in self._broken:
            # sensor break: the controller holds its output off; the air drifts to the room
            wanted = (p.start_temperature_c - self._air_c) / p.air_time_constant_s
        else:
            wanted = (self._working_c - self._air_c) / p.air_time_constant_s
        heat = p.heating_rate_k_per_min / 60.0
        cool = p.cooling_rate_k_per_min / 60.0
        rate = min(max(wanted, -cool), heat)
        self._output_percent = 0.0 if "air" in self._broken else 100.0 * (
            rate / heat if rate >= 0.0 else rate / cool)
        air_before = self._air_c
        self._air_c += rate * dt
        # the specimens follow the mean air temperature of the step (exact for a linear ramp)
        mean_air = 0.5 * (air_before + self._air_c)
        decay = math.exp(-dt / p.specimen_time_constant_s)
        self._specimen_c = mean_air + (self._specimen_c - mean_air) * decay
