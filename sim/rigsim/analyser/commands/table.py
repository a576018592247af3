"""Shorthands for the command tables: one line per setting, as the manual lists them."""

from __future__ import annotations

import math
from collections.abc import Callable, Iterable
from typing import Any

from rigsim.analyser.settings import SettingStore, Spec, bind, check_option
from rigsim.scpi import Call, CommandTree, ScpiError, parse_quantity

__all__ = ["Row", "action", "boolean", "choice", "declare", "integer", "pair", "real", "text"]

Row = tuple[str, str, Spec]


def boolean(preset: bool, **kw: Any) -> Spec:
    """An ``OFF|0|ON|1`` setting."""
    return Spec("bool", preset, **kw)


def integer(preset: int, lo: float, hi: float, **kw: Any) -> Spec:
    """An integer setting in ``lo..hi`` (``MAX|MIN``; ``UP|DOWN`` by 1)."""
    kw.setdefault("step", 1)
    return Spec("int", preset, lo=lo, hi=hi, **kw)


def real(preset: float, lo: float = -math.inf, hi: float = math.inf, units: tuple[str, ...] = (),
         **kw: Any) -> Spec:
    """A real setting; the first unit is the default of a bare number."""
    if units:
        kw.setdefault("default_unit", units[0])
    return Spec("real", preset, lo=lo, hi=hi, units=units, **kw)


def pair(preset: tuple[float, str], units: tuple[str, ...], **kw: Any) -> Spec:
    """A number kept with the unit it came in (``S|CYCLE``)."""
    return Spec("pair", preset, units=units, **kw)


def choice(preset: str, *choices: str, **kw: Any) -> Spec:
    """A keyword setting (long forms, ``LINear``)."""
    return Spec("choice", preset, choices=choices, **kw)


def text(preset: str, length: int, **kw: Any) -> Spec:
    """A quoted string setting."""
    return Spec("string", preset, length=length, **kw)


def declare(tree: CommandTree, store: SettingStore, rows: Iterable[Row],
            after: Callable[[str, Any, tuple[int, ...]], None] | None = None) -> None:
    """Declare settings and register their handlers (``after(name, value, index)`` runs after
    each new value)."""
    for pattern, name, spec in rows:
        hook = None if after is None else (lambda v, i, n=name: after(n, v, i))
        bind(tree, store, pattern, name, spec, after=hook)


def action(
    tree: CommandTree,
    pattern: str,
    do: Callable[[Call], Any] | None = None,
    *,
    params: tuple[int, int] = (0, 0),
    numeric: bool = False,
    modes: frozenset[str] | None = None,
    conflict: str = "",
    option: str | None = None,
    options: Callable[[], tuple[str, ...]] | None = None,
    mode: Callable[[], str] | None = None,
) -> None:
    """A command without a stored value (``CALC:MARK:MAX``); ``params`` is the count allowed
    (min, max); ``numeric`` checks they are numbers."""

    def handler(call: Call) -> Any:
        if option is not None and options is not None:
            check_option(option, options())
        if modes is not None and mode is not None and mode() not in modes:
            raise ScpiError(-221, conflict or "Measurement mode incompatible with command.")
        low, high = params
        if len(call.params) < low:
            raise ScpiError(-109)
        if len(call.params) > high:
            raise ScpiError(-108, call.params[high][:40])
        if numeric:
            for param in call.params:
                parse_quantity(param, ("HZ", "S", "PCT", "V", "DB", "RPM", "ORD"))
        return None if do is None else do(call)

    tree.add(pattern, setter=handler)
