"""Validators of the 35670A's own settings: frequencies, data formats, channels, trace feeds.

The generic ones (ranges, keywords, booleans) are in :mod:`agilent35670a.properties`; a validator
takes ``(value, owner)`` and returns the value as it will be sent, or raises
:class:`SettingOutOfRange` so that nothing is sent.
"""

from __future__ import annotations

import re
from collections.abc import Callable
from typing import TYPE_CHECKING

from .errors import SettingOutOfRange
from .properties import integer_range, number_text, strict_range

if TYPE_CHECKING:
    from .instrument import Agilent35670A

__all__ = [
    "check_data_format",
    "check_feed",
    "check_frequency",
    "check_reference_channel",
    "unit_text",
]


def check_frequency(value: object, analyser: Agilent35670A) -> float:
    """A frequency in Hz above 0 and up to the analyser's limit (four channels: 25.6 kHz)."""
    limit = analyser.max_frequency_hz
    return strict_range(0.0, limit, "Hz", low_inclusive=False)(value, analyser)


def unit_text(unit: str) -> Callable[[float], str]:
    """Format a number followed by ``unit`` (``"100 CYCLE"``)."""
    return lambda value: f"{number_text(value)} {unit}"


def check_data_format(value: object, analyser: object) -> str:
    """``ASC``, ``ASC,3..12``, ``REAL,32`` or ``REAL,64``, spaces removed, upper case."""
    text = str(value).strip().upper().replace(" ", "")
    if text in {"ASC", "REAL,32", "REAL,64"}:
        return text
    if text.startswith("ASC,") and text[4:].isdigit() and 3 <= int(text[4:]) <= 12:
        return text
    raise SettingOutOfRange(f"{value!r} is not ASC, ASC,3..12, REAL,32 or REAL,64")


def check_reference_channel(value: object, analyser: object) -> int:
    """An input channel number, 1..4."""
    return integer_range(1, 4, "channel")(value, analyser)


#: The swept-sine trace feeds (``CALC1:FEED``): a whitelist, because the feed is sent inside a
#: quoted string where a ``'`` or ``;`` would end it and inject commands.
_FEED = re.compile(
    r"^(XFR:POW:(RAT [1-4],[1-4]|CROS [1-4],[1-4]|LIN [1-4]|VAR [1-4])|XTIM:VOLT [1-4])$"
)


def check_feed(feed: object) -> str:
    """Return a swept-sine feed in upper case, or raise :class:`SettingOutOfRange`.

    Accepted: ``XFR:POW:RAT a,b``, ``XFR:POW:CROS a,b``, ``XFR:POW:LIN n``, ``XFR:POW:VAR n``,
    ``XTIM:VOLT n`` with channels 1..4 (coherence is FFT-mode only).
    """
    text = str(feed).strip().upper()
    if not _FEED.match(text):
        raise SettingOutOfRange(
            f"feed {feed!r} is not a swept-sine feed (XFR:POW:RAT a,b, XFR:POW:CROS a,b, "
            "XFR:POW:LIN n, XFR:POW:VAR n, XTIM:VOLT n; channels 1..4)"
        )
    return text
