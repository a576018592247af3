"""``CALCulate``, ``TRACe`` and ``FORMat``: trace feeds and formats, data registers, data format.

``CALCn:DATA?`` answers trace n in its display format; ``TRAC:DATA? D1`` answers a register
untransformed (complex values as real, imaginary pairs). What each feed holds:
:mod:`rigsim.analyser.traces`.
"""

from __future__ import annotations

import re

from rigsim.analyser.params import Params, one
from rigsim.analyser.state import Register
from rigsim.analyser.traces import (
    FORMATS,
    Feed,
    encode,
    form_trace,
    formatted,
    interleaved,
    parse_feed,
)
from rigsim.analyser.worker import SweepWorker
from rigsim.scpi import (
    CommandTree,
    ScpiError,
    format_int,
    format_string,
    parse_choice,
    unquote,
)

__all__ = ["TraceCommands"]

TRACE_COUNT = 4


class TraceCommands(SweepWorker):
    """Handlers of ``CALCulate#``, ``TRACe`` and ``FORMat`` (a base of the analyser)."""

    def _register_trace_commands(self, t: CommandTree) -> None:
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

    def trace(self, number: int) -> Register:
        """The current data of trace ``number`` (1..4, CALC1..CALC4) in engineering units."""
        with self.lock:
            return form_trace(parse_feed(self.settings.feeds[number - 1]), self._measured)

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

    # ---------------------------------------------------------------- CALCulate

    @staticmethod
    def _trace_index(suffix: int | None) -> int:
        n = 1 if suffix is None else suffix
        if not 1 <= n <= TRACE_COUNT:
            raise ScpiError(-114, f"trace {n}")
        return n - 1

    def _feed(self, params: Params, suffix: int | None) -> None:
        index = self._trace_index(suffix)
        feed = parse_feed(unquote(one(params)))
        self._validate_feed(feed)
        self.settings.feeds[index] = feed.text

    def _calc_format(self, params: Params, suffix: int | None) -> None:
        index = self._trace_index(suffix)
        self.settings.formats[index] = parse_choice(one(params), FORMATS)

    def _calc_data(self, params: Params, suffix: int | None) -> bytes:
        index = self._trace_index(suffix)
        register = self.trace(index + 1)
        return encode(formatted(register, self.settings.formats[index]), self.format)

    def _calc_x(self, params: Params, suffix: int | None) -> bytes:
        return encode(self.trace(self._trace_index(suffix) + 1).x, self.format)

    # ---------------------------------------------------------------- TRACe (data registers)

    @staticmethod
    def _register_name(word: str) -> tuple[str, int]:
        match = re.fullmatch(r"(D|TRAC(?:E)?)([1-8])", word.strip().upper())
        if match is None:
            raise ScpiError(-224, f"{word} (expected D1..D8 or TRAC1..TRAC4)")
        kind = "D" if match.group(1) == "D" else "TRAC"
        number = int(match.group(2))
        if kind == "TRAC" and number > TRACE_COUNT:
            raise ScpiError(-224, word)
        return kind, number

    def _register(self, word: str) -> Register:
        kind, number = self._register_name(word)
        if kind == "TRAC":
            return self.trace(number)
        if number not in self.registers:
            raise ScpiError(-221, f"data register D{number} is empty")
        return self.registers[number]

    def _trace_copy(self, params: Params, suffix: int | None) -> None:
        if len(params) != 2:
            raise ScpiError(-109 if len(params) < 2 else -108, "TRAC:DATA <register>,<trace>")
        kind, number = self._register_name(params[0])
        if kind != "D":
            raise ScpiError(-224, f"{params[0]}: copy into a data register D1..D8")
        source = self._register(params[1])
        self.registers[number] = Register(source.feed, source.x.copy(), source.y.copy())

    def _trace_data(self, params: Params, suffix: int | None) -> bytes:
        register = self._register(one(params))
        # frequency responses and spectra: interleaved real, imag
        values = interleaved(register.y) if register.is_complex else register.y
        return encode(values, self.format)

    def _trace_x(self, params: Params, suffix: int | None) -> bytes:
        return encode(self._register(one(params)).x, self.format)

    # ---------------------------------------------------------------- FORMat

    def _format_set(self, params: Params, suffix: int | None) -> None:
        if not params or len(params) > 2:
            raise ScpiError(-109 if not params else -108)
        kind = parse_choice(params[0], ("ASCii", "REAL"))
        if kind == "ASC":
            length = 12 if len(params) == 1 else _format_length(params[1])
            if not 3 <= length <= 12:
                raise ScpiError(-224, f"ASCII length {length} (3..12)")
        else:
            length = 64 if len(params) == 1 else _format_length(params[1])
            if length not in (32, 64):
                raise ScpiError(-224, f"REAL length {length} (32 or 64)")
        self.format = (kind, length)


def _format_length(text: str) -> int:
    try:
        return int(text)
    except ValueError:
        raise ScpiError(-224, f"format length {text}") from None
