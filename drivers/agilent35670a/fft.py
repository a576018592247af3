"""The FFT mode's settings (``[SENSe:]FREQuency``, ``WINDow``, ``AVERage``): span, lines,
window, averaging. Used for a broadband look and for noise floors with the source off."""

from __future__ import annotations

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
    parse_int,
    parse_keyword,
    strict_range,
)

__all__ = ["FFT_LINES", "FftAnalysis", "allowed_span_hz"]

#: Resolutions of the FFT (lines); displayed points are lines + 1.
FFT_LINES = (100, 200, 400, 800)


def allowed_span_hz(span_hz: float, max_span_hz: float) -> float:
    """The FFT span the analyser uses for a request: ``max / 2**n`` at or above it."""
    span = max_span_hz
    while span / 2.0 >= span_hz * (1 - 1e-9) and span / 2.0 >= max_span_hz / 2**19:
        span /= 2.0
    return span


class FftAnalysis(Subsystem):
    """Span, lines, window and averaging of an FFT measurement (baseband, start 0 Hz)."""

    start_frequency_hz = control(
        "FREQ:STAR {value} HZ", "FREQ:STAR?", """Start of the band (0 for baseband).""",
        validator=strict_range(0.0, 115000.0, "Hz"), to_text=number_text, parse=parse_float,
    )
    span_hz = control(
        "FREQ:SPAN {value} HZ", "FREQ:SPAN?",
        """Span in Hz: the widest span (51.2 kHz with two inputs, 25.6 kHz with four) divided
        by a power of two; the analyser takes the next one up.""",
        validator=strict_range(0.1, 102400.0, "Hz"), to_text=number_text, parse=parse_float,
        expect=lambda span: allowed_span_hz(span, 51200.0 if span <= 51200.0 else 102400.0),
    )
    lines = control(
        "FREQ:RES {value}", "FREQ:RES?", """Resolution in lines: 100, 200, 400 or 800.""",
        validator=lambda value, owner: one_of(tuple(str(n) for n in FFT_LINES))(
            str(value), owner), to_text=str, parse=lambda r: str(int(parse_float(r))),
    )
    window = control(
        "WIND {value}", "WIND?", """Window of every input: ``HANN``, ``FLAT`` or ``UNIF``.""",
        validator=one_of(("HANN", "FLAT", "UNIF")), parse=parse_keyword,
    )
    averaging = control(
        "AVER {value}", "AVER?", """Averaging on (bool).""",
        validator=boolean, to_text=on_off_text, parse=parse_bool,
    )
    average_count = control(
        "AVER:COUN {value}", "AVER:COUN?", """Number of averages, 1 to 9 999 999.""",
        validator=integer_range(1, 9999999, "averages"), to_text=str, parse=parse_int,
    )
    average_type = control(
        "AVER:TYPE {value}", "AVER:TYPE?", """``RMS`` (power), ``TIME`` (vector) or ``MAX``.""",
        validator=one_of(("RMS", "TIME", "MAX")), parse=parse_keyword,
    )

    def __init__(self, parent: Parent) -> None:
        super().__init__(parent, "FFT")
