"""SCPI message parsing for the virtual 35670A: framing, headers, parameters, units, responses.

What the 35670A accepts (programming guide, chapter 2): program messages end with a line feed
and/or EOI; ``;`` separates commands and ``;:`` returns to the root; mnemonics have a short and
a long form, in any case; optional nodes (``[SENSe:]``) may be left out; booleans are
``OFF|0|ON|1``; numbers accept a unit suffix with an SI multiplier and ``MAX|MIN|UP|DOWN``;
strings are quoted with ``'`` or ``"`` (a doubled quote stands for itself); blocks are
``#<n><length><bytes>`` (definite) or ``#0<bytes>`` up to the end of the message (indefinite).

A command tree is built from patterns written as in the manual: ``[SENSe:]FREQuency:STARt``,
``CALCulate#:MARKer:X[:ABSolute]`` (``#`` marks a node that takes a numeric suffix, such as
``CALC3``), ``*IDN``. Upper-case letters are the short form. Each pattern carries a setting
handler and/or a query handler, called with a :class:`Call`.

This module knows nothing of the instrument; :mod:`rigsim.analyser` registers the commands.
"""

from __future__ import annotations

import math
import re
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass, field
from itertools import product
from typing import Any

#: Error texts of the 35670A's error numbers (programming guide, appendix C).
ERROR_TEXTS: dict[int, str] = {
    0: "No error",
    -100: "Command error",
    -101: "Invalid character",
    -102: "Syntax error",
    -103: "Invalid separator",
    -104: "Data type error",
    -108: "Parameter not allowed",
    -109: "Missing parameter",
    -112: "Program mnemonic too long",
    -113: "Undefined header",
    -114: "Header suffix out of range",
    -120: "Numeric data error",
    -121: "Invalid character in number",
    -123: "Exponent too large",
    -131: "Invalid suffix",
    -138: "Suffix not allowed",
    -141: "Invalid character data",
    -144: "Character data too long",
    -148: "Character data not allowed",
    -150: "String data error",
    -151: "Invalid string data",
    -158: "String data not allowed",
    -160: "Block data error",
    -161: "Invalid block data",
    -168: "Block data not allowed",
    -200: "Execution error",
    -211: "Trigger ignored",
    -212: "Arm ignored",
    -213: "Init ignored",
    -220: "Parameter error",
    -221: "Settings conflict",
    -222: "Data out of range",
    -224: "Illegal parameter value",
    -230: "Data corrupt or stale",
    -241: "Hardware missing",
    -310: "System error",
    -350: "Queue overflow",
    -410: "Query INTERRUPTED",
    -420: "Query UNTERMINATED",
}

#: The text the 35670A gives with -222 (appendix C).
OUT_OF_RANGE = "Out of range: value not changed."


class ScpiError(Exception):
    """A command failed; ``code`` and ``message`` go to the error queue as ``code,"message"``.

    Parameters
    ----------
    code
        SCPI error number (negative for standard errors).
    detail
        The instrument's message for this cause (appendix C), appended after ``;``.
    """

    def __init__(self, code: int, detail: str | None = None) -> None:
        base = ERROR_TEXTS.get(code, "Error")
        self.code = code
        self.message = f"{base}; {detail}" if detail else base
        super().__init__(f"{code},{self.message}")


# --------------------------------------------------------------------------------------------
# Message framing (bytes from a transport -> program messages)


class MessageTooLong(Exception):  # noqa: N818 - a signal to the transport, not an error class
    """More than the framer's bound arrived without a message terminator."""


