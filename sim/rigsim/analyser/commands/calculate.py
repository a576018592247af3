"""``CALCulate`` (chapter 6): trace feeds, formats and data, units, markers, limits, math.

Feeds, formats and units are kept per trace and per instrument mode. Markers and limit lines
work on the trace's displayed data; curve fit and synthesis need option 1D3, the waterfall is
FFT-only state.
"""

from __future__ import annotations

import itertools
import math

import numpy as np

from rigsim.analyser.commands.table import action, boolean, choice, declare, integer, real, text
from rigsim.analyser.host import Host
from rigsim.analyser.settings import Spec, check_option, one
from rigsim.analyser.traces import FORMATS, check_feed, encode, formatted, parse_feed
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
    parse_choice,
    parse_number,
    parse_quantity,
    unquote,
)

__all__ = ["register", "trace_values"]

_X_UNITS = ("HZ", "S", "ORD", "COUNT", "AVG", "V", "VPK", "RPM", "EU", "REV")
_Y_UNITS = ("DBVRMS", "VPK", "DBVPK", "V", "DBV", "EU", "DBEU", "VRMS")
_FFT_FEEDS = ("XFR:POW 1", "XFR:POW 2", "XTIM:VOLT 1", "XTIM:VOLT 2")
_FFT_FORMATS = ("MLOG", "MLOG", "REAL", "REAL")
_SINE_FEEDS = ("XFR:POW:RAT 2,1", "XFR:POW:RAT 2,1", "XFR:POW:LIN 1", "XFR:POW:LIN 2")
_SINE_FORMATS = ("MLOG", "PHAS", "MLOG", "MLOG")
_NO_WATERFALL = "No WATERFALL display with SWEPT SINE Instrument Mode."


def _trace_preset(sine: tuple[str, ...], other: tuple[str, ...]):
    return lambda mode, index: (sine if mode == "SINE" else other)[index[0] - 1]


def _trace(call: Call) -> int:
    number = 1 if call.suffix is None else call.suffix
    if not 1 <= number <= 4:
        raise ScpiError(-114, f"{call.header}: suffix {number} (1..4)")
    return number


def trace_values(a: Host, number: int) -> tuple[np.ndarray, np.ndarray]:
    """X values and displayed values (NaN: no data) of trace ``number``."""
    register = a.trace(number)
    store = a.store
    fmt = str(store.get("calc.form", (number,)))
    degrees = store.get("calc.unit.angl", (number,)) == "DEGR"
    amplitude = str(store.get("calc.unit.ampl", (number,)))
    power_unit = unquote(format_string(str(store.get("calc.unit.volt", (number,)))))
    values = formatted(register, fmt, degrees=degrees, amplitude=amplitude,
                       power_unit=power_unit, bandwidth_hz=_bandwidth(a))
    return register.x[: register.display_count], values


def _bandwidth(a: Host) -> float:
    """Noise bandwidth of a line (FFT: resolution times the window's factor)."""
    result = a.fft.result
    if a.mode != "FFT" or result is None or result.frequency_hz.size < 2:
        return 1.0
    return float(result.frequency_hz[1] - result.frequency_hz[0]) * 1.5


def register(tree: CommandTree, a: Host) -> None:
    """Register the ``CALCulate`` commands."""
    _trace_data(tree, a)
    _settings(tree, a)
    _markers(tree, a)
    _limits(tree, a)
    _math(tree, a)
    _curve_fit(tree, a)


