"""Traces: feeds, traces formed from the measured points, display formats, data encoding.

Values are in engineering units when ``VOLTn:RANG:UNIT:USER`` is on, else volts:

- ``XFR:POW:RAT a,b``: the complex ratio a/b;
- ``XFR:POW:LIN n``: the complex peak amplitude of channel n (inferred: peak);
- ``XFR:POW:CROS a,b``: ``conj(X_a) X_b`` in peak² (inferred);
- ``XFR:POW:VAR n``: the normalized variance (real);
- ``XTIM:VOLT n``: the last point's steady-state sine rebuilt from its measured amplitude (real,
  X in seconds).

During and after a sweep the traces hold the points measured so far (inferred).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from rigsim.analyser.state import MeasuredPoints, Register
from rigsim.measurement import CHANNEL_COUNT
from rigsim.scpi import ScpiError, definite_block, format_real

__all__ = [
    "COMPLEX_FORMATS",
    "FORMATS",
    "Feed",
    "encode",
    "form_trace",
    "formatted",
    "interleaved",
    "parse_feed",
]

#: ``CALCn:FORM`` choices; the complex ones answer (real, imaginary) pairs.
FORMATS = ("MLINear", "MLOGarithmic", "PHASe", "UPHase", "REAL", "IMAGinary", "NYQuist",
           "POLar", "GDELay")
COMPLEX_FORMATS = {"NYQ", "POL"}


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
_FEED_KINDS = {("XFR", "POW", "RAT"): "RAT", ("XFR", "POW", "LIN"): "LIN",
               ("XFR", "POW", "CROS"): "CROS", ("XFR", "POW", "VAR"): "VAR",
               ("XFR", "POW", "COH"): "COH", ("XTIM", "VOLT"): "XTIM"}
_FEED_ARITY = {"RAT": 2, "CROS": 2, "COH": 2, "LIN": 1, "VAR": 1, "XTIM": 1}


def parse_feed(text: str) -> Feed:
    """Parse a feed string; -224 when it is not one the 35670A offers."""
    head, _, args = text.strip().partition(" ")
    words = tuple(_FEED_WORDS.get(w.upper(), "?") for w in head.split(":"))
    kind = _FEED_KINDS.get(words)
    try:
        channels = tuple(int(a) for a in args.split(",")) if args.strip() else ()
    except ValueError:
        raise ScpiError(-224, f"feed {text!r}: channels must be integers") from None
    if kind is None or len(channels) != _FEED_ARITY[kind]:
        raise ScpiError(-224, f"feed {text!r}")
    if any(not 1 <= c <= CHANNEL_COUNT for c in channels):
        raise ScpiError(-224, f"feed {text!r}: channels are 1..4")
    return Feed(kind, channels)


def form_trace(feed: Feed, measured: MeasuredPoints) -> Register:
    """The trace ``feed`` shows of the points measured so far, in engineering units."""
    m = measured
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
        x, y = _time_record(m, feed.channels[0])
    else:
        raise ScpiError(-221, "coherence is an FFT measurement")
    return Register(feed.text, x, y)


def _time_record(m: MeasuredPoints, channel: int) -> tuple[np.ndarray, np.ndarray]:
    """Time trace of the last measured point: the steady-state sine rebuilt from its
    measured complex amplitude (the simulator returns amplitudes, not time records),
    4 periods in 256 samples, in engineering units."""
    if m.count == 0:
        return np.zeros(0), np.zeros(0)
    f = m.frequency_hz[m.count - 1]
    amplitude = m.channel_v[m.count - 1, channel - 1] / m.v_per_eu[channel - 1]
    t = np.arange(256) * (4.0 / f) / 256
    return t, np.real(amplitude * np.exp(2j * np.pi * f * t))


def interleaved(y: np.ndarray) -> np.ndarray:
    """Complex values as (real, imaginary) pairs, the way the analyser sends them."""
    values = np.empty(2 * y.size)
    values[0::2], values[1::2] = y.real, y.imag
    return values


def formatted(register: Register, fmt: str) -> np.ndarray:
    """A trace's values in display format ``fmt`` (``CALCn:FORM``, short form)."""
    y = register.y
    if not np.iscomplexobj(y):
        y = y.astype(complex)
    if fmt in COMPLEX_FORMATS:
        return interleaved(y)
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


def encode(values: np.ndarray, data_format: tuple[str, int]) -> bytes:
    """Values in the data format of ``FORM`` (``("ASC", digits)`` or ``("REAL", 32|64)``)."""
    kind, length = data_format
    if kind == "REAL":
        return definite_block(np.asarray(values, f">f{length // 8}").tobytes())
    if values.size == 0:
        return b""
    digits = length
    return ",".join(format_real(float(v), digits) for v in values).encode()
