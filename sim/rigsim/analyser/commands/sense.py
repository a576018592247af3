"""``INSTrument`` (chapter 13), ``[SENSe:]`` (18), ``ARM`` (5) and ``TRIGger`` (24).

The mode and the frequency settings of the swept sine and the FFT have their own handlers (they
round and couple: start, stop, centre, span, resolution, record length); the rest are declared
settings. Each instrument mode keeps its own frequency, sweep, averaging and trace settings.
"""

from __future__ import annotations

from collections.abc import Callable

from rigsim.analyser.commands.table import (
    action,
    boolean,
    choice,
    declare,
    integer,
    pair,
    real,
)
from rigsim.analyser.frequency import (
    RESOLUTION_UNITS,
    allowed_span,
    point_count,
    round_down,
    round_up,
)
from rigsim.analyser.host import Host
from rigsim.analyser.limits import (
    FFT_LINES,
    FREQUENCY_STEP_HZ,
    MAX_POINTS,
    MIN_POINTS,
    fft_lines,
    fft_max_span_hz,
    sine_max_frequency_hz,
    sine_min_frequency_hz,
)
from rigsim.analyser.settings import MODE_CONFLICT, Spec, check_option, one
from rigsim.scpi import (
    OUT_OF_RANGE,
    Call,
    CommandTree,
    Quantity,
    ScpiError,
    format_int,
    format_real,
    format_string,
    parse_quantity,
)

__all__ = ["MODES", "register"]

#: ``INST:NSEL`` numbers (chapter 13).
MODES = ("FFT", "OCT", "ORD", "SINE", "HIST", "CORR")
MODE_OPTIONS = {"OCT": "1D1", "ORD": "1D0", "SINE": "1D2"}
SINE_ONLY = frozenset({"SINE"})
FFT_LIKE = frozenset({"FFT", "OCT", "ORD", "HIST", "CORR"})
NO_TRIGGER = "No TRIGGER With SWEPT SINE Instrument Mode."
NO_WINDOW = "No WINDOW With SWEPT SINE Instrument Mode."
_FREQUENCY_UNITS = ("HZ", "CPM")
#: Highest FFT zoom frequency with 1, 2 and 4 inputs (chapter 18, FREQ:STOP and FREQ:CENT).
_FFT_TOP = {1: 115000.0, 2: 57500.0, 4: 28750.0}


def _mode_preset(values: dict[str, object], default: object) -> Callable:
    return lambda mode, index: values.get(mode, default)


def _hz(q: Quantity) -> float:
    return q.value / 60.0 if q.unit == "CPM" else q.value


