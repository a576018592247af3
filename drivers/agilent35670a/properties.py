"""Declarative settings of the analyser: validated, formatted with their unit, written, read back.

In the manner of PyMeasure's ``Instrument.control`` and ``Channel``: a class attribute describes
one setting (the SCPI command that writes it, with ``{value}`` and the owner's placeholders such
as ``{ch}``; the query that reads it back; a validator; what the analyser is expected to answer
for the value sent). Assigning to the attribute validates the value first; a value outside the
manual's range raises :class:`SettingOutOfRange` and nothing is sent. A valid value is written
through the owner's ``configure`` (which checks the error queue) and remembered in
``owner.sent``; :meth:`Subsystem.verify` reads every remembered setting back and names those the
analyser did not take.

A :class:`Subsystem` is one part of the analyser (an input channel, the sweep, the source...):
it has its own settings and sends through its parent, which only has to provide ``ask`` and
``configure`` (:class:`Parent`), so subsystems never import the instrument.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterable
from typing import Any, Protocol

from .errors import MalformedReply, SettingNotApplied, SettingOutOfRange

__all__ = [
    "Control",
    "Parent",
    "Subsystem",
    "boolean",
    "control",
    "integer_range",
    "measurement",
    "number_text",
    "on_off_text",
    "one_of",
    "parse_bool",
    "parse_float",
    "parse_int",
    "parse_keyword",
    "parse_string",
    "setting",
    "strict_range",
]

Validator = Callable[[Any, Any], Any]


def number_text(value: float) -> str:
    """Format a number for SCPI: up to 12 significant digits (every frequency of the
    analyser's 15.625 mHz grid up to 102.4 kHz exactly: 25599.984375 Hz needs 11), no locale,
    no padding."""
    return format(float(value), ".12g")


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


def parse_string(reply: str) -> str:
    """Parse a quoted string reply (``"M/S2"``): its content, doubled quotes undone."""
    text = reply.strip()
    if len(text) >= 2 and text[0] == text[-1] and text[0] in "'\"":
        return text[1:-1].replace(text[0] * 2, text[0])
    raise MalformedReply(f"expected a quoted string, got {reply!r}")


# -- validators: (value, owner) -> value as it will be sent ----------------------------------
def strict_range(low: float, high: float, unit: str, *, low_inclusive: bool = True) -> Validator:
    """Accept a real number in ``[low, high]`` (or ``(low, high]``), unit named in messages."""

    def validate(value: Any, owner: Any) -> float:
        number = _as_real(value, unit)
        above_low = number >= low if low_inclusive else number > low
        if not (above_low and number <= high):
            bracket = "[" if low_inclusive else "("
            raise SettingOutOfRange(
                f"{number:.10g} {unit} is outside {bracket}{low:g}, {high:g}] {unit}"
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
        Command template with ``{value}`` (and the owner's placeholders, such as ``{ch}``).
    get_command
        Query reading the setting back, or ``None`` when nothing can be read back.
    doc
        What is controlled, in which unit and range.
    validator
        ``(value, owner) -> value``; raises :class:`SettingOutOfRange`.
    to_text
        Formats the validated value for ``{value}``.
    parse
        Turns the query's reply into a Python value.
    expect
        The reply expected for a value sent (the analyser rounds some settings); identity by
        default.
    unit
        The unit the analyser must report for ``<query>? UNIT`` after the value was sent, or
        ``None`` when the query has no unit.
    tolerance
        Relative tolerance of a numeric read-back.
    implies
        Other settings of the owner this one changes in the analyser (name -> new value, or
        ``None`` when the other setting is no longer known): a fixed range turns autorange off.
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
        expect: Callable[[Any], Any] | None = None,
        unit: str | None = None,
        tolerance: float = 1e-6,
        implies: dict[str, Any] | None = None,
    ) -> None:
        self.set_command = set_command
        self.implies = implies or {}
        self.get_command = get_command
        self.validator = validator
        self.to_text = to_text
        self.parse = parse
        self.expect = expect
        self.unit = unit
        self.tolerance = tolerance
        self.__doc__ = doc
        self.name = ""

    def __set_name__(self, owner: type, name: str) -> None:
        self.name = name

    def __get__(self, instance: Any, owner: type | None = None) -> Any:
        if instance is None:
            return self
        if self.get_command is None:
            raise AttributeError(f"{self.name} cannot be read back")
        return self.parse(instance.ask(self.get_command.format(**instance.placeholders)))

    def __set__(self, instance: Any, value: Any) -> None:
        try:
            checked = self.validator(value, instance)
        except SettingOutOfRange as error:
            raise SettingOutOfRange(f"{instance.label}.{self.name}: {error}") from None
        command = self.set_command.format(value=self.to_text(checked), **instance.placeholders)
        instance.configure(command)
        instance.sent.pop(self.name, None)  # keep the order of sending
        instance.sent[self.name] = checked
        for name, value in self.implies.items():
            instance.sent.pop(name, None)
            if value is not None:
                instance.sent[name] = value

    def check(self, instance: Any) -> str | None:
        """Read the setting back; a sentence naming the mismatch, or ``None`` when it holds."""
        if self.get_command is None or self.name not in instance.sent:
            return None
        sent = instance.sent[self.name]
        expected = sent if self.expect is None else self.expect(sent)
        query = self.get_command.format(**instance.placeholders)
        got = self.parse(instance.ask(query))
        if isinstance(expected, float) and not isinstance(expected, bool):
            same = math.isclose(float(got), expected, rel_tol=self.tolerance,
                                abs_tol=self.tolerance * 1e-3)
        else:
            same = got == expected
        if not same:
            return f"{instance.label}.{self.name}: sent {sent!r}, {query} answers {got!r}"
        if self.unit is not None:
            unit = parse_string(instance.ask(f"{query} UNIT")).upper()
            if unit != self.unit.upper():
                return (f"{instance.label}.{self.name}: {query} UNIT answers {unit!r}, "
                        f"not {self.unit}")
        return None


def control(set_command: str, get_command: str | None, doc: str, *, validator: Validator,
            to_text: Callable[[Any], str] = str, parse: Callable[[str], Any] = str,
            expect: Callable[[Any], Any] | None = None, unit: str | None = None,
            tolerance: float = 1e-6, implies: dict[str, Any] | None = None) -> Any:
    """Declare a setting; see :class:`Control`. Typed ``Any`` so attributes read naturally."""
    return Control(set_command, get_command, doc, validator=validator, to_text=to_text,
                   parse=parse, expect=expect, unit=unit, tolerance=tolerance, implies=implies)


def setting(set_command: str, doc: str, *, validator: Validator, to_text=number_text) -> Any:
    """Declare a setting that is not read back (a unit or form the analyser keeps elsewhere)."""
    return Control(set_command, None, doc, validator=validator, to_text=to_text)


def measurement(get_command: str, doc: str, *, parse: Callable[[str], Any] = str) -> Any:
    """Declare a read-only value of the analyser."""

    def refuse(value: Any, owner: Any) -> Any:
        raise SettingOutOfRange("is read-only")

    return Control("", get_command, doc, validator=refuse, parse=parse)


# -- subsystems --------------------------------------------------------------------------------
class Parent(Protocol):
    """What a subsystem sends through: the analyser (or a test double)."""

    def ask(self, command: str) -> str:
        """Send a query and return its reply."""

    def configure(self, command: str) -> None:
        """Send a setting and check the error queue."""


class Subsystem:
    """One part of the analyser with its own settings (PyMeasure's ``Channel`` in spirit).

    Parameters
    ----------
    parent
        What commands go through (``ask``, ``configure``).
    label
        Name used in messages (``"channel 3"``, ``"sweep"``).
    placeholders
        Values for the command templates (``{"ch": 3}``).
    """

    def __init__(self, parent: Parent, label: str, **placeholders: Any) -> None:
        self.parent = parent
        self.label = label
        self.placeholders = placeholders
        self.sent: dict[str, Any] = {}

    def ask(self, command: str) -> str:
        """Query through the parent."""
        return self.parent.ask(command)

    def configure(self, command: str) -> None:
        """Write a setting through the parent (error queue checked)."""
        self.parent.configure(command)

    def controls(self) -> list[Control]:
        """The settings this subsystem declares."""
        return [value for cls in type(self).__mro__ for value in vars(cls).values()
                if isinstance(value, Control) and value.set_command]

    def mismatches(self) -> list[str]:
        """Settings sent on this connection that the analyser does not hold (read back)."""
        found = []
        for item in self.controls():
            problem = item.check(self)
            if problem is not None:
                found.append(problem)
        return found

    def verify(self) -> None:
        """Raise :class:`SettingNotApplied` naming every setting the analyser did not take."""
        problems = self.mismatches()
        if problems:
            raise SettingNotApplied("; ".join(problems))