def _trace_data(t: CommandTree, a: Host) -> None:
    """What a trace shows (feed, format) and its data, X values and point count."""
    store = a.store
    store.define("calc.feed", Spec("string", _trace_preset(_SINE_FEEDS, _FFT_FEEDS),
                                   scope=("trace", "mode")))
    store.define("calc.form", Spec("choice", _trace_preset(_SINE_FORMATS, _FFT_FORMATS),
                                   choices=FORMATS, scope=("trace", "mode")))

    def set_feed(call: Call) -> None:
        number = _trace(call)
        feed = parse_feed(unquote(one(call)))
        reference = str(store.get("ref")) if "AY6" in a.options else "SING"
        check_feed(feed, a.mode, a.inputs.count(), reference)
        store.set("calc.feed", feed.text, (number,))

    def set_format(call: Call) -> None:
        number = _trace(call)
        store.set("calc.form", parse_choice(one(call), FORMATS), (number,))

    def data(call: Call) -> bytes:
        _, values = trace_values(a, _trace(call))
        return encode(values, _data_format(a))

    def x_data(call: Call) -> bytes:
        x, _ = trace_values(a, _trace(call))  # NYQ and POL pairs: one X per pair
        return encode(x, _data_format(a))

    def points(call: Call) -> str:
        x, values = trace_values(a, _trace(call))
        paired = values.size == 2 * x.size
        return format_int(x.size if paired else values.size)

    t.add("CALCulate#:FEED", setter=set_feed,
          query=lambda c: format_string(str(store.get("calc.feed", (_trace(c),)))))
    t.add("CALCulate#:FORMat", setter=set_format,
          query=lambda c: str(store.get("calc.form", (_trace(c),))))
    t.add("CALCulate#:DATA", query=data)
    t.add("CALCulate#:X:DATA", query=x_data)
    t.add("CALCulate#:DATA:HEADer:POINts", query=points)