class Frequencies:
    """Start, stop, centre, span and resolution of the mode in use, with their couplings."""

    def __init__(self, a: Host) -> None:
        self.a = a
        self.store = a.store

    # ---------------------------------------------------------------- state

    @property
    def sine(self) -> bool:
        return self.a.mode == "SINE"

    def band(self) -> tuple[float, float]:
        return float(self.store.get("freq.start")), float(self.store.get("freq.stop"))

    def set_band(self, start: float, stop: float) -> None:
        self.store.set("freq.start", start)
        self.store.set("freq.stop", stop)
        self.coerce_resolution()
        self.a.settings_changed("frequency")

    def limits(self) -> tuple[float, float]:
        """Lowest start and highest stop of the mode with the inputs in use."""
        count = self.a.inputs.count()
        if self.sine:
            return sine_min_frequency_hz(count), sine_max_frequency_hz(count)
        return 0.0, _FFT_TOP[count]

    def max_span(self) -> float:
        count = self.a.inputs.count()
        if self.sine:
            lo, hi = self.limits()
            return hi - lo
        return fft_max_span_hz(count)

    def coerce_resolution(self) -> None:
        """A swept-sine resolution in Hz that would give more than 801 points grows."""
        if not self.sine:
            return
        value, unit = self.store.get("freq.res")
        start, stop = self.band()
        if unit == "HZ" and point_count(start, stop, "LIN", value, unit) > MAX_POINTS:
            self.store.set("freq.res", (round_up((stop - start) / (MAX_POINTS - 1)), "HZ"))

    def clamp(self) -> None:
        """After a change of inputs: keep the band within the new limits."""
        lo, hi = self.limits()
        start, stop = self.band()
        if self.sine:
            stop = min(stop, hi)
            start = min(max(start, lo), stop - FREQUENCY_STEP_HZ)
        else:
            span = allowed_span(min(stop - start, self.max_span()), self.max_span())
            start = min(start, max(0.0, hi - span))
            stop = start + span
        self.store.set("freq.start", start)
        self.store.set("freq.stop", stop)
        self.coerce_resolution()

    # ---------------------------------------------------------------- parsing

    def quantity(self, call: Call, current: float, lo: float, hi: float,
                 step: float | None = None) -> float:
        q = parse_quantity(one(call), _FREQUENCY_UNITS)
        if q.keyword == "MAX":
            return hi
        if q.keyword == "MIN":
            return lo
        if q.keyword in ("UP", "DOWN"):
            increment = float(self.store.get("freq.step")) if step is None else step
            return min(hi, max(lo, current + (increment if q.keyword == "UP" else -increment)))
        if q.keyword == "DEF":
            raise ScpiError(-224, "DEF")
        value = _hz(q)
        if not lo - 1e-9 <= value <= hi + 1e-9:
            raise ScpiError(-222, OUT_OF_RANGE)
        return value

    # ---------------------------------------------------------------- the commands

    def set_start(self, call: Call) -> None:
        start, stop = self.band()
        span = stop - start
        lo, hi = self.limits()
        if self.sine:
            value = round_down(self.quantity(call, start, lo, hi - FREQUENCY_STEP_HZ))
            if value >= stop:
                stop = min(hi, round_up(value + span))
            self.set_band(value, stop)
            return
        value = self.quantity(call, start, 0.0, hi - span)
        self.set_band(value, value + span)

    def set_stop(self, call: Call) -> None:
        start, stop = self.band()
        lo, hi = self.limits()
        if self.sine:
            value = round_up(self.quantity(call, stop, lo + FREQUENCY_STEP_HZ, hi))
            if value <= start:
                start = max(lo, round_down(value - (stop - start)))
            self.set_band(start, value)
            return
        value = self.quantity(call, stop, start + 1e-9, hi)
        span = allowed_span(value - start, self.max_span())
        if start + span > hi + 1e-9:
            raise ScpiError(-222, OUT_OF_RANGE)
        self.set_band(start, start + span)

    def set_center(self, call: Call) -> None:
        start, stop = self.band()
        half = (stop - start) / 2.0
        lo, hi = self.limits()
        if self.sine:
            value = round_down(self.quantity(call, start + half, lo, hi - FREQUENCY_STEP_HZ))
            new_start = max(lo, round_down(value - half))
            new_stop = min(hi, round_up(value + half))
            self.set_band(new_start, max(new_stop, new_start + FREQUENCY_STEP_HZ))
            return
        value = self.quantity(call, start + half, 0.0, hi)
        # the span shrinks to the widest allowed one that fits around the centre (inferred)
        span = 2 * half
        room = 2 * min(hi - value, value) if value > 0 else span
        if span > room:
            span = allowed_span(room, self.max_span())
            while span > room * (1 + 1e-12) and span > FREQUENCY_STEP_HZ:
                span /= 2.0
        new_start = max(0.0, value - span / 2)
        self.set_band(new_start, new_start + span)

    def set_span(self, call: Call) -> None:
        start, stop = self.band()
        lo, hi = self.limits()
        current = stop - start
        link = self.store.get("freq.span.link")
        q = parse_quantity(one(call), _FREQUENCY_UNITS)
        maximum = self.max_span()
        if q.keyword in ("UP", "DOWN") and not self.sine:
            value = min(maximum, current * (2.0 if q.keyword == "UP" else 0.5))
        elif q.keyword is not None:
            value = self.quantity(call, current, FREQUENCY_STEP_HZ, maximum)
        else:
            value = _hz(q)
            if not FREQUENCY_STEP_HZ - 1e-12 <= value <= maximum * (1 + 1e-9):
                raise ScpiError(-222, OUT_OF_RANGE)
        if self.sine:
            value = round_up(value)
            new_start = start if link == "STAR" else round_down(start + current / 2 - value / 2)
            new_start = min(max(lo, new_start), hi - value)
            self.set_band(new_start, round_up(new_start + value))
            return
        value = allowed_span(value, maximum)
        new_start = start if link == "STAR" else max(0.0, start + current / 2 - value / 2)
        new_start = min(new_start, hi - value)
        self.set_band(max(0.0, new_start), max(0.0, new_start) + value)

    def set_full_span(self, call: Call) -> None:
        if self.sine:
            raise ScpiError(-221, MODE_CONFLICT)
        self.set_band(0.0, self.max_span())

    def span_query(self, call: Call) -> str:
        start, stop = self.band()
        return _frequency_answer(call, stop - start)

    def center_query(self, call: Call) -> str:
        start, stop = self.band()
        return _frequency_answer(call, (start + stop) / 2.0)

    # ---------------------------------------------------------------- resolution

    def set_resolution(self, call: Call) -> None:
        if not self.sine:
            self.store.set("freq.res", _fft_lines(call, int(self.store.get("freq.res")),
                                                  fft_lines(self.a.inputs.count())))
            self.a.settings_changed("resolution")
            return
        self.store.set("freq.res", self._sine_resolution(call, "freq.res"))

    def _sine_resolution(self, call: Call, name: str, limit_points: bool = True
                         ) -> tuple[float, str]:
        q = parse_quantity(one(call), RESOLUTION_UNITS)
        value, unit = self.store.get(name)
        spacing = str(self.store.get("swe.spac"))
        start, stop = self.band()
        if q.keyword is not None:
            if q.keyword not in ("MAX", "MIN"):
                raise ScpiError(-224, q.keyword)
            return (float(MAX_POINTS if q.keyword == "MAX" else MIN_POINTS), "PNT/SWP")
        unit = q.unit or "PNT/SWP"
        allowed = ("HZ", "PNT/SWP", "PCT") if spacing == "LIN" else (
            "PNT/SWP", "PNT/DEC", "PNT/OCT", "PCT")
        if unit not in allowed:
            raise ScpiError(-131, f"{unit} with SWE:SPAC {spacing}")
        value = q.value
        if unit == "HZ":
            value = round_up(value)
        if value <= 0:
            raise ScpiError(-222, OUT_OF_RANGE)
        count = point_count(start, stop, spacing, value, unit)
        if unit == "PNT/SWP" and not MIN_POINTS <= round(value) <= MAX_POINTS:
            raise ScpiError(-222, OUT_OF_RANGE)
        if limit_points and count > MAX_POINTS:
            raise ScpiError(-222, OUT_OF_RANGE)
        return (float(round(value)) if unit == "PNT/SWP" else value, unit)

    def resolution_query(self, call: Call) -> str:
        value = self.store.get("freq.res")
        if not self.sine:
            if call.params:
                return _unit_answer(call, "")
            return format_real(float(value))
        return _pair_answer(call, value)

    def set_auto_minimum(self, call: Call) -> None:
        # a minimum step: the sweep stops at 801 points however fine it is
        self.store.set("freq.res.auto.min",
                       self._sine_resolution(call, "freq.res.auto.min", limit_points=False))

    def set_manual(self, call: Call) -> None:
        start, stop = self.band()
        current = float(self.store.get("freq.man"))
        value = round_down(self.quantity(call, current, FREQUENCY_STEP_HZ, 51200.0))
        if not start - 1e-9 <= value <= stop + 1e-9:
            raise ScpiError(-222, OUT_OF_RANGE)
        self.store.set("freq.man", value)

    def set_blocksize(self, call: Call) -> None:
        q = parse_quantity(one(call))
        lines = int(self.store.get("freq.res"))
        if q.keyword is not None:
            block = {"MAX": 2048.0, "MIN": 256.0, "UP": lines * 5.12, "DOWN": lines * 1.28}.get(
                q.keyword)
            if block is None:
                raise ScpiError(-224, q.keyword)
        else:
            block = q.value
        if not 256 - 1e-9 <= block <= 2048 + 1e-9:
            raise ScpiError(-222, OUT_OF_RANGE)
        fitting = [n for n in FFT_LINES if n * 2.56 >= block - 1e-9]
        self.store.set("freq.res", fitting[0])
        self.a.settings_changed("resolution")

    def set_record_length(self, call: Call) -> None:
        start, stop = self.band()
        lines = int(self.store.get("freq.res"))
        q = parse_quantity(one(call), ("S",))
        record = lines / (stop - start)
        if q.keyword in ("UP", "DOWN"):
            value = record * (2.0 if q.keyword == "UP" else 0.5)
        elif q.keyword in ("MAX", "MIN"):
            value = 8192.0 if q.keyword == "MAX" else 976.5625e-6
        elif q.keyword is not None:
            raise ScpiError(-224, q.keyword)
        else:
            value = q.value
        if not 976.5625e-6 - 1e-12 <= value <= 8192.0:
            raise ScpiError(-222, OUT_OF_RANGE)
        span = allowed_span(lines / value, self.max_span())
        if self.store.get("freq.span.link") == "CENT":
            start = max(0.0, (start + stop) / 2 - span / 2)
        self.set_band(start, start + span)

    def record_length_query(self, call: Call) -> str:
        start, stop = self.band()
        if call.params:
            return _unit_answer(call, "S")
        return format_real(int(self.store.get("freq.res")) / (stop - start))


