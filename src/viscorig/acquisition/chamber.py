"""The temperature chamber in a sequence: soaks, the specimen temperature of every point, and
the chamber left at the station's safe set point however the sequence ends.

- :class:`ChamberMonitor` holds the controller (any object with ``air_c``, ``specimen_c``,
  ``set_target``, ``set_rate_limit``: the ``eurotherm3200`` driver), the station's limits and
  the soak in force, and lets time pass (really, or on a simulated rig's clock).
- :func:`temperature_step` is the plan of a ``temperature`` step: write the ramp and the set
  point, then poll the specimen thermocouple until it has stayed within the band for the soak
  time; past the time limit it is a chamber fault.
- :class:`ChamberedAnalyser` wraps the analyser: it reads the specimen thermocouple before and
  after each segment and gives each point its temperature (the run's per-point
  ``temperature_c`` dataset, °C) (interpolated between the two
  readings in proportion to the points' durations, ∝ 1/f at fixed cycles) and whether it lies
  outside the soak band (flag 16 in the file).
- :class:`ChamberEngine` is the run engine with the chamber's messages (``chamber``,
  ``pass_time``) and, at any ending, the chamber set to the safe set point.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np

from viscorig.acquisition.engine import Msg, Plan, RunEngine
from viscorig.acquisition.session import Session, StepRecord
from viscorig.errors import InstrumentError
from viscorig.sequences import ChamberStation, TemperatureStep

__all__ = ["POLL_S", "ChamberEngine", "ChamberMonitor", "ChamberedAnalyser", "temperature_step"]

#: Seconds between two readings of the specimen thermocouple during a soak.
POLL_S = 10.0
#: Seconds of soak between two progress lines.
SAY_EVERY_S = 300.0


@dataclass(frozen=True)
class Soak:
    """The set point and band the points are checked against."""

    set_point_c: float
    band_k: float

    def outside(self, temperature_c: np.ndarray) -> np.ndarray:
        return ~(np.abs(np.asarray(temperature_c, float) - self.set_point_c) <= self.band_k)


class ChamberMonitor:
    """The chamber as the runner drives it (module text).

    Parameters
    ----------
    controller
        The connected controller (``eurotherm3200.Eurotherm3200`` or alike).
    station
        The station's ``[chamber]``: limits and safe set point.
    pass_time
        How time passes on a simulated rig (``pass_time(seconds)``); None: really sleep.
    errors
        The driver's exception types that mean a chamber fault: raised again as
        :class:`~viscorig.errors.InstrumentError` with the driver's one-line message.
    """

    def __init__(self, controller: Any, station: ChamberStation,
                 pass_time: Callable[[float], None] | None = None,
                 errors: tuple[type[BaseException], ...] = ()) -> None:
        self.controller = controller
        self.station = station
        self.pass_time = pass_time
        self.errors = errors
        self.soak: Soak | None = None

    def _call(self, method: str, *args: Any) -> Any:
        try:
            return getattr(self.controller, method)(*args)
        except self.errors as error:
            raise InstrumentError(" ".join(str(error).split())) from None

    def go_to(self, step: TemperatureStep) -> None:
        """Write the ramp and the set point of a temperature step (within the limits)."""
        if not self.station.allows(step.set_point_c):
            raise InstrumentError(
                f"chamber: set point {step.set_point_c:g} °C is outside the station's limits "
                f"[{self.station.low_limit_c:g}, {self.station.high_limit_c:g}] °C; nothing "
                "written")
        self._call("set_rate_limit", step.ramp_c_per_min)
        self._call("set_target", step.set_point_c)
        self.soak = Soak(step.set_point_c, step.soak_band_k)

    def specimen_c(self) -> float:
        return float(self._call("specimen_c"))

    def air_c(self) -> float:
        return float(self._call("air_c"))

    def to_safe(self) -> float:
        """Set the station's safe set point (rate limit off); returns it."""
        safe = self.station.safe_set_point_c
        self._call("set_rate_limit", 0.0)
        self._call("set_target", safe)
        self.soak = None
        return safe

    def wait(self, seconds: float) -> None:
        """Let ``seconds`` pass: on the simulated rig's clock, else really."""
        if self.pass_time is not None:
            self.pass_time(seconds)
        else:
            time.sleep(seconds)