def _settings(t: CommandTree, a: Host) -> None:
    """The trace settings that are stored and read back: units, limits' switches, the
    marker's options, math and waterfall."""
    store = a.store
    trace = {"scope": ("trace",)}
    per_mode = {"scope": ("trace", "mode")}
    declare(t, store, [
        ("CALCulate#:ACTive", "calc.act", choice("A", "A", "B", "C", "D", "AB", "CD", "ABCD")),
        ("CALCulate#:GDAPerture:APERture", "calc.gdap",
         real(2.0, 0.0, 20.0, ("PCT",), rst=0.25, **trace)),
        ("CALCulate#:UNIT:AMPLitude", "calc.unit.ampl",
         choice("RMS", "PEAK", "PP", "RMS", **per_mode)),
        ("CALCulate#:UNIT:ANGLe", "calc.unit.angl", choice("DEGR", "DEGRees", "RADians",
                                                          **trace)),
        ("CALCulate#:UNIT:DBReference:IMPedance", "calc.unit.dbr.imp",
         real(50.0, 1e-15, 1e15, ("OHM",), **trace)),
        ("CALCulate#:UNIT:DBReference:USER:LABel", "calc.unit.dbr.lab", text("V", 5, **trace)),
        ("CALCulate#:UNIT:DBReference:USER:REFerence", "calc.unit.dbr.ref",
         real(1.0, 1e-15, 1e15, **trace)),
        ("CALCulate#:UNIT:X:ORDer:FACTor", "calc.unit.x.ord",
         real(1.0, 1e-6, 1e6, ("HZ/ORD", "RPM/ORD"), **trace)),
        ("CALCulate#:UNIT:X:USER:FREQuency:FACTor", "calc.unit.x.ffact",
         real(1.0, -9.9e37, 9.9e37, **trace)),
        ("CALCulate#:UNIT:X:USER:FREQuency:LABel", "calc.unit.x.flab", text("Hz", 5, **trace)),
        ("CALCulate#:UNIT:X:USER:TIME:FACTor", "calc.unit.x.tfact",
         real(1.0, -9.9e37, 9.9e37, **trace)),
        ("CALCulate#:UNIT:X:USER:TIME:LABel", "calc.unit.x.tlab", text("s", 5, **trace)),
        # ---------------------------------------------------------- limits
        ("CALCulate#:LIMit:BEEP[:STATe]", "calc.lim.beep", boolean(False, **trace)),
        ("CALCulate#:LIMit:STATe", "calc.lim.stat", boolean(False, **trace)),
        # ---------------------------------------------------------- markers
        ("CALCulate#:MARKer:BAND:STARt", "calc.mark.band.star",
         real(0.0, -9.9e37, 9.9e37, _X_UNITS, **trace)),
        ("CALCulate#:MARKer:BAND:STOP", "calc.mark.band.stop",
         real(0.0, -9.9e37, 9.9e37, _X_UNITS, **trace)),
        ("CALCulate#:MARKer:COUPled[:STATe]", "calc.mark.coup", boolean(False, **trace)),
        ("CALCulate#:MARKer:DTABle:X:LABel", "calc.mark.dtab.lab", text("", 16, **trace)),
        ("CALCulate#:MARKer:DTABle:X:SELect[:POINt]", "calc.mark.dtab.sel",
         integer(1, 1, 50, **trace)),
        ("CALCulate#:MARKer:FUNCtion", "calc.mark.func",
         choice("OFF", "OFF", "HPOWer", "THD", "BPOWer", "BRMS", "SPOWer", "OVERshoot",
                "RTIMe", "STIMe", "DTIMe", "SSL", "GMARgin", "PMARgin", "GCRossover",
                "PCRossover", "FREQuency", "DAMPing", "SINFo", "WEIGht", "TPOWer", "WPOWer",
                aliases={"0": "OFF"}, **trace)),
        ("CALCulate#:MARKer:HARMonic:COUNt", "calc.mark.harm.coun",
         integer(5, 0, 400, **trace)),
        ("CALCulate#:MARKer:HARMonic:FUNDamental", "calc.mark.harm.fund",
         real(1.0, -9.9e37, 9.9e37, ("HZ", "ORD", "CPM", "RPM"), **trace)),
        ("CALCulate#:MARKer:MAXimum[:GLOBal]:TRACk", "calc.mark.max.trac",
         boolean(False, **trace)),
        ("CALCulate#:MARKer:MODE", "calc.mark.mode",
         choice("ABS", "ABSolute", "RELative", **trace)),
        ("CALCulate#:MARKer:REFerence:X", "calc.mark.ref.x",
         real(0.0, -9.9e37, 9.9e37, _X_UNITS, **trace)),
        ("CALCulate#:MARKer:REFerence:Y", "calc.mark.ref.y",
         real(0.0, -9.9e37, 9.9e37, _Y_UNITS, **trace)),
        ("CALCulate#:MARKer:SIDeband:CARRier", "calc.mark.sid.carr",
         real(0.0, -9.9e37, 9.9e37, ("HZ", "ORD", "CPM", "RPM"), **trace)),
        ("CALCulate#:MARKer:SIDeband:COUNt", "calc.mark.sid.coun", integer(1, 0, 200, **trace)),
        ("CALCulate#:MARKer:SIDeband:INCRement", "calc.mark.sid.incr",
         real(0.0, -9.9e37, 9.9e37, ("HZ", "ORD", "CPM", "RPM"), **trace)),
        ("CALCulate#:MARKer[:STATe]", "calc.mark.stat", boolean(True, **trace)),
        ("CALCulate#:MARKer:X:RELative", "calc.mark.x.rel",
         real(0.0, -102400.0, 102400.0, _X_UNITS, **trace)),
        ("CALCulate#:MARKer:Y:RELative", "calc.mark.y.rel",
         real(0.0, -150.0, 150.0, _Y_UNITS, **trace)),
        # ---------------------------------------------------------- math
        ("CALCulate#:MATH:SELect", "calc.math.sel",
         choice("F1", "F1", "F2", "F3", "F4", "F5", **trace)),
        ("CALCulate#:MATH:STATe", "calc.math.stat", boolean(False, **trace)),
        # ---------------------------------------------------------- waterfall
        ("CALCulate#:WATerfall:COUNt", "calc.wat.coun",
         integer(15, 1, 9999, modes=frozenset({"FFT", "OCT", "ORD"}), conflict=_NO_WATERFALL,
                 **trace)),
    ])
    _string_choices(t, a, "CALCulate#:UNIT:DBReference", "calc.unit.dbr", "DBV",
                    ("DBV", "DBM", "DBSPL", "DBUSER"))
    _string_choices(t, a, "CALCulate#:UNIT:MECHanical", "calc.unit.mech", "M/S2",
                    ("G", "M/S2", "M/S", "M", "INCH/S2", "INCH/S", "INCH", "MILS"))
    _string_choices(t, a, "CALCulate#:UNIT:VOLTage", "calc.unit.volt", "V2",
                    ("V", "V2", "V/RTHZ", "V2/HZ", "V2S/HZ"))
    _string_choices(t, a, "CALCulate#:UNIT:X", "calc.unit.x", "HZ", ("HZ", "CPM", "ORD", "USER"))