def _fft_lines(call: Call, current: int, allowed: tuple[int, ...]) -> int:
    q = parse_quantity(one(call))
    index = allowed.index(current) if current in allowed else 2
    if q.keyword == "MAX":
        return allowed[-1]
    if q.keyword == "MIN":
        return allowed[0]
    if q.keyword == "UP":
        return allowed[min(index + 1, len(allowed) - 1)]
    if q.keyword == "DOWN":
        return allowed[max(index - 1, 0)]
    if q.keyword is not None:
        raise ScpiError(-224, q.keyword)
    fitting = [n for n in allowed if n >= q.value - 1e-9]
    if not fitting or q.value <= 0:
        raise ScpiError(-222, OUT_OF_RANGE)
    return fitting[0]


def _unit_answer(call: Call, unit: str) -> str:
    if len(call.params) == 1 and call.params[0].strip().upper() == "UNIT":
        return format_string(unit)
    raise ScpiError(-108, call.params[0][:40])


def _frequency_answer(call: Call, value: float) -> str:
    return _unit_answer(call, "HZ") if call.params else format_real(value)


def _pair_answer(call: Call, value: tuple[float, str]) -> str:
    return _unit_answer(call, value[1]) if call.params else format_real(float(value[0]))


#: The unit of a bare number sent to ``SWE:DWEL`` and ``SWE:STIM``: seconds. The programming
#: guide lists ``[S|CYCLE]`` with no word on a number without a unit; S is inferred (the first
#: unit listed, as ``VOLT:RANG``'s documented default ``DBVRMS`` is, and SCPI's own unit of
#: ``SWEep:DWELl``, a command the guide marks "SCPI compliance: confirmed").
TIMING_DEFAULT_UNIT = "S"


