"""SCPI message parsing for the virtual 35670A: headers, compound paths, parameters, responses.

What the 35670A accepts (``shared/docs/35670a.md``, "Interface"): program messages end with a
newline and/or EOI; ``;`` separates commands and ``;:`` returns to the root; mnemonics have a
short and a long form, in any case; optional nodes (``[SENSe:]``) may be left out; booleans are
``OFF|0|ON|1`` and are answered ``+0``/``+1``; numbers accept a unit suffix and
``MAX|MIN|UP|DOWN``.

A command tree is built from patterns written as in the manual: ``[SENSe:]FREQuency:STARt``,
``INPut#[:STATe]`` (``#`` marks a node that takes a numeric suffix such as ``INP2``),
``*IDN``. Upper-case letters are the short form. Each pattern may carry a setting handler and a
query handler. Lookup is a dictionary walk, so parsing stays cheap on the hot path.

This module knows nothing of the instrument; :mod:`rigsim.analyser` registers the commands.
"""

from __future__ import annotations

import math
import re
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass, field
from itertools import product
from typing import Any

#: Standard SCPI error texts (SCPI 1999 volume 2, chapter 21). The 35670A uses the standard
#: numbers; the wording after ``;`` is ours.
ERROR_TEXTS: dict[int, str] = {
    0: "No error",
    -100: "Command error",
    -101: "Invalid character",
    -102: "Syntax error",
    -103: "Invalid separator",
    -104: "Data type error",
    -108: "Parameter not allowed",
    -109: "Missing parameter",
    -113: "Undefined header",
    -114: "Header suffix out of range",
    -120: "Numeric data error",
    -131: "Invalid suffix",
    -138: "Suffix not allowed",
    -141: "Invalid character data",
    -151: "Invalid string data",
    -158: "String data not allowed",
    -200: "Execution error",
    -213: "Init ignored",
    -221: "Settings conflict",
    -222: "Data out of range",
    -224: "Illegal parameter value",
    -241: "Hardware missing",
    -310: "System error",
    -350: "Queue overflow",
    -410: "Query INTERRUPTED",
    -420: "Query UNTERMINATED",
}


class ScpiError(Exception):
    """A command failed; ``code`` and ``message`` go to the error queue as ``code,"message"``.

    Parameters
    ----------
    code
        SCPI error number (negative for standard errors).
    detail
        Optional detail appended to the standard text after ``;``.
    """

    def __init__(self, code: int, detail: str | None = None) -> None:
        base = ERROR_TEXTS.get(code, "Error")
        self.code = code
        self.message = f"{base}; {detail}" if detail else base
        super().__init__(f"{code},{self.message}")


# --------------------------------------------------------------------------------------------
# Command tree


Handler = Callable[..., Any]


@dataclass
class _Node:
    """One mnemonic of the command tree."""

    long: str
    suffix_allowed: bool = False
    children: dict[str, _Node] = field(default_factory=dict)
    setter: Handler | None = None
    query: Handler | None = None


@dataclass(frozen=True)
class Resolved:
    """A header resolved against the tree.

    Attributes
    ----------
    handler
        The setting or query handler.
    suffix
        Numeric suffix of the suffixed node in the header (``INP3`` gives 3), or ``None`` if the
        header left it out.
    """

    handler: Handler
    suffix: int | None


_MNEMONIC = re.compile(r"([A-Za-z][A-Za-z_]*?)(\d*)$")


def _split_pattern(pattern: str) -> list[list[tuple[str, bool]]]:
    """Expand a pattern with optional ``[...]`` parts into its variants of (mnemonic, suffix)."""
    parts: list[tuple[list[tuple[str, bool]], bool]] = []
    for match in re.finditer(r"\[:?([^\]]+?):?\]|:?([^:\[\]]+)", pattern):
        text, optional = (match.group(1), True) if match.group(1) else (match.group(2), False)
        nodes = [(name.rstrip("#"), name.endswith("#")) for name in text.split(":") if name]
        parts.append((nodes, optional))
    variants: list[list[tuple[str, bool]]] = []
    optional_indices = [i for i, (_, optional) in enumerate(parts) if optional]
    for keep in product((True, False), repeat=len(optional_indices)):
        kept = dict(zip(optional_indices, keep, strict=True))
        variant: list[tuple[str, bool]] = []
        for i, (nodes, optional) in enumerate(parts):
            if not optional or kept[i]:
                variant.extend(nodes)
        variants.append(variant)
    return variants


def short_form(long: str) -> str:
    """The short form of a mnemonic: its upper-case letters (``FREQuency`` gives ``FREQ``)."""
    if long.startswith("*"):
        return long.upper()
    short = "".join(c for c in long if c.isupper() or c.isdigit())
    return short or long.upper()


