"""The swept sine's settings (``[SENSe:]FREQuency``, ``SWEep``, ``REFerence``): band, grid,
manual points, settle and integration times.

The analyser rounds start, centre and manual frequencies to the next lower 15.625 mHz step and
stop and span to the next higher (chapter 18); the read-back checks expect exactly that.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any

from .errors import SettingOutOfRange
from .properties import (
    Parent,
    Subsystem,
    boolean,
    control,
    integer_range,
    number_text,
    on_off_text,
    one_of,
    parse_bool,
    parse_float,
    parse_keyword,
    strict_range,
)

__all__ = ["FREQUENCY_STEP_HZ", "MAX_CYCLES", "MAX_POINTS", "SweptSine", "round_down", "round_up"]

#: Frequency resolution of the swept sine (Hz).
FREQUENCY_STEP_HZ = 0.015625
#: Most points of one swept sine (traces of 401 or 801 points).
MAX_POINTS = 801
#: Integration time in cycles: 1 to 234 (chapter 18).
MAX_CYCLES = 234.0


def round_down(frequency_hz: float) -> float:
    """The analyser's start/manual rounding: the next lower 15.625 mHz step."""
    return math.floor(frequency_hz / FREQUENCY_STEP_HZ + 1e-9) * FREQUENCY_STEP_HZ


def round_up(frequency_hz: float) -> float:
    """The analyser's stop/span rounding: the next higher 15.625 mHz step."""
    return math.ceil(frequency_hz / FREQUENCY_STEP_HZ - 1e-9) * FREQUENCY_STEP_HZ


def _frequency(value: Any, owner: Any) -> float:
    top = owner.max_frequency_hz()
    return strict_range(FREQUENCY_STEP_HZ, top, "Hz")(value, owner)


def _cycles(low: float, high: float) -> Callable[[Any, Any], float]:
    return strict_range(low, high, "cycles")


