"""The virtual Agilent 35670A: instrument state, command set, status registers, measurement.

:class:`VirtualAnalyser` holds what the instrument holds (modes and their settings, inputs,
source, traces, data registers, status registers, error queue) and runs swept-sine
measurements on a rig simulator (``rigsim.engine.RigSimulator``) in a background worker, through
the volts-only interface of :mod:`rigsim.measurement`. It converts volts to engineering units
per channel and forms the traces. :class:`ScpiSession` is one controller's connection to it
(its own parser path and output), so a socket server and in-process code can share one
instrument.

The command set follows ``shared/docs/35670a.md``. Behaviour marked **(inferred)** in comments
and docstrings is our reading where that page and the manual are silent; keep it easy to change.

Not simulated, on purpose and visibly: FFT, octave, order and histogram measurements (``INIT``
outside swept sine answers -221); the swept sine's automatic resolution (``FREQ:RES:AUTO ON``
still measures the fixed ``FREQ:RES`` grid, so always read the X axis); the source slew rate
(stored only). Traces and data registers (all values in engineering units when
``VOLTn:RANG:UNIT:USER`` is on, else volts): ``XFR:POW:RAT a,b`` the complex ratio a/b;
``XFR:POW:LIN n`` the complex peak amplitude of channel n (inferred: peak); ``XFR:POW:CROS a,b``
``conj(X_a) X_b`` in peak² (inferred); ``XFR:POW:VAR n`` the normalized variance (real);
``XTIM:VOLT n`` the last point's steady-state sine rebuilt from its measured amplitude (real,
X in seconds). During and after a sweep the traces hold the points measured so far (inferred).

In-process control (not SCPI; the instrument has no such command): :meth:`VirtualAnalyser.mount`
swaps the specimens on the simulated rig between sweeps, as a technician does when a sequence
prompt says "mount the soft specimens".
"""

from __future__ import annotations

import math
import re
import threading
import time
from collections import deque
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Protocol

import numpy as np

from rigsim.measurement import (
    CHANNEL_COUNT,
    INPUT_RANGES_DBVRMS,
    SourceControl,
    SweepRecord,
    SweepRequest,
)
from rigsim.scpi import (
    CommandTree,
    ProgramUnit,
    Quantity,
    ScpiError,
    definite_block,
    format_bool,
    format_int,
    format_real,
    format_string,
    parse_bool,
    parse_choice,
    parse_quantity,
    parse_unit,
    split_units,
    unquote,
)

__all__ = [
    "DEFAULT_IDN",
    "DEFAULT_OPTIONS",
    "MAX_POINTS",
    "ScpiSession",
    "Simulator",
    "VirtualAnalyser",
]

#: ``*IDN?`` answer. The vendor string differs by era; ours says where it comes from.
DEFAULT_IDN = "Agilent Technologies,35670A,RIGSIM0001,A.02.02"
#: Installed options: 1D2 swept sine, AY6 four channels.
DEFAULT_OPTIONS: tuple[str, ...] = ("1D2", "AY6")
#: Points per swept-sine sweep (inferred from the display table: 402-801 points show as 801).
MAX_POINTS = 801
MIN_POINTS = 2  # (inferred)
#: Source and frequency resolution of the swept sine.
FREQUENCY_STEP_HZ = 0.015625
MAX_FREQUENCY_2CH_HZ = 51200.0
MAX_FREQUENCY_4CH_HZ = 25600.0
MAX_SOURCE_VPK = 5.0
MIN_DWELL_S = 250e-6
MAX_CYCLES = 1.0e6  # the manual's upper cycle limit is illegible (inferred)
ERROR_QUEUE_LENGTH = 5
ZERO_SOURCE_MESSAGE = "Settings conflict; SOURCE LEVEL is 0 Volts, measurement paused"

# STAT:OPER:COND bits
OPER_SETTLING = 2
OPER_RANGING = 4
OPER_MEASURING = 16
# *ESR bits
ESR_OPC, ESR_QYE, ESR_DDE, ESR_EXE, ESR_CME, ESR_PON = 1, 4, 8, 16, 32, 128

_MODES_BY_NUMBER = {1: "FFT", 2: "OCT", 3: "SINE", 4: "ORD", 5: "HIST"}  # (inferred, but 3=SINE)
_MODE_OPTION = {"FFT": None, "SINE": "1D2", "OCT": "1D1", "ORD": "1D0", "HIST": None}
_FORMATS = ("MLINear", "MLOGarithmic", "PHASe", "UPHase", "REAL", "IMAGinary", "NYQuist",
            "POLar", "GDELay")
_COMPLEX_FORMATS = {"NYQ", "POL"}


class Simulator(Protocol):
    """What the analyser needs of the rig simulator (``rigsim.engine.RigSimulator``)."""

    clock_s: float

    def sweep(self, request: SweepRequest) -> SweepRecord:
        """Measure the request's points, volts at the analyser inputs."""

    def mount(self, rig: Any) -> None:
        """Replace the rig (new specimens); the clock restarts."""


# --------------------------------------------------------------------------------------------
# settings


@dataclass
class ChannelSettings:
    """One input channel."""

    enabled: bool
    coupling: str = "DC"
    low: str = "FLO"
    bias: bool = False
    range_dbvrms: float = 27.0
    autorange: bool = True
    label: str = "V"
    user_sfac_v_per_eu: float = 1.0
    user_units: bool = False

    def v_per_eu(self) -> float:
        """Volts per engineering unit (1 when engineering units are off)."""
        return self.user_sfac_v_per_eu if self.user_units else 1.0


@dataclass
class ModeSettings:
    """Settings that each instrument mode keeps on its own."""

    start_hz: float
    stop_hz: float
    spacing: str = "LIN"
    direction: str = "UP"
    sweep_mode: str = "AUTO"
    manual_hz: float = 1000.0
    points: int = 101
    resolution_unit: str = "PNT/SWP"
    resolution_auto: bool = True
    settle: tuple[float, str] = (5.0, "CYCLE")
    dwell: tuple[float, str] = (5.0, "CYCLE")
    reference: str = "SING"
    feeds: list[str] = field(default_factory=list)
    formats: list[str] = field(default_factory=list)
    window: str = "HANN"
    average_type: str = "RMS"
    trigger_source: str = "FREE"


def _preset_mode(mode: str) -> ModeSettings:
    if mode == "SINE":  # preset start/stop and trace setup (inferred)
        return ModeSettings(
            start_hz=1.0, stop_hz=12800.0, points=101,
            feeds=["XFR:POW:RAT 2,1", "XFR:POW:LIN 1", "XFR:POW:LIN 2", "XFR:POW:VAR 2"],
            formats=["MLOG", "PHAS", "MLOG", "MLIN"],
        )
    return ModeSettings(
        start_hz=0.0, stop_hz=MAX_FREQUENCY_2CH_HZ, points=401,
        feeds=["XFR:POW:LIN 1", "XFR:POW:LIN 2", "XFR:POW:LIN 1", "XFR:POW:LIN 2"],
        formats=["MLOG", "MLOG", "MLOG", "MLOG"],
    )


@dataclass
class SourceSettings:
    """The source and its auto-level controller."""

    output: bool = False
    level_vpk: float = 0.0
    auto_level: bool = False
    reference_channel: int = 2
    reference: tuple[float, str] = (1.0, "VPK")
    tolerance_db: float = 2.0
    limit_vpk: float = 2.0
    input_limit: tuple[float, str] = (1.0, "VPK")
    input_limit_channel: int = 1  # SOUR:VOLT:LIM:INP:CHAN (inferred command, preset INP1)
    input_limit_on: bool = False  # SOUR:VOLT:LIM:INP:STAT (inferred; setting a level turns on)
    slew_v_per_s: float = 10.0  # stored only: the simulator's controller steps the level


@dataclass
class Register:
    """A data register (D1..D8) or the snapshot of a trace."""

    feed: str
    x: np.ndarray
    y: np.ndarray  # complex for frequency responses, spectra; real for variance, time

    @property
    def is_complex(self) -> bool:
        return bool(np.iscomplexobj(self.y))


# --------------------------------------------------------------------------------------------
# feeds


