"""Common commands (chapter 3), ``SYSTem`` (21) and ``STATus`` (20).

``*OPC?`` and ``*WAI`` wait outside the instrument lock, so the controller's session handles
them (:class:`rigsim.analyser.session.ScpiSession`); ``*OPC`` is here.
"""

from __future__ import annotations

import json
import time

from rigsim.analyser.commands.table import action, boolean, choice, declare, integer
from rigsim.analyser.host import Host
from rigsim.analyser.settings import one
from rigsim.scpi import (
    Call,
    CommandTree,
    ScpiError,
    block_payload,
    definite_block,
    format_bool,
    format_int,
    format_real,
    format_string,
    parse_number,
    parse_quantity,
)

__all__ = ["register"]

_STATUS_GROUPS = {
    "OPERation": "OPER", "QUEStionable": "QUES", "QUEStionable:VOLTage": "QUES:VOLT",
    "QUEStionable:LIMit": "QUES:LIM", "DEVice": "DEV",
}


def _int_param(call: Call, lo: int, hi: int) -> int:
    q = parse_quantity(one(call))
    if q.keyword == "MAX":
        return hi
    if q.keyword == "MIN":
        return lo
    if q.keyword is not None:
        raise ScpiError(-224, q.keyword)
    value = round(q.value)
    if not lo <= value <= hi:
        raise ScpiError(-222, "Out of range: value not changed.")
    return value


def _numbers(call: Call, count: int, limits: list[tuple[float, float]]) -> list[int]:
    if len(call.params) != count:
        raise ScpiError(-109 if len(call.params) < count else -108)
    values = [round(parse_number(p)) for p in call.params]
    for value, (lo, hi) in zip(values, limits, strict=True):
        if not lo <= value <= hi:
            raise ScpiError(-222, "Out of range: value not changed.")
    return values


def register(tree: CommandTree, a: Host) -> None:
    """Register the common, ``SYSTem`` and ``STATus`` commands."""
    status = a.status
    t = tree

    def set_status(name: str, value: int) -> None:
        setattr(status, name, value)

    t.add("*IDN", query=lambda c: a.idn)
    t.add("*OPT", query=lambda c: format_string(",".join(a.options)))
    t.add("*RST", setter=lambda c: a.reset("RST"))
    t.add("*CLS", setter=lambda c: status.clear())
    t.add("*ESE", setter=lambda c: set_status("ese", _int_param(c, 0, 255)),
          query=lambda c: format_int(status.ese))
    t.add("*ESR", query=lambda c: format_int(status.read_esr()))
    t.add("*SRE", setter=lambda c: set_status("sre", _int_param(c, 0, 255) & ~64),
          query=lambda c: format_int(status.sre))
    t.add("*STB", query=lambda c: format_int(status.status_byte()))
    t.add("*PSC", setter=lambda c: set_status("psc", _int_param(c, -32767, 32767) != 0),
          query=lambda c: format_bool(status.psc))
    t.add("*PCB", setter=lambda c: _numbers(c, len(c.params) or 1, [(0, 30)] * (
        len(c.params) or 1)) and None)
    t.add("*TST", query=lambda c: format_int(0))
    t.add("*CAL", query=lambda c: (a.calibrate_now(), format_int(0))[1])
    t.add("*OPC", setter=lambda c: status.operation_complete(idle=a.run.state == "IDLE"))
    t.add("*TRG", setter=lambda c: _trigger(a))

    # ---------------------------------------------------------------- SYSTem
    t.add("SYSTem:ERRor[:NEXT]", query=lambda c: status.next_error())
    t.add("SYSTem:PRESet", setter=lambda c: a.reset("PRES"))
    t.add("SYSTem:VERSion", query=lambda c: format_real(1992.0))
    t.add("SYSTem:POWer:SOURce", query=lambda c: "AC")
    t.add("SYSTem:DATE", setter=lambda c: _numbers(c, 3, [(1900, 2099), (1, 12), (1, 31)])
          and None, query=lambda c: ",".join(format_int(v) for v in time.localtime()[:3]))
    t.add("SYSTem:TIME", setter=lambda c: _numbers(c, 3, [(0, 23), (0, 59), (0, 59)]) and None,
          query=lambda c: ",".join(format_int(v) for v in time.localtime()[3:6]))
    action(t, "SYSTem:BEEPer[:IMMediate]", params=(0, 3), numeric=True)
    action(t, "SYSTem:FLOG:CLEar")
    t.add("SYSTem:SET", setter=lambda c: _restore_state(a, c),
          query=lambda c: definite_block(_state_text(a)))
    comm = "SYSTem:COMMunicate:SERial"
    declare(t, a.store, [
        ("SYSTem:BEEPer:STATe", "syst.beep", boolean(True)),
        ("SYSTem:COMMunicate:GPIB[:SELF]:ADDRess", "syst.gpib",
         integer(11, 0, 30, keep=True)),
        (f"{comm}[:RECeive]:BAUD", "syst.baud", integer(9600, 300, 9600, keep=True)),
        (f"{comm}[:RECeive]:BITS", "syst.bits", integer(8, 5, 8, keep=True)),
        (f"{comm}[:RECeive]:PACE", "syst.pace", choice("XON", "NONE", "XON", keep=True)),
        (f"{comm}[:RECeive]:PARity:CHECk", "syst.parity.check", boolean(False, keep=True)),
        (f"{comm}[:RECeive]:PARity[:TYPE]", "syst.parity",
         choice("NONE", "NONE", "EVEN", "ODD", keep=True)),
        (f"{comm}[:RECeive]:SBITs", "syst.sbits", integer(1, 1, 2, keep=True)),
        (f"{comm}:TRANsmit:PACE", "syst.tpace", choice("XON", "NONE", "XON", "DSR", keep=True)),
        ("SYSTem:FAN[:STATe]", "syst.fan", choice("AUTO", "OFF", "FULL", "AUTO",
                                                   aliases={"0": "OFF"})),
        ("SYSTem:KEY", "syst.key", integer(0, 0, 255)),
        ("SYSTem:KLOCk", "syst.klock", boolean(False)),
        ("SYSTem:POWer:STATe", "syst.power", boolean(True)),
    ])

    # ---------------------------------------------------------------- STATus
    for node, group in _STATUS_GROUPS.items():
        register_group(t, a, f"STATus:{node}", group)
    t.add("STATus:USER:ENABle",
          setter=lambda c: setattr(status.user, "enable", _int_param(c, 0, 32767)),
          query=lambda c: format_int(status.user.enable))
    t.add("STATus:USER[:EVENt]", query=lambda c: format_int(status.read_event("USER")))
    t.add("STATus:USER:PULSe", setter=lambda c: status.user.pulse(_int_param(c, 0, 32767)))
    t.add("STATus:PRESet", setter=lambda c: status.preset_registers())


