"""Declarative settings: what a command accepts, its presets, and where its value lives.

Most of the 35670A's commands set or query one value: a switch, a number with units, a keyword,
a string. Each such setting is one :class:`Spec` (kind, limits, units, presets after
``SYST:PRES`` and ``*RST``, whether it is kept per instrument mode, per trace or per input,
the modes it is valid in, the option it needs); :class:`SettingStore` holds the values and
:func:`bind` makes the command tree's setting and query handlers for it. Settings whose effect
reaches further (frequencies, resolution, channels, ranges, levels) have their own handlers in
:mod:`rigsim.analyser.commands` but keep their values here too.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Any, Protocol

from rigsim.analyser.units import LEVEL_UNITS, Level, to_vpk
from rigsim.scpi import (
    OUT_OF_RANGE,
    Call,
    CommandTree,
    ScpiError,
    format_bool,
    format_int,
    format_real,
    format_string,
    parse_bool,
    parse_choice,
    parse_quantity,
    unquote,
)

__all__ = [
    "MODE_CONFLICT",
    "OPTION_ERRORS",
    "SAME",
    "Context",
    "SettingStore",
    "Spec",
    "bind",
    "check_option",
    "one",
]

#: The 35670A's -221 text for a command its current mode does not have (appendix C).
MODE_CONFLICT = "Measurement mode incompatible with command."
#: The error of a command whose option is not installed (appendix C).
OPTION_ERRORS: dict[str, tuple[int, str]] = {
    "AY6": (-241, "OPTION AY6 Add 2 Input Channels not installed."),
    "1D2": (-200, "OPTION 1D2, Swept Sine Measurements not installed."),
    "1D3": (-200, "OPTION 1D3 Curve Fit/Synthesis not installed."),
    "1D1": (-200, "OPTION 1D1, Octave Measurements not installed."),
    "1D0": (-200, "OPTION 1D0, Computed Order Tracking not installed."),
    "1D4": (-200, "OPTION 1D4, Arbitrary Source not installed."),
    "1C2": (-200, "OPTION 1C2, Instrument BASIC not installed."),
}


class _Same:
    def __repr__(self) -> str:
        return "SAME"


#: ``Spec.rst`` default: ``*RST`` leaves the same value as ``SYST:PRES``.
SAME: Any = _Same()


class Context(Protocol):
    """What a setting needs of the instrument: the mode, the options, input sensitivities."""

    @property
    def mode(self) -> str:
        """The instrument mode (``FFT``, ``SINE``, ...)."""

    @property
    def options(self) -> tuple[str, ...]:
        """Installed options."""

    def v_per_eu(self, channel: int) -> float | None:
        """Volts per engineering unit of an input in engineering units, else ``None``."""


def check_option(option: str | None, options: Sequence[str]) -> None:
    """Raise the manual's error when ``option`` is not installed."""
    if option is not None and option not in options:
        code, text = OPTION_ERRORS.get(option, (-241, f"OPTION {option} not installed."))
        raise ScpiError(code, text)


def one(call: Call) -> str:
    """The single parameter of a call (-109 if missing, -108 if more than one)."""
    if not call.params:
        raise ScpiError(-109)
    if len(call.params) > 1:
        raise ScpiError(-108, ",".join(call.params[1:])[:40])
    return call.params[0]