def temperature_step(session: Session, step: TemperatureStep, record: StepRecord) -> Plan:
    """Bring the specimens to the step's set point and soak them (module text).

    Raises
    ------
    InstrumentError
        The soak is not done within the step's time limit.
    """
    record.move("soaking")
    yield Msg("chamber", ("go_to", step), step="temperature")
    ramp = (f", ramp {step.ramp_c_per_min:g} °C/min" if step.ramp_c_per_min > 0 else "")
    yield Msg("say", (f"chamber set to {step.set_point_c:g} °C{ramp}; soaking until the "
                      f"specimen stays within ±{step.soak_band_k:g} K for "
                      f"{step.soak_minutes:g} min",), step="temperature")
    elapsed = 0.0
    entered: float | None = None
    said = 0.0
    while True:
        specimen = yield Msg("chamber", ("specimen_c",), step="temperature")
        if abs(specimen - step.set_point_c) <= step.soak_band_k:
            entered = elapsed if entered is None else entered
            if elapsed - entered >= step.soak_s:
                break
        else:
            entered = None
        if elapsed >= step.time_limit_s:
            raise InstrumentError(
                f"chamber: the specimen is at {specimen:.1f} °C after {elapsed / 60:.0f} min, "
                f"not soaked within ±{step.soak_band_k:g} K of {step.set_point_c:g} °C for "
                f"{step.soak_minutes:g} min (time limit {step.time_limit_minutes:g} min)")
        if elapsed - said >= SAY_EVERY_S:
            air = yield Msg("chamber", ("air_c",), step="temperature")
            soaked = "" if entered is None else f", in band for {(elapsed - entered) / 60:.0f} min"
            yield Msg("say", (f"  {elapsed / 60:.0f} min: specimen {specimen:.1f} °C, air "
                              f"{air:.1f} °C{soaked}",), step="temperature")
            said = elapsed
        yield Msg("pass_time", (POLL_S,), step="temperature")
        elapsed += POLL_S
    record.move("done", f"soaked at {specimen:.2f} °C after {elapsed / 60:.1f} min")
    yield Msg("say", (f"soaked: specimen {specimen:.2f} °C after {elapsed / 60:.1f} min",),
              step="temperature")


class ChamberEngine(RunEngine):
    """The run engine with a chamber (module text)."""

    def __init__(self, campaign, rig, console, chamber: ChamberMonitor, **engine: Any) -> None:
        self.chamber = chamber
        super().__init__(campaign, rig, console, **engine)

    def run(self, plan: Plan, *, signals: bool = True) -> Any:
        """Run ``plan``; whatever the ending, leave the chamber at the safe set point."""
        try:
            return super().run(plan, signals=signals)
        finally:
            self._leave_safe()

    def _leave_safe(self) -> None:
        try:
            safe = self.chamber.to_safe()
        except Exception as error:  # the chamber's own fault: say so, keep the first error
            self.console.warn(f"chamber: could not set the safe set point "
                              f"({' '.join(str(error).split())}); check the chamber")
            return
        self.console.say(f"chamber left at the safe set point {safe:g} °C")

    def _do_chamber(self, method: str, *args: Any) -> Any:
        return getattr(self.chamber, method)(*args)

    def _do_pass_time(self, seconds: float) -> None:
        self.chamber.wait(seconds)


class ChamberedAnalyser:
    """The analyser, with the specimen temperature read around every segment (module text).

    Every other attribute is the analyser's own.
    """

    def __init__(self, analyser: Any, chamber: ChamberMonitor) -> None:
        self._analyser = analyser
        self._chamber = chamber

    def __getattr__(self, name: str) -> Any:
        return getattr(self._analyser, name)

    def _stamped(self, call: Callable[..., Any], *args: Any, **kwargs: Any) -> Any:
        before = self._chamber.specimen_c()
        measured = call(*args, **kwargs)
        after = self._chamber.specimen_c()
        frequency = np.asarray(measured.frequency_hz, dtype=float)
        weights = np.cumsum(1.0 / frequency)
        share = weights / weights[-1] if weights.size and weights[-1] > 0 else weights
        temperature = before + (after - before) * share
        soak = self._chamber.soak
        outside = (np.zeros(frequency.size, bool) if soak is None
                   else soak.outside(temperature))
        return _Stamped(measured, temperature, outside)

    def measure(self, *args: Any, **kwargs: Any) -> Any:
        return self._stamped(self._analyser.measure, *args, **kwargs)

    def measure_point(self, *args: Any, **kwargs: Any) -> Any:
        return self._stamped(self._analyser.measure_point, *args, **kwargs)

    def measure_points(self, *args: Any, **kwargs: Any) -> Any:
        return self._stamped(self._analyser.measure_points, *args, **kwargs)


class _Stamped:
    """A measured segment with ``specimen_temperature_c`` and ``outside_soak_band``."""

    def __init__(self, measured: Any, temperature: np.ndarray, outside: np.ndarray) -> None:
        self._measured = measured
        self.specimen_temperature_c = temperature
        self.outside_soak_band = outside

    def __getattr__(self, name: str) -> Any:
        return getattr(self._measured, name)
