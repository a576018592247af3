"""``INPut`` (chapter 12) and ``[SENSe:]VOLTage`` (18): inputs, ranges, engineering units."""

from __future__ import annotations

import math

from rigsim.analyser.commands.table import boolean, choice, declare, integer, real, text
from rigsim.analyser.host import Host
from rigsim.analyser.inputs import range_step_dbvrms, snap_range_dbvrms
from rigsim.analyser.settings import Spec, check_option, one
from rigsim.analyser.units import LEVEL_UNITS, Level, from_vpk, to_vpk
from rigsim.scpi import (
    OUT_OF_RANGE,
    Call,
    CommandTree,
    ScpiError,
    format_bool,
    format_real,
    format_string,
    parse_bool,
    parse_quantity,
)

__all__ = ["TRANSDUCER_LABELS", "register"]

#: ``VOLT:RANG:UNIT:XDCR:LAB`` labels (chapter 18).
TRANSDUCER_LABELS = ("PA", "G", "M/S2", "M/S", "M", "KG", "N", "DYN", "INCH/S2", "INCH/S",
                     "INCH", "MIL", "LB", "USER")
_TOP_DBVRMS, _BOTTOM_DBVRMS = 27.0, -51.0


def _channel(call: Call) -> int:
    number = 1 if call.suffix is None else call.suffix
    if not 1 <= number <= 4:
        raise ScpiError(-114, f"{call.header}: suffix {number} (1..4)")
    return number


def register(tree: CommandTree, a: Host) -> None:
    """Register the input and range commands."""
    _inputs(tree, a)
    _ranges(tree, a)


def _inputs(tree: CommandTree, a: Host) -> None:
    """``INPut``: which inputs are on (1 always; 3 and 4 together), coupling, filters."""
    store = a.store
    channel = {"scope": ("channel",)}
    store.define("inp.state", Spec("bool", lambda mode, index: index[0] <= 2, scope=("channel",)))

    def set_state(call: Call) -> None:
        number = _channel(call)
        on = parse_bool(one(call))
        if number >= 3:
            check_option("AY6", a.options)
        if number == 1 and not on:
            raise ScpiError(-200, "Channel 1 input cannot be disabled.")
        if number >= 3:  # inputs 3 and 4 go together: four-channel mode (chapter 12)
            store.set("inp.state", on, (3,))
            store.set("inp.state", on, (4,))
        else:
            store.set("inp.state", on, (number,))
            if number == 2 and not on:
                store.set("inp.state", False, (3,))
                store.set("inp.state", False, (4,))
        a.settings_changed("channels")

    tree.add("INPut#[:STATe]", setter=set_state,
             query=lambda c: format_bool(a.inputs.enabled(_channel(c))))
    declare(tree, store, [
        ("INPut#:BIAS[:STATe]", "inp.bias", boolean(False, **channel)),
        ("INPut#:COUPling", "inp.coup", choice("DC", "AC", "DC", **channel)),
        ("INPut#:LOW", "inp.low", choice("FLO", "GROund", "FLOat", **channel)),
        ("INPut#:FILTer:AWEighting[:STATe]", "inp.awe", boolean(False, **channel)),
        ("INPut#:FILTer[:LPASs][:STATe]", "inp.filt", boolean(True, **channel)),
        ("INPut#:REFerence:DIRection", "inp.ref.dir", integer(0, 0, 32767, keep=True, **channel)),
        ("INPut#:REFerence:POINt", "inp.ref.poin", integer(0, 0, 32767, keep=True, **channel)),
    ])


