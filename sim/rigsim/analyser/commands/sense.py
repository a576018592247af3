"""``INSTrument`` and ``SENSe``: the mode, the frequency span and grid, the sweep and its timing.

Settings are kept per mode (:class:`rigsim.analyser.state.ModeSettings`). Swept-sine-only
settings answer -221 in FFT mode and FFT-only ones in swept sine.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence

from rigsim.analyser.limits import (
    FREQUENCY_STEP_HZ,
    MAX_CYCLES,
    MAX_POINTS,
    MIN_DWELL_S,
    MIN_POINTS,
)
from rigsim.analyser.params import (
    Params,
    bool_setter,
    integer,
    limited,
    one,
    quantity_query,
)
from rigsim.analyser.worker import SweepWorker
from rigsim.scpi import (
    CommandTree,
    ScpiError,
    format_bool,
    format_int,
    parse_choice,
    parse_quantity,
)

__all__ = ["SenseCommands"]

MODES_BY_NUMBER = {1: "FFT", 2: "OCT", 3: "SINE", 4: "ORD", 5: "HIST"}  # (inferred, but 3=SINE)
#: The option each mode needs (``None``: standard).
MODE_OPTION = {"FFT": None, "SINE": "1D2", "OCT": "1D1", "ORD": "1D0", "HIST": None}


def round_frequency(value_hz: float) -> float:
    """A frequency on the swept sine's 15.625 mHz grid."""
    return round(value_hz / FREQUENCY_STEP_HZ) * FREQUENCY_STEP_HZ


