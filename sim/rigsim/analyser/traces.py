"""Traces: measurement data feeds, their data in each mode, display formats, data encoding.

A trace (``CALCn``) shows one feed (``CALCn:FEED``, chapter 2's ``<CMDSTR>``):
``XFR:POW:RAT b,a`` frequency response, ``XFR:POW:LIN n`` linear spectrum, ``XFR:POW n`` power
spectrum (FFT), ``XFR:POW:CROS a,b`` cross spectrum, ``XFR:POW:COH a,b`` coherence (FFT),
``XFR:POW:VAR n`` normalized variance (swept sine), ``XTIM:VOLT n`` time record,
``XTIM:VOLT:WIND n`` windowed time record (FFT), ``XVOL:VOLT a,b`` orbit (FFT), ``Dn`` a data
register.

Raw data (``TRAC:DATA?``, what a data register holds) is in engineering units when the input
is, else volts: linear spectra as complex peak amplitudes, power and cross spectra in rms²,
frequency responses as complex ratios. ``CALCn:DATA?`` gives the same data in the trace's
display format (``CALCn:FORM``) and amplitude units (``CALCn:UNIT:AMPL``, ``CALCn:UNIT:VOLT``).

Lengths (chapters 6 and 23): a swept-sine trace holds 401 points (3..401 measured) or 801
(402..801); a baseband FFT trace displays ``lines + 1`` points and stores ``lines × 1.28 + 1``
(the alias lines too). Where a trace holds no data (a point not measured yet or beyond the
sweep's points; the dB value of zero) the analyser puts -3.40282346639E+038: both the value and
its X are that marker for slots beyond the sweep's points, only the value for planned points not
yet measured **(inferred)**.
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass

import numpy as np

from rigsim.analyser.fft import FftResult
from rigsim.analyser.limits import MARKER
from rigsim.analyser.sine import MeasuredPoints
from rigsim.scpi import ScpiError, definite_block, format_real

__all__ = [
    "COMPLEX_FORMATS",
    "FORMATS",
    "Feed",
    "Register",
    "encode",
    "fft_trace",
    "formatted",
    "interleaved",
    "parse_feed",
    "sine_trace",
]

FORMATS = ("MLINear", "MLOGarithmic", "PHASe", "UPHase", "REAL", "IMAGinary", "NYQuist",
           "POLar", "GDELay")
COMPLEX_FORMATS = {"NYQ", "POL"}
_NOT_IN_SINE = "MEAS DATA selection not available with Inst Mode SWEPT SINE."
_NOT_IN_FFT = "MEAS DATA selection not available with Inst Mode FFT ANALYSIS."


@dataclass(frozen=True)
class Feed:
    """A parsed feed: its kind (``RAT``, ``LIN``, ``POW``, ``CROS``, ``COH``, ``VAR``, ``TIME``,
    ``WTIME``, ``ORBIT``, ``REG``, ``WREG``, ``TCAP``, or another mode's kind) and channels or
    register number."""

    kind: str
    channels: tuple[int, ...]
    text: str


_WORDS = {
    "XFR": ("XFR", "XFREQ", "XFREQUENCY"), "POW": ("POW", "POWER"), "RAT": ("RAT", "RATIO"),
    "LIN": ("LIN", "LINEAR"), "CROS": ("CROS", "CROSS"), "COH": ("COH", "COHERENCE"),
    "VAR": ("VAR", "VARIANCE"), "XTIM": ("XTIM", "XTIME"), "VOLT": ("VOLT", "VOLTAGE"),
    "WIND": ("WIND", "WINDOW"), "XVOL": ("XVOL", "XVOLTAGE"), "CORR": ("CORR", "CORRELATION"),
    "CDF": ("CDF",), "HIST": ("HIST", "HISTOGRAM"), "PDF": ("PDF",), "XORD": ("XORD", "XORDER"),
    "TRAC": ("TRAC", "TRACK"), "XRPM": ("XRPM",), "PROF": ("PROF", "PROFILE"),
    "COMP": ("COMP", "COMPOSITE"),
}
_WORD = {alias: short for short, aliases in _WORDS.items() for alias in aliases}
_KINDS: dict[tuple[str, ...], tuple[str, int]] = {
    ("XFR", "POW"): ("POW", 1), ("XFR", "POW", "RAT"): ("RAT", 2),
    ("XFR", "POW", "LIN"): ("LIN", 1), ("XFR", "POW", "CROS"): ("CROS", 2),
    ("XFR", "POW", "COH"): ("COH", 2), ("XFR", "POW", "VAR"): ("VAR", 1),
    ("XTIM", "VOLT"): ("TIME", 1), ("XTIM", "VOLT", "WIND"): ("WTIME", 1),
    ("XVOL", "VOLT"): ("ORBIT", 2), ("XTIM", "CORR"): ("CORR", 1),
    ("XTIM", "CORR", "CROS"): ("CCORR", 0), ("XTIM", "VOLT", "CDF"): ("CDF", 1),
    ("XTIM", "VOLT", "HIST"): ("HIST", 1), ("XTIM", "VOLT", "PDF"): ("PDF", 1),
    ("XORD", "TRAC"): ("ORDTRACK", 0), ("XRPM", "PROF"): ("RPM", 0),
    ("XFR", "POW", "COMP"): ("COMP", 1),
}
_SINE_KINDS = {"RAT", "LIN", "CROS", "VAR", "TIME", "REG"}
_FFT_KINDS = {"RAT", "LIN", "CROS", "COH", "POW", "TIME", "WTIME", "ORBIT", "REG", "WREG", "TCAP"}
_SHORT = {"POW": "XFR:POW", "RAT": "XFR:POW:RAT", "LIN": "XFR:POW:LIN", "CROS": "XFR:POW:CROS",
          "COH": "XFR:POW:COH", "VAR": "XFR:POW:VAR", "TIME": "XTIM:VOLT",
          "WTIME": "XTIM:VOLT:WIND", "ORBIT": "XVOL:VOLT"}


def parse_feed(text: str) -> Feed:
    """Parse a feed string (-151 for one the analyser does not know)."""
    stripped = text.strip()
    register = re.fullmatch(r"(D|W|TCAP)([1-8])", stripped.upper())
    if register is not None:
        kind = {"D": "REG", "W": "WREG", "TCAP": "TCAP"}[register.group(1)]
        number = int(register.group(2))
        if kind == "TCAP" and number > 4:
            raise ScpiError(-151, f"'{stripped}'")
        return Feed(kind, (number,), stripped.upper())
    head, _, args = stripped.partition(" ")
    words = tuple(_WORD.get(w.upper(), "?") for w in head.split(":"))
    found = _KINDS.get(words)
    if found is None:
        raise ScpiError(-151, f"'{stripped[:40]}'")
    kind, arity = found
    try:
        channels = tuple(int(a) for a in args.split(",")) if args.strip() else ()
    except ValueError:
        raise ScpiError(-151, f"'{stripped[:40]}'") from None
    if (arity and len(channels) != arity) or any(not 1 <= c <= 4 for c in channels):
        raise ScpiError(-151, f"'{stripped[:40]}'")
    text = f"{_SHORT.get(kind, ':'.join(words))} {','.join(map(str, channels))}".strip()
    return Feed(kind, channels, text)


def check_feed(feed: Feed, mode: str, channel_count: int, reference: str) -> None:
    """The feed is valid in ``mode`` with the inputs in use (appendix C's errors)."""
    if mode == "SINE" and feed.kind not in _SINE_KINDS:
        raise ScpiError(-200, _NOT_IN_SINE)
    if mode == "FFT" and feed.kind not in _FFT_KINDS:
        raise ScpiError(-200, _NOT_IN_FFT)
    if mode not in ("SINE", "FFT") and feed.kind not in ("REG",):
        raise ScpiError(-200, "Instrument must be in either FFT ANALYSIS or SWEPT SINE mode.")
    if feed.kind in ("REG", "WREG", "TCAP"):
        return
    channels = feed.channels
    if any(c > 2 for c in channels) and channel_count < 4:
        raise ScpiError(-200, "MEAS DATA selection only available with four active channels")
    if any(c > 1 for c in channels) and channel_count < 2:
        raise ScpiError(-200, "MEAS DATA selection only available with two or more active "
                              "channels")
    if feed.kind in ("RAT", "CROS", "COH", "ORBIT") and len(set(channels)) != 2:
        raise ScpiError(-224, "the two channels must differ")
    if feed.kind == "RAT":  # REF SING: input 1 is every input's reference (chapter 18)
        allowed = {(2, 1), (4, 3)} if reference == "PAIR" else {(2, 1), (3, 1), (4, 1)}
        if channels not in allowed:
            raise ScpiError(-224, f"XFR:POW:RAT {channels[0]},{channels[1]} with REF {reference}")
    if feed.kind in ("CROS", "COH"):
        pairs = {(1, 2), (3, 4)} if reference == "PAIR" else {(1, 2), (1, 3), (1, 4)}
        if channels not in pairs:
            raise ScpiError(-224, f"channels {channels[0]},{channels[1]} with REF {reference}")


@dataclass
class Register:
    """Data of a trace or data register: X values, Y values (complex or real; NaN where there
    is no data), what it holds and how many points are displayed.

    Attributes
    ----------
    feed
        The feed the data came from.
    x, y
        X values (Hz or s; NaN slots have no X either) and Y values.
    power
        Y is a power-like quantity (dB is 10 log10).
    displayed
        Points ``CALCn:DATA?`` shows (the first ones; the rest are alias lines).
    domain
        ``freq`` or ``time``.
    kind
        The feed kind (``LIN``, ``POW``...), for display units.
    """

    feed: str
    x: np.ndarray
    y: np.ndarray
    power: bool = False
    displayed: int | None = None
    domain: str = "freq"
    kind: str = ""

    @property
    def is_complex(self) -> bool:
        return bool(np.iscomplexobj(self.y))

    @property
    def display_count(self) -> int:
        return self.y.size if self.displayed is None else self.displayed

    def copy(self) -> Register:
        return Register(self.feed, self.x.copy(), self.y.copy(), self.power, self.displayed,
                        self.domain, self.kind)


def sine_trace(feed: Feed, points: MeasuredPoints) -> Register:
    """The data a swept-sine trace shows of the points measured so far (in their slots)."""
    slots = points.slots
    planned = points.planned_hz
    x = np.full(slots, np.nan)
    x[: min(slots, planned.size)] = planned[:slots]
    n = min(points.count, slots)
    x[:n] = np.array(points.frequency_hz[:n])
    values = points.channels()[:n]
    y: np.ndarray
    kind = feed.kind
    if kind == "TIME":
        return _sine_time(points, feed.channels[0])
    if kind == "VAR":
        y = np.full(slots, np.nan)
        y[:n] = points.variances()[:n, feed.channels[0] - 1]
        return Register(feed.text, x, y, kind=kind)
    y = np.full(slots, complex(np.nan, np.nan))
    if kind == "RAT":
        out, ref = feed.channels
        with np.errstate(divide="ignore", invalid="ignore"):
            y[:n] = values[:, out - 1] / values[:, ref - 1]
    elif kind == "LIN":
        y[:n] = values[:, feed.channels[0] - 1]
    elif kind == "CROS":
        a, b = feed.channels
        y[:n] = np.conj(values[:, a - 1]) * values[:, b - 1] / 2.0
        return Register(feed.text, x, y, power=True, kind=kind)
    else:
        raise ScpiError(-200, _NOT_IN_SINE)
    return Register(feed.text, x, y, kind=kind)


def _sine_time(points: MeasuredPoints, channel: int) -> Register:
    """The last point's steady sine rebuilt from its measured amplitude: 4 periods in 256
    samples (the simulator gives amplitudes, not time records)."""
    if points.count == 0:
        return Register(f"XTIM:VOLT {channel}", np.arange(256) * 1e-3, np.full(256, np.nan),
                        domain="time", kind="TIME")
    f = points.frequency_hz[-1]
    amplitude = points.channels()[-1, channel - 1]
    t = np.arange(256) * (4.0 / f) / 256
    return Register(f"XTIM:VOLT {channel}", t, np.real(amplitude * np.exp(2j * np.pi * f * t)),
                    domain="time", kind="TIME")


def fft_trace(feed: Feed, result: FftResult | None, lines: int) -> Register:
    """The data an FFT trace shows (all marker when nothing is measured yet)."""
    kind = feed.kind
    if result is None:
        count = round(lines * 1.28) + 1
        empty = np.full(count, np.nan)
        if kind in ("TIME", "WTIME", "ORBIT"):
            return Register(feed.text, np.full(count, np.nan), empty, domain="time", kind=kind)
        return Register(feed.text, np.full(count, np.nan), empty, displayed=lines + 1, kind=kind)
    scale = result.scale
    f = result.frequency_hz
    displayed = min(result.lines + 1, f.size)
    if kind in ("TIME", "WTIME"):
        data = result.time if kind == "TIME" else result.windowed
        channel = feed.channels[0] - 1
        return Register(feed.text, result.time_s.copy(), data[channel] / scale[channel],
                        domain="time", kind=kind)
    if kind == "ORBIT":
        a, b = (c - 1 for c in feed.channels)
        y = result.time[a] / scale[a] + 1j * result.time[b] / scale[b]
        return Register(feed.text, result.time_s.copy(), y, domain="time", kind=kind)
    if result.peak_hold and kind in ("RAT", "CROS", "COH"):
        raise ScpiError(-200, "FREQUENCY RESPONSE, COHERENCE, and CROSS SPECTRUM data are not "
                              "valid with PEAK HOLD average.")
    if kind == "POW":
        n = feed.channels[0] - 1
        return Register(feed.text, f.copy(), result.power[n] / scale[n] ** 2, power=True,
                        displayed=displayed, kind=kind)
    if kind == "LIN":
        n = feed.channels[0] - 1
        return Register(feed.text, f.copy(), result.linear[n] / scale[n], displayed=displayed,
                        kind=kind)
    a, b = (c - 1 for c in feed.channels)
    if kind == "RAT":  # XFR:POW:RAT out,ref: H1 = G(ref,out) / G(ref,ref)
        out, ref = a, b
        with np.errstate(divide="ignore", invalid="ignore"):
            y = result.cross[ref, out] / result.power[ref] * scale[ref] / scale[out]
        return Register(feed.text, f.copy(), y, displayed=displayed, kind=kind)
    if kind == "CROS":
        y = result.cross[a, b] / (scale[a] * scale[b])
        return Register(feed.text, f.copy(), y, power=True, displayed=displayed, kind=kind)
    if kind == "COH":
        with np.errstate(divide="ignore", invalid="ignore"):
            y = np.abs(result.cross[a, b]) ** 2 / (result.power[a] * result.power[b])
        return Register(feed.text, f.copy(), np.real(y), displayed=displayed, kind=kind)
    raise ScpiError(-200, _NOT_IN_FFT)


def interleaved(y: np.ndarray) -> np.ndarray:
    """Complex values as (real, imaginary) pairs, the way the analyser sends them."""
    values = np.empty(2 * y.size)
    values[0::2], values[1::2] = y.real, y.imag
    return values


def amplitude_factor(kind: str, amplitude: str) -> float:
    """Factor from raw data (peak, rms²) to the ``CALCn:UNIT:AMPL`` unit."""
    if kind == "LIN":
        return {"PEAK": 1.0, "RMS": 1.0 / math.sqrt(2.0), "PP": 2.0}.get(amplitude, 1.0)
    if kind in ("POW", "CROS"):
        return {"PEAK": 2.0, "RMS": 1.0, "PP": 8.0}.get(amplitude, 1.0)
    return 1.0


def formatted(register: Register, fmt: str, *, degrees: bool = True, amplitude: str = "RMS",
              power_unit: str = "V2", bandwidth_hz: float = 1.0) -> np.ndarray:
    """A trace's displayed values in display format ``fmt`` (``CALCn:FORM``, short form)."""
    count = register.display_count
    y = register.y[:count] * amplitude_factor(register.kind, amplitude)
    power = register.power
    if register.kind == "POW" and power_unit != "V2":
        y = {"V": np.sqrt(np.abs(y)), "V/RTHZ": np.sqrt(np.abs(y) / bandwidth_hz),
             "V2/HZ": y / bandwidth_hz, "V2S/HZ": y / bandwidth_hz}.get(power_unit, y)
        power = power_unit in ("V2/HZ", "V2S/HZ")
    angle = np.degrees if degrees else (lambda v: v)
    if not np.iscomplexobj(y):
        y = y.astype(complex)
    if fmt == "NYQ":
        return interleaved(y)
    if fmt == "POL":
        values = np.empty(2 * y.size)
        values[0::2], values[1::2] = np.abs(y), angle(np.angle(y))
        return values
    if fmt == "MLIN":
        return np.abs(y)
    if fmt == "MLOG":
        with np.errstate(divide="ignore", invalid="ignore"):
            magnitude = np.abs(y)
            db = (10.0 if power else 20.0) * np.log10(magnitude)
        return np.where(magnitude > 0, db, np.nan)
    if fmt == "PHAS":
        return angle(np.angle(y))
    if fmt == "UPH":
        phase = np.angle(y)
        good = np.isfinite(phase)
        phase[good] = np.unwrap(phase[good])
        return angle(phase)
    if fmt == "REAL":
        return y.real.copy()
    if fmt == "IMAG":
        return y.imag.copy()
    if fmt == "GDEL":
        good = np.isfinite(y) & np.isfinite(register.x[:count])
        out = np.full(y.size, np.nan)
        if np.count_nonzero(good) >= 2:
            phase = np.unwrap(np.angle(y[good]))
            out[good] = -np.gradient(phase, 2 * np.pi * register.x[:count][good])
        return out
    raise ScpiError(-224, fmt)


def encode(values: np.ndarray, data_format: tuple[str, int]) -> bytes:
    """Values in the data format of ``FORM`` (no data -> the analyser's marker value)."""
    values = np.where(np.isfinite(values), values, MARKER)
    kind, length = data_format
    if kind == "REAL":
        return definite_block(np.asarray(values, f">f{length // 8}").tobytes())
    if values.size == 0:
        return b""
    return ",".join(format_real(float(v), length) for v in values).encode()