def _timing_setter(a: Host, name: str, limits: dict[str, tuple[float, float]],
                   floor_cycle: bool) -> Callable[[Call], None]:
    """``SWE:DWEL`` / ``SWE:STIM``: a time in seconds or cycles with per-unit limits.

    A number without a unit is in seconds (:data:`TIMING_DEFAULT_UNIT`, see
    docs/virtual-analyser.md), whatever unit was in use; a step or bound keeps the unit in use.
    """

    def setter(call: Call) -> None:
        _check_mode(a, SINE_ONLY, MODE_CONFLICT, "1D2")
        q = parse_quantity(one(call), ("S", "CYCLE"))
        value, unit = a.store.get(name)
        if q.unit:
            new_unit = q.unit
        elif q.keyword is None:
            new_unit = TIMING_DEFAULT_UNIT
        else:
            new_unit = unit
        lo, hi = limits[new_unit]
        if q.keyword in ("MAX", "MIN"):
            new = hi if q.keyword == "MAX" else lo
        elif q.keyword in ("UP", "DOWN"):
            new = min(hi, max(lo, value * (2.0 if q.keyword == "UP" else 0.5)))
        elif q.keyword is not None:
            raise ScpiError(-224, q.keyword)
        else:
            new = q.value
            if floor_cycle and new_unit == "CYCLE" and 0 <= new < 1:
                new = 1.0  # the analyser takes less than one cycle as one
            if not lo - 1e-12 <= new <= hi * (1 + 1e-12):
                raise ScpiError(-222, OUT_OF_RANGE)
        a.store.set(name, (new, new_unit))

    return setter


def _check_mode(a: Host, modes: frozenset[str], conflict: str, option: str | None = None) -> None:
    check_option(option, a.options)
    if a.mode not in modes:
        raise ScpiError(-221, conflict)


def _guarded(a: Host, handler: Callable[[Call], object], modes: frozenset[str] | None = None,
             conflict: str = MODE_CONFLICT, option: str | None = None) -> Callable[[Call], object]:
    def run(call: Call) -> object:
        _check_mode(a, modes or frozenset(MODES), conflict, option)
        return handler(call)

    return run


def register(tree: CommandTree, a: Host) -> None:
    """Register the mode, ``SENSe``, ``ARM`` and ``TRIGger`` commands."""
    freq = Frequencies(a)
    for part in (_register_mode, _register_frequency, _register_sweep, _register_window,
                 _register_trigger):
        part(tree, a, freq)


