"""The virtual 35670A itself: its parts put together, and what in-process code may ask of it."""

from __future__ import annotations

import threading
import time
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

from rigsim.analyser.commands import register_all
from rigsim.analyser.fft import FftMeasurement
from rigsim.analyser.frequency import allowed_span
from rigsim.analyser.inputs import CHANNELS, InputView
from rigsim.analyser.limits import (
    AUTOCAL_DURATION_S,
    AUTOCAL_PERIOD_S,
    AUTOCAL_SCHEDULE_S,
    DEFAULT_IDN,
    DEFAULT_OPTIONS,
    FREQUENCY_STEP_HZ,
    fft_lines,
    fft_max_span_hz,
    sine_max_frequency_hz,
)
from rigsim.analyser.run import Run, Simulator
from rigsim.analyser.session import ScpiSession
from rigsim.analyser.settings import SettingStore
from rigsim.analyser.sine import SweptSine
from rigsim.analyser.status import (
    DEV_AUTOCAL_OFF,
    ESR_PON,
    OPER_CALIBRATING,
    StatusRegisters,
)
from rigsim.analyser.traces import Register, fft_trace, parse_feed, sine_trace
from rigsim.faults import FrontEnd
from rigsim.scpi import CommandTree, ScpiError

__all__ = ["VirtualAnalyser", "build_simulator", "load_rig"]

#: Highest FFT zoom frequency with 1, 2 and 4 inputs.
_FFT_TOP = {1: 115000.0, 2: 57500.0, 4: 28750.0}


def load_rig(rig: Any) -> Any:
    """A ``Rig`` as given, or loaded from a rig file path or a preset name."""
    from rigsim import rigfile

    if isinstance(rig, Path) or (isinstance(rig, str) and rig.endswith(".toml")):
        return rigfile.load_rig(rig)
    if isinstance(rig, str):
        return rigfile.load_preset(rig)
    return rig


def build_simulator(rig: Any, seed: int | None = None) -> Simulator:
    """Make a rig simulator from a ``Rig``, a rig file path, or a preset name."""
    from rigsim import engine  # the engine is heavy; import on first use

    return engine.RigSimulator(load_rig(rig), seed=seed)