class MessageFramer:
    """Cuts a byte stream into program messages at line feeds outside blocks.

    A line feed inside a definite-length block (``#<n><length><bytes>``) does not end the
    message; an indefinite block (``#0``) runs to the next line feed. A line feed inside a
    quoted string ends the message too (the parser then reports the string unterminated,
    -151): a stream has no END signal to tell a string's line feed from a terminator, and a
    client that lost a quote must not wait for a reply until its time-out.

    At most ``max_bytes`` of one message are held: past that, :meth:`feed` raises
    :class:`MessageTooLong` (the transport answers with an error and drops the connection), so
    a peer that never sends a terminator cannot fill the memory.

    Parameters
    ----------
    max_bytes
        Longest message accepted, terminator excluded.
    """

    def __init__(self, max_bytes: int) -> None:
        self.max_bytes = max_bytes
        self._buffer = bytearray()
        self._scan = 0  # bytes of the buffer already scanned
        self._quote = 0  # the open quote character, or 0
        self._skip = 0  # block bytes still to pass over

    @property
    def pending(self) -> bool:
        """Part of a message has arrived and its terminator not yet."""
        return bool(self._buffer)

    def feed(self, data: bytes) -> list[bytes]:
        """Add received bytes; return the messages they complete (terminator removed)."""
        messages: list[bytes] = []
        self._buffer += data
        buf = self._buffer
        i = self._scan
        start = 0
        while i < len(buf):
            if self._skip:
                step = min(self._skip, len(buf) - i)
                self._skip -= step
                i += step
                continue
            byte = buf[i]
            if self._quote and byte != 0x0A:
                if byte == self._quote:
                    self._quote = 0
                i += 1
                continue
            if byte in (0x22, 0x27):
                self._quote = byte
            elif byte == 0x23:  # '#': a block header may follow
                header = self._block_header(buf, i)
                if header is None:
                    break  # the header is not complete yet
                i, self._skip = header
                continue
            elif byte == 0x0A:
                if i - start > self.max_bytes:
                    break
                messages.append(bytes(buf[start:i]))
                start = i + 1
                self._quote = 0
            i += 1
        del buf[:start]
        self._scan = i - start
        if self._scan > self.max_bytes or len(buf) > self.max_bytes:
            self._buffer = bytearray()
            self._scan = self._skip = self._quote = 0
            raise MessageTooLong(f"message longer than {self.max_bytes} bytes")
        return messages

    @staticmethod
    def _block_header(buf: bytearray, i: int) -> tuple[int, int] | None:
        """(index after the header, payload length) of a definite block at ``i``; an indefinite
        block or a ``#`` that starts no block gives (i + 1, 0)."""
        if i + 1 >= len(buf):
            return None
        digit = chr(buf[i + 1])
        if not digit.isdigit() or digit == "0":
            return i + 1, 0
        width = int(digit)
        if i + 2 + width > len(buf):
            return None
        length_text = bytes(buf[i + 2 : i + 2 + width])
        if not length_text.isdigit():
            return i + 1, 0
        return i + 2 + width, int(length_text)


# --------------------------------------------------------------------------------------------
# Command tree


@dataclass(frozen=True)
class Call:
    """One command or query as a handler sees it.

    Attributes
    ----------
    params
        Parameter strings as sent, stripped, quotes kept (blocks as latin-1 text).
    suffixes
        Numeric suffix of each suffixed node of the pattern, in order (``None`` where the
        header left it out): ``CALC3:MARK`` gives ``(3,)``.
    header
        The full header path, as the mnemonics sent (for messages).
    """

    params: tuple[str, ...]
    suffixes: tuple[int | None, ...] = ()
    header: str = ""

    @property
    def suffix(self) -> int | None:
        """The first numeric suffix (``None`` when absent)."""
        return self.suffixes[0] if self.suffixes else None


Handler = Callable[[Call], Any]


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
    """A header resolved against the tree: its handler and the suffixes of its nodes."""

    handler: Handler
    suffixes: tuple[int | None, ...]


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
        self.patterns: list[str] = []

    def add(self, pattern: str, setter: Handler | None = None,
            query: Handler | None = None) -> None:
        """Register a header pattern (``[SENSe:]FREQuency:STARt``, ``INPut#[:STATe]``, ``*IDN``)."""
        self.patterns.append(pattern)
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
        suffixes: list[int | None] = []
        for token in tokens:
            match = _MNEMONIC.match(token)
            if match is None:
                raise ScpiError(-113, ":".join(tokens))
            name, digits = match.group(1).upper(), match.group(2)
            child = node.children.get(name)
            if child is None and digits:
                # a mnemonic whose own name ends in a digit (none in this instrument, but cheap)
                child = node.children.get(name + digits)
                digits = "" if child is not None else digits
            if child is None:
                raise ScpiError(-113, ":".join(tokens))
            if digits and not child.suffix_allowed:
                raise ScpiError(-113, ":".join(tokens))
            if child.suffix_allowed:
                suffixes.append(int(digits) if digits else None)
            node = child
        handler = node.query if is_query else node.setter
        if handler is None:
            if is_query and node.setter is not None:
                raise ScpiError(-113, ":".join(tokens) + "? (command is not a query)")
            if not is_query and node.query is not None:
                raise ScpiError(-100, "Command is query only.")
            raise ScpiError(-113, ":".join(tokens))
        return Resolved(handler, tuple(suffixes))

    def resolve_common(self, header: str, is_query: bool) -> Handler:
        """Find the handler of a common command (``*IDN``)."""
        node = self.common.get(header.upper())
        handler = None if node is None else (node.query if is_query else node.setter)
        if handler is None:
            if node is not None and node.query is not None:
                raise ScpiError(-100, "Command is query only.")
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


