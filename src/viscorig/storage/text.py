"""Text read from files, made safe to print: no control or format characters reach a terminal.

A campaign or exchange file may come from anywhere; a specimen name holding ``ESC [ 2 J`` would
clear the screen of whoever runs ``viscorig show``, and a right-to-left override would make a
line read differently from what it holds. Every text the storage layer hands out passes through
:func:`printable`, so the commands that print it need no care of their own.
"""

from __future__ import annotations

import unicodedata

#: Unicode categories removed: controls (C0, DEL, C1), format characters (bidirectional
#: overrides, zero-width characters), unassigned, private use and lone surrogates.
_UNSAFE_CATEGORIES = frozenset({"Cc", "Cf", "Cn", "Co", "Cs"})


def printable(text: str, *, keep: str = "") -> str:
    """``text`` without control and format characters.

    Parameters
    ----------
    text
        Text read from a file.
    keep
        Control characters to keep, e.g. ``"\\n\\t"`` for a multi-line text such as a TOML file.

    Examples
    --------
    >>> printable("soft\\x1b[2J rubber")
    'soft[2J rubber'
    >>> printable("a\\nb", keep="\\n")
    'a\\nb'
    """
    if text.isprintable():
        return text
    return "".join(
        char for char in text
        if char in keep or unicodedata.category(char) not in _UNSAFE_CATEGORIES
    )


def first_control(text: str, *, allowed: str = "\n\t") -> str | None:
    """The first control character of ``text`` (C0, DEL, C1) other than ``allowed``, or
    ``None``: what a text field written by a person may not hold."""
    return next((char for char in text
                 if char not in allowed and unicodedata.category(char) == "Cc"), None)