class SweptSine(Subsystem):
    """Sweep band, resolution, order, manual points and timing of the swept sine.

    Parameters
    ----------
    parent
        The analyser.
    max_frequency_hz
        Callable giving the highest frequency the inputs in use allow.
    """

    start_frequency_hz = control(
        "FREQ:STAR {value} HZ", "FREQ:STAR?",
        """Sweep start in Hz (15.625 mHz up to 51.2 kHz, 25.6 kHz with four channels); the
        analyser rounds it down to 15.625 mHz.""",
        validator=_frequency, to_text=number_text, parse=parse_float, expect=round_down,
        unit="HZ", tolerance=1e-9,
    )
    stop_frequency_hz = control(
        "FREQ:STOP {value} HZ", "FREQ:STOP?",
        """Sweep stop in Hz; the analyser rounds it up to 15.625 mHz.""",
        validator=_frequency, to_text=number_text, parse=parse_float, expect=round_up,
        unit="HZ", tolerance=1e-9,
    )
    manual_frequency_hz = control(
        "FREQ:MAN {value} HZ", "FREQ:MAN?",
        """Frequency measured in manual sweep mode (within start..stop), rounded down.""",
        validator=_frequency, to_text=number_text, parse=parse_float, expect=round_down,
        unit="HZ", tolerance=1e-9,
    )
    resolution_hz = control(
        "FREQ:RES {value} HZ", "FREQ:RES?",
        """Linear sweep resolution in Hz (point spacing); LIN spacing only.""",
        validator=strict_range(FREQUENCY_STEP_HZ, 51200.0, "Hz"), to_text=number_text,
        parse=parse_float, expect=round_up, unit="HZ", implies={"points_per_sweep": None},
    )
    points_per_sweep = control(
        "FREQ:RES {value} PNT/SWP", "FREQ:RES?",
        """Points per sweep, 2 to 801 (preset 101).""",
        validator=integer_range(2, MAX_POINTS, "points"), to_text=str,
        parse=lambda r: round(parse_float(r)), unit="PNT/SWP",
        implies={"resolution_hz": None},
    )
    auto_resolution = control(
        "FREQ:RES:AUTO {value}", "FREQ:RES:AUTO?",
        """Automatic resolution (bool): off for a fixed grid (*RST turns it on).""",
        validator=boolean, to_text=on_off_text, parse=parse_bool,
    )
    settle_cycles = control(
        "SWE:STIM {value} CYCLE", "SWE:STIM?",
        """Settle time after each frequency change, in cycles of the source, 0 to 1e6.""",
        validator=_cycles(0.0, 1e6), to_text=number_text, parse=parse_float, unit="CYCLE",
        implies={"settle_s": None},
    )
    settle_s = control(
        "SWE:STIM {value} S", "SWE:STIM?",
        """Settle time after each frequency change, in seconds, 0 to 1e5.""",
        validator=strict_range(0.0, 1e5, "s"), to_text=number_text, parse=parse_float,
        unit="S", implies={"settle_cycles": None},
    )
    integrate_cycles = control(
        "SWE:DWEL {value} CYCLE", "SWE:DWEL?",
        """Integration time per point in cycles, 1 to 234 (and at least 250 µs).""",
        validator=_cycles(1.0, MAX_CYCLES), to_text=number_text, parse=parse_float,
        unit="CYCLE", implies={"integrate_s": None},
    )
    integrate_s = control(
        "SWE:DWEL {value} S", "SWE:DWEL?",
        """Integration time per point in seconds, 250 µs to 32768 s.""",
        validator=strict_range(250e-6, 32768.0, "s"), to_text=number_text, parse=parse_float,
        unit="S", implies={"integrate_cycles": None},
    )
    spacing = control(
        "SWE:SPAC {value}", "SWE:SPAC?", """Point spacing: ``"LIN"`` or ``"LOG"`` (preset LIN).""",
        validator=one_of(("LIN", "LOG")), parse=parse_keyword,
    )
    direction = control(
        "SWE:DIR {value}", "SWE:DIR?", """Sweep direction: ``"UP"`` or ``"DOWN"`` (preset UP).""",
        validator=one_of(("UP", "DOWN")), parse=parse_keyword,
    )
    sweep_mode = control(
        "SWE:MODE {value}", "SWE:MODE?",
        """``"AUTO"`` sweeps start to stop; ``"MAN"`` measures only the manual frequency.""",
        validator=one_of(("AUTO", "MAN")), parse=parse_keyword,
    )
    reference_pairing = control(
        "REF {value}", "REF?",
        """``"PAIR"``: channel 1 is the reference of 2 and channel 3 of 4; ``"SING"``: channel 1
        is the reference of all (option AY6).""",
        validator=one_of(("PAIR", "SING")), parse=parse_keyword,
    )

    def __init__(self, parent: Parent, max_frequency_hz: Callable[[], float]) -> None:
        super().__init__(parent, "sweep")
        self.max_frequency_hz = max_frequency_hz

    def set_band(self, start_hz: float, stop_hz: float) -> None:
        """Start and stop, written in the order that keeps start below stop throughout.

        Between the two writes the band is the old start to the new stop (or the new start to
        the old stop). Where that band holds more than :data:`MAX_POINTS` at the resolution
        sent, the analyser grows its resolution (a linear sweep's quirk): the resolution is
        then asked for again, where the new band holds it.
        """
        if stop_hz <= start_hz:
            raise SettingOutOfRange(f"sweep: stop {stop_hz:g} Hz must be above start {start_hz:g}")
        current_stop = self.sent.get("stop_frequency_hz")
        if current_stop is None:
            current_stop = self.stop_frequency_hz
        if start_hz >= float(current_stop):
            between = (self.sent.get("start_frequency_hz"), stop_hz)
            self.stop_frequency_hz = stop_hz
            self.start_frequency_hz = start_hz
        else:
            between = (start_hz, float(current_stop))
            self.start_frequency_hz = start_hz
            self.stop_frequency_hz = stop_hz
        resolution = self.sent.get("resolution_hz")
        if resolution is None or between[0] is None:
            return
        if (float(between[1]) - float(between[0])) / float(resolution) + 1 > MAX_POINTS \
                and (stop_hz - start_hz) / float(resolution) + 1 <= MAX_POINTS:
            self.resolution_hz = resolution

    def set_linear_sweep(self, start_hz: float, stop_hz: float, resolution_hz: float,
                         direction: str = "UP") -> None:
        """An automatic sweep on a linear grid: mode, spacing, ``direction`` (``"UP"`` or
        ``"DOWN"``), automatic resolution off, the band (:meth:`set_band`), then
        ``resolution_hz``, which must give at most 801 points over the band just set."""
        self.sweep_mode = "AUTO"
        self.spacing = "LIN"
        self.direction = direction
        self.auto_resolution = False
        self.set_band(start_hz, stop_hz)
        self.resolution_hz = resolution_hz

    def set_timing(self, settle: float, integrate: float, unit: str) -> None:
        """Settle and integration time per point, both in ``"CYCLE"`` or both in ``"S"``."""
        if unit == "CYCLE":
            self.settle_cycles = settle
            self.integrate_cycles = integrate
        elif unit == "S":
            self.settle_s = settle
            self.integrate_s = integrate
        else:
            raise SettingOutOfRange(f"sweep: timing unit {unit!r} is not CYCLE or S")

    def point_time_s(self, frequency_hz: float) -> float:
        """Settle plus integration time of one point from the settings sent (s)."""
        total = 0.0
        for cycles, seconds, floor in (("settle_cycles", "settle_s", 0.0),
                                       ("integrate_cycles", "integrate_s", 250e-6)):
            if cycles in self.sent:
                total += max(float(self.sent[cycles]) / frequency_hz, floor)
            elif seconds in self.sent:
                total += float(self.sent[seconds])
        return total