def _register_mode(t: CommandTree, a: Host, freq: Frequencies) -> None:
    """The instrument mode: ``INSTrument[:SELect]`` and ``INSTrument:NSELect``."""
    store = a.store
    store.define("mode", Spec("choice", "FFT", choices=MODES))

    def select(mode: str) -> None:
        check_option(MODE_OPTIONS.get(mode), a.options)
        if mode != a.mode:
            a.abort()
            store.set("mode", mode)
            freq.clamp()
            a.settings_changed("mode")

    def select_word(call: Call) -> None:
        word = one(call).strip().upper()
        names = {"FFT": "FFT", "OCT": "OCT", "OCTAVE": "OCT", "ORD": "ORD", "ORDER": "ORD",
                 "SINE": "SINE", "HIST": "HIST", "HISTOGRAM": "HIST", "CORR": "CORR",
                 "CORRELATION": "CORR"}
        if word not in names:
            raise ScpiError(-141, f"{word[:20]} is not one of FFT|OCT|ORD|SINE|HIST|CORR")
        select(names[word])

    def select_number(call: Call) -> None:
        q = parse_quantity(one(call))
        if q.keyword is not None or q.value != round(q.value):
            raise ScpiError(-224, one(call)[:20])
        if not 0 <= q.value <= 5:
            raise ScpiError(-222, OUT_OF_RANGE)
        select(MODES[int(q.value)])

    t.add("INSTrument[:SELect]", setter=select_word, query=lambda c: a.mode)
    t.add("INSTrument:NSELect", setter=select_number,
          query=lambda c: format_int(MODES.index(a.mode)))


def _register_frequency(t: CommandTree, a: Host, freq: Frequencies) -> None:
    """``[SENSe:]FREQuency``: band, resolution, manual frequency, block size."""
    store = a.store
    store.define("freq.start", Spec("real", _mode_preset({"SINE": 51.2}, 0.0), scope=("mode",)))
    store.define("freq.stop", Spec("real", _mode_preset({"SINE": 51200.0}, 51200.0),
                                   scope=("mode",)))
    store.define("freq.res", Spec("pair", _mode_preset({"SINE": (101.0, "PNT/SWP")}, 400),
                                  scope=("mode",)))
    store.define("freq.res.auto.min", Spec("pair", (401.0, "PNT/SWP"), scope=("mode",)))
    store.define("freq.man", Spec("real", 51.2, scope=("mode",)))
    sweep_modes = frozenset({"FFT", "SINE", "CORR"})
    t.add("[SENSe:]FREQuency:STARt", setter=_guarded(a, freq.set_start, sweep_modes),
          query=lambda c: _frequency_answer(c, freq.band()[0]))
    t.add("[SENSe:]FREQuency:STOP", setter=_guarded(a, freq.set_stop, sweep_modes),
          query=lambda c: _frequency_answer(c, freq.band()[1]))
    t.add("[SENSe:]FREQuency:CENTer", setter=_guarded(a, freq.set_center, sweep_modes),
          query=freq.center_query)
    t.add("[SENSe:]FREQuency:SPAN", setter=_guarded(a, freq.set_span, sweep_modes),
          query=freq.span_query)
    t.add("[SENSe:]FREQuency:SPAN:FULL", setter=freq.set_full_span)
    t.add("[SENSe:]FREQuency:RESolution", setter=_guarded(a, freq.set_resolution, sweep_modes),
          query=freq.resolution_query)
    t.add("[SENSe:]FREQuency:RESolution:AUTO:MINimum",
          setter=_guarded(a, freq.set_auto_minimum, SINE_ONLY, option="1D2"),
          query=_guarded(a, lambda c: _pair_answer(c, store.get("freq.res.auto.min")),
                         SINE_ONLY, option="1D2"))
    t.add("[SENSe:]FREQuency:MANual", setter=_guarded(a, freq.set_manual, SINE_ONLY,
                                                      option="1D2"),
          query=_guarded(a, lambda c: _frequency_answer(c, float(store.get("freq.man"))),
                         SINE_ONLY, option="1D2"))
    t.add("[SENSe:]FREQuency:BLOCksize",
          setter=_guarded(a, freq.set_blocksize, frozenset({"FFT", "CORR"})),
          query=_guarded(a, lambda c: format_real(int(store.get("freq.res")) * 2.56),
                         frozenset({"FFT", "CORR"})))
    declare(t, store, [
        ("[SENSe:]FREQuency:RESolution:AUTO", "freq.res.auto",
         boolean(False, rst=True, scope=("mode",), modes=SINE_ONLY, option="1D2")),
        ("[SENSe:]FREQuency:RESolution:AUTO:MCHange", "freq.res.auto.mch",
         real(2.0, 0.00391, 100.0, ("PCT",), scope=("mode",), modes=SINE_ONLY, option="1D2")),
        ("[SENSe:]FREQuency:STEP[:INCRement]", "freq.step",
         real(2000.0, 0.015625, 102400.0, _FREQUENCY_UNITS, scope=("mode",))),
        ("[SENSe:]FREQuency:SPAN:LINK", "freq.span.link",
         choice("STAR", "STARt", "CENTer", rst="CENT", scope=("mode",))),
        ("[SENSe:]FREQuency:RESolution:OCTave", "freq.res.oct",
         choice("THIR", "FULL", "THIRd", "TWELfth", modes=frozenset({"OCT"}), option="1D1")),
    ])