@dataclass(frozen=True)
class Feed:
    """A parsed trace feed (``'XFR:POW:RAT 2,1'``)."""

    kind: str  # RAT, LIN, CROS, VAR, XTIM, COH
    channels: tuple[int, ...]

    @property
    def text(self) -> str:
        head = "XTIM:VOLT" if self.kind == "XTIM" else f"XFR:POW:{self.kind}"
        return f"{head} {','.join(str(c) for c in self.channels)}"


_FEED_WORDS = {
    "XFR": "XFR", "POW": "POW", "POWER": "POW", "RAT": "RAT", "RATIO": "RAT", "LIN": "LIN",
    "LINEAR": "LIN", "CROS": "CROS", "CROSS": "CROS", "VAR": "VAR", "VARIANCE": "VAR",
    "COH": "COH", "COHERENCE": "COH", "XTIM": "XTIM", "XTIME": "XTIM", "VOLT": "VOLT",
    "VOLTAGE": "VOLT",
}
_FEED_ARITY = {"RAT": 2, "CROS": 2, "COH": 2, "LIN": 1, "VAR": 1, "XTIM": 1}


def parse_feed(text: str) -> Feed:
    """Parse a feed string; -224 when it is not one the 35670A offers."""
    head, _, args = text.strip().partition(" ")
    words = tuple(_FEED_WORDS.get(w.upper(), "?") for w in head.split(":"))
    kind = {("XFR", "POW", "RAT"): "RAT", ("XFR", "POW", "LIN"): "LIN",
            ("XFR", "POW", "CROS"): "CROS", ("XFR", "POW", "VAR"): "VAR",
            ("XFR", "POW", "COH"): "COH", ("XTIM", "VOLT"): "XTIM"}.get(words)
    try:
        channels = tuple(int(a) for a in args.split(",")) if args.strip() else ()
    except ValueError:
        raise ScpiError(-224, f"feed {text!r}: channels must be integers") from None
    if kind is None or len(channels) != _FEED_ARITY[kind]:
        raise ScpiError(-224, f"feed {text!r}")
    if any(not 1 <= c <= CHANNEL_COUNT for c in channels):
        raise ScpiError(-224, f"feed {text!r}: channels are 1..4")
    return Feed(kind, channels)


# --------------------------------------------------------------------------------------------
# measurement store


class _Measured:
    """Points measured by the current sweep, in measurement order (grows as points complete)."""

    def __init__(self, capacity: int) -> None:
        self.count = 0
        self.frequency_hz = np.zeros(capacity)
        self.channel_v = np.zeros((capacity, CHANNEL_COUNT), complex)
        self.variance = np.zeros((capacity, CHANNEL_COUNT))
        self.range_vpk = np.zeros((capacity, CHANNEL_COUNT))
        self.overload = np.zeros((capacity, CHANNEL_COUNT), bool)
        self.half_range = np.zeros((capacity, CHANNEL_COUNT), bool)
        self.source_vpk = np.zeros(capacity)
        self.level_reached = np.ones(capacity, bool)
        self.integrate_s = np.zeros(capacity)
        self.v_per_eu = np.ones(CHANNEL_COUNT)

    def append(self, record: SweepRecord, rows: slice, integrate_s: np.ndarray) -> None:
        n = rows.stop - rows.start
        i = self.count
        self.frequency_hz[i:i + n] = record.frequency_hz[rows]
        self.channel_v[i:i + n] = record.channel_v[rows]
        self.variance[i:i + n] = record.variance[rows]
        self.range_vpk[i:i + n] = record.range_vpk[rows]
        self.overload[i:i + n] = record.overload[rows]
        self.half_range[i:i + n] = record.half_range[rows]
        self.source_vpk[i:i + n] = record.source_vpk[rows]
        self.level_reached[i:i + n] = record.level_reached[rows]
        self.integrate_s[i:i + n] = integrate_s
        self.count += n


# --------------------------------------------------------------------------------------------
# the instrument


def _round_frequency(value_hz: float) -> float:
    return round(value_hz / FREQUENCY_STEP_HZ) * FREQUENCY_STEP_HZ


def build_simulator(rig: Any, seed: int | None = None) -> Simulator:
    """Make a rig simulator from a ``Rig``, a rig file path, or a preset name."""
    from rigsim import engine, rigfile  # the engine is heavy; import on first use

    if isinstance(rig, Path) or (isinstance(rig, str) and rig.endswith(".toml")):
        rig = rigfile.load_rig(rig)
    elif isinstance(rig, str):
        rig = rigfile.load_preset(rig)
    return engine.RigSimulator(rig, seed=seed)


