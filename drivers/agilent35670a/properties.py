"""Declarative settings of the analyser: validated, formatted with their unit, then written.

In the manner of PyMeasure's ``Instrument.control``: a class attribute describes one setting, the
SCPI command that writes it (with ``{value}`` and, for input channels, ``{ch}`` placeholders),
the query that reads it back (``None`` for write-only settings, whose reply unit the manual leaves
open), and a validator. Assigning to the attribute validates the value first; a value outside the
manual's range raises :class:`SettingOutOfRange` and nothing is sent. A valid value is written
through the owner's ``configure`` method, which checks the error queue afterwards.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterable
from typing import Any

from .errors import MalformedReply, SettingOutOfRange

Validator = Callable[[Any, Any], Any]


def number_text(value: float) -> str:
    """Format a number for SCPI: up to 10 significant digits, no locale, no padding."""
    return format(float(value), ".10g")


def on_off_text(value: bool) -> str:
    """Format a boolean as SCPI ``ON``/``OFF``."""
    return "ON" if value else "OFF"


def parse_bool(reply: str) -> bool:
    """Parse a boolean reply (``+0``/``+1``, ``0``/``1``, ``OFF``/``ON``)."""
    text = reply.strip().upper()
    if text in {"1", "+1", "ON"}:
        return True
    if text in {"0", "+0", "OFF"}:
        return False
    raise MalformedReply(f"expected a boolean (+0/+1), got {reply!r}")


def parse_float(reply: str) -> float:
    """Parse a numeric reply, refusing anything that is not a finite number."""
    try:
        value = float(reply.strip().split()[0])
    except (ValueError, IndexError):
        raise MalformedReply(f"expected a number, got {reply!r}") from None
    if not math.isfinite(value) or abs(value) >= 9.91e37:
        raise MalformedReply(f"expected a finite number, got {reply!r}")
    return value


def parse_int(reply: str) -> int:
    """Parse an integer reply (status registers, counts)."""
    value = parse_float(reply)
    if value != int(value):
        raise MalformedReply(f"expected an integer, got {reply!r}")
    return int(value)


def parse_keyword(reply: str) -> str:
    """Parse a keyword reply (``SINE``, ``"LIN"``): unquoted, upper case."""
    return reply.strip().strip('"').upper()


def parse_channel(reply: str) -> int:
    """Parse a channel reply ``INP1`` .. ``INP4`` into its number."""
    text = parse_keyword(reply)
    if text.startswith("INP") and text[3:].isdigit():
        return int(text[3:])
    raise MalformedReply(f"expected INP1..INP4, got {reply!r}")


# -- validators: (value, owner) -> value as it will be sent ----------------------------------
def strict_range(low: float, high: float, unit: str, *, low_inclusive: bool = True) -> Validator:
    """Accept a real number in ``[low, high]`` (or ``(low, high]``), unit named in messages."""

    def validate(value: Any, owner: Any) -> float:
        number = _as_real(value, unit)
        above_low = number >= low if low_inclusive else number > low
        if not (above_low and number <= high):
            bracket = "[" if low_inclusive else "("
            raise SettingOutOfRange(
                f"{number:g} {unit} is outside {bracket}{low:g}, {high:g}] {unit}"
            )
        return number

    return validate


def integer_range(low: int, high: int, unit: str) -> Validator:
    """Accept an integer in ``[low, high]``."""

    def validate(value: Any, owner: Any) -> int:
        if isinstance(value, bool) or not float(value).is_integer():
            raise SettingOutOfRange(f"{value!r} is not a whole number of {unit}")
        number = int(value)
        if not low <= number <= high:
            raise SettingOutOfRange(f"{number} {unit} is outside [{low}, {high}] {unit}")
        return number

    return validate


def stepped_range(high: float, low: float, step: float, unit: str) -> Validator:
    """Accept only values on the grid ``high, high - step, ..., low`` (input ranges)."""
    count = round((high - low) / step)

    def validate(value: Any, owner: Any) -> float:
        number = _as_real(value, unit)
        index = (high - number) / step
        if not (-1e-9 <= index <= count + 1e-9) or abs(index - round(index)) > 1e-9:
            raise SettingOutOfRange(
                f"{number:g} {unit} is not one of {high:g} to {low:g} {unit} in {step:g} {unit} "
                "steps"
            )
        return high - round(index) * step

    return validate


def one_of(values: Iterable[str]) -> Validator:
    """Accept one of a fixed set of keywords (any case); returned upper case."""
    allowed = tuple(v.upper() for v in values)

    def validate(value: Any, owner: Any) -> str:
        text = str(value).strip().upper()
        if text not in allowed:
            raise SettingOutOfRange(f"{value!r} is not one of {', '.join(allowed)}")
        return text

    return validate


def boolean(value: Any, owner: Any) -> bool:
    """Accept a Python boolean only (not 0/1 or strings, which hide mistakes)."""
    if not isinstance(value, bool):
        raise SettingOutOfRange(f"{value!r} is not True or False")
    return value


def _as_real(value: Any, unit: str) -> float:
    if isinstance(value, bool):
        raise SettingOutOfRange(f"{value!r} is not a number of {unit}")
    try:
        number = float(value)
    except (TypeError, ValueError):
        raise SettingOutOfRange(f"{value!r} is not a number of {unit}") from None
    if not math.isfinite(number):
        raise SettingOutOfRange(f"{value!r} is not a finite number of {unit}")
    return number


# -- the descriptor ----------------------------------------------------------------------------
class Control:
    """One analyser setting, declared as a class attribute.

    Parameters
    ----------
    set_command
        Command template with ``{value}`` (and ``{ch}`` on input channels).
    get_command
        Query reading the setting back, or ``None`` when it is write-only.
    doc
        What is controlled, in which unit and range.
    validator
        ``(value, owner) -> value``; raises :class:`SettingOutOfRange`.
    to_text
        Formats the validated value for ``{value}``.
    parse
        Turns the query's reply into a Python value.
    """

    def __init__(
        self,
        set_command: str,
        get_command: str | None,
        doc: str,
        *,
        validator: Validator,
        to_text: Callable[[Any], str] = str,
        parse: Callable[[str], Any] = str,
    ) -> None:
        self.set_command = set_command
        self.get_command = get_command
        self.validator = validator
        self.to_text = to_text
        self.parse = parse
        self.__doc__ = doc
        self.name = ""

    def __set_name__(self, owner: type, name: str) -> None:
        self.name = name

    def __get__(self, instance: Any, owner: type | None = None) -> Any:
        if instance is None:
            return self
        if self.get_command is None:
            raise AttributeError(
                f"{self.name} is write-only: the analyser's reply unit for it is not documented"
            )
        return self.parse(instance.ask(self.get_command.format(**instance.placeholders)))

    def __set__(self, instance: Any, value: Any) -> None:
        try:
            checked = self.validator(value, instance)
        except SettingOutOfRange as error:
            raise SettingOutOfRange(f"{instance.label}.{self.name}: {error}") from None
        command = self.set_command.format(value=self.to_text(checked), **instance.placeholders)
        instance.configure(command)
        instance.sent[self.name] = checked


def control(
    set_command: str,
    get_command: str | None,
    doc: str,
    *,
    validator: Validator,
    to_text: Callable[[Any], str] = str,
    parse: Callable[[str], Any] = str,
) -> Any:
    """Declare a setting; see :class:`Control`. Typed ``Any`` so attributes read naturally."""
    return Control(set_command, get_command, doc, validator=validator, to_text=to_text, parse=parse)


def setting(set_command: str, doc: str, *, validator: Validator, to_text=number_text) -> Any:
    """Declare a write-only setting (its query's reply unit is not documented)."""
    return Control(set_command, None, doc, validator=validator, to_text=to_text)


def measurement(get_command: str, doc: str, *, parse: Callable[[str], Any] = str) -> Any:
    """Declare a read-only value of the analyser."""

    def refuse(value: Any, owner: Any) -> Any:
        raise SettingOutOfRange("is read-only")

    return Control("", get_command, doc, validator=refuse, parse=parse)
