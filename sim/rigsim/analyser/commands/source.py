"""``OUTPut`` and ``SOURce``: the source, its level and limit, and the auto-level controller."""

from __future__ import annotations

import re
from collections.abc import Callable

from rigsim.analyser.limits import MAX_SOURCE_VPK
from rigsim.analyser.params import Params, bool_setter, limited, one, quantity_query
from rigsim.analyser.worker import SweepWorker
from rigsim.scpi import CommandTree, ScpiError, format_bool, format_real, parse_quantity

__all__ = ["SourceCommands"]


class SourceCommands(SweepWorker):
    """Handlers of ``OUTPut`` and ``SOURce:VOLTage`` (a base of the analyser)."""

    def _register_source_commands(self, t: CommandTree) -> None:
        src = "SOURce:VOLTage[:LEVel]"
        t.add("OUTPut[:STATe]",
              setter=bool_setter(lambda v: setattr(self.source, "output", v)),
              query=lambda p, s: format_bool(self.source.output))
        t.add(f"{src}[:IMMediate][:AMPLitude]", setter=self._vpk_setter("level_vpk"),
              query=quantity_query(lambda: (self.source.level_vpk, "VPK")))
        t.add(f"{src}:AUTO[:STATe]", setter=bool_setter(
            lambda v: setattr(self.source, "auto_level", v)),
            query=lambda p, s: format_bool(self.source.auto_level))
        t.add(f"{src}:REFerence:CHANnel", setter=self._channel_word_setter("reference_channel"),
              query=lambda p, s: f"INP{self.source.reference_channel}")
        t.add(f"{src}:REFerence[:LEVel]", setter=self._level_eu_setter("reference"),
              query=quantity_query(lambda: self.source.reference))
        t.add(f"{src}:REFerence:TOLerance", setter=self._tolerance,
              query=lambda p, s: format_real(self.source.tolerance_db))
        t.add(f"{src}:LIMit[:LEVel]", setter=self._vpk_setter("limit_vpk"),
              query=quantity_query(lambda: (self.source.limit_vpk, "VPK")))
        t.add(f"{src}:LIMit:INPut[:LEVel]", setter=self._level_eu_setter("input_limit"),
              query=quantity_query(lambda: self.source.input_limit))
        t.add(f"{src}:LIMit:INPut:CHANnel",
              setter=self._channel_word_setter("input_limit_channel"),
              query=lambda p, s: f"INP{self.source.input_limit_channel}")
        t.add(f"{src}:LIMit:INPut:STATe", setter=bool_setter(
            lambda v: setattr(self.source, "input_limit_on", v)),
            query=lambda p, s: format_bool(self.source.input_limit_on))
        t.add(f"{src}:SLEW", setter=self._slew,
              query=lambda p, s: format_real(self.source.slew_v_per_s))

    def _vpk_setter(self, name: str) -> Callable[..., None]:
        """A level in volts peak, 0 to the source's 5 Vpk (the level, the limit)."""
        def setter(params: Params, suffix: int | None) -> None:
            q = parse_quantity(one(params), ("VPK",), "VPK")
            current = getattr(self.source, name)
            setattr(self.source, name, limited(q, current, 0.0, MAX_SOURCE_VPK, 0.1))
        return setter

    def _channel_word_setter(self, name: str) -> Callable[..., None]:
        """A channel given as ``INP1`` .. ``INP4``."""
        def setter(params: Params, suffix: int | None) -> None:
            word = one(params).strip().upper()
            match = re.fullmatch(r"INP(?:UT)?([1-4])", word)
            if match is None:
                raise ScpiError(-224, f"{word} (expected INP1..INP4)")
            setattr(self.source, name, int(match.group(1)))
        return setter

    def _level_eu_setter(self, name: str) -> Callable[..., None]:
        """A level in the channel's engineering unit or in volts peak; the unit is kept."""
        def setter(params: Params, suffix: int | None) -> None:
            current_value, current_unit = getattr(self.source, name)
            q = parse_quantity(one(params), ("EU", "VPK"), current_unit)
            value = limited(q, current_value, 0.0, 1.0e9, 0.1)
            if value <= 0:
                raise ScpiError(-222, "level must be positive; value not changed")
            setattr(self.source, name, (value, q.unit))
            if name == "input_limit":
                self.source.input_limit_on = True
        return setter

    def _tolerance(self, params: Params, suffix: int | None) -> None:
        q = parse_quantity(one(params), ("DB",), "DB")
        self.source.tolerance_db = limited(q, self.source.tolerance_db, 0.1, 20.0, 0.1)

    def _slew(self, params: Params, suffix: int | None) -> None:
        q = parse_quantity(one(params), ("V/S",), "V/S")
        self.source.slew_v_per_s = limited(q, self.source.slew_v_per_s, 1e-3, 1e4, 1.0)