@dataclass(frozen=True)
class Spec:
    """One setting of the instrument.

    Attributes
    ----------
    kind
        ``bool``, ``int``, ``real``, ``pair`` (a number and the unit it came in: ``S|CYCLE``),
        ``level`` (an amplitude in :data:`rigsim.analyser.units.LEVEL_UNITS`), ``choice``,
        ``string``.
    preset
        Value after ``SYST:PRES`` and at power-on; a callable ``(mode, index) -> value`` when it
        depends on the mode or the trace. Levels: a :class:`~rigsim.analyser.units.Level`;
        pairs: ``(value, unit)``.
    rst
        Value after ``*RST`` when it differs (:data:`SAME` otherwise).
    lo, hi
        Limits in the default unit (levels: in volts peak); outside, -222.
    step
        ``UP``/``DOWN`` increment (``None``: the keywords are refused).
    units
        Accepted units; ``default_unit`` is the unit of a bare number.
    choices
        Long forms of ``choice`` keywords (``LINear``); ``aliases`` maps other accepted words
        (``0``) to a choice's short form.
    length
        Longest string (``string`` kind).
    scope
        Where one value lives, one entry per numeric suffix of the header: ``trace`` (1..4,
        ``CALCn``/``WINDn``), ``channel`` (1..4, ``INPn``/``VOLTn``), ``item:N`` (1..N); plus
        ``mode`` when each instrument mode keeps its own value.
    modes
        Modes the command is valid in (``None``: all); elsewhere -221 with ``conflict``.
    keep
        ``SYST:PRES`` and ``*RST`` leave it alone (addresses, limit segments, math constants).
    answer
        ``onoff`` answers a boolean as ``ON``/``OFF`` (the manual says so for a few commands).
    option
        Option the command needs.
    settable, queryable
        The command has a setting form / a query form.
    clamp
        Out-of-range values are limited instead of refused.
    """

    kind: str
    preset: Any = None
    rst: Any = SAME
    lo: float = -math.inf
    hi: float = math.inf
    step: float | None = None
    units: tuple[str, ...] = ()
    default_unit: str = ""
    choices: tuple[str, ...] = ()
    aliases: dict[str, str] = field(default_factory=dict)
    length: int = 0
    scope: tuple[str, ...] = ()
    modes: frozenset[str] | None = None
    conflict: str = MODE_CONFLICT
    keep: bool = False
    answer: str = ""
    option: str | None = None
    settable: bool = True
    queryable: bool = True
    clamp: bool = False


Key = tuple[str, str | None, tuple[int, ...]]