class VirtualAnalyser:
    """A simulated 35670A measuring a simulated rig.

    Parameters
    ----------
    simulator
        The rig simulator (``rigsim.engine.RigSimulator`` or anything with its ``sweep``,
        ``mount`` and ``clock_s``).
    pace
        ``None``: measure as fast as the computer allows. A number: simulated seconds of test
        time per wall-clock second, so a client sees the measuring bit, can pause or abort
        mid-sweep, and a long sweep really outlasts a VISA timeout.
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
        self.simulator = simulator
        self.pace = pace
        self.options = tuple(o.upper() for o in options)
        self.idn = idn
        self.lock = threading.RLock()
        self.changed = threading.Condition(self.lock)
        self.tree = CommandTree()
        self._register_commands()
        # status
        self.errors: deque[tuple[int, str]] = deque()
        self.esr = ESR_PON
        self.ese = 0
        self.sre = 0
        self.oper_event = 0
        self.oper_enable = 0
        self.ques_event = 0
        self.ques_enable = 0
        self.volt_event = 0
        self.volt_enable = 0x0F0F  # (inferred)
        self._opc_armed = False
        self._clear_generation = 0
        # measurement
        self.state = "IDLE"  # IDLE | RUNNING | PAUSED
        self._generation = 0
        self._worker: threading.Thread | None = None
        self._measured = _Measured(0)
        self._point_window: tuple[float, float, float] | None = None  # wall: start, settled, end
        self._last_flags = np.zeros((2, CHANNEL_COUNT), bool)
        self._forced_overload: dict[int, int | None] = {}
        self.segment_points = 64
        self.on_point: Callable[[int], None] | None = None  # in-process hook (tests, progress)
        self._reset(preset=False)

    # ---------------------------------------------------------------- public in-process API

    def mount(self, rig: Any) -> None:
        """Mount another rig (new specimens) on the simulator. **In-process only, not SCPI.**

        Parameters
        ----------
        rig
            A ``rigsim.rigfile.Rig``, a rig file path or a preset name.

        Raises
        ------
        RuntimeError
            A sweep is running or paused: abort it first.
        """
        from rigsim import rigfile

        if isinstance(rig, Path) or (isinstance(rig, str) and rig.endswith(".toml")):
            rig = rigfile.load_rig(rig)
        elif isinstance(rig, str):
            rig = rigfile.load_preset(rig)
        with self.lock:
            if self.state != "IDLE":
                raise RuntimeError("cannot change the specimens while a sweep is running or paused")
            self.simulator.mount(rig)

    def session(self) -> ScpiSession:
        """A new controller connection (its own parser state)."""
        return ScpiSession(self)

    def push_error(self, code: int, message: str) -> None:
        """Put an error in the queue (5 entries; on overflow the oldest stay, the last says so)."""
        with self.lock:
            if len(self.errors) < ERROR_QUEUE_LENGTH:
                self.errors.append((code, message))
            else:
                self.errors[-1] = (-350, "Queue overflow")
            if code <= -400:
                self.esr |= ESR_QYE
            elif code <= -300 or code > 0:
                self.esr |= ESR_DDE
            elif code <= -200:
                self.esr |= ESR_EXE
            elif code <= -100:
                self.esr |= ESR_CME

    def force_overload(self, channel: int, points: int | None = None) -> None:
        """Flag an input overload on ``channel`` (1..4) for the next ``points`` measured points
        (all points of the next sweep when ``None``), as if the signal exceeded the range."""
        if not 1 <= channel <= CHANNEL_COUNT:
            raise ValueError(f"channel must be 1..4, got {channel}")
        with self.lock:
            self._forced_overload[channel] = points

    def wait_until_idle(self, timeout_s: float | None = None) -> bool:
        """Block until no sweep runs (a paused sweep counts as running). True if idle."""
        deadline = None if timeout_s is None else time.monotonic() + timeout_s
        with self.changed:
            while self.state != "IDLE":
                remaining = None if deadline is None else deadline - time.monotonic()
                if remaining is not None and remaining <= 0:
                    return False
                self.changed.wait(remaining)
        return True

    @property
    def points_measured(self) -> int:
        """Points of the current or last sweep measured so far."""
        return self._measured.count

    def close(self) -> None:
        """Stop any sweep (the worker thread ends)."""
        with self.lock:
            self._abort()

    # ---------------------------------------------------------------- state

    def _reset(self, preset: bool) -> None:
        """``*RST`` (preset False) or ``SYST:PRES`` (preset True)."""
        self._abort()
        self.mode = "FFT"
        self.modes = {"FFT": _preset_mode("FFT"), "SINE": _preset_mode("SINE")}
        self.channels = [ChannelSettings(enabled=i < 2) for i in range(CHANNEL_COUNT)]
        self.source = SourceSettings()
        self.format = ("ASC", 12)
        self.registers: dict[int, Register] = {}
        self._measured = _Measured(0)
        # The two resets differ (35670a.md): *RST leaves INIT:CONT OFF and FREQ:RES:AUTO ON;
        # SYST:PRES the opposite (inferred: the front-panel preset state).
        self.continuous = preset
        for settings in self.modes.values():
            settings.resolution_auto = not preset

    @property
    def settings(self) -> ModeSettings:
        return self.modes[self.mode]

    def _four_channel(self) -> bool:
        return self.channels[2].enabled or self.channels[3].enabled

    def _max_frequency(self) -> float:
        return MAX_FREQUENCY_4CH_HZ if self._four_channel() else MAX_FREQUENCY_2CH_HZ

    def _require_sine(self, what: str) -> None:
        if self.mode != "SINE":
            raise ScpiError(-221, f"{what} is a swept-sine setting (INST:SEL SINE first)")

    def _forbid_in_sine(self, what: str) -> None:
        if self.mode == "SINE":
            raise ScpiError(-221, f"{what} not valid in swept sine")

    # ---------------------------------------------------------------- status

    def status_byte(self, mav: bool = False) -> int:
        """``*STB?``: bit 3 questionable, 4 message available, 5 standard event, 6 MSS,
        7 operation (bit 2, device state, is not simulated)."""
        with self.lock:
            stb = 0
            if self.ques_event & self.ques_enable:
                stb |= 8
            if mav:
                stb |= 16
            if self.esr & self.ese:
                stb |= 32
            if self.oper_event & self.oper_enable:
                stb |= 128
            if stb & self.sre & ~64:
                stb |= 64
            return stb

    def oper_condition(self) -> int:
        """``STAT:OPER:COND?``: settling 2, ranging 4, measuring 16."""
        with self.lock:
            if self.state != "RUNNING":
                return 0
            bits = OPER_MEASURING
            window = self._point_window
            if window is not None:
                now = time.monotonic()
                start, settled, _ = window
                if start <= now < settled:
                    bits |= OPER_SETTLING
                    # autorange ranges at the start of each point (inferred: first 20 % of settle)
                    autorange = any(c.enabled and c.autorange for c in self.channels)
                    if autorange and now < start + 0.2 * (settled - start):
                        bits |= OPER_RANGING
            return bits

    def _volt_condition(self) -> int:
        over, half = self._last_flags if self.state == "RUNNING" else (None, None)
        if over is None:
            return 0
        bits = 0
        for i in range(CHANNEL_COUNT):
            bits |= (1 << i) if over[i] else 0
            bits |= (1 << (8 + i)) if half[i] else 0
        return bits

    def _complete_operation(self) -> None:
        """Pending operations are done: ``*OPC`` sets ESR bit 0, ``*OPC?``/``*WAI`` wake up."""
        if self._opc_armed:
            self.esr |= ESR_OPC
            self._opc_armed = False
        self.changed.notify_all()

    # ---------------------------------------------------------------- measurement

    def _point_list(self) -> np.ndarray:
        s = self.settings
        if s.sweep_mode == "MAN":
            return np.array([s.manual_hz])
        lo, hi = sorted((s.start_hz, s.stop_hz))
        if s.spacing == "LOG":
            if lo <= 0:
                raise ScpiError(-221, "logarithmic sweep needs a start frequency above 0 Hz")
            points = np.geomspace(lo, hi, s.points)
        else:
            points = np.linspace(lo, hi, s.points)
        return points[::-1].copy() if s.direction == "DOWN" else points

    def _seconds(self, setting: tuple[float, str], frequency_hz: np.ndarray) -> np.ndarray:
        value, unit = setting
        if unit == "CYCLE":
            return value / frequency_hz
        return np.full(frequency_hz.shape, value)

    def _control(self, start_vpk: float) -> SourceControl:
        src = self.source
        ref_channel = self.channels[src.reference_channel - 1]
        ref_value, ref_unit = src.reference
        reference_vpk = ref_value * ref_channel.v_per_eu() if ref_unit == "EU" else ref_value
        limit_channel = limit_vpk = None
        if src.input_limit_on:
            limit_channel = src.input_limit_channel
            value, unit = src.input_limit
            scale = self.channels[limit_channel - 1].v_per_eu() if unit == "EU" else 1.0
            limit_vpk = value * scale
        return SourceControl(
            source_vpk=start_vpk,
            auto_level=src.auto_level,
            reference_channel=src.reference_channel,
            reference_vpk=reference_vpk,
            tolerance_db=src.tolerance_db,
            source_limit_vpk=src.limit_vpk,
            input_limit_channel=limit_channel,
            input_limit_vpk=limit_vpk,
        )

    def _zero_source(self) -> bool:
        return not self.source.output or self.source.level_vpk <= 0.0

    def _initiate(self) -> None:
        if self.mode != "SINE":
            # FFT measurements are not simulated: say so instead of returning nothing (inferred)
            raise ScpiError(-221, "only swept sine (INST:SEL SINE) is simulated")
        if self.state != "IDLE":
            raise ScpiError(-213, "measurement already running; ABOR first")
        if self.source.auto_level and not self.channels[self.source.reference_channel - 1].enabled:
            channel = self.source.reference_channel
            raise ScpiError(-221, f"auto-level reference channel {channel} is off")
        frequencies = self._point_list()
        settle_s = self._seconds(self.settings.settle, frequencies)
        integrate_s = np.maximum(self._seconds(self.settings.dwell, frequencies),
                                 np.maximum(MIN_DWELL_S, 1.0 / frequencies))
        ranges = tuple(
            None if c.autorange else float(math.sqrt(2.0) * 10 ** (c.range_dbvrms / 20))
            for c in self.channels
        )
        self._plan = (frequencies, settle_s, integrate_s, ranges)
        self._measured = _Measured(frequencies.size)
        self._measured.v_per_eu = np.array([c.v_per_eu() for c in self.channels])
        self._source_level = self.source.level_vpk
        self._generation += 1
        self._point_window = None
        if self._zero_source():
            self.state = "PAUSED"
            self.push_error(-221, ZERO_SOURCE_MESSAGE)
        else:
            self.state = "RUNNING"
        self._worker = threading.Thread(
            target=self._run, args=(self._generation,), name="35670A-sweep", daemon=True
        )
        self._worker.start()

    def _abort(self) -> None:
        if self.state != "IDLE":
            self.state = "IDLE"
            self._generation += 1
            self._point_window = None
            self._complete_operation()

    def _pause(self) -> None:
        if self.state == "RUNNING":
            self.state = "PAUSED"
            self._point_window = None
            self.changed.notify_all()

    def _resume(self) -> None:
        if self.state == "PAUSED":
            if self._zero_source():
                self.push_error(-221, ZERO_SOURCE_MESSAGE)
                return
            self.state = "RUNNING"
            self.changed.notify_all()

    def _next_segment(self, start: int) -> int:
        frequencies, settle_s, integrate_s, _ = self._plan
        stop = min(frequencies.size, start + self.segment_points)
        if self.pace is not None:
            # compute ahead about half a wall second of paced test time
            durations = np.cumsum(settle_s[start:stop] + integrate_s[start:stop]) / self.pace
            stop = start + max(1, int(np.searchsorted(durations, 0.5)))
        return stop

    def _run(self, generation: int) -> None:
        """Worker: measure segment by segment, reveal points as simulated time passes."""
        try:
            self._run_points(generation)
        except Exception as exc:  # the simulator failed: a device error, never a silent stop
            with self.lock:
                if generation == self._generation:
                    self.push_error(-310, f"System error; simulator: {exc}"[:200])
                    self.state = "IDLE"
                    self._complete_operation()

    def _run_points(self, generation: int) -> None:
        frequencies, settle_s, integrate_s, ranges = self._plan
        computed = 0
        while True:
            with self.changed:
                while self.state == "PAUSED" and generation == self._generation:
                    self.changed.wait()
                if generation != self._generation:
                    return
                start = computed
                if start >= frequencies.size:
                    self.state = "IDLE"
                    self._point_window = None
                    # an overload forced "for the next sweep" ends with it
                    for channel, remaining in list(self._forced_overload.items()):
                        if remaining is None:
                            del self._forced_overload[channel]
                    self._complete_operation()
                    return
                stop = self._next_segment(start)
                request = SweepRequest(
                    frequency_hz=frequencies[start:stop],
                    settle_s=settle_s[start:stop],
                    integrate_s=integrate_s[start:stop],
                    control=self._control(self._source_level),
                    input_range_vpk=ranges,
                )
                clock_before = float(self.simulator.clock_s)
            record = self.simulator.sweep(request)
            computed = stop
            ends = np.asarray(record.end_time_s, float)
            previous_end = clock_before
            for k in range(len(record)):
                if self.pace is not None:
                    duration = max(0.0, (ends[k] - previous_end) / self.pace)
                    point_s = settle_s[start + k] + integrate_s[start + k]
                    settle_share = settle_s[start + k] / max(point_s, 1e-12)
                    if not self._wait_point(generation, duration, settle_share):
                        return
                previous_end = ends[k]
                with self.lock:
                    if generation != self._generation:
                        return
                    self._reveal(record, k, integrate_s[start + k])

    def _wait_point(self, generation: int, duration_s: float, settle_share: float) -> bool:
        """Wait a paced point's wall time, honouring pause and abort. False when aborted."""
        with self.changed:
            while True:
                while self.state == "PAUSED" and generation == self._generation:
                    self.changed.wait()
                if generation != self._generation:
                    return False
                start = time.monotonic()
                end = start + duration_s
                self._point_window = (start, start + settle_share * duration_s, end)
                while self.state == "RUNNING" and generation == self._generation:
                    remaining = end - time.monotonic()
                    if remaining <= 0:
                        return True
                    self.changed.wait(remaining)
                if generation != self._generation:
                    return False
                # paused mid-point: the point starts again on resume

    def _reveal(self, record: SweepRecord, k: int, integrate_s: float) -> None:
        self._source_level = float(record.source_vpk[k]) or self._source_level
        overload = np.array(record.overload[k], bool)
        for channel, remaining in list(self._forced_overload.items()):
            overload[channel - 1] = True
            if remaining is not None:
                if remaining <= 1:
                    del self._forced_overload[channel]
                else:
                    self._forced_overload[channel] = remaining - 1
        record.overload[k] = overload
        self._measured.append(record, slice(k, k + 1), np.array([integrate_s]))
        half = np.array(record.half_range[k], bool)
        self._last_flags = np.array([overload, half])
        bits = 0
        for i in range(CHANNEL_COUNT):
            if self.channels[i].enabled:
                bits |= (1 << i) if overload[i] else 0
                bits |= (1 << (8 + i)) if half[i] else 0
        self.volt_event |= bits
        if bits & self.volt_enable:
            self.ques_event |= 1  # QUES bit 0: voltage summary (inferred)
        self.oper_event |= OPER_MEASURING
        if self.on_point is not None:
            self.on_point(self._measured.count)

    # ---------------------------------------------------------------- traces

    def _validate_feed(self, feed: Feed) -> None:
        if self.mode == "SINE" and feed.kind == "COH":
            raise ScpiError(-221, "coherence is an FFT measurement")
        for channel in feed.channels:
            if not self.channels[channel - 1].enabled:
                raise ScpiError(-221, f"channel {channel} is off (INP{channel} ON first)")
        if feed.kind == "RAT" and self.mode == "SINE":
            out, ref = feed.channels
            pair = self.settings.reference == "PAIR"
            allowed = {(2, 1), (4, 3)} if pair else {(2, 1), (3, 1), (4, 1)}
            if (out, ref) not in allowed:
                raise ScpiError(-221, f"XFR:POW:RAT {out},{ref} with REF {self.settings.reference}")

    def trace(self, number: int) -> Register:
        """The current data of trace ``number`` (1..4, CALC1..CALC4) in engineering units."""
        with self.lock:
            feed = parse_feed(self.settings.feeds[number - 1])
            m = self._measured
            n = m.count
            eu = m.channel_v[:n] / m.v_per_eu
            x = m.frequency_hz[:n].copy()
            if feed.kind == "RAT":
                out, ref = feed.channels
                y = eu[:, out - 1] / eu[:, ref - 1]
            elif feed.kind == "LIN":
                y = eu[:, feed.channels[0] - 1].copy()  # peak amplitude (inferred)
            elif feed.kind == "CROS":
                a, b = feed.channels
                y = np.conj(eu[:, a - 1]) * eu[:, b - 1]  # conj(X_a) X_b, peak^2 (inferred)
            elif feed.kind == "VAR":
                y = m.variance[:n, feed.channels[0] - 1].copy()
            elif feed.kind == "XTIM":
                x, y = self._time_record(feed.channels[0])
            else:
                raise ScpiError(-221, "coherence is an FFT measurement")
            return Register(feed.text, x, y)

    def _time_record(self, channel: int) -> tuple[np.ndarray, np.ndarray]:
        """Time trace of the last measured point: the steady-state sine rebuilt from its
        measured complex amplitude (the simulator returns amplitudes, not time records),
        4 periods in 256 samples, in engineering units."""
        m = self._measured
        if m.count == 0:
            return np.zeros(0), np.zeros(0)
        f = m.frequency_hz[m.count - 1]
        amplitude = m.channel_v[m.count - 1, channel - 1] / m.v_per_eu[channel - 1]
        t = np.arange(256) * (4.0 / f) / 256
        return t, np.real(amplitude * np.exp(2j * np.pi * f * t))

    def _formatted(self, register: Register, fmt: str) -> np.ndarray:
        y = register.y
        if not np.iscomplexobj(y):
            y = y.astype(complex)
        if fmt in _COMPLEX_FORMATS:
            out = np.empty(2 * y.size)
            out[0::2], out[1::2] = y.real, y.imag
            return out
        if fmt == "MLIN":
            return np.abs(y)
        if fmt == "MLOG":
            with np.errstate(divide="ignore"):
                return 20.0 * np.log10(np.maximum(np.abs(y), 1e-300))
        if fmt == "PHAS":
            return np.degrees(np.angle(y))
        if fmt == "UPH":
            return np.degrees(np.unwrap(np.angle(y)))
        if fmt == "REAL":
            return y.real.copy()
        if fmt == "IMAG":
            return y.imag.copy()
        if fmt == "GDEL":
            if y.size < 2:
                return np.zeros(y.size)
            return -np.gradient(np.unwrap(np.angle(y)), 2 * np.pi * register.x)
        raise ScpiError(-224, fmt)

    def _encode(self, values: np.ndarray) -> bytes:
        kind, length = self.format
        if kind == "REAL":
            return definite_block(np.asarray(values, f">f{length // 8}").tobytes())
        if values.size == 0:
            return b""
        digits = length
        return ",".join(format_real(float(v), digits) for v in values).encode()

    # ---------------------------------------------------------------- command registration

    def _register_commands(self) -> None:
        t = self.tree
        # common commands
        t.add("*IDN", query=lambda p, s: self.idn)
        t.add("*OPT", query=lambda p, s: ",".join(self.options) or "0")
        t.add("*RST", setter=lambda p, s: self._reset(preset=False))
        t.add("*CLS", setter=self._cls)
        t.add("*ESE", setter=lambda p, s: setattr(self, "ese", self._int(p, 0, 255)),
              query=lambda p, s: format_int(self.ese))
        t.add("*ESR", query=self._esr_query)
        t.add("*SRE", setter=lambda p, s: setattr(self, "sre", self._int(p, 0, 255) & ~64),
              query=lambda p, s: format_int(self.sre))
        t.add("*STB", query=lambda p, s: format_int(self.status_byte()))
        t.add("*TST", query=lambda p, s: format_int(0))
        t.add("*CAL", query=lambda p, s: format_int(0))
        t.add("*OPC", setter=self._opc)
        t.add("*TRG", setter=lambda p, s: self._forbid_in_sine("*TRG"))
        # *OPC? and *WAI wait outside the instrument lock: ScpiSession handles them.
        t.add("SYSTem:ERRor[:NEXT]", query=self._error_query)
        t.add("SYSTem:PRESet", setter=lambda p, s: self._reset(preset=True))
        t.add("SYSTem:VERSion", query=lambda p, s: "1992.0")
        # mode
        t.add("INSTrument[:SELect]", setter=self._inst_select, query=lambda p, s: self.mode)
        t.add("INSTrument:NSELect", setter=self._inst_nselect,
              query=lambda p, s: format_int({v: k for k, v in _MODES_BY_NUMBER.items()}[self.mode]))
        # frequency and sweep
        t.add("[SENSe:]FREQuency:STARt", setter=self._freq_setter("start_hz"),
              query=self._freq_query("start_hz"))
        t.add("[SENSe:]FREQuency:STOP", setter=self._freq_setter("stop_hz"),
              query=self._freq_query("stop_hz"))
        t.add("[SENSe:]FREQuency:CENTer", setter=self._center, query=self._hz_query(
            lambda: (self.settings.start_hz + self.settings.stop_hz) / 2))
        t.add("[SENSe:]FREQuency:SPAN", setter=self._span, query=self._hz_query(
            lambda: abs(self.settings.stop_hz - self.settings.start_hz)))
        t.add("[SENSe:]FREQuency:SPAN:FULL", setter=self._span_full)
        t.add("[SENSe:]FREQuency:MANual", setter=self._manual, query=self._hz_query(
            lambda: self.settings.manual_hz))
        t.add("[SENSe:]FREQuency:RESolution", setter=self._resolution, query=self._resolution_query)
        t.add("[SENSe:]FREQuency:RESolution:AUTO", setter=self._bool_setter(
            lambda v: setattr(self.settings, "resolution_auto", v)),
            query=lambda p, s: format_bool(self.settings.resolution_auto))
        t.add("[SENSe:]SWEep:SPACing", setter=self._choice_setter(
            "spacing", ("LINear", "LOGarithmic"), sine=True),
            query=lambda p, s: self.settings.spacing)
        t.add("[SENSe:]SWEep:DIRection", setter=self._choice_setter(
            "direction", ("UP", "DOWN"), sine=True), query=lambda p, s: self.settings.direction)
        t.add("[SENSe:]SWEep:MODE", setter=self._choice_setter(
            "sweep_mode", ("AUTO", "MANual"), sine=True),
            query=lambda p, s: self.settings.sweep_mode)
        t.add("[SENSe:]SWEep:STIMe", setter=self._cycles_setter("settle", minimum_cycles=0.0),
              query=self._cycles_query("settle"))
        t.add("[SENSe:]SWEep:DWELl", setter=self._cycles_setter("dwell", minimum_cycles=1.0),
              query=self._cycles_query("dwell"))
        t.add("[SENSe:]SWEep:TIME", setter=lambda p, s: self._forbid_in_sine("SWE:TIME"))
        t.add("[SENSe:]SWEep:OVERlap", setter=lambda p, s: self._forbid_in_sine("SWE:OVER"))
        t.add("[SENSe:]REFerence", setter=self._choice_setter(
            "reference", ("PAIR", "SINGle")), query=lambda p, s: self.settings.reference)
        t.add("[SENSe:]WINDow[:TYPE]", setter=self._fft_only("WIND", "window"),
              query=lambda p, s: self.settings.window)
        t.add("[SENSe:]AVERage:TYPE", setter=self._fft_only("AVER:TYPE", "average_type"),
              query=lambda p, s: self.settings.average_type)
        t.add("TRIGger[:SEQuence]:SOURce", setter=self._fft_only("TRIG:SOUR", "trigger_source"),
              query=lambda p, s: self.settings.trigger_source)
        # inputs
        t.add("INPut#[:STATe]", setter=self._input_state,
              query=lambda p, s: format_bool(self._channel(s).enabled))
        t.add("INPut#:COUPling", setter=self._channel_choice("coupling", ("AC", "DC")),
              query=lambda p, s: self._channel(s).coupling)
        t.add("INPut#:LOW", setter=self._channel_choice("low", ("GROund", "FLOat")),
              query=lambda p, s: self._channel(s).low)
        t.add("INPut#:BIAS[:STATe]", setter=self._channel_bool("bias"),
              query=lambda p, s: format_bool(self._channel(s).bias))
        t.add("[SENSe:]VOLTage#[:DC]:RANGe[:UPPer]", setter=self._range,
              query=lambda p, s: format_real(self._channel(s).range_dbvrms))
        t.add("[SENSe:]VOLTage#[:DC]:RANGe:AUTO", setter=self._channel_bool("autorange"),
              query=lambda p, s: format_bool(self._channel(s).autorange))
        t.add("[SENSe:]VOLTage#[:DC]:RANGe:AUTO:DIRection", setter=self._autorange_direction)
        t.add("[SENSe:]VOLTage#[:DC]:RANGe:UNIT:XDCR:LABel", setter=self._label,
              query=lambda p, s: self._channel(s).label)
        t.add("[SENSe:]VOLTage#[:DC]:RANGe:UNIT:USER:SFACtor", setter=self._sfac,
              query=lambda p, s: format_real(self._channel(s).user_sfac_v_per_eu))
        t.add("[SENSe:]VOLTage#[:DC]:RANGe:UNIT:USER[:STATe]", setter=self._channel_bool(
            "user_units"), query=lambda p, s: format_bool(self._channel(s).user_units))
        # source
        t.add("OUTPut[:STATe]",
              setter=self._bool_setter(lambda v: setattr(self.source, "output", v)),
              query=lambda p, s: format_bool(self.source.output))
        t.add("SOURce:VOLTage[:LEVel][:IMMediate][:AMPLitude]", setter=self._source_level_set,
              query=self._vpk_query(lambda: self.source.level_vpk))
        t.add("SOURce:VOLTage[:LEVel]:AUTO[:STATe]", setter=self._bool_setter(
            lambda v: setattr(self.source, "auto_level", v)),
            query=lambda p, s: format_bool(self.source.auto_level))
        t.add("SOURce:VOLTage[:LEVel]:REFerence:CHANnel", setter=self._ref_channel_set,
              query=lambda p, s: f"INP{self.source.reference_channel}")
        t.add("SOURce:VOLTage[:LEVel]:REFerence[:LEVel]", setter=self._level_eu_setter("reference"),
              query=self._level_eu_query("reference"))
        t.add("SOURce:VOLTage[:LEVel]:REFerence:TOLerance", setter=self._tolerance,
              query=lambda p, s: format_real(self.source.tolerance_db))
        t.add("SOURce:VOLTage[:LEVel]:LIMit[:LEVel]", setter=self._limit,
              query=self._vpk_query(lambda: self.source.limit_vpk))
        t.add("SOURce:VOLTage[:LEVel]:LIMit:INPut[:LEVel]", setter=self._level_eu_setter(
            "input_limit"), query=self._level_eu_query("input_limit"))
        t.add("SOURce:VOLTage[:LEVel]:LIMit:INPut:CHANnel", setter=self._limit_channel_set,
              query=lambda p, s: f"INP{self.source.input_limit_channel}")
        t.add("SOURce:VOLTage[:LEVel]:LIMit:INPut:STATe", setter=self._bool_setter(
            lambda v: setattr(self.source, "input_limit_on", v)),
            query=lambda p, s: format_bool(self.source.input_limit_on))
        t.add("SOURce:VOLTage[:LEVel]:SLEW", setter=self._slew,
              query=lambda p, s: format_real(self.source.slew_v_per_s))
        # traces and data
        t.add("CALCulate#:FEED", setter=self._feed, query=lambda p, s: format_string(
            self.settings.feeds[self._trace_index(s)]))
        t.add("CALCulate#:FORMat", setter=self._calc_format,
              query=lambda p, s: self.settings.formats[self._trace_index(s)])
        t.add("CALCulate#:DATA", query=self._calc_data)
        t.add("CALCulate#:X[:DATA]", query=self._calc_x)
        t.add("CALCulate#:DATA:HEADer:POINts", query=lambda p, s: format_int(
            self.trace(self._trace_index(s) + 1).x.size))
        t.add("TRACe[:DATA]", setter=self._trace_copy, query=self._trace_data)
        t.add("TRACe:X[:DATA]", query=self._trace_x)
        t.add("FORMat[:DATA]", setter=self._format_set,
              query=lambda p, s: f"{self.format[0]},{self.format[1]:+d}")
        # running
        t.add("ABORt", setter=lambda p, s: self._abort())
        t.add("INITiate[:IMMediate]", setter=lambda p, s: self._initiate())
        t.add("INITiate:CONTinuous", setter=self._continuous,
              query=lambda p, s: format_bool(self.continuous))
        # status
        t.add("STATus:OPERation:CONDition", query=lambda p, s: format_int(self.oper_condition()))
        t.add("STATus:OPERation[:EVENt]", query=self._read_event("oper_event"))
        t.add("STATus:OPERation:ENABle", setter=self._enable("oper_enable"),
              query=lambda p, s: format_int(self.oper_enable))
        t.add("STATus:QUEStionable:CONDition", query=lambda p, s: format_int(
            1 if self._volt_condition() & self.volt_enable else 0))
        t.add("STATus:QUEStionable[:EVENt]", query=self._read_event("ques_event"))
        t.add("STATus:QUEStionable:ENABle", setter=self._enable("ques_enable"),
              query=lambda p, s: format_int(self.ques_enable))
        t.add("STATus:QUEStionable:VOLTage:CONDition", query=lambda p, s: format_int(
            self._volt_condition()))
        t.add("STATus:QUEStionable:VOLTage[:EVENt]", query=self._read_event("volt_event"))
        t.add("STATus:QUEStionable:VOLTage:ENABle", setter=self._enable("volt_enable"),
              query=lambda p, s: format_int(self.volt_enable))
        t.add("STATus:PRESet", setter=self._status_preset)

    # ---------------------------------------------------------------- parameter helpers

    @staticmethod
    def _one(params: tuple[str, ...]) -> str:
        if not params:
            raise ScpiError(-109)
        if len(params) > 1:
            raise ScpiError(-108, ",".join(params[1:]))
        return params[0]

    def _int(self, params: tuple[str, ...], lo: int, hi: int) -> int:
        q = parse_quantity(self._one(params), ("",), "")
        if q.keyword is not None:
            return hi if q.keyword == "MAX" else lo
        value = round(q.value)
        if not lo <= value <= hi:
            raise ScpiError(-222, f"{value} outside {lo}..{hi}; value not changed")
        return value

    @staticmethod
    def _limited(q: Quantity, current: float, lo: float, hi: float, step: float) -> float:
        """Resolve MAX/MIN/UP/DOWN/DEF and check the range (-222, value not changed)."""
        if q.keyword == "MAX":
            return hi
        if q.keyword == "MIN":
            return lo
        if q.keyword == "UP":
            return min(hi, current + step)
        if q.keyword == "DOWN":
            return max(lo, current - step)
        if q.keyword == "DEF":
            raise ScpiError(-224, "DEF")
        if not lo - 1e-12 <= q.value <= hi + 1e-12:
            raise ScpiError(-222, f"{q.value:g} {q.unit} outside {lo:g}..{hi:g}; value not changed")
        return q.value

    def _bool_setter(self, apply: Callable[[bool], None]) -> Callable[..., None]:
        return lambda p, s: apply(parse_bool(self._one(p)))

    def _query_unit(self, params: tuple[str, ...], unit: str) -> str | None:
        """``<query>? UNIT`` answers the unit in use (inferred response: a quoted string)."""
        if params and params[0].upper() == "UNIT":
            return format_string(unit)
        if params:
            raise ScpiError(-108, params[0])
        return None

    # ---------------------------------------------------------------- handlers: common

    def _cls(self, params: tuple[str, ...], suffix: int | None) -> None:
        self.errors.clear()
        self.esr = 0
        self.oper_event = self.ques_event = self.volt_event = 0
        self._opc_armed = False

    def _esr_query(self, params: tuple[str, ...], suffix: int | None) -> str:
        value, self.esr = self.esr, 0
        return format_int(value)

    def _opc(self, params: tuple[str, ...], suffix: int | None) -> None:
        if self.state == "IDLE":
            self.esr |= ESR_OPC
        else:
            self._opc_armed = True

    def _error_query(self, params: tuple[str, ...], suffix: int | None) -> str:
        if not self.errors:
            return '+0,"No error"'
        code, message = self.errors.popleft()
        return f"{code:+d},{format_string(message)}"

    def _status_preset(self, params: tuple[str, ...], suffix: int | None) -> None:
        self.oper_enable = self.ques_enable = 0
        self.volt_enable = 0x0F0F

    def _read_event(self, name: str) -> Callable[..., str]:
        def read(params: tuple[str, ...], suffix: int | None) -> str:
            value = getattr(self, name)
            setattr(self, name, 0)
            return format_int(value)
        return read

    def _enable(self, name: str) -> Callable[..., None]:
        return lambda p, s: setattr(self, name, self._int(p, 0, 65535))

    # ---------------------------------------------------------------- handlers: mode

    def _select_mode(self, mode: str) -> None:
        option = _MODE_OPTION.get(mode)
        if option is not None and option not in self.options:
            raise ScpiError(-241, f"{mode} needs option {option}")
        if mode not in ("FFT", "SINE"):
            raise ScpiError(-221, f"{mode} mode is not simulated")
        if mode != self.mode:
            self._abort()
            self.mode = mode

    def _inst_select(self, params: tuple[str, ...], suffix: int | None) -> None:
        choice = parse_choice(self._one(params), ("FFT", "OCTave", "ORDer", "SINE", "HISTogram"))
        self._select_mode(choice)

    def _inst_nselect(self, params: tuple[str, ...], suffix: int | None) -> None:
        number = self._int(params, 1, len(_MODES_BY_NUMBER))
        self._select_mode(_MODES_BY_NUMBER[number])

    # ---------------------------------------------------------------- handlers: frequency

    def _hz_query(self, get: Callable[[], float]) -> Callable[..., str]:
        def query(params: tuple[str, ...], suffix: int | None) -> str:
            unit = self._query_unit(params, "HZ")
            return unit if unit is not None else format_real(get())
        return query

    def _freq_query(self, name: str) -> Callable[..., str]:
        return self._hz_query(lambda: getattr(self.settings, name))

    def _frequency(self, params: tuple[str, ...], current: float) -> float:
        q = parse_quantity(self._one(params), ("HZ",), "HZ")
        lo = FREQUENCY_STEP_HZ if self.mode == "SINE" else 0.0
        value = self._limited(q, current, lo, self._max_frequency(), 1.0)
        return _round_frequency(value)

    def _freq_setter(self, name: str) -> Callable[..., None]:
        def setter(params: tuple[str, ...], suffix: int | None) -> None:
            s = self.settings
            setattr(s, name, self._frequency(params, getattr(s, name)))
        return setter

    def _center(self, params: tuple[str, ...], suffix: int | None) -> None:
        s = self.settings
        half = abs(s.stop_hz - s.start_hz) / 2
        center = self._frequency(params, (s.start_hz + s.stop_hz) / 2)
        lo = FREQUENCY_STEP_HZ if self.mode == "SINE" else 0.0
        if center - half < lo or center + half > self._max_frequency():
            raise ScpiError(-222, "center with this span leaves the band; value not changed")
        s.start_hz, s.stop_hz = _round_frequency(center - half), _round_frequency(center + half)

    def _span(self, params: tuple[str, ...], suffix: int | None) -> None:
        s = self.settings
        center = (s.start_hz + s.stop_hz) / 2
        span = self._frequency(params, abs(s.stop_hz - s.start_hz))
        lo = FREQUENCY_STEP_HZ if self.mode == "SINE" else 0.0
        start = max(lo, center - span / 2)
        s.start_hz, s.stop_hz = _round_frequency(start), _round_frequency(min(
            start + span, self._max_frequency()))

    def _span_full(self, params: tuple[str, ...], suffix: int | None) -> None:
        self._forbid_in_sine("FREQ:SPAN:FULL")
        self.settings.start_hz, self.settings.stop_hz = 0.0, self._max_frequency()

    def _manual(self, params: tuple[str, ...], suffix: int | None) -> None:
        self._require_sine("FREQ:MAN")
        self.settings.manual_hz = self._frequency(params, self.settings.manual_hz)

    def _resolution(self, params: tuple[str, ...], suffix: int | None) -> None:
        s = self.settings
        q = parse_quantity(self._one(params), ("HZ", "PNT/SWP"), s.resolution_unit)
        if q.keyword is not None:
            value = self._limited(q, s.points, MIN_POINTS, MAX_POINTS, 1)
            s.points = int(value)
            return
        if q.unit == "HZ":
            if s.spacing == "LOG" and self.mode == "SINE":
                raise ScpiError(-221, "resolution in HZ needs linear spacing (use PNT/SWP)")
            if q.value <= 0:
                raise ScpiError(-222, "resolution must be positive; value not changed")
            points = round(abs(s.stop_hz - s.start_hz) / q.value) + 1
        else:
            points = round(q.value)
        if not MIN_POINTS <= points <= MAX_POINTS:
            raise ScpiError(-222, f"{points} points per sweep (2..{MAX_POINTS}); value not changed")
        s.points = points
        s.resolution_unit = q.unit

    def _resolution_query(self, params: tuple[str, ...], suffix: int | None) -> str:
        s = self.settings
        unit = self._query_unit(params, s.resolution_unit)
        if unit is not None:
            return unit
        if s.resolution_unit == "HZ":
            return format_real(abs(s.stop_hz - s.start_hz) / max(s.points - 1, 1))
        return format_real(s.points)

    def _choice_setter(self, name: str, choices: Sequence[str], sine: bool = False
                       ) -> Callable[..., None]:
        def setter(params: tuple[str, ...], suffix: int | None) -> None:
            if sine:
                self._require_sine(name)
            setattr(self.settings, name, parse_choice(self._one(params), choices))
        return setter

    def _fft_only(self, what: str, name: str) -> Callable[..., None]:
        def setter(params: tuple[str, ...], suffix: int | None) -> None:
            self._forbid_in_sine(what)
            setattr(self.settings, name, self._one(params).upper())
        return setter

    def _cycles_setter(self, name: str, minimum_cycles: float) -> Callable[..., None]:
        def setter(params: tuple[str, ...], suffix: int | None) -> None:
            self._require_sine(name)
            current_value, current_unit = getattr(self.settings, name)
            # a bare number keeps the unit in use (inferred)
            q = parse_quantity(self._one(params), ("S", "CYCLE"), current_unit)
            if q.unit == "CYCLE":
                value = self._limited(q, current_value, minimum_cycles, MAX_CYCLES, 1.0)
            else:
                lo = MIN_DWELL_S if minimum_cycles > 0 else 0.0
                value = self._limited(q, current_value, lo, 1.0e5, 0.1)
            setattr(self.settings, name, (value, q.unit))
        return setter

    def _cycles_query(self, name: str) -> Callable[..., str]:
        def query(params: tuple[str, ...], suffix: int | None) -> str:
            value, unit = getattr(self.settings, name)
            answer = self._query_unit(params, unit)
            return answer if answer is not None else format_real(value)
        return query

    # ---------------------------------------------------------------- handlers: inputs

    def _channel(self, suffix: int | None) -> ChannelSettings:
        n = 1 if suffix is None else suffix
        if not 1 <= n <= CHANNEL_COUNT:
            raise ScpiError(-114, f"channel {n}")
        return self.channels[n - 1]

    def _input_state(self, params: tuple[str, ...], suffix: int | None) -> None:
        n = 1 if suffix is None else suffix
        channel = self._channel(n)
        on = parse_bool(self._one(params))
        if n == 1 and not on:
            raise ScpiError(-221, "channel 1 is always on")  # (inferred)
        if n >= 3 and on and "AY6" not in self.options:
            raise ScpiError(-241, "four channels need option AY6")
        channel.enabled = on
        if self._four_channel():
            limit = MAX_FREQUENCY_4CH_HZ  # clamp to the four-channel band (inferred)
            for s in self.modes.values():
                s.start_hz, s.stop_hz = min(s.start_hz, limit), min(s.stop_hz, limit)

    def _channel_choice(self, name: str, choices: Sequence[str]) -> Callable[..., None]:
        def setter(params: tuple[str, ...], suffix: int | None) -> None:
            setattr(self._channel(suffix), name, parse_choice(self._one(params), choices))
        return setter

    def _channel_bool(self, name: str) -> Callable[..., None]:
        def setter(params: tuple[str, ...], suffix: int | None) -> None:
            setattr(self._channel(suffix), name, parse_bool(self._one(params)))
        return setter

    def _range(self, params: tuple[str, ...], suffix: int | None) -> None:
        channel = self._channel(suffix)
        q = parse_quantity(self._one(params), ("DBVRMS", "VPK"), "DBVRMS")
        if q.keyword is None and q.unit == "VPK":
            if q.value <= 0:
                raise ScpiError(-222, "range must be positive; value not changed")
            q = Quantity(20 * math.log10(q.value / math.sqrt(2.0)), "DBVRMS")
        value = self._limited(q, channel.range_dbvrms, float(INPUT_RANGES_DBVRMS[-1]),
                              float(INPUT_RANGES_DBVRMS[0]), 2.0)
        # the smallest range that holds the requested level (inferred)
        candidates = INPUT_RANGES_DBVRMS[value - 1e-9 <= INPUT_RANGES_DBVRMS]
        channel.range_dbvrms = float(candidates[-1])
        channel.autorange = False  # a fixed range turns autorange off (inferred)

    def _autorange_direction(self, params: tuple[str, ...], suffix: int | None) -> None:
        self._channel(suffix)
        direction = parse_choice(self._one(params), ("UP", "EITHer"))
        if direction == "UP":
            self._forbid_in_sine("VOLT:RANG:AUTO:DIR UP")

    def _label(self, params: tuple[str, ...], suffix: int | None) -> None:
        text = self._one(params)
        label = unquote(text) if text[:1] in "'\"" else text
        if not label or len(label) > 6:
            raise ScpiError(-224, f"transducer label {text}")
        self._channel(suffix).label = label.upper()

    def _sfac(self, params: tuple[str, ...], suffix: int | None) -> None:
        channel = self._channel(suffix)
        q = parse_quantity(self._one(params), ("V/EU",), "V/EU")
        value = self._limited(q, channel.user_sfac_v_per_eu, 1e-12, 1e12, 0.0)
        if value <= 0:
            raise ScpiError(-222, "sensitivity must be positive; value not changed")
        channel.user_sfac_v_per_eu = value

    # ---------------------------------------------------------------- handlers: source

    def _vpk_query(self, get: Callable[[], float]) -> Callable[..., str]:
        def query(params: tuple[str, ...], suffix: int | None) -> str:
            unit = self._query_unit(params, "VPK")
            return unit if unit is not None else format_real(get())
        return query

    def _source_level_set(self, params: tuple[str, ...], suffix: int | None) -> None:
        q = parse_quantity(self._one(params), ("VPK",), "VPK")
        self.source.level_vpk = self._limited(q, self.source.level_vpk, 0.0, MAX_SOURCE_VPK, 0.1)

    def _limit(self, params: tuple[str, ...], suffix: int | None) -> None:
        q = parse_quantity(self._one(params), ("VPK",), "VPK")
        self.source.limit_vpk = self._limited(q, self.source.limit_vpk, 0.0, MAX_SOURCE_VPK, 0.1)

    def _parse_channel_word(self, params: tuple[str, ...]) -> int:
        word = self._one(params).strip().upper()
        match = re.fullmatch(r"INP(?:UT)?([1-4])", word)
        if match is None:
            raise ScpiError(-224, f"{word} (expected INP1..INP4)")
        return int(match.group(1))

    def _ref_channel_set(self, params: tuple[str, ...], suffix: int | None) -> None:
        self.source.reference_channel = self._parse_channel_word(params)

    def _limit_channel_set(self, params: tuple[str, ...], suffix: int | None) -> None:
        self.source.input_limit_channel = self._parse_channel_word(params)

    def _level_eu_setter(self, name: str) -> Callable[..., None]:
        def setter(params: tuple[str, ...], suffix: int | None) -> None:
            current_value, current_unit = getattr(self.source, name)
            q = parse_quantity(self._one(params), ("EU", "VPK"), current_unit)
            value = self._limited(q, current_value, 0.0, 1.0e9, 0.1)
            if value <= 0:
                raise ScpiError(-222, "level must be positive; value not changed")
            setattr(self.source, name, (value, q.unit))
            if name == "input_limit":
                self.source.input_limit_on = True
        return setter

    def _level_eu_query(self, name: str) -> Callable[..., str]:
        def query(params: tuple[str, ...], suffix: int | None) -> str:
            value, unit = getattr(self.source, name)
            answer = self._query_unit(params, unit)
            return answer if answer is not None else format_real(value)
        return query

    def _tolerance(self, params: tuple[str, ...], suffix: int | None) -> None:
        q = parse_quantity(self._one(params), ("DB",), "DB")
        self.source.tolerance_db = self._limited(q, self.source.tolerance_db, 0.1, 20.0, 0.1)

    def _slew(self, params: tuple[str, ...], suffix: int | None) -> None:
        q = parse_quantity(self._one(params), ("V/S",), "V/S")
        self.source.slew_v_per_s = self._limited(q, self.source.slew_v_per_s, 1e-3, 1e4, 1.0)

    # ---------------------------------------------------------------- handlers: traces

    def _trace_index(self, suffix: int | None) -> int:
        n = 1 if suffix is None else suffix
        if not 1 <= n <= 4:
            raise ScpiError(-114, f"trace {n}")
        return n - 1

    def _feed(self, params: tuple[str, ...], suffix: int | None) -> None:
        index = self._trace_index(suffix)
        feed = parse_feed(unquote(self._one(params)))
        self._validate_feed(feed)
        self.settings.feeds[index] = feed.text

    def _calc_format(self, params: tuple[str, ...], suffix: int | None) -> None:
        index = self._trace_index(suffix)
        self.settings.formats[index] = parse_choice(self._one(params), _FORMATS)

    def _calc_data(self, params: tuple[str, ...], suffix: int | None) -> bytes:
        index = self._trace_index(suffix)
        register = self.trace(index + 1)
        return self._encode(self._formatted(register, self.settings.formats[index]))

    def _calc_x(self, params: tuple[str, ...], suffix: int | None) -> bytes:
        return self._encode(self.trace(self._trace_index(suffix) + 1).x)

    def _register_name(self, word: str) -> tuple[str, int]:
        match = re.fullmatch(r"(D|TRAC(?:E)?)([1-8])", word.strip().upper())
        if match is None:
            raise ScpiError(-224, f"{word} (expected D1..D8 or TRAC1..TRAC4)")
        kind = "D" if match.group(1) == "D" else "TRAC"
        number = int(match.group(2))
        if kind == "TRAC" and number > 4:
            raise ScpiError(-224, word)
        return kind, number

    def _register(self, word: str) -> Register:
        kind, number = self._register_name(word)
        if kind == "TRAC":
            return self.trace(number)
        if number not in self.registers:
            raise ScpiError(-221, f"data register D{number} is empty")
        return self.registers[number]

    def _trace_copy(self, params: tuple[str, ...], suffix: int | None) -> None:
        if len(params) != 2:
            raise ScpiError(-109 if len(params) < 2 else -108, "TRAC:DATA <register>,<trace>")
        kind, number = self._register_name(params[0])
        if kind != "D":
            raise ScpiError(-224, f"{params[0]}: copy into a data register D1..D8")
        source = self._register(params[1])
        self.registers[number] = Register(source.feed, source.x.copy(), source.y.copy())

    def _trace_data(self, params: tuple[str, ...], suffix: int | None) -> bytes:
        register = self._register(self._one(params))
        y = register.y
        if register.is_complex:  # frequency responses and spectra: interleaved real, imag
            values = np.empty(2 * y.size)
            values[0::2], values[1::2] = y.real, y.imag
        else:
            values = y
        return self._encode(values)

    def _trace_x(self, params: tuple[str, ...], suffix: int | None) -> bytes:
        return self._encode(self._register(self._one(params)).x)

    def _format_set(self, params: tuple[str, ...], suffix: int | None) -> None:
        if not params or len(params) > 2:
            raise ScpiError(-109 if not params else -108)
        kind = parse_choice(params[0], ("ASCii", "REAL"))
        if kind == "ASC":
            length = 12 if len(params) == 1 else self._format_length(params[1])
            if not 3 <= length <= 12:
                raise ScpiError(-224, f"ASCII length {length} (3..12)")
        else:
            length = 64 if len(params) == 1 else self._format_length(params[1])
            if length not in (32, 64):
                raise ScpiError(-224, f"REAL length {length} (32 or 64)")
        self.format = (kind, length)

    @staticmethod
    def _format_length(text: str) -> int:
        try:
            return int(text)
        except ValueError:
            raise ScpiError(-224, f"format length {text}") from None

    # ---------------------------------------------------------------- handlers: running

    def _continuous(self, params: tuple[str, ...], suffix: int | None) -> None:
        # In swept sine, INIT:CONT OFF pauses and ON resumes a sweep in progress; a finished
        # sweep is not restarted (inferred).
        on = parse_bool(self._one(params))
        self.continuous = on
        if on:
            self._resume()
        else:
            self._pause()


