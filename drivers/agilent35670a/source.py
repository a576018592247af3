"""The source (``SOURce``, ``OUTPut``): level, limits and the swept sine's auto level.

In swept sine the sweep drives the source (``OUTPut`` does not exist in that mode); the source
limit is always written before anything that could drive the shaker. ``SOUR:VOLT:LIM:INP``
holds every input but the reference below one level during auto level (chapter 19): with
engineering units on, that level is in each input's own unit.
"""

from __future__ import annotations

from typing import Any

from .errors import MalformedReply, SettingOutOfRange
from .properties import (
    Parent,
    Subsystem,
    boolean,
    control,
    number_text,
    on_off_text,
    one_of,
    parse_bool,
    parse_float,
    parse_keyword,
    strict_range,
)

__all__ = ["DEFAULT_SLEW_V_PER_S", "MAX_SOURCE_VPK", "FftSource", "Source"]

#: Highest source amplitude (volts peak).
MAX_SOURCE_VPK = 5.0
#: Source ramp rate :meth:`~.instrument.Agilent35670A.configure_swept_sine` sets unless told
#: (V/s; the analyser's preset is 0, no ramp).
DEFAULT_SLEW_V_PER_S = 1.0
#: Highest input level (the +27 dBVrms range), volts peak.
MAX_INPUT_VPK = 31.66


def _channel(value: Any, owner: Any) -> int:
    if isinstance(value, bool) or value not in (1, 2, 3, 4):
        raise SettingOutOfRange(f"{value!r} is not an input 1..4")
    return int(value)


def _parse_channel(reply: str) -> int:
    text = parse_keyword(reply)
    if text.startswith("INP") and text[3:].isdigit():
        return int(text[3:])
    raise MalformedReply(f"expected INP1..INP4, got {reply!r}")


class Source(Subsystem):
    """Source level and limit, and the swept sine's auto-level controller.

    The level cannot be set before the limit on this connection (:meth:`check_limit_first`).
    """

    limit_vpk = control(
        "SOUR:VOLT:LIM {value} VPK", "SOUR:VOLT:LIM?",
        """Highest level the auto-level controller may use, volts peak, above 0 up to 5 Vpk
        (preset 2 Vpk).""",
        validator=strict_range(0.0, MAX_SOURCE_VPK, "Vpk", low_inclusive=False),
        to_text=number_text, parse=parse_float, unit="VPK",
    )
    level_vpk = control(
        "SOUR:VOLT {value} VPK", "SOUR:VOLT?",
        """Source level in volts peak, 0 to 5 Vpk (with auto level: the starting level). A 0 V
        level pauses a swept sine with error -221.""",
        validator=lambda value, owner: owner.check_limit_first(
            strict_range(0.0, MAX_SOURCE_VPK, "Vpk")(value, owner)),
        to_text=number_text, parse=parse_float, unit="VPK",
    )
    auto_level = control(
        "SOUR:VOLT:AUTO {value}", "SOUR:VOLT:AUTO?",
        """Auto level (bool): adjust the source so the reference input holds the reference
        level.""",
        validator=boolean, to_text=on_off_text, parse=parse_bool,
    )
    reference_channel = control(
        "SOUR:VOLT:REF:CHAN INP{value}", "SOUR:VOLT:REF:CHAN?",
        """Input (1..4) the auto-level controller holds at the reference level (preset 2).""",
        validator=_channel, parse=_parse_channel,
    )
    reference_eu = control(
        "SOUR:VOLT:REF {value} EU", "SOUR:VOLT:REF?",
        """Reference level in the reference input's engineering unit (peak), above 0 up to
        1e6.""",
        validator=strict_range(0.0, 1e6, "EU", low_inclusive=False), to_text=number_text,
        parse=parse_float, unit="EU", implies={"reference_vpk": None},
    )
    reference_vpk = control(
        "SOUR:VOLT:REF {value} VPK", "SOUR:VOLT:REF?",
        """Reference level in volts peak at the reference input, above 0 up to 31.66 Vpk.""",
        validator=strict_range(0.0, MAX_INPUT_VPK, "Vpk", low_inclusive=False),
        to_text=number_text, parse=parse_float, unit="VPK", implies={"reference_eu": None},
    )
    tolerance_db = control(
        "SOUR:VOLT:REF:TOL {value}", "SOUR:VOLT:REF:TOL?",
        """Auto-level tolerance in dB, 0.1 to 20 dB (preset 2 dB).""",
        validator=strict_range(0.1, 20.0, "dB"), to_text=number_text, parse=parse_float,
    )
    input_limit_eu = control(
        "SOUR:VOLT:LIM:INP {value} EU", "SOUR:VOLT:LIM:INP?",
        """Input limit during auto level, in each input's engineering unit (peak): every input
        but the reference stays below it (with force transducers, the shaker force limit).""",
        validator=strict_range(0.0, 1e6, "EU", low_inclusive=False), to_text=number_text,
        parse=parse_float, unit="EU", implies={"input_limit_vpk": None},
    )
    input_limit_vpk = control(
        "SOUR:VOLT:LIM:INP {value} VPK", "SOUR:VOLT:LIM:INP?",
        """Input limit during auto level, volts peak, above 0 up to 31.66 Vpk.""",
        validator=strict_range(0.0, MAX_INPUT_VPK, "Vpk", low_inclusive=False),
        to_text=number_text, parse=parse_float, unit="VPK", implies={"input_limit_eu": None},
    )
    slew_v_per_s = control(
        "SOUR:VOLT:SLEW {value} V/S", "SOUR:VOLT:SLEW?",
        """Ramp rate of the source at the start and end of a sweep, 0 (none, the preset) to
        10000 V/s: the source ramps up to its level as a sweep starts and down to 0 when the
        sweep ends or ``ABOR`` stops it (inferred for ``ABOR``, module :mod:`.running`).""",
        validator=strict_range(0.0, 10000.0, "V/s"), to_text=number_text, parse=parse_float,
    )

    def __init__(self, parent: Parent) -> None:
        super().__init__(parent, "source")

    def check_limit_first(self, value: float) -> float:
        """A non-zero level needs the limit set first on this connection."""
        if value > 0 and "limit_vpk" not in self.sent:
            raise SettingOutOfRange(
                "the source limit (limit_vpk) must be set before a source level"
            )
        return value


class FftSource(Subsystem):
    """The FFT mode's source: output switch, waveform, fixed-sine frequency."""

    output = control(
        "OUTP {value}", "OUTP?",
        """Source output on (bool), FFT mode only (a swept sine drives its own source).""",
        validator=boolean, to_text=on_off_text, parse=parse_bool,
    )
    function = control(
        "SOUR:FUNC {value}", "SOUR:FUNC?",
        """Waveform: ``SIN``, ``RAND``, ``BRAN``, ``PCH``, ``BCH`` or ``PINK``.""",
        validator=one_of(("SIN", "RAND", "BRAN", "PCH", "BCH", "PINK")), parse=parse_keyword,
    )
    frequency_hz = control(
        "SOUR:FREQ {value} HZ", "SOUR:FREQ?",
        """Frequency of the fixed sine, 0 to 115 kHz (15.625 mHz steps).""",
        validator=strict_range(0.0, 115000.0, "Hz"), to_text=number_text, parse=parse_float,
        expect=lambda f: int(f / 0.015625 + 1e-9) * 0.015625, tolerance=1e-9,
    )

    def __init__(self, parent: Parent) -> None:
        super().__init__(parent, "FFT source")
