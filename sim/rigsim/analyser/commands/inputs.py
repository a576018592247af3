"""``INPut`` and ``SENSe:VOLTage``: channels on and off, coupling, ranges, engineering units."""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence

from rigsim.analyser.limits import MAX_FREQUENCY_4CH_HZ
from rigsim.analyser.params import Params, limited, one
from rigsim.analyser.worker import SweepWorker
from rigsim.measurement import INPUT_RANGES_DBVRMS
from rigsim.scpi import (
    CommandTree,
    Quantity,
    ScpiError,
    format_bool,
    format_real,
    parse_bool,
    parse_choice,
    parse_quantity,
    unquote,
)

__all__ = ["InputCommands"]


class InputCommands(SweepWorker):
    """Handlers of ``INPut#`` and ``[SENSe:]VOLTage#`` (a base of the analyser)."""

    def _register_input_commands(self, t: CommandTree) -> None:
        t.add("INPut#[:STATe]", setter=self._input_state,
              query=lambda p, s: format_bool(self._channel(s).enabled))
        t.add("INPut#:COUPling", setter=self._channel_choice("coupling", ("AC", "DC")),
              query=lambda p, s: self._channel(s).coupling)
        t.add("INPut#:LOW", setter=self._channel_choice("low", ("GROund", "FLOat")),
              query=lambda p, s: self._channel(s).low)
        t.add("INPut#:BIAS[:STATe]", setter=self._channel_bool("bias"),
              query=lambda p, s: format_bool(self._channel(s).bias))
        t.add("[SENSe:]VOLTage#[:DC]:RANGe[:UPPer]", setter=self._range,
              query=lambda p, s: format_real(self._channel(s).range_dbvrms))
        t.add("[SENSe:]VOLTage#[:DC]:RANGe:AUTO", setter=self._channel_bool("autorange"),
              query=lambda p, s: format_bool(self._channel(s).autorange))
        t.add("[SENSe:]VOLTage#[:DC]:RANGe:AUTO:DIRection", setter=self._autorange_direction)
        t.add("[SENSe:]VOLTage#[:DC]:RANGe:UNIT:XDCR:LABel", setter=self._label,
              query=lambda p, s: self._channel(s).label)
        t.add("[SENSe:]VOLTage#[:DC]:RANGe:UNIT:USER:SFACtor", setter=self._sfac,
              query=lambda p, s: format_real(self._channel(s).user_sfac_v_per_eu))
        t.add("[SENSe:]VOLTage#[:DC]:RANGe:UNIT:USER[:STATe]", setter=self._channel_bool(
            "user_units"), query=lambda p, s: format_bool(self._channel(s).user_units))

    def _input_state(self, params: Params, suffix: int | None) -> None:
        n = 1 if suffix is None else suffix
        channel = self._channel(n)
        on = parse_bool(one(params))
        if n == 1 and not on:
            raise ScpiError(-221, "channel 1 is always on")  # (inferred)
        if n >= 3 and on and "AY6" not in self.options:
            raise ScpiError(-241, "four channels need option AY6")
        channel.enabled = on
        if self._four_channel():
            limit = MAX_FREQUENCY_4CH_HZ  # clamp to the four-channel band (inferred)
            for s in self.modes.values():
                s.start_hz, s.stop_hz = min(s.start_hz, limit), min(s.stop_hz, limit)

    def _channel_choice(self, name: str, choices: Sequence[str]) -> Callable[..., None]:
        def setter(params: Params, suffix: int | None) -> None:
            setattr(self._channel(suffix), name, parse_choice(one(params), choices))
        return setter

    def _channel_bool(self, name: str) -> Callable[..., None]:
        def setter(params: Params, suffix: int | None) -> None:
            setattr(self._channel(suffix), name, parse_bool(one(params)))
        return setter

    def _range(self, params: Params, suffix: int | None) -> None:
        channel = self._channel(suffix)
        q = parse_quantity(one(params), ("DBVRMS", "VPK"), "DBVRMS")
        if q.keyword is None and q.unit == "VPK":
            if q.value <= 0:
                raise ScpiError(-222, "range must be positive; value not changed")
            q = Quantity(20 * math.log10(q.value / math.sqrt(2.0)), "DBVRMS")
        value = limited(q, channel.range_dbvrms, float(INPUT_RANGES_DBVRMS[-1]),
                        float(INPUT_RANGES_DBVRMS[0]), 2.0)
        # the smallest range that holds the requested level (inferred)
        candidates = INPUT_RANGES_DBVRMS[value - 1e-9 <= INPUT_RANGES_DBVRMS]
        channel.range_dbvrms = float(candidates[-1])
        channel.autorange = False  # a fixed range turns autorange off (inferred)

    def _autorange_direction(self, params: Params, suffix: int | None) -> None:
        self._channel(suffix)
        direction = parse_choice(one(params), ("UP", "EITHer"))
        if direction == "UP":
            self._forbid_in_sine("VOLT:RANG:AUTO:DIR UP")

    def _label(self, params: Params, suffix: int | None) -> None:
        text = one(params)
        label = unquote(text) if text[:1] in "'\"" else text
        if not label or len(label) > 6:
            raise ScpiError(-224, f"transducer label {text}")
        self._channel(suffix).label = label.upper()

    def _sfac(self, params: Params, suffix: int | None) -> None:
        channel = self._channel(suffix)
        q = parse_quantity(one(params), ("V/EU",), "V/EU")
        value = limited(q, channel.user_sfac_v_per_eu, 1e-12, 1e12, 0.0)
        if value <= 0:
            raise ScpiError(-222, "sensitivity must be positive; value not changed")
        channel.user_sfac_v_per_eu = value