class CommandTree:
    """Headers of an instrument, with their setting and query handlers."""

    def __init__(self) -> None:
        self.root = _Node("")
        self.common: dict[str, _Node] = {}

    def add(
        self, pattern: str, setter: Handler | None = None, query: Handler | None = None
    ) -> None:
        """Register a header pattern (``[SENSe:]FREQuency:STARt``, ``INPut#[:STATe]``, ``*IDN``).

        Handlers are called as ``handler(params, suffix)`` with the parameter strings and the
        numeric suffix (``None`` when absent).
        """
        if pattern.startswith("*"):
            node = self.common.setdefault(pattern.upper(), _Node(pattern.upper()))
            node.setter = setter or node.setter
            node.query = query or node.query
            return
        for variant in _split_pattern(pattern):
            node = self.root
            for name, suffix_allowed in variant:
                key_long, key_short = name.upper(), short_form(name)
                child = node.children.get(key_long) or node.children.get(key_short)
                if child is None:
                    child = _Node(name, suffix_allowed)
                    node.children[key_long] = child
                    node.children[key_short] = child
                child.suffix_allowed = child.suffix_allowed or suffix_allowed
                node = child
            node.setter = setter or node.setter
            node.query = query or node.query

    def resolve(self, tokens: Sequence[str], is_query: bool) -> Resolved:
        """Find the handler of a header given as its mnemonics (``["FREQ", "STAR"]``).

        Raises
        ------
        ScpiError
            -113 for an unknown header, -114 for a suffix on a node that takes none.
        """
        node = self.root
        suffix: int | None = None
        for token in tokens:
            match = _MNEMONIC.match(token)
            if match is None:
                raise ScpiError(-113, token)
            name, digits = match.group(1).upper(), match.group(2)
            child = node.children.get(name)
            if child is None and digits:
                # a mnemonic whose short form itself ends in a digit would land here
                child = node.children.get(name + digits)
                digits = "" if child is not None else digits
            if child is None:
                raise ScpiError(-113, ":".join(tokens))
            if digits:
                if not child.suffix_allowed:
                    raise ScpiError(-114, token)
                suffix = int(digits)
            node = child
        handler = node.query if is_query else node.setter
        if handler is None:
            raise ScpiError(-113, ":".join(tokens) + ("?" if is_query else ""))
        return Resolved(handler, suffix)

    def resolve_common(self, header: str, is_query: bool) -> Handler:
        """Find the handler of a common command (``*IDN``)."""
        node = self.common.get(header.upper())
        handler = None if node is None else (node.query if is_query else node.setter)
        if handler is None:
            raise ScpiError(-113, header + ("?" if is_query else ""))
        return handler


# --------------------------------------------------------------------------------------------
# Program messages


@dataclass(frozen=True)
class ProgramUnit:
    """One command or query of a program message.

    Attributes
    ----------
    header
        The header as sent, without the ``?`` (``:FREQ:STAR``, ``*IDN``).
    is_query
        The header ended with ``?``.
    params
        Parameter strings as sent, stripped, quotes kept.
    text
        The whole unit as sent (for error details).
    """

    header: str
    is_query: bool
    params: tuple[str, ...]
    text: str


def split_units(message: str) -> Iterator[str]:
    """Split a program message at ``;`` outside quoted strings."""
    start = 0
    quote = ""
    for i, char in enumerate(message):
        if quote:
            if char == quote:
                quote = ""
        elif char in "'\"":
            quote = char
        elif char == ";":
            yield message[start:i]
            start = i + 1
    if quote:
        raise ScpiError(-151, "unterminated string")
    yield message[start:]


def split_params(text: str) -> tuple[str, ...]:
    """Split a parameter list at commas outside quoted strings."""
    if not text.strip():
        return ()
    params: list[str] = []
    start = 0
    quote = ""
    for i, char in enumerate(text):
        if quote:
            if char == quote:
                quote = ""
        elif char in "'\"":
            quote = char
        elif char == ",":
            params.append(text[start:i].strip())
            start = i + 1
    params.append(text[start:].strip())
    if any(not p for p in params):
        raise ScpiError(-103, text)
    return tuple(params)


def parse_unit(text: str) -> ProgramUnit:
    """Parse one program message unit into header, query flag and parameters."""
    stripped = text.strip()
    if not stripped:
        raise ScpiError(-102, "empty command")
    header, _, rest = stripped.partition(" ")
    if "\t" in header:
        header, _, more = header.partition("\t")
        rest = more + " " + rest
    is_query = header.endswith("?")
    if is_query:
        header = header[:-1]
    if not header or "?" in header:
        raise ScpiError(-102, stripped)
    return ProgramUnit(header, is_query, split_params(rest), stripped)


# --------------------------------------------------------------------------------------------
# Parameters


def unquote(param: str) -> str:
    """The content of a quoted string parameter (doubled quotes inside are undone)."""
    if len(param) >= 2 and param[0] == param[-1] and param[0] in "'\"":
        quote = param[0]
        return param[1:-1].replace(quote * 2, quote)
    raise ScpiError(-151, f"expected a quoted string, got {param}")


def parse_bool(param: str) -> bool:
    """``OFF|0|ON|1`` (and any number, non-zero meaning on, as SCPI allows)."""
    word = param.strip().upper()
    if word == "ON":
        return True
    if word == "OFF":
        return False
    try:
        return round(float(word)) != 0
    except ValueError:
        raise ScpiError(-224, f"expected OFF|0|ON|1, got {param}") from None