# --------------------------------------------------------------------------------------------
# a controller's connection


class _DeviceCleared(Exception):  # noqa: N818 - a signal, not an error
    """A device clear ended a ``*OPC?`` or ``*WAI`` wait."""


class ScpiSession:
    """One controller's connection: its own header path; the instrument is shared.

    :meth:`execute` runs one program message and returns the response message (bytes ending
    with a line feed) or ``None`` when the message held no query.
    """

    def __init__(self, analyser: VirtualAnalyser) -> None:
        self.analyser = analyser
        self._cleared = 0

    def device_clear(self) -> None:
        """IEEE 488.2 device clear: pending ``*OPC?``/``*WAI`` waits of this session end."""
        with self.analyser.changed:
            self._cleared += 1
            self.analyser.changed.notify_all()

    def execute(self, message: str | bytes) -> bytes | None:
        """Run a program message (newline and/or EOI already stripped or not)."""
        a = self.analyser
        if isinstance(message, bytes):
            message = message.decode("latin-1")
        message = message.strip("\r\n")
        if not message.strip():
            return None
        responses: list[bytes] = []
        path: list[str] = []
        try:
            units = list(split_units(message))
        except ScpiError as error:
            a.push_error(error.code, error.message)
            return None
        for text in units:
            try:
                unit = parse_unit(text)
                answer = self._execute_unit(unit, path)
            except _DeviceCleared:
                return None  # the rest of the message and its responses are gone
            except ScpiError as error:
                a.push_error(error.code, error.message)
                if -199 <= error.code <= -100:
                    break  # a command error ends the message
                continue
            if answer is not None:
                responses.append(answer if isinstance(answer, bytes) else answer.encode())
        if not responses:
            return None
        return b";".join(responses) + b"\n"

    def _execute_unit(self, unit: ProgramUnit, path: list[str]) -> str | bytes | None:
        a = self.analyser
        header = unit.header
        if header.startswith("*"):
            name = header.upper()
            if name == "*OPC" and unit.is_query:
                self._wait_idle()
                return "+1"
            if name == "*WAI" and not unit.is_query:
                self._wait_idle()
                return None
            with a.lock:
                return a.tree.resolve_common(header, unit.is_query)(unit.params, None)
        absolute = header.startswith(":")
        tokens = [t for t in header.lstrip(":").split(":")]
        if any(not t for t in tokens):
            raise ScpiError(-102, unit.text)
        full = tokens if absolute else [*path, *tokens]
        path[:] = full[:-1]
        if a.mode == "SINE" and full[0].upper() in ("TRIG", "TRIGGER", "ARM"):
            raise ScpiError(-221, f"{':'.join(full)} not valid in swept sine")
        resolved = a.tree.resolve(full, unit.is_query)
        with a.lock:
            return resolved.handler(unit.params, resolved.suffix)

    def _wait_idle(self) -> None:
        a = self.analyser
        with a.changed:
            cleared = self._cleared
            while a.state != "IDLE" and self._cleared == cleared:
                a.changed.wait()
            if self._cleared != cleared:
                raise _DeviceCleared