def _scan(text: str, separators: str) -> Iterator[tuple[int, int]]:
    """Spans of ``text`` between ``separators`` outside strings, blocks and parentheses."""
    start = 0
    quote = ""
    depth = 0
    i = 0
    while i < len(text):
        char = text[i]
        if quote:
            if char == quote:
                quote = ""
        elif char in "'\"":
            quote = char
        elif char == "(":
            depth += 1
        elif char == ")":
            depth = max(0, depth - 1)
        elif char == "#" and i + 1 < len(text) and text[i + 1].isdigit():
            width = int(text[i + 1])
            if width == 0:  # indefinite block: the rest of the message
                i = len(text)
                break
            digits = text[i + 2 : i + 2 + width]
            if len(digits) == width and digits.isdigit():
                i = i + 2 + width + int(digits)
                continue
        elif depth == 0 and char in separators:
            yield start, i
            start = i + 1
        i += 1
    if quote:
        raise ScpiError(-151, "unterminated string")
    yield start, len(text)


def split_units(message: str) -> Iterator[str]:
    """Split a program message at ``;`` outside quoted strings, blocks and parentheses (a
    ``;`` just before the terminator ends nothing more: programs send ``DISP:FORM ULOW;``)."""
    spans = list(_scan(message, ";"))
    if len(spans) > 1 and not message[spans[-1][0]:spans[-1][1]].strip():
        spans.pop()
    for start, end in spans:
        yield message[start:end]


def split_params(text: str) -> tuple[str, ...]:
    """Split a parameter list at commas outside quoted strings, blocks and parentheses."""
    if not text.strip():
        return ()
    params = tuple(text[a:b].strip() for a, b in _scan(text, ","))
    if any(not p for p in params):
        raise ScpiError(-103, text.strip())
    return params


_HEADER = re.compile(r"\s*(\*?[A-Za-z0-9:_]+\??)(?:[ \t]+(.*))?$", re.DOTALL)


def parse_unit(text: str) -> ProgramUnit:
    """Parse one program message unit into header, query flag and parameters."""
    stripped = text.strip(" \t\r\n")
    if not stripped:
        raise ScpiError(-102, "empty command")
    match = _HEADER.match(stripped)
    if match is None:
        raise ScpiError(-102, stripped[:60])
    header, rest = match.group(1), match.group(2) or ""
    is_query = header.endswith("?")
    if is_query:
        header = header[:-1]
    if not header or "?" in header or header.endswith(":"):
        raise ScpiError(-102, stripped[:60])
    return ProgramUnit(header, is_query, split_params(rest), stripped)


# --------------------------------------------------------------------------------------------
# Parameters


def unquote(param: str) -> str:
    """The content of a quoted string parameter (doubled quotes inside are undone)."""
    if len(param) >= 2 and param[0] == param[-1] and param[0] in "'\"":
        quote = param[0]
        return param[1:-1].replace(quote * 2, quote)
    raise ScpiError(-151, f"expected a quoted string, got {param[:40]}")


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
        raise ScpiError(-141, f"expected OFF|0|ON|1, got {param[:40]}") from None


def parse_choice(param: str, choices: Sequence[str]) -> str:
    """Character data matched against long-form choices (``LINear``); returns the short form."""
    word = param.strip().upper()
    for choice in choices:
        short = short_form(choice) if any(c.islower() for c in choice) else choice.upper()
        if word in (choice.upper(), short):
            return short
    shown = "|".join(short_form(c) if any(x.islower() for x in c) else c for c in choices)
    raise ScpiError(-141, f"{param[:40]} is not one of {shown}")


_NUMBER = re.compile(
    r"\s*([+-]?(?:\d+\.?\d*|\.\d+)(?:\s*[eE]\s*[+-]?\d+)?)\s*([A-Za-z/%_0-9^.]*)\s*$")

#: SI multipliers of suffixes (SCPI 1999 volume 1, 7.7.3). ``M`` is milli; ``MA`` mega.
SI_PREFIXES: dict[str, float] = {
    "EX": 1e18, "PE": 1e15, "T": 1e12, "G": 1e9, "MA": 1e6, "K": 1e3,
    "M": 1e-3, "U": 1e-6, "N": 1e-9, "P": 1e-12, "F": 1e-15, "A": 1e-18,
}
#: Whole suffixes read against the prefix rule: ``MHZ`` is megahertz, ``MOHM`` megohm.
SPECIAL_SUFFIXES: dict[str, tuple[str, float]] = {"MHZ": ("HZ", 1e6), "MOHM": ("OHM", 1e6)}
#: Units that take no SI multiplier (logarithmic units, counts, ratios).
NO_PREFIX_UNITS = {"DB", "DBVRMS", "DBVPK", "DBV", "DBEU", "PCT", "PNT/SWP", "PNT/DEC",
                   "PNT/OCT", "CYCLE", "ORD", "COUNT", "AVG", "REV", "BLK", "EU"}