def _register_sweep(t: CommandTree, a: Host, freq: Frequencies) -> None:
    """``[SENSe:]SWEep`` (dwell, settle, overlap), ``AVERage``, and the other ``SENSe`` settings."""
    store = a.store
    store.define("swe.dwel", Spec("pair", (5.0, "CYCLE"), scope=("mode",)))
    store.define("swe.stim", Spec("pair", (5.0, "CYCLE"), scope=("mode",)))
    t.add("[SENSe:]SWEep:DWELl",
          setter=_timing_setter(a, "swe.dwel", {"S": (250e-6, 32768.0), "CYCLE": (1.0, 234.0)},
                                True),
          query=_guarded(a, lambda c: _pair_answer(c, store.get("swe.dwel")), SINE_ONLY,
                         option="1D2"))
    t.add("[SENSe:]SWEep:STIMe",
          setter=_timing_setter(a, "swe.stim", {"S": (0.0, 9.9e37), "CYCLE": (0.0, 9.9e37)},
                                False),
          query=_guarded(a, lambda c: _pair_answer(c, store.get("swe.stim")), SINE_ONLY,
                         option="1D2"))
    t.add("[SENSe:]SWEep:TIME",
          setter=_guarded(a, freq.set_record_length, frozenset({"FFT", "CORR"})),
          query=_guarded(a, freq.record_length_query, frozenset({"FFT", "CORR"})))
    store.define("swe.over", Spec("int", 0, scope=("mode",)))

    def set_overlap(call: Call) -> None:
        _check_mode(a, frozenset({"FFT", "CORR"}), MODE_CONFLICT)
        q = parse_quantity(one(call), ("PCT",))
        current = int(store.get("swe.over"))
        if q.keyword is not None:
            value = {"MAX": 99, "MIN": 0, "UP": current + 1, "DOWN": current - 1}.get(q.keyword)
            if value is None:
                raise ScpiError(-224, q.keyword)
        else:
            value = q.value * 100.0 if q.unit == "" and 0 < q.value < 1 else q.value
        if not 0 <= round(value) <= 99:
            raise ScpiError(-222, OUT_OF_RANGE)
        store.set("swe.over", round(value))

    t.add("[SENSe:]SWEep:OVERlap", setter=set_overlap,
          query=_guarded(a, lambda c: format_int(int(store.get("swe.over"))),
                         frozenset({"FFT", "CORR"})))
    sine = {"modes": SINE_ONLY, "option": "1D2", "scope": ("mode",)}
    fft = {"modes": frozenset({"FFT", "ORD", "CORR"}), "scope": ("mode",)}
    declare(t, store, [
        ("[SENSe:]SWEep:DIRection", "swe.dir", choice("UP", "UP", "DOWN", **sine)),
        ("[SENSe:]SWEep:MODE", "swe.mode", choice("AUTO", "AUTO", "MANual", **sine)),
        ("[SENSe:]SWEep:SPACing", "swe.spac", choice("LIN", "LINear", "LOGarithmic", **sine)),
        # ---------------------------------------------------------- AVERage
        ("[SENSe:]AVERage:COUNt", "aver.count", integer(10, 1, 9999999, **fft)),
        ("[SENSe:]AVERage[:STATe]", "aver.state", boolean(False, **fft)),
        ("[SENSe:]AVERage:TYPE", "aver.type",
         choice("RMS", "MAXimum", "RMS", "TIME", "VECTor", "ECONomy", **fft)),
        ("[SENSe:]AVERage:TCONtrol", "aver.tcon",
         choice("EXP", "FREeze", "REPeat", "EXPonential", **fft)),
        ("[SENSe:]AVERage:IRESult[:STATe]", "aver.ires", boolean(False, scope=("mode",))),
        ("[SENSe:]AVERage:IRESult:RATE", "aver.ires.rate",
         integer(5, 1, 9999999, scope=("mode",))),
        ("[SENSe:]AVERage:PREView", "aver.prev",
         choice("OFF", "OFF", "MANual", "TIMed", modes=frozenset({"FFT"}))),
        ("[SENSe:]AVERage:PREView:TIME", "aver.prev.time",
         real(10.0, 0.1, 3600.0, ("S",), modes=frozenset({"FFT"}))),
        ("[SENSe:]AVERage:CONFidence", "aver.conf",
         real(0.25, 0.0, 3.0, ("DB",), modes=frozenset({"OCT"}), option="1D1")),
        ("[SENSe:]AVERage:HOLD", "aver.hold",
         choice("OFF", "OFF", "MAXimum", "MINimum", modes=frozenset({"OCT"}), option="1D1")),
        ("[SENSe:]AVERage:IMPulse", "aver.imp",
         boolean(False, modes=frozenset({"OCT"}), option="1D1")),
        ("[SENSe:]AVERage:TIME", "aver.time",
         real(2.0, 0.0, 9.9e37, ("S",), modes=frozenset({"OCT", "HIST"}))),
        # ---------------------------------------------------------- WINDow, REFerence, ...
        ("[SENSe:]WINDow#:EXPonential", "wind.exp",
         real(9.999e3, 3.8147e-6, 9.9999e6, ("S",), modes=FFT_LIKE, conflict=NO_WINDOW,
              scope=("item:4",))),
        ("[SENSe:]WINDow#:FORCe", "wind.forc",
         real(9.999e3, 3.8147e-6, 9.9999e6, ("S",), modes=FFT_LIKE, conflict=NO_WINDOW,
              scope=("item:4",))),
        ("[SENSe:]WINDow#:ORDer:DC", "wind.ord.dc",
         boolean(True, option="1D0", scope=("item:4",))),
        ("[SENSe:]REFerence", "ref", choice("SING", "SINGle", "PAIR", option="AY6")),
        ("[SENSe:]REJect:STATe", "rej.state", boolean(False, modes=frozenset({"FFT", "CORR"}))),
        ("[SENSe:]FEED", "sens.feed", choice("INP", "INPut", "TCAPture")),
        ("[SENSe:]HISTogram:BINS", "hist.bins",
         integer(64, 4, 1024, modes=frozenset({"HIST"}))),
        ("[SENSe:]ORDer:MAXimum", "ord.max", real(10.0, 0.5, 400.0, option="1D0")),
        ("[SENSe:]ORDer:RESolution", "ord.res", real(0.25, 0.0625, 1.0, option="1D0")),
        ("[SENSe:]ORDer:RESolution:TRACk", "ord.res.trac", real(100.0, 1, 1e4, option="1D0")),
        ("[SENSe:]ORDer:RPM:MAXimum", "ord.rpm.max", real(6000.0, 1.0, 1e6, option="1D0")),
        ("[SENSe:]ORDer:RPM:MINimum", "ord.rpm.min", real(600.0, 1.0, 1e6, option="1D0")),
        ("[SENSe:]ORDer:TRACk#", "ord.trac",
         real(1.0, 0.0, 400.0, option="1D0", scope=("item:5",))),
        ("[SENSe:]ORDer:TRACk#:STATe", "ord.trac.stat",
         boolean(False, option="1D0", scope=("item:5",))),
    ])