def _ranges(tree: CommandTree, a: Host) -> None:
    """``[SENSe:]VOLTage:RANGe``: each input's range, autorange and engineering units."""
    store = a.store
    channel = {"scope": ("channel",)}
    volt = "[SENSe:]VOLTage#[:DC]:RANGe"
    declare(tree, store, [
        (f"{volt}:AUTO", "volt.auto", boolean(True, **channel)),
        (f"{volt}:UNIT:USER:LABel", "volt.user.label", text("EU", 4, **channel)),
        (f"{volt}:UNIT:USER[:STATe]", "volt.user", boolean(False, **channel)),
        (f"{volt}:UNIT:XDCR:LABel", "volt.xdcr", choice("USER", *TRANSDUCER_LABELS, **channel)),
    ])
    store.define("volt.sfac", real(1.0, -9.9e37, 9.9e37, ("V/EU", "EU/V"), **channel))

    def set_sfac(call: Call) -> None:
        number = _channel(call)
        q = parse_quantity(one(call), ("V/EU", "EU/V"))
        current = float(store.get("volt.sfac", (number,)))
        if q.keyword is not None:
            value = {"MAX": 9.9e37, "MIN": -9.9e37}.get(q.keyword)
            if value is None:
                raise ScpiError(-224, q.keyword)
        else:
            value = q.value
            if q.unit == "EU/V":
                if value == 0:
                    raise ScpiError(-222, OUT_OF_RANGE)
                value = 1.0 / value
        if not -9.9e37 <= value <= 9.9e37 or value == 0:
            raise ScpiError(-222, OUT_OF_RANGE)
        del current
        store.set("volt.sfac", value, (number,))

    tree.add(f"{volt}:UNIT:USER:SFACtor", setter=set_sfac,
             query=lambda c: _answer(c, format_real(float(store.get("volt.sfac",
                                                                    (_channel(c),)))), "V/EU"))

    store.define("volt.range", Spec("level", Level(math.sqrt(2.0) * 10 ** (-51 / 20), "DBVRMS"),
                                    units=LEVEL_UNITS, default_unit="DBVRMS", **channel))

    def set_range(call: Call) -> None:
        number = _channel(call)
        q = parse_quantity(one(call), LEVEL_UNITS)
        current: Level = store.get("volt.range", (number,))
        current_db = 20 * math.log10(current.vpk / math.sqrt(2.0))
        unit = q.unit or "DBVRMS"
        if q.keyword in ("UP", "DOWN"):
            value_db = range_step_dbvrms(current_db, 1 if q.keyword == "UP" else -1)
            unit = current.unit
        elif q.keyword in ("MAX", "MIN"):
            value_db = _TOP_DBVRMS if q.keyword == "MAX" else _BOTTOM_DBVRMS
            unit = current.unit
        elif q.keyword is not None:
            raise ScpiError(-224, q.keyword)
        else:
            vpk = to_vpk(q.value, unit, a.v_per_eu(number))
            if vpk <= 0:
                raise ScpiError(-222, OUT_OF_RANGE)
            value_db = 20 * math.log10(vpk / math.sqrt(2.0))
            if not _BOTTOM_DBVRMS - 1e-6 <= value_db <= _TOP_DBVRMS + 1e-3:
                raise ScpiError(-222, OUT_OF_RANGE)
        snapped = snap_range_dbvrms(value_db)
        store.set("volt.range", Level(math.sqrt(2.0) * 10 ** (snapped / 20), unit), (number,))
        store.set("volt.auto", False, (number,))  # a fixed range turns autorange off

    def range_query(call: Call) -> str:
        number = _channel(call)
        level: Level = store.get("volt.range", (number,))
        unit = level.unit
        if unit in ("EU", "DBEU") and a.v_per_eu(number) is None:
            unit = "DBVRMS"
        return _answer(call, format_real(from_vpk(level.vpk, unit, a.v_per_eu(number))), unit)

    tree.add(f"{volt}[:UPPer]", setter=set_range, query=range_query)
    store.define("volt.auto.dir", choice("EITH", "UP", "EITHer", **channel))

    def set_direction(call: Call) -> None:
        number = _channel(call)
        word = one(call).strip().upper()
        if word not in ("UP", "EITH", "EITHER"):
            raise ScpiError(-141, f"{word[:20]} is not one of UP|EITH")
        # in swept sine the analyser ignores it (chapter 18): stored, not used
        store.set("volt.auto.dir", "UP" if word == "UP" else "EITH", (number,))

    tree.add(f"{volt}:AUTO:DIRection", setter=set_direction,
             query=lambda c: str(store.get("volt.auto.dir", (_channel(c),))))


def _answer(call: Call, value: str, unit: str) -> str:
    if not call.params:
        return value
    if len(call.params) == 1 and call.params[0].strip().upper() == "UNIT":
        return format_string(unit)
    raise ScpiError(-108, call.params[0][:40])
