"""Parameter helpers shared by the command handlers: count, range, keywords, unit queries.

A handler takes ``(params, suffix)``: the program unit's parameters as strings and the numeric
suffix of the header (``INP2`` -> 2, ``None`` when absent).
"""

from __future__ import annotations

from collections.abc import Callable

from rigsim.scpi import (
    Quantity,
    ScpiError,
    format_real,
    format_string,
    parse_bool,
    parse_quantity,
)

__all__ = [
    "Params",
    "bool_setter",
    "integer",
    "limited",
    "one",
    "quantity_query",
    "query_unit",
]

Params = tuple[str, ...]


def one(params: Params) -> str:
    """The single parameter (-109 if missing, -108 if more than one)."""
    if not params:
        raise ScpiError(-109)
    if len(params) > 1:
        raise ScpiError(-108, ",".join(params[1:]))
    return params[0]


def integer(params: Params, lo: int, hi: int) -> int:
    """One integer parameter in ``lo..hi`` (``MAX``/``MIN`` accepted; -222 outside)."""
    q = parse_quantity(one(params), ("",), "")
    if q.keyword is not None:
        return hi if q.keyword == "MAX" else lo
    value = round(q.value)
    if not lo <= value <= hi:
        raise ScpiError(-222, f"{value} outside {lo}..{hi}; value not changed")
    return value


def limited(q: Quantity, current: float, lo: float, hi: float, step: float) -> float:
    """Resolve MAX/MIN/UP/DOWN/DEF and check the range (-222, value not changed)."""
    if q.keyword == "MAX":
        return hi
    if q.keyword == "MIN":
        return lo
    if q.keyword == "UP":
        return min(hi, current + step)
    if q.keyword == "DOWN":
        return max(lo, current - step)
    if q.keyword == "DEF":
        raise ScpiError(-224, "DEF")
    if not lo - 1e-12 <= q.value <= hi + 1e-12:
        raise ScpiError(-222, f"{q.value:g} {q.unit} outside {lo:g}..{hi:g}; value not changed")
    return q.value


def bool_setter(apply: Callable[[bool], None]) -> Callable[..., None]:
    """A handler that parses one boolean parameter and passes it to ``apply``."""
    return lambda p, s: apply(parse_bool(one(p)))


def query_unit(params: Params, unit: str) -> str | None:
    """``<query>? UNIT`` answers the unit in use (inferred response: a quoted string)."""
    if params and params[0].upper() == "UNIT":
        return format_string(unit)
    if params:
        raise ScpiError(-108, params[0])
    return None


def quantity_query(get: Callable[[], tuple[float, str]]) -> Callable[..., str]:
    """A query handler answering ``get()``'s value, or its unit for ``<query>? UNIT``."""
    def query(params: Params, suffix: int | None) -> str:
        value, unit = get()
        answer = query_unit(params, unit)
        return answer if answer is not None else format_real(value)
    return query