def _register_window(t: CommandTree, a: Host, freq: Frequencies) -> None:
    """``[SENSe:]WINDow`` types and the average preview actions."""
    store = a.store
    # WIND without a suffix sets every input, as the front panel's choice does; WINDn sets
    # input n (the force/exponential pair: WIND1 FORC;WIND2 EXP...) (inferred)
    store.define("wind.type", choice("FLAT", "HANNing", "FLATtop", "UNIForm", "FORCe",
                                     "EXPonential", scope=("channel",), modes=FFT_LIKE,
                                     conflict=NO_WINDOW))

    def set_window(call: Call) -> None:
        index = store.check_call("wind.type", call)
        value = store.parse("wind.type", call, index)
        for number in (range(1, 5) if call.suffix is None else (index[0],)):
            store.set("wind.type", value, (number,))

    t.add("[SENSe:]WINDow#[:TYPE]", setter=set_window,
          query=lambda c: store.answer("wind.type", c, store.check_call("wind.type", c)))
    action(t, "[SENSe:]AVERage:PREView:ACCept")
    action(t, "[SENSe:]AVERage:PREView:REJect")
    # removes the time capture buffer (chapter 18); this model keeps none, so there is
    # nothing to remove, and the manual names no error for an empty buffer
    action(t, "[SENSe:]TCAPture:DELete")