class SettingStore:
    """Values of the declared settings, with presets and the two kinds of reset.

    Parameters
    ----------
    context
        The instrument (mode, options, input sensitivities).
    """

    def __init__(self, context: Context) -> None:
        self.context = context
        self.specs: dict[str, Spec] = {}
        self.values: dict[Key, Any] = {}
        self.reset_kind = "PRES"
        #: Levels whose engineering units belong to an input other than their own suffix:
        #: name -> callable(index) giving the input, or 0 for "each input its own".
        self.level_channels: dict[str, Callable[[tuple[int, ...]], int | None]] = {}

    def define(self, name: str, spec: Spec) -> Spec:
        """Declare a setting (names are unique)."""
        if name in self.specs and self.specs[name] != spec:
            raise ValueError(f"setting {name!r} declared twice differently")
        self.specs[name] = spec
        return spec

    def _key(self, name: str, index: tuple[int, ...], mode: str | None) -> Key:
        spec = self.specs[name]
        keyed_mode = (mode or self.context.mode) if "mode" in spec.scope else None
        return name, keyed_mode, index

    def default(self, name: str, index: tuple[int, ...] = (), mode: str | None = None) -> Any:
        """The preset (or ``*RST``) value of a setting."""
        spec = self.specs[name]
        value = spec.rst if self.reset_kind == "RST" and spec.rst is not SAME else spec.preset
        if callable(value):
            return value(mode or self.context.mode, index)
        return value

    def get(self, name: str, index: tuple[int, ...] = (), mode: str | None = None) -> Any:
        """The value of a setting (its preset until set)."""
        key = self._key(name, index, mode)
        if key in self.values:
            return self.values[key]
        return self.default(name, index, mode)

    def set(self, name: str, value: Any, index: tuple[int, ...] = (),
            mode: str | None = None) -> None:
        """Store a value (checks are the caller's)."""
        self.values[self._key(name, index, mode)] = value

    def reset(self, kind: str) -> None:
        """``SYST:PRES`` (``"PRES"``) or ``*RST`` (``"RST"``): every setting not kept returns to
        its preset."""
        self.reset_kind = kind
        self.values = {key: value for key, value in self.values.items()
                       if self.specs[key[0]].keep}

    # -------------------------------------------------------------------- checks

    def check_call(self, name: str, call: Call) -> tuple[int, ...]:
        """Mode and option checks; the value's index from the header's suffixes."""
        spec = self.specs[name]
        check_option(spec.option, self.context.options)
        if spec.modes is not None and self.context.mode not in spec.modes:
            raise ScpiError(-221, spec.conflict)
        return self.index(spec, call)

    @staticmethod
    def index(spec: Spec, call: Call) -> tuple[int, ...]:
        """The index a call addresses (suffix 1 when the header leaves it out)."""
        index: list[int] = []
        suffixes = list(call.suffixes)
        for scope in spec.scope:
            if scope == "mode":
                continue
            count = int(scope.split(":")[1]) if scope.startswith("item:") else 4
            number = suffixes.pop(0) if suffixes else None
            number = 1 if number is None else number
            if not 1 <= number <= count:
                raise ScpiError(-114, f"{call.header}: suffix {number} (1..{count})")
            index.append(number)
        return tuple(index)

    # -------------------------------------------------------------------- parsing values

    def parse(self, name: str, call: Call, index: tuple[int, ...]) -> Any:
        """The new value a setting call asks for (checked; -222 out of range)."""
        spec = self.specs[name]
        kind = spec.kind
        if kind == "bool":
            return parse_bool(one(call))
        if kind == "choice":
            word = one(call).strip().upper()
            if word in spec.aliases:
                return spec.aliases[word]
            return parse_choice(word, spec.choices)
        if kind == "string":
            text = unquote(one(call))
            if spec.length and len(text) > spec.length:
                raise ScpiError(-151, f"longer than {spec.length} characters")
            return text
        if kind == "level":
            return self._parse_level(name, spec, call, index)
        q = parse_quantity(one(call), spec.units)
        current = self.get(name, index)
        if kind == "pair":
            value, unit = current
            new_unit = q.unit or (spec.default_unit or unit)
            new = self._resolve(spec, q, value if new_unit == unit else math.nan)
            return (new, new_unit)
        value = self._resolve(spec, q, float(current))
        if kind == "int":
            return round(value)
        return value

    def _resolve(self, spec: Spec, q: Any, current: float) -> float:
        if q.keyword == "MAX":
            return spec.hi
        if q.keyword == "MIN":
            return spec.lo
        if q.keyword in ("UP", "DOWN"):
            if spec.step is None or math.isnan(current):
                raise ScpiError(-224, f"{q.keyword} not allowed here")
            value = current + (spec.step if q.keyword == "UP" else -spec.step)
            return min(spec.hi, max(spec.lo, value))
        if q.keyword == "DEF":
            raise ScpiError(-224, "DEF")
        value = q.value
        if spec.kind == "int" and value != round(value):
            value = round(value)
        if not spec.lo - 1e-9 * max(1.0, abs(spec.lo)) <= value <= spec.hi + 1e-9 * max(
                1.0, abs(spec.hi)):
            if spec.clamp:
                return min(spec.hi, max(spec.lo, value))
            raise ScpiError(-222, OUT_OF_RANGE)
        return value

    def _parse_level(self, name: str, spec: Spec, call: Call, index: tuple[int, ...]) -> Level:
        channel = self.level_channel(name, index)
        q = parse_quantity(one(call), spec.units)
        v_per_eu = None if not channel else self.context.v_per_eu(channel)
        if q.keyword in ("MAX", "MIN"):
            vpk = spec.hi if q.keyword == "MAX" else spec.lo
            current = self.get(name, index)
            return Level(vpk, current.unit if current.unit not in ("EU", "DBEU") else "VPK")
        if q.keyword is not None:
            raise ScpiError(-224, q.keyword)
        unit = q.unit or spec.default_unit
        if channel == 0 and unit in ("EU", "DBEU"):  # each input in its own units
            eu = q.value if unit == "EU" else 10.0 ** (q.value / 20.0)
            return Level(math.nan, unit, eu)
        vpk = to_vpk(q.value, unit, v_per_eu)
        if not spec.lo * (1 - 1e-9) <= vpk <= spec.hi * (1 + 1e-9):
            raise ScpiError(-222, OUT_OF_RANGE)
        eu = vpk / v_per_eu if unit in ("EU", "DBEU") and v_per_eu else None
        return Level(vpk, unit, eu)

    def level_channel(self, name: str, index: tuple[int, ...]) -> int | None:
        """The input whose engineering units a level refers to (its own suffix, else none;
        0: each input its own)."""
        resolver = self.level_channels.get(name)
        if resolver is not None:
            return resolver(index)
        spec = self.specs[name]
        if "channel" in spec.scope and index:
            return index[0]
        return None

    # -------------------------------------------------------------------- answers

    def answer(self, name: str, call: Call, index: tuple[int, ...]) -> str:
        """The query answer of a setting (``? UNIT`` answers the unit in use)."""
        spec = self.specs[name]
        value = self.get(name, index)
        if call.params:
            if len(call.params) == 1 and call.params[0].strip().upper() == "UNIT":
                return format_string(self.unit_of(spec, value))
            raise ScpiError(-108, call.params[0][:40])
        return self.format(spec, value, name, index)

    @staticmethod
    def unit_of(spec: Spec, value: Any) -> str:
        """The unit a setting's value is in."""
        if isinstance(value, Level):
            return value.unit
        if spec.kind == "pair":
            return str(value[1])
        if spec.units:
            return spec.default_unit or spec.units[0]
        return ""

    def format(self, spec: Spec, value: Any, name: str = "", index: tuple[int, ...] = ()) -> str:
        """A value in the form the manual gives for the query."""
        if spec.kind == "bool":
            if spec.answer == "onoff":
                return "ON" if value else "OFF"
            return format_bool(bool(value))
        if spec.kind == "int":
            return format_int(int(value))
        if spec.kind == "choice":
            return str(value)
        if spec.kind == "string":
            return format_string(str(value))
        if spec.kind == "pair":
            return format_real(float(value[0]))
        if isinstance(value, Level):
            channel = self.level_channel(name, index)
            v_per_eu = None if not channel else self.context.v_per_eu(channel)
            return format_real(value.value(v_per_eu))
        return format_real(float(value))


