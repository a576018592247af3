"""What the instrument holds: settings per mode, inputs, source, data registers, measured points.

:class:`InstrumentState` is the base of the command groups (:mod:`rigsim.analyser.commands`)
and of the sweep worker: it declares the state they share and the checks they all make.
``*RST`` and ``SYST:PRES`` set it through :meth:`InstrumentState._reset_settings`.
"""

from __future__ import annotations

import threading
from dataclasses import dataclass, field

import numpy as np

from rigsim.analyser.limits import MAX_FREQUENCY_2CH_HZ, MAX_FREQUENCY_4CH_HZ
from rigsim.analyser.status import StatusRegisters
from rigsim.measurement import CHANNEL_COUNT, SweepRecord
from rigsim.scpi import ScpiError

__all__ = [
    "ChannelSettings",
    "InstrumentState",
    "MeasuredPoints",
    "ModeSettings",
    "Register",
    "SourceSettings",
    "preset_mode",
]


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


def preset_mode(mode: str) -> ModeSettings:
    """The preset settings of ``mode`` (``"SINE"`` or ``"FFT"``)."""
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


class MeasuredPoints:
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


class InstrumentState:
    """The state every command handler and the sweep worker share (a base class, not used alone).

    ``lock`` guards all of it; ``changed`` is notified when a sweep starts, pauses, resumes or
    ends. The mode, settings, inputs, source, data format, data registers and ``INIT:CONT`` are
    what ``*RST`` and ``SYST:PRES`` set.
    """

    lock: threading.RLock
    changed: threading.Condition
    status: StatusRegisters
    options: tuple[str, ...]
    mode: str
    modes: dict[str, ModeSettings]
    channels: list[ChannelSettings]
    source: SourceSettings
    format: tuple[str, int]
    registers: dict[int, Register]
    continuous: bool

    def _reset_settings(self, preset: bool) -> None:
        """The settings of ``*RST`` (preset False) or ``SYST:PRES`` (preset True)."""
        self.mode = "FFT"
        self.modes = {"FFT": preset_mode("FFT"), "SINE": preset_mode("SINE")}
        self.channels = [ChannelSettings(enabled=i < 2) for i in range(CHANNEL_COUNT)]
        self.source = SourceSettings()
        self.format = ("ASC", 12)
        self.registers = {}
        # The two resets differ (35670a.md): *RST leaves INIT:CONT OFF and FREQ:RES:AUTO ON;
        # SYST:PRES the opposite (inferred: the front-panel preset state).
        self.continuous = preset
        for settings in self.modes.values():
            settings.resolution_auto = not preset

    @property
    def settings(self) -> ModeSettings:
        """The settings of the mode in use."""
        return self.modes[self.mode]

    def _channel(self, suffix: int | None) -> ChannelSettings:
        n = 1 if suffix is None else suffix
        if not 1 <= n <= CHANNEL_COUNT:
            raise ScpiError(-114, f"channel {n}")
        return self.channels[n - 1]

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