def _curve_fit(t: CommandTree, a: Host) -> None:
    """Curve fit and synthesis (option 1D3): accepted with the option, not modelled."""
    for node in ("CFIT:ABORt", "CFIT:COPY", "CFIT[:IMMediate]", "SYNThesis:COPY",
                 "SYNThesis[:IMMediate]"):
        action(t, f"CALCulate#:{node}", option="1D3", options=lambda: a.options)
    for node in ("CFIT:DATA", "CFIT:DESTination", "CFIT:FREQuency[:AUTO]",
                 "CFIT:FREQuency:STARt", "CFIT:FREQuency:STOP", "CFIT:FSCale",
                 "CFIT:ORDer:AUTO", "CFIT:ORDer:POLes", "CFIT:ORDer:ZERos", "CFIT:TDELay",
                 "CFIT:WEIGht:AUTO", "CFIT:WEIGht:REGister", "SYNThesis:DATA",
                 "SYNThesis:DESTination", "SYNThesis:FSCale", "SYNThesis:GAIN",
                 "SYNThesis:SPACing", "SYNThesis:TDELay", "SYNThesis:TTYPe"):
        def needs_1d3(call: Call) -> None:
            check_option("1D3", a.options)
        t.add(f"CALCulate#:{node}", setter=needs_1d3, query=needs_1d3)


def _data_format(a: Host) -> tuple[str, int]:
    return a.store.get("form")


def _string_choices(t: CommandTree, a: Host, pattern: str, name: str, preset: str,
                    allowed: tuple[str, ...]) -> None:
    """A setting given as one of a few quoted strings (``CALC:UNIT:VOLT 'V2/HZ'``)."""
    a.store.define(name, Spec("string", preset, scope=("trace", "mode")))

    def setter(call: Call) -> None:
        value = unquote(one(call)).strip().upper()
        if value not in allowed:
            raise ScpiError(-224, f"'{value[:20]}' is not one of {'|'.join(allowed)}")
        a.store.set(name, value, (_trace(call),))

    t.add(pattern, setter=setter,
          query=lambda c: format_string(str(a.store.get(name, (_trace(c),)))))