class SenseCommands(SweepWorker):
    """Handlers of ``INSTrument`` and ``SENSe`` (a base of the analyser)."""

    def _register_mode_commands(self, t: CommandTree) -> None:
        t.add("INSTrument[:SELect]", setter=self._inst_select, query=lambda p, s: self.mode)
        t.add("INSTrument:NSELect", setter=self._inst_nselect,
              query=lambda p, s: format_int({v: k for k, v in MODES_BY_NUMBER.items()}[self.mode]))

    def _register_sense_commands(self, t: CommandTree) -> None:
        t.add("[SENSe:]FREQuency:STARt", setter=self._freq_setter("start_hz"),
              query=self._hz_query(lambda: self.settings.start_hz))
        t.add("[SENSe:]FREQuency:STOP", setter=self._freq_setter("stop_hz"),
              query=self._hz_query(lambda: self.settings.stop_hz))
        t.add("[SENSe:]FREQuency:CENTer", setter=self._center, query=self._hz_query(
            lambda: (self.settings.start_hz + self.settings.stop_hz) / 2))
        t.add("[SENSe:]FREQuency:SPAN", setter=self._span, query=self._hz_query(
            lambda: abs(self.settings.stop_hz - self.settings.start_hz)))
        t.add("[SENSe:]FREQuency:SPAN:FULL", setter=self._span_full)
        t.add("[SENSe:]FREQuency:MANual", setter=self._manual, query=self._hz_query(
            lambda: self.settings.manual_hz))
        t.add("[SENSe:]FREQuency:RESolution", setter=self._resolution,
              query=quantity_query(self._resolution_in_use))
        t.add("[SENSe:]FREQuency:RESolution:AUTO", setter=bool_setter(
            lambda v: setattr(self.settings, "resolution_auto", v)),
            query=lambda p, s: format_bool(self.settings.resolution_auto))
        t.add("[SENSe:]SWEep:SPACing", setter=self._choice_setter(
            "spacing", ("LINear", "LOGarithmic"), sine=True),
            query=lambda p, s: self.settings.spacing)
        t.add("[SENSe:]SWEep:DIRection", setter=self._choice_setter(
            "direction", ("UP", "DOWN"), sine=True), query=lambda p, s: self.settings.direction)
        t.add("[SENSe:]SWEep:MODE", setter=self._choice_setter(
            "sweep_mode", ("AUTO", "MANual"), sine=True),
            query=lambda p, s: self.settings.sweep_mode)
        t.add("[SENSe:]SWEep:STIMe", setter=self._cycles_setter("settle", minimum_cycles=0.0),
              query=quantity_query(lambda: self.settings.settle))
        t.add("[SENSe:]SWEep:DWELl", setter=self._cycles_setter("dwell", minimum_cycles=1.0),
              query=quantity_query(lambda: self.settings.dwell))
        t.add("[SENSe:]SWEep:TIME", setter=lambda p, s: self._forbid_in_sine("SWE:TIME"))
        t.add("[SENSe:]SWEep:OVERlap", setter=lambda p, s: self._forbid_in_sine("SWE:OVER"))
        t.add("[SENSe:]REFerence", setter=self._choice_setter(
            "reference", ("PAIR", "SINGle")), query=lambda p, s: self.settings.reference)
        t.add("[SENSe:]WINDow[:TYPE]", setter=self._fft_only("WIND", "window"),
              query=lambda p, s: self.settings.window)
        t.add("[SENSe:]AVERage:TYPE", setter=self._fft_only("AVER:TYPE", "average_type"),
              query=lambda p, s: self.settings.average_type)
        t.add("TRIGger[:SEQuence]:SOURce", setter=self._fft_only("TRIG:SOUR", "trigger_source"),
              query=lambda p, s: self.settings.trigger_source)

    # ---------------------------------------------------------------- mode

    def _select_mode(self, mode: str) -> None:
        option = MODE_OPTION.get(mode)
        if option is not None and option not in self.options:
            raise ScpiError(-241, f"{mode} needs option {option}")
        if mode not in ("FFT", "SINE"):
            raise ScpiError(-221, f"{mode} mode is not simulated")
        if mode != self.mode:
            self._abort()
            self.mode = mode

    def _inst_select(self, params: Params, suffix: int | None) -> None:
        choice = parse_choice(one(params), ("FFT", "OCTave", "ORDer", "SINE", "HISTogram"))
        self._select_mode(choice)

    def _inst_nselect(self, params: Params, suffix: int | None) -> None:
        number = integer(params, 1, len(MODES_BY_NUMBER))
        self._select_mode(MODES_BY_NUMBER[number])

    # ---------------------------------------------------------------- frequency

    @staticmethod
    def _hz_query(get: Callable[[], float]) -> Callable[..., str]:
        return quantity_query(lambda: (get(), "HZ"))

    def _lowest_frequency(self) -> float:
        return FREQUENCY_STEP_HZ if self.mode == "SINE" else 0.0

    def _frequency(self, params: Params, current: float) -> float:
        q = parse_quantity(one(params), ("HZ",), "HZ")
        value = limited(q, current, self._lowest_frequency(), self._max_frequency(), 1.0)
        return round_frequency(value)

    def _freq_setter(self, name: str) -> Callable[..., None]:
        def setter(params: Params, suffix: int | None) -> None:
            s = self.settings
            setattr(s, name, self._frequency(params, getattr(s, name)))
        return setter

    def _center(self, params: Params, suffix: int | None) -> None:
        s = self.settings
        half = abs(s.stop_hz - s.start_hz) / 2
        center = self._frequency(params, (s.start_hz + s.stop_hz) / 2)
        if center - half < self._lowest_frequency() or center + half > self._max_frequency():
            raise ScpiError(-222, "center with this span leaves the band; value not changed")
        s.start_hz, s.stop_hz = round_frequency(center - half), round_frequency(center + half)

    def _span(self, params: Params, suffix: int | None) -> None:
        s = self.settings
        center = (s.start_hz + s.stop_hz) / 2
        span = self._frequency(params, abs(s.stop_hz - s.start_hz))
        start = max(self._lowest_frequency(), center - span / 2)
        s.start_hz, s.stop_hz = round_frequency(start), round_frequency(min(
            start + span, self._max_frequency()))

    def _span_full(self, params: Params, suffix: int | None) -> None:
        self._forbid_in_sine("FREQ:SPAN:FULL")
        self.settings.start_hz, self.settings.stop_hz = 0.0, self._max_frequency()

    def _manual(self, params: Params, suffix: int | None) -> None:
        self._require_sine("FREQ:MAN")
        self.settings.manual_hz = self._frequency(params, self.settings.manual_hz)

    def _resolution(self, params: Params, suffix: int | None) -> None:
        s = self.settings
        q = parse_quantity(one(params), ("HZ", "PNT/SWP"), s.resolution_unit)
        if q.keyword is not None:
            value = limited(q, s.points, MIN_POINTS, MAX_POINTS, 1)
            s.points = int(value)
            return
        if q.unit == "HZ":
            if s.spacing == "LOG" and self.mode == "SINE":
                raise ScpiError(-221, "resolution in HZ needs linear spacing (use PNT/SWP)")
            if q.value <= 0:
                raise ScpiError(-222, "resolution must be positive; value not changed")
            points = round(abs(s.stop_hz - s.start_hz) / q.value) + 1
        else:
            points = round(q.value)
        if not MIN_POINTS <= points <= MAX_POINTS:
            raise ScpiError(-222, f"{points} points per sweep (2..{MAX_POINTS}); value not changed")
        s.points = points
        s.resolution_unit = q.unit

    def _resolution_in_use(self) -> tuple[float, str]:
        """The resolution in the unit last set: point spacing in HZ, or points per sweep."""
        s = self.settings
        if s.resolution_unit == "HZ":
            return abs(s.stop_hz - s.start_hz) / max(s.points - 1, 1), "HZ"
        return s.points, s.resolution_unit

    # ---------------------------------------------------------------- sweep

    def _choice_setter(self, name: str, choices: Sequence[str], sine: bool = False
                       ) -> Callable[..., None]:
        def setter(params: Params, suffix: int | None) -> None:
            if sine:
                self._require_sine(name)
            setattr(self.settings, name, parse_choice(one(params), choices))
        return setter

    def _fft_only(self, what: str, name: str) -> Callable[..., None]:
        def setter(params: Params, suffix: int | None) -> None:
            self._forbid_in_sine(what)
            setattr(self.settings, name, one(params).upper())
        return setter

    def _cycles_setter(self, name: str, minimum_cycles: float) -> Callable[..., None]:
        def setter(params: Params, suffix: int | None) -> None:
            self._require_sine(name)
            current_value, current_unit = getattr(self.settings, name)
            # a bare number keeps the unit in use (inferred)
            q = parse_quantity(one(params), ("S", "CYCLE"), current_unit)
            if q.unit == "CYCLE":
                value = limited(q, current_value, minimum_cycles, MAX_CYCLES, 1.0)
            else:
                lo = MIN_DWELL_S if minimum_cycles > 0 else 0.0
                value = limited(q, current_value, lo, 1.0e5, 0.1)
            setattr(self.settings, name, (value, q.unit))
        return setter