def parse_choice(param: str, choices: Sequence[str]) -> str:
    """Character data matched against long-form choices (``LINear``); returns the short form."""
    word = param.strip().upper()
    for choice in choices:
        if word in (choice.upper(), short_form(choice)):
            return short_form(choice)
    raise ScpiError(-224, f"{param} is not one of {'|'.join(short_form(c) for c in choices)}")


_NUMBER = re.compile(r"\s*([+-]?(?:\d+\.?\d*|\.\d+)(?:[eE][+-]?\d+)?)\s*([A-Za-z/%_0-9]*)\s*$")


@dataclass(frozen=True)
class Quantity:
    """A numeric parameter: ``value`` in the base unit ``unit`` (``HZ``, ``S``, ``CYCLE``...).

    ``keyword`` is ``MAX``, ``MIN``, ``UP``, ``DOWN`` or ``DEF`` when the parameter was one of
    those words (then ``value`` is NaN and the command decides what it means).
    """

    value: float
    unit: str
    keyword: str | None = None


#: Unit suffixes: suffix -> (base unit, factor to the base unit). SCPI reads ``MHZ`` as megahertz.
UNIT_SUFFIXES: dict[str, tuple[str, float]] = {
    "HZ": ("HZ", 1.0),
    "KHZ": ("HZ", 1e3),
    "MHZ": ("HZ", 1e6),
    "MAHZ": ("HZ", 1e6),
    "GHZ": ("HZ", 1e9),
    "S": ("S", 1.0),
    "MS": ("S", 1e-3),
    "US": ("S", 1e-6),
    "NS": ("S", 1e-9),
    "CYCLE": ("CYCLE", 1.0),
    "CYCLES": ("CYCLE", 1.0),
    "CYC": ("CYCLE", 1.0),
    "VPK": ("VPK", 1.0),
    "V": ("VPK", 1.0),
    "MV": ("VPK", 1e-3),
    "MVPK": ("VPK", 1e-3),
    "VRMS": ("VPK", math.sqrt(2.0)),
    "MVRMS": ("VPK", math.sqrt(2.0) * 1e-3),
    "DBVRMS": ("DBVRMS", 1.0),
    "DBV": ("DBVRMS", 1.0),
    "DB": ("DB", 1.0),
    "EU": ("EU", 1.0),
    "PNT/SWP": ("PNT/SWP", 1.0),
    "PNT": ("PNT/SWP", 1.0),
    "V/EU": ("V/EU", 1.0),
    "MV/EU": ("V/EU", 1e-3),
    "V/S": ("V/S", 1.0),
    "VPK/S": ("V/S", 1.0),
}

_KEYWORDS = {"MAX": "MAX", "MAXIMUM": "MAX", "MIN": "MIN", "MINIMUM": "MIN", "UP": "UP",
             "DOWN": "DOWN", "DEF": "DEF", "DEFAULT": "DEF"}


def parse_quantity(param: str, allowed_units: Sequence[str], default_unit: str) -> Quantity:
    """Parse a number with an optional unit suffix, or one of ``MAX|MIN|UP|DOWN|DEF``.

    Parameters
    ----------
    param
        The parameter as sent (``"2.5 KHZ"``, ``"100 CYCLE"``, ``"MAX"``).
    allowed_units
        Base units this command accepts (``("HZ",)``, ``("S", "CYCLE")``).
    default_unit
        Base unit of a bare number.

    Raises
    ------
    ScpiError
        -120 for a malformed number, -131 for an unknown or unsuitable suffix.
    """
    keyword = _KEYWORDS.get(param.strip().upper())
    if keyword is not None:
        return Quantity(math.nan, default_unit, keyword)
    match = _NUMBER.match(param)
    if match is None:
        raise ScpiError(-120, param)
    value = float(match.group(1))
    suffix = match.group(2).upper()
    if not suffix:
        return Quantity(value, default_unit)
    unit = UNIT_SUFFIXES.get(suffix)
    if unit is None or unit[0] not in allowed_units:
        raise ScpiError(-131, f"{suffix} (accepted: {', '.join(allowed_units)})")
    base, factor = unit
    return Quantity(value * factor, base)


# --------------------------------------------------------------------------------------------
# Responses


def format_int(value: int) -> str:
    """NR1 response: ``+0``, ``+16``."""
    return f"{int(value):+d}"


def format_bool(value: bool) -> str:
    """Boolean response: ``+0`` or ``+1``."""
    return "+1" if value else "+0"


def format_real(value: float, digits: int = 12) -> str:
    """NR3 response with ``digits`` significant digits (``+1.00000000000E+002``)."""
    # Three-digit exponents as HP instruments print them (inferred).
    mantissa, exponent = f"{value:+.{digits - 1}E}".split("E")
    return f"{mantissa}E{int(exponent):+04d}"


def format_string(text: str) -> str:
    """String response in double quotes."""
    return '"' + text.replace('"', '""') + '"'


def definite_block(payload: bytes) -> bytes:
    """IEEE 488.2 definite-length block ``#<n><len><bytes>``."""
    length = str(len(payload)).encode()
    return b"#" + str(len(length)).encode() + length + payload
