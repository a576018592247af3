"""``TRACe`` (chapter 23) and ``FORMat`` (chapter 9): data registers and the data format."""

from __future__ import annotations

import re

import numpy as np

from rigsim.analyser.host import Host
from rigsim.analyser.settings import Spec, one
from rigsim.analyser.traces import Register, encode, interleaved
from rigsim.scpi import (
    Call,
    CommandTree,
    ScpiError,
    block_payload,
    format_int,
    format_string,
    parse_choice,
    parse_number,
)

__all__ = ["register"]


def _register_name(word: str) -> tuple[str, int]:
    match = re.fullmatch(r"(D|TRAC(?:E)?|CAL(?:C)?)([1-8])", word.strip().upper())
    if match is None:
        raise ScpiError(-141, f"{word[:20]} (expected D1..D8 or TRAC1..TRAC4)")
    kind = {"D": "D", "TRAC": "TRAC", "TRACE": "TRAC", "CAL": "TRAC", "CALC": "TRAC"}[
        match.group(1)]
    number = int(match.group(2))
    if kind == "TRAC" and number > 4:
        raise ScpiError(-141, word[:20])
    return kind, number


def register(tree: CommandTree, a: Host) -> None:
    """Register ``TRACe`` and ``FORMat``."""
    store = a.store
    store.define("form", Spec("pair", ("ASC", 12)))

    def source(word: str) -> Register:
        kind, number = _register_name(word)
        if kind == "TRAC":
            return a.trace(number)
        if number not in a.registers:
            raise ScpiError(-200, "Cannot edit an empty data register.")
        return a.registers[number]

    def copy(call: Call) -> None:
        if len(call.params) < 2:
            raise ScpiError(-109, "TRAC:DATA <register>,<source>")
        kind, number = _register_name(call.params[0])
        if kind != "D":
            raise ScpiError(-141, f"{call.params[0][:20]}: data goes into D1..D8")
        first = call.params[1].strip()
        if len(call.params) == 2 and not first.startswith("#") and re.match(r"[A-Za-z]", first):
            a.registers[number] = source(first).copy()
            return
        if number not in a.registers:
            raise ScpiError(-200, "Cannot edit an empty data register.")
        target = a.registers[number]
        if first.startswith("#"):
            width = 8 if store.get("form")[1] == 64 else 4
            payload = block_payload(first)
            if len(payload) % width:
                raise ScpiError(-161, f"{len(payload)} bytes is not a whole number of values")
            values = np.frombuffer(payload, f">f{width}").astype(float)
        else:
            values = np.array([parse_number(p) for p in call.params[1:]])
        expected = 2 * target.y.size if target.is_complex else target.y.size
        if values.size != expected:
            raise ScpiError(-161, f"{values.size} values for a register of {expected}")
        y = values[0::2] + 1j * values[1::2] if target.is_complex else values
        a.registers[number] = Register(target.feed, target.x.copy(), y, target.power,
                                       target.displayed, target.domain, target.kind)

    def data(call: Call) -> bytes:
        register = source(one(call))
        values = interleaved(register.y) if register.is_complex else register.y
        return encode(values, store.get("form"))

    tree.add("TRACe[:DATA]", setter=copy, query=data)
    tree.add("TRACe:X[:DATA]", query=lambda c: encode(source(one(c)).x, store.get("form")))
    tree.add("TRACe:X:UNIT", query=lambda c: format_string(
        "HZ" if source(one(c)).domain == "freq" else "S"))
    tree.add("TRACe:Z:UNIT", query=lambda c: (source(one(c)), format_string("COUNTS"))[1])
    tree.add("TRACe:Z[:DATA]", query=lambda c: (source(one(c)), encode(np.array([1.0]),
                                                                         store.get("form")))[1])

    def set_format(call: Call) -> None:
        if not call.params or len(call.params) > 2:
            raise ScpiError(-109 if not call.params else -108)
        kind = parse_choice(call.params[0], ("ASCii", "REAL"))
        default = 12 if kind == "ASC" else 64
        length = default if len(call.params) == 1 else round(parse_number(call.params[1]))
        if kind == "ASC" and not 3 <= length <= 12:
            raise ScpiError(-222, "Out of range: value not changed.")
        if kind == "REAL" and length not in (32, 64):
            raise ScpiError(-224, "REAL format length is only 32 and 64.")
        store.set("form", (kind, length))

    tree.add("FORMat[:DATA]", setter=set_format,
             query=lambda c: f"{store.get('form')[0]},{format_int(store.get('form')[1])}")