def _markers(t: CommandTree, a: Host) -> None:
    """The main marker: position on the displayed data, its value, peak search."""
    store = a.store
    store.define("calc.mark.x", Spec("real", 0.0, scope=("trace",)))

    def nearest(number: int, x_value: float) -> int:
        return _nearest(a, number, x_value)

    def set_x(call: Call) -> None:
        number = _trace(call)
        q = parse_quantity(one(call), _X_UNITS)
        x, _ = trace_values(a, number)
        finite = x[np.isfinite(x)]
        lo, hi = (float(finite.min()), float(finite.max())) if finite.size else (0.0, 0.0)
        if q.keyword is not None:
            value = {"MAX": hi, "MIN": lo}.get(q.keyword)
            if value is None:
                index = nearest(number, float(store.get("calc.mark.x", (number,))))
                index += 1 if q.keyword == "UP" else -1
                index = min(max(index, 0), max(x.size - 1, 0))
                value = float(x[index]) if x.size and np.isfinite(x[index]) else lo
        else:
            value = min(hi, max(lo, q.value))  # the marker stays on the displayed range
        store.set("calc.mark.x", value, (number,))

    def set_point(call: Call) -> None:
        number = _trace(call)
        value = round(parse_number(one(call)))
        if not 0 <= value <= 2047:
            raise ScpiError(-222, "Out of range: value not changed.")
        x, _ = trace_values(a, number)
        index = min(value, max(x.size - 1, 0))
        if x.size and np.isfinite(x[index]):
            store.set("calc.mark.x", float(x[index]), (number,))

    def x_query(call: Call) -> str:
        if call.params:
            return format_string("HZ" if a.trace(_trace(call)).domain == "freq" else "S")
        return format_real(float(store.get("calc.mark.x", (_trace(call),))))

    def point_query(call: Call) -> str:
        number = _trace(call)
        return format_int(nearest(number, float(store.get("calc.mark.x", (number,)))))

    def y_query(call: Call) -> str:
        number = _trace(call)
        _, values = trace_values(a, number)
        index = nearest(number, float(store.get("calc.mark.x", (number,))))
        value = values[index] if index < values.size else math.nan
        return format_real(float(value) if math.isfinite(value) else -3.40282346639e38)

    def peak(call: Call, side: int = 0) -> None:
        number = _trace(call)
        x, values = trace_values(a, number)
        if values.size != x.size or not np.any(np.isfinite(values)):
            return
        current = nearest(number, float(store.get("calc.mark.x", (number,))))
        candidates = np.flatnonzero(np.isfinite(values))
        if side < 0:
            candidates = candidates[candidates < current]
        elif side > 0:
            candidates = candidates[candidates > current]
        if candidates.size:
            best = candidates[np.argmax(values[candidates])]
            store.set("calc.mark.x", float(x[best]), (number,))

    for pattern in ("CALCulate#:MARKer:X[:ABSolute]", "CALCulate#:MARKer:POSition"):
        t.add(pattern, setter=set_x, query=x_query)
    t.add("CALCulate#:MARKer:POSition:POINt", setter=set_point, query=point_query)
    t.add("CALCulate#:MARKer:Y[:ABSolute]", query=y_query)
    t.add("CALCulate#:MARKer:FUNCtion:RESult", query=lambda c: format_real(9.91e37))
    action(t, "CALCulate#:MARKer:MAXimum[:GLOBal]", peak)
    action(t, "CALCulate#:MARKer:MAXimum:LEFT", lambda c: peak(c, -1))
    action(t, "CALCulate#:MARKer:MAXimum:RIGHt", lambda c: peak(c, +1))
    _marker_table(t, a)


def _nearest(a: Host, number: int, x_value: float) -> int:
    """Index of the displayed point of trace ``number`` nearest ``x_value``."""
    x, _ = trace_values(a, number)
    good = np.flatnonzero(np.isfinite(x))
    if good.size == 0:
        return 0
    return int(good[np.argmin(np.abs(x[good] - x_value))])