def _register_trigger(t: CommandTree, a: Host, freq: Frequencies) -> None:
    """``ARM`` and ``TRIGger``: accepted where the mode has them, never waiting in this model."""
    store = a.store
    not_sine = frozenset({"FFT", "OCT", "ORD", "HIST", "CORR"})
    trig = {"modes": not_sine, "conflict": NO_TRIGGER}
    declare(t, store, [
        ("ARM:RPM:INCRement", "arm.rpm.incr", real(60.0, 1.0, 500000.0, ("RPM",), **trig)),
        ("ARM:RPM:MODE", "arm.rpm.mode", choice("UP", "OFF", "UP", "DOWN",
                                                 aliases={"0": "OFF"}, **trig)),
        ("ARM:RPM:THReshold", "arm.rpm.thr", real(600.0, 5.0, 491520.0, ("RPM",), **trig)),
        ("ARM:SOURce", "arm.sour", choice("IMM", "IMMediate", "MANual", "RPM", "TIMer", **trig)),
        ("ARM:TIMer", "arm.tim", real(0.5, 0.0, 500000.0, ("S",), **trig)),
        ("TRIGger:EXTernal:FILTer[:LPASs][:STATe]", "trig.ext.filt", boolean(False, **trig)),
        ("TRIGger:EXTernal:LEVel", "trig.ext.lev", real(0.0, -10.0, 10.0, ("V",), **trig)),
        ("TRIGger:EXTernal:RANGe", "trig.ext.rang", choice("HIGH", "HIGH", "LOW", **trig)),
        ("TRIGger:LEVel", "trig.lev", pair((0.0, "V"), ("PCT", "V", "VPK", "EU"), **trig)),
        ("TRIGger:SLOPe", "trig.slop", choice("POS", "POSitive", "NEGative", **trig)),
        ("TRIGger:SOURce", "trig.sour",
         choice("IMM", "IMMediate", "EXTernal", "INTernal1", "INTernal2", "INTernal3",
                "INTernal4", "OUTPut", "BUS", **trig)),
        ("TRIGger:STARt#", "trig.star", real(0.0, -9.9e37, 9.9e37, ("S", "PNT"),
                                             scope=("item:4",), modes=frozenset({"FFT", "CORR",
                                                                                  "HIST"}),
                                             conflict=NO_TRIGGER)),
        ("TRIGger:TACHometer:HOLDoff", "trig.tach.hold",
         real(0.0, 0.0, 0.052224, ("S",), **trig)),
        ("TRIGger:TACHometer:LEVel", "trig.tach.lev", real(0.0, -20.0, 20.0, ("V",), **trig)),
        ("TRIGger:TACHometer:PCOunt", "trig.tach.pco", real(1.0, 0.5, 2048.0, **trig)),
        ("TRIGger:TACHometer:RANGe", "trig.tach.rang", choice("LOW", "HIGH", "LOW", **trig)),
        ("TRIGger:TACHometer:SLOPe", "trig.tach.slop",
         choice("POS", "POSitive", "NEGative", **trig)),
    ])
    t.add("TRIGger:TACHometer[:RPM]",
          query=_guarded(a, lambda c: format_real(0.0), not_sine, NO_TRIGGER))

    def trigger(call: Call) -> None:
        _check_mode(a, not_sine, NO_TRIGGER)
        if len(call.params):
            raise ScpiError(-108)
        raise ScpiError(-211, "Trigger received when not waiting for trigger.")

    def arm(call: Call) -> None:
        _check_mode(a, not_sine, NO_TRIGGER)
        if len(call.params):
            raise ScpiError(-108)
        raise ScpiError(-212, "Arm received when not waiting for arm.")

    t.add("TRIGger[:IMMediate]", setter=trigger)
    t.add("ARM[:IMMediate]", setter=arm)