def bind(
    tree: CommandTree,
    store: SettingStore,
    pattern: str,
    name: str,
    spec: Spec,
    *,
    after: Callable[[Any, tuple[int, ...]], None] | None = None,
) -> None:
    """Declare a setting and register its setting and query handlers under ``pattern``.

    ``after(value, index)`` runs once a new value is stored (side effects such as aborting the
    measurement).
    """
    store.define(name, spec)

    def setter(call: Call) -> None:
        index = store.check_call(name, call)
        value = store.parse(name, call, index)
        store.set(name, value, index)
        if after is not None:
            after(value, index)

    def query(call: Call) -> str:
        index = store.check_call(name, call)
        return store.answer(name, call, index)

    tree.add(pattern, setter=setter if spec.settable else None,
             query=query if spec.queryable else None)


def level_spec(preset_vpk: float, preset_unit: str, lo_vpk: float, hi_vpk: float,
               default_unit: str, *, eu: bool = False, **kwargs: Any) -> Spec:
    """A level setting (volts peak inside; ``eu``: engineering units accepted)."""
    units = LEVEL_UNITS if eu else tuple(u for u in LEVEL_UNITS if u not in ("EU", "DBEU"))
    return Spec("level", Level(preset_vpk, preset_unit), lo=lo_vpk, hi=hi_vpk, units=units,
                default_unit=default_unit, **kwargs)
