"""Trace data (``CALCulate``, ``TRACe``, ``FORMat``): feeds, data format, reading values.

A feed is shown on trace A (``CALC1:FEED``), copied untransformed into data register D1
(``TRAC:DATA D1,TRAC1``) and read from there (``TRAC:DATA? D1``, ``TRAC:X? D1``). A swept-sine
trace holds 401 or 801 points: the measured ones first, then slots holding the analyser's
no-data marker, in X too (:func:`agilent35670a.blocks.measured_slots`). Inside the measured
points the marker means no valid data: it becomes NaN and the caller flags the point.
"""

from __future__ import annotations

import re

import numpy as np

from .blocks import (
    check_values,
    decode_ascii,
    decode_real,
    interleaved_to_complex,
    measured_slots,
    split_definite_block,
)
from .errors import MalformedReply, SettingOutOfRange
from .properties import Parent, Subsystem, control
from .quirks import Quirks

__all__ = ["Traces", "check_feed"]

_FEED = re.compile(
    r"^(XFR:POW:(RAT|CROS|COH) [1-4],[1-4]|XFR:POW(:LIN|:VAR)? [1-4]|XTIM:VOLT(:WIND)? [1-4])$"
)


def check_feed(feed: object) -> str:
    """A feed from a fixed grammar (it is written inside quotes in a SCPI message)."""
    text = str(feed).strip().upper()
    if not _FEED.match(text):
        raise SettingOutOfRange(f"feed {feed!r} is not a 35670A feed this driver reads")
    return text


def _data_format(value: object, owner: object) -> str:
    text = str(value).replace(" ", "").upper()
    if text in ("REAL,64", "REAL,32", "ASC", "ASC,12"):
        return text
    match = re.fullmatch(r"ASC,(\d{1,2})", text)
    if match and 3 <= int(match.group(1)) <= 12:
        return text
    raise SettingOutOfRange(f"data format {value!r} is not REAL,64, REAL,32 or ASC[,3..12]")


def _parse_format(reply: str) -> str:
    kind, _, length = reply.strip().upper().partition(",")
    return f"{kind},{int(length)}" if length.strip("+").isdigit() else kind


class Traces(Subsystem):
    """Data format and trace reads."""

    data_format = control(
        "FORM {value}", "FORM?",
        """Data format of trace queries: ``"REAL,64"`` (default here), ``"REAL,32"``, ``"ASC"``
        or ``"ASC,<3..12 digits>"``.""",
        validator=_data_format, parse=_parse_format,
        expect=lambda sent: "ASC,12" if sent == "ASC" else sent,
    )

    def __init__(self, parent: Parent, resource: str, query_block) -> None:
        super().__init__(parent, "traces")
        self.resource = resource
        self.query_block = query_block

    def read_values(self, query: str) -> np.ndarray:
        """Send a data query and decode its reply in the data format in use."""
        data_format = str(self.sent.get("data_format", "ASC"))
        if data_format.startswith("REAL"):
            message = self.query_block(query)
            bits = int(data_format.split(",")[1])
            try:
                return decode_real(split_definite_block(message), bits, Quirks.REAL_BIG_ENDIAN)
            except MalformedReply as error:
                raise MalformedReply(f"{query!r}: {error.detail}", self.resource) from None
        try:
            return decode_ascii(self.ask(query))
        except MalformedReply as error:
            raise MalformedReply(f"{query!r}: {error.detail}", self.resource) from None

    def show(self, feed: str) -> None:
        """Feed trace A and copy it into data register D1 (both checked for errors)."""
        self.configure(f"CALC1:FEED '{check_feed(feed)}';*WAI")
        self.configure("TRAC:DATA D1,TRAC1")

    def axis(self) -> tuple[np.ndarray, int]:
        """The frequency axis of register D1 and how many of its slots hold measured points."""
        values = self.read_values("TRAC:X? D1")
        count = measured_slots(values, "TRAC:X? D1")
        return values[:count], count

    def data(self, feed: str, points: int, *, real: bool = False) -> np.ndarray:
        """The first ``points`` values of register D1 (NaN where the analyser has no data)."""
        raw = self.read_values("TRAC:DATA? D1")
        what = f"TRAC:DATA? D1 ({feed})"
        if real:
            slots = raw.size
            if Quirks.REAL_TRACE_MAY_BE_PAIRED and slots >= 2 * points and slots % 2 == 0 and (
                    np.all(raw[1::2] == 0) and raw.size != points):
                raw = raw[0::2]
            check_values(raw, what, allow_no_data=True)
            if raw.size < points:
                raise MalformedReply(f"{what}: expected {points} values, got {raw.size}",
                                     self.resource)
            values = raw.copy()
            values[values < -1e37] = np.nan
            return self._measured(values, points, what)
        values = interleaved_to_complex(raw, what, allow_no_data=True)
        return self._measured(values, points, what)

    def _measured(self, values: np.ndarray, points: int, what: str) -> np.ndarray:
        """The measured points; the slots after them must hold no data."""
        if values.size < points:
            raise MalformedReply(f"{what}: expected {points} values, got {values.size}",
                                 self.resource)
        if not np.all(np.isnan(values[points:])):
            raise MalformedReply(f"{what}: {values.size} values where {points} points were "
                                 "measured and the rest should hold no data", self.resource)
        return values[:points]
