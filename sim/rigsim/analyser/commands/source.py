"""``OUTPut`` (chapter 16) and ``SOURce`` (19): the source, its level, limits and auto level.

Levels keep the unit they were set in (``SOUR:VOLT 0.5 VRMS`` then ``SOUR:VOLT?`` answers 0.5,
``SOUR:VOLT? UNIT`` answers ``"VRMS"``). A bare number is in dB re 1 V peak for the source level
and limit (their upper limit, 13.9794, is 5 Vpk in those units) and in dBVrms for the reference
and input limit, as for the input range **(inferred: the manual gives the limits, not the
default unit)**.
"""

from __future__ import annotations

import math

from rigsim.analyser.commands.table import boolean, choice, declare, real
from rigsim.analyser.host import Host
from rigsim.analyser.limits import FREQUENCY_STEP_HZ, MAX_SOURCE_VPK
from rigsim.analyser.settings import check_option, level_spec, one
from rigsim.scpi import (
    OUT_OF_RANGE,
    Call,
    CommandTree,
    ScpiError,
    format_real,
    format_string,
    parse_quantity,
)

__all__ = ["register"]

_DBVRMS_MIN_VPK = math.sqrt(2.0) * 10 ** (-69.276 / 20)
_RANGE_TOP_VPK = 31.66
#: Pink noise can be at most 4.196 Vpk (chapter 19).
MAX_PINK_VPK = 4.196


def register(tree: CommandTree, a: Host) -> None:
    """Register the source commands."""
    store = a.store
    fft = frozenset({"FFT", "OCT", "ORD", "HIST", "CORR"})
    sine = frozenset({"SINE"})
    declare(tree, store, [
        ("OUTPut[:STATe]", "outp.state", boolean(False, modes=fft)),
        ("OUTPut:FILTer[:LPASs][:STATe]", "outp.filt",
         boolean(True, option="1D4", answer="onoff")),
        ("SOURce:BURSt", "sour.burs", real(50.0, 0.0, 100.0, ("PCT",), modes=fft)),
        ("SOURce:FUNCtion[:SHAPe]", "sour.func",
         choice("SIN", "SINusoid", "RANDom", "BRANdom", "PCHirp", "BCHirp", "PINK", "USER",
                "CAPTure", modes=fft)),
        ("SOURce:USER:CAPTure", "sour.user.capt",
         real(1.0, 1.0, 4.0, option="1D4", modes=fft)),
        ("SOURce:USER[:REGister]", "sour.user.reg",
         choice("D1", "D1", "D2", "D3", "D4", "D5", "D6", "D7", "D8", option="1D4")),
        ("SOURce:USER:REPeat", "sour.user.rep", boolean(True, option="1D4")),
        ("SOURce:VOLTage[:LEVel][:IMMediate]:OFFSet", "sour.offs",
         real(0.0, -10.0, 10.0, ("V",))),
        ("SOURce:VOLTage[:LEVel]:AUTO", "sour.volt.auto",
         boolean(False, modes=sine, option="1D2")),
        ("SOURce:VOLTage[:LEVel]:REFerence:CHANnel", "sour.ref.chan",
         choice("INP2", "INPut1", "INPut2", "INPut3", "INPut4", modes=sine, option="1D2")),
        ("SOURce:VOLTage[:LEVel]:REFerence:TOLerance", "sour.ref.tol",
         real(2.0, 0.1, 20.0, ("DB",), modes=sine, option="1D2")),
        ("SOURce:VOLTage:SLEW", "sour.slew",
         real(0.0, 0.0, 10000.0, ("V/S", "VPK/S", "VRMS/S"))),
        ("SOURce:VOLTage:LIMit[:AMPLitude]", "sour.lim",
         level_spec(2.0, "VPK", 0.0, MAX_SOURCE_VPK, "DBV", modes=sine, option="1D2")),
        ("SOURce:VOLTage[:LEVel]:REFerence", "sour.ref",
         level_spec(2.0, "VPK", _DBVRMS_MIN_VPK, _RANGE_TOP_VPK, "DBVRMS", eu=True,
                    modes=sine, option="1D2")),
        ("SOURce:VOLTage:LIMit:INPut", "sour.lim.inp",
         level_spec(2.0, "VPK", _DBVRMS_MIN_VPK, _RANGE_TOP_VPK, "DBVRMS", eu=True,
                    modes=sine, option="1D2")),
        ("SOURce:VOLTage[:LEVel][:IMMediate][:AMPLitude]", "sour.volt",
         level_spec(0.0, "VPK", 0.0, MAX_SOURCE_VPK, "DBV")),
    ], after=lambda name, value, index: _after(a, name))
    store.level_channels["sour.ref"] = lambda index: int(str(store.get("sour.ref.chan"))[-1])
    store.level_channels["sour.lim.inp"] = lambda index: 0
    store.define("sour.freq", real(10240.0, 0.0, 115000.0, ("HZ",)))

    def set_frequency(call: Call) -> None:
        if a.mode not in fft:
            raise ScpiError(-221, "Measurement mode incompatible with command.")
        q = parse_quantity(one(call), ("HZ",))
        current = float(store.get("sour.freq"))
        if q.keyword is not None:
            step = float(store.get("freq.step"))
            value = {"MAX": 115000.0, "MIN": 0.0, "UP": current + step,
                     "DOWN": current - step}.get(q.keyword)
            if value is None:
                raise ScpiError(-224, q.keyword)
            value = min(115000.0, max(0.0, value))
        else:
            value = q.value
            if not 0.0 <= value <= 115000.0:
                raise ScpiError(-222, OUT_OF_RANGE)
        store.set("sour.freq", math.floor(value / FREQUENCY_STEP_HZ + 1e-9) * FREQUENCY_STEP_HZ)

    def frequency_query(call: Call) -> str:
        if a.mode not in fft:
            raise ScpiError(-221, "Measurement mode incompatible with command.")
        params = call.params
        if params:
            if params[0].strip().upper() == "UNIT":
                return format_string("HZ")
            raise ScpiError(-108)
        return format_real(float(store.get("sour.freq")))

    for pattern in ("SOURce:FREQuency[:CW]", "SOURce:FREQuency:FIXed"):
        tree.add(pattern, setter=set_frequency, query=frequency_query)


def _after(a: Host, name: str) -> None:
    """Checks that involve more than one source setting."""
    store = a.store
    if name in ("sour.volt", "sour.offs", "sour.func"):
        level = store.get("sour.volt")
        offset = float(store.get("sour.offs"))
        function = store.get("sour.func")
        if function in ("USER", "CAPT") and "1D4" not in a.options:
            store.set("sour.func", "SIN")
            check_option("1D4", a.options)
        if function == "PINK" and level.vpk > MAX_PINK_VPK + 1e-9:
            store.set("sour.volt", type(level)(MAX_PINK_VPK, level.unit))
        if abs(level.vpk) + abs(offset) > 10.0 + 1e-9:
            # the offset is reset to a valid value (chapter 19)
            store.set("sour.offs", math.copysign(10.0 - abs(level.vpk), offset))
    if name == "sour.volt":
        a.settings_changed("source")