class VirtualAnalyser:
    """A simulated 35670A measuring a simulated rig.

    Parts: ``store`` (every setting, :mod:`rigsim.analyser.settings`), ``status`` (error queue
    and registers), ``run`` (the measurement thread), ``sine`` and ``fft`` (the two
    measurements), ``front_end`` (the wiring between rig and inputs, where wiring faults are
    injected), ``registers`` (data registers D1..D8), ``tree`` (the command set).

    Parameters
    ----------
    simulator
        The rig simulator (``rigsim.engine.RigSimulator``).
    pace
        ``None``: measure as fast as the computer allows. A number: simulated seconds per
        wall-clock second (1 is real time), so a client sees the status change as the
        instrument would, can pause or abort mid-sweep, and a long sweep outlasts a time-out.
    options
        Installed options for ``*OPT?`` (``1D2`` swept sine, ``AY6`` four channels).
    idn
        The ``*IDN?`` answer.
    """

    def __init__(
        self,
        simulator: Simulator,
        *,
        pace: float | None = None,
        options: Sequence[str] = DEFAULT_OPTIONS,
        idn: str = DEFAULT_IDN,
    ) -> None:
        if pace is not None and not pace > 0:
            raise ValueError(f"pace must be positive (simulated seconds per second), got {pace}")
        self._options = tuple(o.upper() for o in options)
        self.idn = idn
        self.lock = threading.RLock()
        self.changed = threading.Condition(self.lock)
        self.status = StatusRegisters(self.changed)
        self.front_end = FrontEnd()
        self.store = SettingStore(self)
        self.inputs = InputView(self.store)
        self.run = Run(self.changed, self.status, pace)
        self.run.on_end = self._measurement_ended
        self.simulator = simulator
        self.sine = SweptSine(self.store, self.status, self.run, simulator, self.front_end,
                              self._calibration_point)
        self.fft = FftMeasurement(self.store, self.status, self.run, simulator,
                                  self.front_end, self._calibration_point)
        self.registers: dict[int, Register] = {}
        self.tree = CommandTree()
        register_all(self.tree, self)
        self._uptime_s = 0.0
        self._last_clock_s = 0.0
        self._next_calibration = 0
        self._calibration_requested = False
        self._measuring_mode = "FFT"
        self.reset("PRES")
        self.status.esr = ESR_PON

    # ---------------------------------------------------------------- context of the settings

    @property
    def options(self) -> tuple[str, ...]:
        """Installed options."""
        return self._options

    @property
    def mode(self) -> str:
        """The instrument mode (``FFT``, ``SINE``, ...)."""
        return str(self.store.get("mode"))

    @property
    def pace(self) -> float | None:
        """Simulated seconds per wall second (``None``: as fast as possible)."""
        return self.run.pace

    def v_per_eu(self, channel: int) -> float | None:
        """Volts per engineering unit of an input in engineering units, else ``None``."""
        return self.inputs.v_per_eu(channel)

    # ---------------------------------------------------------------- what commands do

    def reset(self, kind: str) -> None:
        """``*RST`` (``"RST"``) or ``SYST:PRES`` (``"PRES"``): the measurement stops."""
        with self.lock:
            self.abort()
            self.store.reset(kind)
            self.status.opc_armed = False
            if kind == "PRES":
                self.status.preset_clear()
            self.sine.points = type(self.sine.points)()
            self.fft.result = None
            self.settings_changed("reset")

    def initiate(self) -> None:
        """``INIT``: a new measurement in the current mode (a running one restarts)."""
        self.abort()
        mode = self.mode
        if mode == "SINE":
            plan = self.sine.plan()
            self._measuring_mode = mode
            self.sine.start(plan)
        elif mode == "FFT":
            plan = self.fft.plan()
            self._measuring_mode = mode
            self.fft.start(plan)
        else:  # octave, order, histogram and correlation analyses are not simulated
            raise ScpiError(-221, "Measurement mode incompatible with command.")

    def abort(self) -> None:
        """``ABOR``: stop the measurement (its data so far stays); the source ramps down."""
        with self.lock:
            if self.run.state != "IDLE" and self._measuring_mode == "SINE":
                self.sine.aborting = True
            self.run.abort()

    def set_continuous(self, on: bool) -> None:
        """``INIT:CONT``: OFF pauses; ON resumes a paused measurement, or adds averages to a
        finished FFT measurement."""
        if not on:
            self.run.pause()
            return
        if self.run.state == "PAUSED":
            if self._measuring_mode == "SINE":
                self.sine.resume()
            else:
                self.run.resume()
        elif self.run.state == "IDLE" and self.mode == "FFT" and self.fft.result is not None:
            self._measuring_mode = "FFT"
            self.fft.start(self.fft.plan(), more=True)

    def trace(self, number: int) -> Register:
        """The current data of trace ``number`` (1..4)."""
        with self.lock:
            feed = parse_feed(str(self.store.get("calc.feed", (number,))))
            if feed.kind == "REG":
                register = self.registers.get(feed.channels[0])
                if register is None:
                    raise ScpiError(-200, "Trace contains invalid data.")
                return register.copy()
            if self.mode == "SINE":
                return sine_trace(feed, self.sine.points)
            if feed.kind in ("WREG", "TCAP"):
                raise ScpiError(-200, "Trace contains invalid data.")
            lines = int(self.store.get("freq.res")) if self.mode == "FFT" else 400
            return fft_trace(feed, self.fft.result, lines)

    def settings_changed(self, what: str) -> None:
        """Keep dependent state right after a change (band limits, device status bits)."""
        if what in ("channels", "reset"):
            self._clamp_bands()
        if what in ("cal.auto", "reset", "state"):
            autocal_off = not self.store.get("cal.auto")
            condition = self.status.device.condition
            self.status.device.set_condition(
                condition | DEV_AUTOCAL_OFF if autocal_off else condition & ~DEV_AUTOCAL_OFF)

    def _clamp_bands(self) -> None:
        count = self.inputs.count()
        for mode in ("FFT", "CORR"):
            if int(self.store.get("freq.res", mode=mode)) not in fft_lines(count):
                self.store.set("freq.res", max(fft_lines(count)), mode=mode)
        for mode in ("SINE", "FFT"):
            start = float(self.store.get("freq.start", mode=mode))
            stop = float(self.store.get("freq.stop", mode=mode))
            if mode == "SINE":
                top = sine_max_frequency_hz(count)
                stop = min(stop, top)
                start = min(start, stop - FREQUENCY_STEP_HZ)
            else:
                span = allowed_span(min(stop - start, fft_max_span_hz(count)),
                                    fft_max_span_hz(count))
                start = min(start, max(0.0, _FFT_TOP[count] - span))
                stop = start + span
            if (start, stop) != (self.store.get("freq.start", mode=mode),
                                 self.store.get("freq.stop", mode=mode)):
                self.store.set("freq.start", start, mode=mode)
                self.store.set("freq.stop", stop, mode=mode)

    # ---------------------------------------------------------------- auto-calibration

    def calibrate_now(self) -> None:
        """``*CAL?``, ``CAL:AUTO ONCE``: a calibration now (between points if measuring)."""
        with self.lock:
            if self.run.state == "IDLE":
                self.status.oper.pulse(OPER_CALIBRATING)
            else:
                self._calibration_requested = True

    def request_calibration(self) -> None:
        """An auto-calibration before the next point or record (a fault to inject)."""
        with self.lock:
            self._calibration_requested = True

    def _calibration_due(self) -> bool:
        clock = float(self.simulator.clock_s)
        self._uptime_s += max(0.0, clock - self._last_clock_s)
        self._last_clock_s = clock
        index = self._next_calibration
        due_at = (AUTOCAL_SCHEDULE_S[index] if index < len(AUTOCAL_SCHEDULE_S)
                  else AUTOCAL_SCHEDULE_S[-1] + AUTOCAL_PERIOD_S * (index - len(
                      AUTOCAL_SCHEDULE_S) + 1))
        timed = self._uptime_s >= due_at
        if timed:
            self._next_calibration += 1
        requested, self._calibration_requested = self._calibration_requested, False
        return requested or (timed and bool(self.store.get("cal.auto")))

    def _calibration_point(self, generation: int) -> None:
        """Called by a measurement between points: calibrate when due (the measurement
        waits, ``STAT:OPER`` bit 0 is set meanwhile)."""
        with self.lock:
            if not self._calibration_due():
                return
            self.status.oper.set_condition(self.status.oper.condition | OPER_CALIBRATING)
        try:
            self.run.wait(generation, AUTOCAL_DURATION_S, self.run.operation)
        finally:
            with self.lock:
                self.status.oper.set_condition(self.status.oper.condition & ~OPER_CALIBRATING)

    def _measurement_ended(self) -> None:
        if self._measuring_mode == "SINE":
            self.sine.finished()
        else:
            self.status.volt.set_condition(0)

    # ---------------------------------------------------------------- in-process API

    def mount(self, rig: Any) -> None:
        """Mount another rig (new specimens) on the simulator. **In-process only, not SCPI.**

        Raises
        ------
        RuntimeError
            A measurement is running or paused: abort it first.
        """
        rig = load_rig(rig)
        with self.lock:
            if self.run.state != "IDLE":
                raise RuntimeError("cannot change the specimens while a sweep is running or paused")
            self.simulator.mount(rig)
            self._last_clock_s = 0.0

    def session(self) -> ScpiSession:
        """A new controller connection (its own parser state)."""
        return ScpiSession(self)

    def push_error(self, code: int, message: str) -> None:
        """Put an error in the queue (5 entries; on overflow the oldest stay, the last says so)."""
        self.status.push_error(code, message)

    def status_byte(self, mav: bool = False) -> int:
        """``*STB?`` with message-available as given."""
        return self.status.status_byte(mav)

    def end_after_point(self) -> None:
        """Make the running swept sine stop at its next point boundary, as a paced one gives a
        controller time to: the point being measured is finished, then the sweep holds settling
        (``STAT:OPER``) until ``ABOR`` (at most ``END_HOLD_S`` of wall time). Unpaced, a sweep
        otherwise ends before a controller polls again, so its end at a point is never seen.
        **In-process only, not SCPI.**"""
        with self.changed:
            self.sine.end_wanted = True
            self.changed.notify_all()

    def force_overload(self, channel: int, points: int | None = None) -> None:
        """Flag an input overload on ``channel`` (1..4) for the next ``points`` swept-sine
        points (all points of the next sweep when ``None``)."""
        if not 1 <= channel <= CHANNELS:
            raise ValueError(f"channel must be 1..4, got {channel}")
        with self.lock:
            self.sine.forced_overload[channel] = points

    def wait_until_idle(self, timeout_s: float | None = None) -> bool:
        """Block until no measurement runs (a paused one counts as running). True if idle."""
        deadline = None if timeout_s is None else time.monotonic() + timeout_s
        with self.changed:
            while self.run.state != "IDLE":
                remaining = None if deadline is None else deadline - time.monotonic()
                if remaining is not None and remaining <= 0:
                    return False
                self.changed.wait(remaining)
        return True

    @property
    def state(self) -> str:
        """``IDLE``, ``RUNNING`` or ``PAUSED``."""
        return self.run.state

    @property
    def points_measured(self) -> int:
        """Swept-sine points of the current or last sweep measured so far."""
        return self.sine.points.count

    @property
    def on_point(self) -> Callable[[int], None] | None:
        """Called with the number of swept-sine points measured after each point."""
        return self.sine.on_point

    @on_point.setter
    def on_point(self, hook: Callable[[int], None] | None) -> None:
        self.sine.on_point = hook

    @property
    def source_on(self) -> bool:
        """The source drives the rig: ``OUTP ON`` in FFT mode, a sweep running in swept sine
        (where ``OUTP`` does not exist: the sweep drives the source)."""
        with self.lock:
            if self.mode == "SINE":
                return self.run.state == "RUNNING" and self._measuring_mode == "SINE"
            return bool(self.store.get("outp.state", mode="FFT"))

    @property
    def source_output_vpk(self) -> float:
        """What the source outputs now, volts peak: the swept sine's level while it runs, then
        its ramp down at ``SOUR:VOLT:SLEW`` (:mod:`rigsim.analyser.ramp`). **In-process only,
        not SCPI** (the 35670A has no query for it)."""
        with self.lock:
            return self.sine.output.level_vpk()

    def close(self) -> None:
        """Stop any measurement (the worker thread ends)."""
        self.abort()
