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

Leaving the chamber safe (:meth:`ChamberMonitor.to_safe`) writes the safe set point first (the
write that matters), then the ramp-rate limit off; each write is tried again on a bad or missing
reply (a corrupted frame, a lost one) within :data:`SAFE_BUDGET_S` in all. A controller that
still does not take the set point is :class:`ChamberNotSafeError`: the operator must set it by hand.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np

from viscorig.acquisition.console import single_line
from viscorig.acquisition.engine import Msg, Plan, RunEngine
from viscorig.acquisition.session import Session, StepRecord
from viscorig.errors import InstrumentError
from viscorig.sequences import ChamberStation, TemperatureStep

__all__ = ["POLL_S", "SAFE_BUDGET_S", "ChamberEngine", "ChamberFaultError", "ChamberMonitor",
           "ChamberNotSafeError", "ChamberedAnalyser", "temperature_step"]

#: Seconds between two readings of the specimen thermocouple during a soak.
POLL_S = 10.0
#: Seconds of soak between two progress lines.
SAY_EVERY_S = 300.0
#: Wall-clock seconds that leaving the chamber safe may take with a controller that does not
#: answer: no write is tried again once the next attempt would end past this.
SAFE_BUDGET_S = 5.0
#: Attempts of each write when leaving the chamber safe, at most.
SAFE_ATTEMPTS = 3
#: Seconds between two attempts of a write (a noisy line settles, stray bytes are dropped).
SAFE_RETRY_PAUSE_S = 0.2


class ChamberFaultError(InstrumentError):
    """A fault of the chamber (its controller, its link, its thermocouples, a soak not done):
    not the analyser's."""


class ChamberNotSafeError(ChamberFaultError):
    """The controller did not take the safe set point: the chamber must be set by hand.

    Attributes
    ----------
    safe_c
        The station's safe set point, °C.
    controller
        Where the controller is (``tcp://HOST:PORT`` or the serial port).
    detail
        The last write's fault, one line.
    """

    def __init__(self, safe_c: float, controller: str, detail: str) -> None:
        self.safe_c = safe_c
        self.controller = controller
        self.detail = detail
        super().__init__(
            f"the chamber could NOT be set to its safe set point {safe_c:g} °C ({detail}): "
            f"set it to {safe_c:g} °C by hand at the controller")


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

    @property
    def address(self) -> str:
        """Where the controller is: its link as connected, else the station's address."""
        link = getattr(self.controller, "link", None)
        return str(link) if link is not None else self.station.address

    def _call(self, method: str, *args: Any) -> Any:
        try:
            return getattr(self.controller, method)(*args)
        except self.errors as error:
            raise ChamberFaultError(" ".join(str(error).split())) from None

    def go_to(self, step: TemperatureStep) -> None:
        """Write the ramp and the set point of a temperature step (within the limits)."""
        if not self.station.allows(step.set_point_c):
            raise ChamberFaultError(
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

    def to_safe(self) -> tuple[float, str]:
        """Set the station's safe set point, then the rate limit off (module text).

        Returns
        -------
        safe, note
            The safe set point, °C, and "" or why the ramp-rate limit could not be cleared
            (the set point is written: the chamber goes there, at the last step's ramp rate).

        Raises
        ------
        ChamberNotSafeError
            The controller did not take the safe set point within the attempts and time.
        """
        safe = self.station.safe_set_point_c
        started = time.monotonic()
        error = self._persist("set_target", safe, started)
        if error is not None:
            raise ChamberNotSafeError(safe, self.address, error)
        self.soak = None
        rate_error = self._persist("set_rate_limit", 0.0, started)
        note = "" if rate_error is None else f"its ramp-rate limit is not cleared ({rate_error})"
        return safe, note

    def _persist(self, method: str, value: float, started: float) -> str | None:
        """Write ``value`` with ``method``, again on a fault while attempts and time remain;
        None once written, else the last fault (one line, with the attempts made)."""
        longest = 0.0
        attempt = 0
        while True:
            attempt += 1
            begun = time.monotonic()
            try:
                getattr(self.controller, method)(value)
                return None
            except self.errors as error:
                text = " ".join(str(error).split())
            now = time.monotonic()
            longest = max(longest, now - begun)
            if (attempt >= SAFE_ATTEMPTS
                    or now + SAFE_RETRY_PAUSE_S + longest - started > SAFE_BUDGET_S):
                tries = "1 attempt" if attempt == 1 else f"{attempt} attempts"
                return f"{text}; {tries} in {now - started:.1f} s"
            time.sleep(SAFE_RETRY_PAUSE_S)

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
            raise ChamberFaultError(
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

    #: Set by :meth:`run` when the chamber could not be left at its safe set point.
    not_safe: ChamberNotSafeError | None = None

    def run(self, plan: Plan, *, signals: bool = True) -> Any:
        """Run ``plan``; whatever the ending, leave the chamber at the safe set point.

        Raises
        ------
        ChamberNotSafeError
            The plan ended well but the controller did not take the safe set point. When the
            plan itself raised, its exception goes on and :attr:`not_safe` holds this one (the
            runner says both in one line).
        """
        self.not_safe = None
        try:
            result = super().run(plan, signals=signals)
        except BaseException:
            self._leave_safe()
            raise
        self._leave_safe()
        if self.not_safe is not None:
            raise self.not_safe
        return result

    def _leave_safe(self) -> None:
        try:
            safe, note = self.chamber.to_safe()
        except ChamberNotSafeError as error:  # said by the runner, in its one line
            self.not_safe = error
            return
        except Exception as error:  # not the controller's reply: the set point is not known
            self.not_safe = ChamberNotSafeError(self.chamber.station.safe_set_point_c,
                                           self.chamber.address, single_line(str(error)))
            return
        self.console.say(f"chamber left at the safe set point {safe:g} °C"
                         + (f"; {note}" if note else ""))

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