def register_group(t: CommandTree, a: Host, node: str, group: str) -> None:
    """The five commands of one register group."""
    status = a.status
    register = status.groups[group]
    t.add(f"{node}:CONDition", query=lambda c: format_int(status.condition(group)))
    t.add(f"{node}[:EVENt]", query=lambda c: format_int(status.read_event(group)))
    for word, attribute in (("ENABle", "enable"), ("NTRansition", "ntr"),
                            ("PTRansition", "ptr")):
        t.add(f"{node}:{word}",
              setter=lambda c, n=attribute: setattr(register, n, _int_param(c, 0, 32767)),
              query=lambda c, n=attribute: format_int(getattr(register, n)))


def _trigger(a: Host) -> None:
    if a.mode == "SINE":
        raise ScpiError(-221, "No TRIGGER With SWEPT SINE Instrument Mode.")
    if a.store.get("trig.sour") != "BUS":
        raise ScpiError(-211, "Bus trigger ignored when trigger type is not GPIB trigger.")
    raise ScpiError(-211, "Trigger received when not waiting for trigger.")


def _state_text(a: Host) -> bytes:
    """``SYST:SET?``: the settings as a block (our own layout, read back by ``SYST:SET``)."""
    entries = []
    for (name, mode, index), value in a.store.values.items():
        plain = value
        if hasattr(value, "unit") and hasattr(value, "vpk"):
            plain = {"vpk": value.vpk, "unit": value.unit, "eu": value.eu}
        entries.append([name, mode, list(index), plain])
    return json.dumps({"kind": a.store.reset_kind, "values": entries}).encode()


def _restore_state(a: Host, call: Call) -> None:
    from rigsim.analyser.units import Level

    try:
        state = json.loads(block_payload(one(call)).decode("latin-1"))
        values = {}
        for name, mode, index, plain in state["values"]:
            if name not in a.store.specs:
                raise KeyError(name)
            value = Level(plain["vpk"], plain["unit"], plain["eu"]) if isinstance(
                plain, dict) else (tuple(plain) if isinstance(plain, list) else plain)
            values[(name, mode, tuple(index))] = value
    except (ValueError, KeyError, TypeError) as error:
        raise ScpiError(-161, f"not a state saved by SYST:SET? ({error})"[:60]) from None
    a.abort()
    a.store.reset_kind = state.get("kind", "PRES")
    a.store.values = values
    a.settings_changed("state")