@dataclass(frozen=True)
class Quantity:
    """A numeric parameter: ``value`` in ``unit`` (one of the command's units, or ``""`` when
    the number came bare).

    ``keyword`` is ``MAX``, ``MIN``, ``UP``, ``DOWN`` or ``DEF`` when the parameter was one of
    those words (then ``value`` is NaN and the command decides what it means).
    """

    value: float
    unit: str
    keyword: str | None = None


_KEYWORDS = {"MAX": "MAX", "MAXIMUM": "MAX", "MIN": "MIN", "MINIMUM": "MIN", "UP": "UP",
             "DOWN": "DOWN", "DEF": "DEF", "DEFAULT": "DEF"}
_UNIT_ALIASES = {"CYCLES": "CYCLE", "CYC": "CYCLE", "SEC": "S", "PNT": "PNT/SWP"}


def _resolve_suffix(suffix: str, units: Sequence[str]) -> tuple[str, float]:
    """The unit among ``units`` that ``suffix`` names, and the multiplier it carries."""
    upper = suffix.upper()
    upper = _UNIT_ALIASES.get(upper, upper)
    if upper in units:
        return upper, 1.0
    special = SPECIAL_SUFFIXES.get(upper)
    if special is not None and special[0] in units:
        return special
    for unit in sorted(units, key=len, reverse=True):
        if unit in NO_PREFIX_UNITS or not upper.endswith(unit) or upper == unit:
            continue
        prefix = upper[: -len(unit)]
        if prefix in SI_PREFIXES:
            return unit, SI_PREFIXES[prefix]
    raise ScpiError(-131, f"{suffix} (accepted: {', '.join(units) or 'none'})")


def parse_quantity(param: str, units: Sequence[str] = ()) -> Quantity:
    """Parse a number with an optional unit suffix, or one of ``MAX|MIN|UP|DOWN|DEF``.

    Parameters
    ----------
    param
        The parameter as sent (``"2.5 KHZ"``, ``"100 CYCLE"``, ``"300mv"``, ``"MAX"``).
    units
        Unit names this command accepts (``("HZ", "CPM")``); SI multipliers apply to them.

    Raises
    ------
    ScpiError
        -120 for a malformed number, -131 for an unknown or unsuitable suffix, -138 for a
        suffix on a unitless number.
    """
    keyword = _KEYWORDS.get(param.strip().upper())
    if keyword is not None:
        return Quantity(math.nan, "", keyword)
    match = _NUMBER.match(param)
    if match is None:
        raise ScpiError(-120 if param[:1] in "+-.0123456789" else -104, param[:40])
    value = float(re.sub(r"\s+", "", match.group(1)))
    if not math.isfinite(value):
        raise ScpiError(-123, param[:40])
    suffix = match.group(2)
    if not suffix:
        return Quantity(value, "")
    if not units:
        raise ScpiError(-138, suffix)
    unit, factor = _resolve_suffix(suffix, units)
    return Quantity(value * factor, unit)


def parse_number(param: str) -> float:
    """A plain number (no unit, no keyword)."""
    q = parse_quantity(param)
    if q.keyword is not None:
        raise ScpiError(-104, param)
    return q.value


# --------------------------------------------------------------------------------------------
# Responses


def format_int(value: int) -> str:
    """NR1 response: ``+0``, ``+16``."""
    return f"{int(value):+d}"


def format_bool(value: bool) -> str:
    """Boolean response: ``+0`` or ``+1``."""
    return "+1" if value else "+0"


def format_real(value: float, digits: int = 12) -> str:
    """NR3 response with ``digits`` significant digits, three-digit exponent, as the 35670A
    prints it (``+1.00000000000E+002``, ``-3.40282346639E+038``)."""
    mantissa, exponent = f"{value:+.{digits - 1}E}".split("E")
    return f"{mantissa}E{int(exponent):+04d}"


def format_string(text: str) -> str:
    """String response in double quotes."""
    return '"' + text.replace('"', '""') + '"'


def definite_block(payload: bytes) -> bytes:
    """IEEE 488.2 definite-length block ``#<n><len><bytes>``."""
    length = str(len(payload)).encode()
    return b"#" + str(len(length)).encode() + length + payload


def block_payload(param: str) -> bytes:
    """The bytes of a block parameter (definite ``#<n><len>...`` or indefinite ``#0...``)."""
    if len(param) < 2 or param[0] != "#" or not param[1].isdigit():
        raise ScpiError(-161, "expected a block")
    width = int(param[1])
    if width == 0:
        return param[2:].encode("latin-1")
    digits = param[2 : 2 + width]
    if len(digits) != width or not digits.isdigit():
        raise ScpiError(-161, "bad block length")
    payload = param[2 + width :]
    if len(payload) != int(digits):
        raise ScpiError(-161, f"block declares {int(digits)} bytes, carries {len(payload)}")
    return payload.encode("latin-1")
