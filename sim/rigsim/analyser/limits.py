"""The 35670A's identity, and the limits and timings of its measurements.

Sources: programming guide chapters 18 (``SENSe``) and 19 (``SOURce``), service guide chapter 1
(specifications). Figures the manual does not give are marked **(inferred)**.
"""

from __future__ import annotations

__all__ = [
    "AUTOCAL_DURATION_S",
    "AUTOCAL_PERIOD_S",
    "AUTOCAL_SCHEDULE_S",
    "DEFAULT_IDN",
    "DEFAULT_OPTIONS",
    "FFT_LINES",
    "FREQUENCY_STEP_HZ",
    "MARKER",
    "MAX_POINTS",
    "MAX_SOURCE_VPK",
    "MIN_DWELL_S",
    "MIN_POINTS",
    "POINT_OVERHEAD_S",
    "display_points",
    "fft_lines",
    "fft_max_span_hz",
    "sine_max_frequency_hz",
    "sine_min_frequency_hz",
]

#: ``*IDN?`` answer: maker, model, serial number, firmware revision.
DEFAULT_IDN = "Agilent Technologies,35670A,RIGSIM0001,A.02.02"
#: Installed options: 1D2 swept sine, AY6 four input channels.
DEFAULT_OPTIONS: tuple[str, ...] = ("1D2", "AY6")
#: Most points measured in one swept sine (the display holds 401 or 801 points).
MAX_POINTS = 801
#: Fewest points of a sweep (a resolution equal to the span gives two) **(inferred)**.
MIN_POINTS = 2
#: Frequency resolution of the swept sine and of the source.
FREQUENCY_STEP_HZ = 0.015625
#: The value the analyser puts in a trace where a point holds no data (not measured, or the
#: logarithm of zero): the most negative 32-bit float.
MARKER = -3.40282346639e38
#: Highest source amplitude (volts peak).
MAX_SOURCE_VPK = 5.0
#: Shortest integration time of a swept-sine point.
MIN_DWELL_S = 250e-6
#: FFT resolutions (lines); displayed points are lines + 1, stored points lines * 1.28 + 1.
#: The programming guide's FREQuency:RESolution entry lists 100 to 800; the specifications
#: (service guide) add 1600-line displays "only available in 1 or 2 channel mode", and real
#: programs send FREQ:RES 1600 (see :func:`fft_lines`).
FFT_LINES = (100, 200, 400, 800, 1600)


def fft_lines(channels: int) -> tuple[int, ...]:
    """The FFT resolutions with ``channels`` inputs on: 1600 lines with one or two only."""
    return FFT_LINES if channels <= 2 else FFT_LINES[:-1]
#: Time the swept sine spends per point beyond settle and integration: frequency change,
#: autorange, computation. The specification's 101-point sweep at 100 ms integration takes
#: about 60 s, i.e. about 0.45 s per point besides the integration **(inferred)**.
POINT_OVERHEAD_S = 0.45
#: Auto-calibration: several times in the first hour after power-on, then every 140 minutes
#: (service guide); the times within the first hour and the duration are **(inferred)**.
AUTOCAL_SCHEDULE_S = (300.0, 900.0, 1800.0, 3600.0)
AUTOCAL_PERIOD_S = 140 * 60.0
AUTOCAL_DURATION_S = 15.0


def sine_max_frequency_hz(channels: int) -> float:
    """Highest swept-sine frequency: 51.2 kHz with one or two inputs, 25.6 kHz with four."""
    return 25600.0 if channels > 2 else 51200.0


def sine_min_frequency_hz(channels: int) -> float:
    """Lowest swept-sine frequency: 15.625 mHz (two inputs), 31.25 mHz (four)."""
    return 2 * FREQUENCY_STEP_HZ if channels > 2 else FREQUENCY_STEP_HZ


def fft_max_span_hz(channels: int) -> float:
    """Widest FFT span: 102.4 kHz (one input), 51.2 kHz (two), 25.6 kHz (four)."""
    return {1: 102400.0, 2: 51200.0}.get(channels, 25600.0)


def display_points(measured: int) -> int:
    """Points a swept-sine trace holds: 401 for 3..401 measured points, 801 for 402..801."""
    return 401 if measured <= 401 else 801
