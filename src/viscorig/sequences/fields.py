"""Typed, range-checked reading of one TOML table, with errors that name file and field."""

from __future__ import annotations

import math
from collections.abc import Iterable, Mapping
from typing import Any

from viscorig.errors import InputError

_MISSING = object()


def kind_name(value: object) -> str:
    """How TOML would call a Python value's type, for messages."""
    return {
        bool: "boolean", int: "integer", float: "number", str: "text", list: "array",
        dict: "table",
    }.get(type(value), type(value).__name__)


class TableReader:
    """Read the fields of one table; each value comes from the table itself or its defaults.

    Parameters
    ----------
    table
        The table's own keys.
    where
        ``"file.toml: steps[3]"``; a field's location is ``where.key`` (``where: key`` for
        the top level of a file, ``top_level=True``).
    defaults, defaults_where
        Values used when the table lacks a key, and where they come from (``"file.toml:
        defaults"``), so an error in a default names the defaults table.
    """

    def __init__(
        self,
        table: Mapping[str, Any],
        where: str,
        defaults: Mapping[str, Any] | None = None,
        defaults_where: str = "",
        *,
        top_level: bool = False,
    ) -> None:
        if not isinstance(table, Mapping):
            raise InputError(f"expected a table, got {kind_name(table)}", where)
        self.table = table
        self.where = where
        self.defaults = defaults or {}
        self.defaults_where = defaults_where
        self.used: set[str] = set()
        self._separator = ": " if top_level else "."

    def location(self, key: str) -> str:
        """Where the value of ``key`` was written."""
        if key not in self.table and key in self.defaults:
            return f"{self.defaults_where}.{key}"
        return f"{self.where}{self._separator}{key}"

    def fail(self, key: str, message: str) -> InputError:
        """An error about ``key`` (to raise)."""
        return InputError(message, self.location(key))

    def raw(self, key: str, default: object = _MISSING) -> Any:
        """The value as written, or ``default``; missing without default is an error."""
        self.used.add(key)
        if key in self.table:
            return self.table[key]
        if key in self.defaults:
            return self.defaults[key]
        if default is _MISSING:
            raise InputError("missing", f"{self.where}{self._separator}{key}")
        return default

    def text(self, key: str, default: object = _MISSING, *, choices: Iterable[str] = ()) -> str:
        """A non-empty string (one of ``choices`` if given)."""
        value = self.raw(key, default)
        if not isinstance(value, str):
            raise self.fail(key, f"expected text, got {kind_name(value)} {value!r}")
        if not value.strip():
            raise self.fail(key, "must not be empty")
        options = tuple(choices)
        if options and value not in options:
            raise self.fail(key, f"{value!r} is not one of {', '.join(options)}")
        return value

    def number(
        self,
        key: str,
        default: object = _MISSING,
        *,
        low: float = -math.inf,
        high: float = math.inf,
        low_open: bool = False,
        unit: str = "",
    ) -> float:
        """A finite float in [low, high] (``(low, high]`` with ``low_open``); ints accepted."""
        if default is not _MISSING and key not in self.table and key not in self.defaults:
            self.used.add(key)
            return default  # type: ignore[return-value]
        value = self.raw(key)
        if isinstance(value, bool) or not isinstance(value, int | float):
            raise self.fail(key, f"expected a number, got {kind_name(value)} {value!r}")
        value = float(value)
        below = value <= low if low_open else value < low
        if not math.isfinite(value) or below or value > high:
            bracket = "(" if low_open else "["
            suffix = f" {unit}" if unit else ""
            raise self.fail(key, f"{value!r} is outside {bracket}{low:g}, {high:g}]{suffix}")
        return value

    def integer(self, key: str, default: object = _MISSING, *, low: int, high: int) -> int:
        """An integer in [low, high]."""
        value = self.raw(key, default)
        if isinstance(value, bool) or not isinstance(value, int):
            raise self.fail(key, f"expected a whole number, got {kind_name(value)} {value!r}")
        if not low <= value <= high:
            raise self.fail(key, f"{value} is outside [{low}, {high}]")
        return value

    def flag(self, key: str, default: object = _MISSING) -> bool:
        """A boolean."""
        value = self.raw(key, default)
        if not isinstance(value, bool):
            raise self.fail(key, f"expected true or false, got {kind_name(value)} {value!r}")
        return value

    def subtable(self, key: str, *, required: bool = True) -> Mapping[str, Any] | None:
        """A nested table, or None when absent and not required."""
        value = self.raw(key, _MISSING if required else None)
        if value is None:
            return None
        if not isinstance(value, Mapping):
            raise self.fail(key, f"expected a table, got {kind_name(value)}")
        return value

    def finish(self) -> None:
        """Refuse keys nobody read (typos, fields of another step type)."""
        for key in self.table:
            if key not in self.used:
                known = ", ".join(sorted(self.used)) or "none"
                raise InputError(f"unknown key (known here: {known})", self.location(key))