def _marker_table(t: CommandTree, a: Host) -> None:
    """The marker table: positions inserted by X value, read back as blocks."""
    store = a.store
    store.define("calc.mark.dtab", Spec("string", "", scope=("trace",)))

    def table(call: Call) -> list[float]:
        raw = str(store.get("calc.mark.dtab", (_trace(call),)))
        return [float(v) for v in raw.split(",") if v]

    def insert(call: Call) -> None:
        rows = table(call)
        if len(rows) >= 50:
            raise ScpiError(-221, "Invalid program state change requested.")
        rows.append(parse_number(one(call)))
        store.set("calc.mark.dtab", ",".join(repr(v) for v in sorted(rows)), (_trace(call),))

    def delete(call: Call) -> None:
        rows = table(call)
        selected = int(store.get("calc.mark.dtab.sel", (_trace(call),))) - 1
        if 0 <= selected < len(rows):
            del rows[selected]
        store.set("calc.mark.dtab", ",".join(repr(v) for v in rows), (_trace(call),))

    def table_values(call: Call) -> bytes:
        number = _trace(call)
        _, values = trace_values(a, number)
        picked = [values[_nearest(a, number, x)] if values.size else math.nan
                  for x in table(call)]
        return encode(np.array(picked, float), _data_format(a))

    t.add("CALCulate#:MARKer:DTABle:X:INSert", setter=insert,
          query=lambda c: format_real(table(c)[-1] if table(c) else 0.0))
    action(t, "CALCulate#:MARKer:DTABle:X:DELete", delete)
    action(t, "CALCulate#:MARKer:DTABle:CLEar[:IMMediate]",
           lambda c: store.set("calc.mark.dtab", "", (_trace(c),)))
    action(t, "CALCulate#:MARKer:DTABle:COPY#")
    t.add("CALCulate#:MARKer:DTABle[:DATA]", query=table_values)
    t.add("CALCulate#:MARKer:DTABle:X[:DATA]",
          query=lambda c: encode(np.array(table(c), float), _data_format(a)))


def _limits(t: CommandTree, a: Host) -> None:
    """Upper and lower limit lines (segments kept through presets) and the limit test."""
    store = a.store
    for side in ("UPPer", "LOWer"):
        name = f"calc.lim.{side[:3].lower()}"
        store.define(name, Spec("string", "", scope=("trace",), keep=True))

        def segments(call: Call, key: str = name) -> list[float]:
            raw = str(store.get(key, (_trace(call),)))
            return [float(v) for v in raw.split(",") if v]

        def set_segments(call: Call, key: str = name) -> None:
            values = [parse_number(p) for p in call.params]
            if not values or len(values) % 4:
                raise ScpiError(-109 if not values else -108, "x1,y1,x2,y2 per segment")
            old = segments(call, key)
            store.set(key, ",".join(repr(v) for v in old + values), (_trace(call),))

        def clear_segment(call: Call, key: str = name) -> None:
            x = parse_number(one(call))
            old = segments(call, key)
            kept = [old[i:i + 4] for i in range(0, len(old), 4)
                    if not old[i] <= x <= old[i + 2]]
            store.set(key, ",".join(repr(v) for seg in kept for v in seg), (_trace(call),))

        def move(call: Call, key: str = name) -> None:
            dy = parse_number(one(call))
            old = segments(call, key)
            moved = [v + dy if i % 2 else v for i, v in enumerate(old)]
            store.set(key, ",".join(repr(v) for v in moved), (_trace(call),))

        def from_trace(call: Call, key: str = name) -> None:
            x, values = trace_values(a, _trace(call))
            good = np.flatnonzero(np.isfinite(x) & np.isfinite(values[: x.size]))
            rows = []
            for i, j in itertools.pairwise(good):
                rows += [x[i], values[i], x[j], values[j]]
            store.set(key, ",".join(repr(float(v)) for v in rows), (_trace(call),))

        def report(call: Call, key: str = name, upper: bool = side == "UPPer",
                   y_data: bool = False) -> bytes:
            failed = _failures(a, _trace(call), segments(call, key), upper)
            column = 1 if y_data else 0
            return encode(np.array([f[column] for f in failed], float), _data_format(a))

        base = f"CALCulate#:LIMit:{side}"
        t.add(f"{base}:SEGMent", setter=set_segments,
              query=lambda c, s=segments: encode(np.array(s(c), float), _data_format(a)))
        action(t, f"{base}:SEGMent:CLEar", clear_segment, params=(1, 1))
        action(t, f"{base}:CLEar[:IMMediate]",
               lambda c, key=name: store.set(key, "", (_trace(c),)))
        action(t, f"{base}:MOVE:Y", move, params=(1, 1))
        action(t, f"{base}:TRACe[:IMMediate]", from_trace)
        t.add(f"{base}:REPort[:DATA]", query=report)
        t.add(f"{base}:REPort:YDATa", query=lambda c, r=report: r(c, y_data=True))

    def fail(call: Call) -> str:
        number = _trace(call)
        if not store.get("calc.lim.stat", (number,)):
            a.status.push_error(-200, "Limit testing is turned off.")
            return format_bool(True)
        upper = [float(v) for v in str(store.get("calc.lim.upp", (number,))).split(",") if v]
        lower = [float(v) for v in str(store.get("calc.lim.low", (number,))).split(",") if v]
        if not upper and not lower:
            a.status.push_error(-200, "Limits are undefined.")
            return format_bool(True)
        failed = _failures(a, number, upper, True) + _failures(a, number, lower, False)
        return format_bool(bool(failed))

    t.add("CALCulate#:LIMit:FAIL", query=fail)


def _failures(a: Host, number: int, segments: list[float],
              upper: bool) -> list[tuple[float, float]]:
    """Points of the displayed trace beyond the limit segments."""
    x, values = trace_values(a, number)
    if values.size != x.size:
        return []
    failed = []
    for i in range(0, len(segments) - 3, 4):
        x1, y1, x2, y2 = segments[i:i + 4]
        inside = np.isfinite(x) & (x >= min(x1, x2)) & (x <= max(x1, x2)) & np.isfinite(values)
        if not np.any(inside):
            continue
        limit = np.interp(x[inside], [min(x1, x2), max(x1, x2)],
                          [y1, y2] if x1 <= x2 else [y2, y1])
        beyond = values[inside] > limit if upper else values[inside] < limit
        failed += list(zip(x[inside][beyond], values[inside][beyond], strict=True))
    return failed


def _math(t: CommandTree, a: Host) -> None:
    """Math constants, expressions and data (the result is not computed: state only)."""
    store = a.store
    store.define("calc.math.cons", Spec("string", "0,0", scope=("trace", "item:5"), keep=True))
    store.define("calc.math.expr", Spec("string", "", scope=("trace", "item:5"), keep=True))

    def set_constant(call: Call) -> None:
        if not 1 <= len(call.params) <= 2:
            raise ScpiError(-109 if not call.params else -108)
        values = [parse_number(p) for p in call.params] + [0.0]
        index = store.check_call("calc.math.cons", call)
        store.set("calc.math.cons", f"{values[0]!r},{values[1]!r}", index)

    def constant(call: Call) -> str:
        index = store.check_call("calc.math.cons", call)
        re_, im = (float(v) for v in str(store.get("calc.math.cons", index)).split(","))
        return f"{format_real(re_)},{format_real(im)}"

    def set_expression(call: Call) -> None:
        expression = ",".join(call.params).strip()
        if not (expression.startswith("(") and expression.endswith(")")):
            raise ScpiError(-104, "the expression must be in parentheses")
        index = store.check_call("calc.math.expr", call)
        store.set("calc.math.expr", expression, index)

    def expression(call: Call) -> str:
        index = store.check_call("calc.math.expr", call)
        return format_string(str(store.get("calc.math.expr", index)))

    t.add("CALCulate#:MATH:CONStant#", setter=set_constant, query=constant)
    t.add("CALCulate#:MATH[:EXPRession#]", setter=set_expression, query=expression)
    store.define("calc.math.data", Spec("string", "", scope=("trace",), keep=True))

    def set_data(call: Call) -> None:
        store.set("calc.math.data", block_payload(one(call)).decode("latin-1"), (_trace(call),))

    def math_data(call: Call) -> bytes:
        return definite_block(str(store.get("calc.math.data", (_trace(call),))).encode(
            "latin-1"))

    t.add("CALCulate#:MATH:DATA", setter=set_data, query=math_data)
