"""The fields of sequence and station files, written once: the readers use them, the reference
(``sequences/README.md``, ``viscorig check --fields``) is generated from them.

A :class:`Field` says a value's type, unit, default, range and an example, and converts what a
file holds into the value the program uses; a :class:`TableSchema` lists the fields of one
table (a step type, a section of the station file). :func:`read_table` reads a table against
its schema and records every problem in a :class:`~viscorig.sequences.problems.Problems`
instead of stopping at the first.
"""

from __future__ import annotations

import math
import re
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from typing import Any

from viscorig.analyser import FREQUENCY_STEP_HZ
from viscorig.analyser import MAX_FREQUENCY_HZ as ANALYSER_MAX_FREQUENCY_HZ
from viscorig.sequences import segments
from viscorig.sequences.levels import parse_level
from viscorig.sequences.problems import Path, Problems, did_you_mean, quoted
from viscorig.storage import layout
from viscorig.storage.text import first_control

#: A day: the longest dwell, wait, retry or time constant a sequence may set.
LONGEST_S = 86_400.0
#: Longest text a field may hold (a specimen's name, a prompt's instruction): the campaign file
#: stores it as an attribute, which readers take up to 64 KiB.
MAX_TEXT_CHARACTERS = 4096

#: A field that must be given (in its table, or in ``[defaults]`` where allowed).
REQUIRED: Any = type("Required", (), {"__repr__": lambda self: "REQUIRED"})()

#: The analyser's highest frequency with four channels, Hz.
MAX_FREQUENCY_HZ = ANALYSER_MAX_FREQUENCY_HZ
#: Frequencies are set in steps of 15.625 mHz.
MIN_RESOLUTION_HZ = FREQUENCY_STEP_HZ
#: The analyser's lowest frequency, Hz (its frequency step).
MIN_FREQUENCY_HZ = FREQUENCY_STEP_HZ
#: Beyond any shaker rig, m/s² peak.
MAX_LEVEL_M_PER_S2 = 500.0
#: Rig preset names (``sim/rigs/<name>.toml``).
PRESET_NAME = re.compile(r"^[A-Za-z0-9][A-Za-z0-9._-]{0,63}\Z")
#: A VISA resource string.
VISA_RESOURCE = re.compile(r"^[A-Za-z][A-Za-z0-9-]*::\S+::(INSTR|SOCKET|INTFC)\Z")


class FieldError(ValueError):
    """A value a field refuses: ``message`` says why, ``hint`` how to fix it."""

    def __init__(self, message: str, hint: str = "") -> None:
        super().__init__(message)
        self.message = message
        self.hint = hint


def kind_name(value: object) -> str:
    """How TOML would call a Python value's type, for messages."""
    return {
        bool: "boolean", int: "integer", float: "number", str: "text", list: "array",
        dict: "table",
    }.get(type(value), type(value).__name__)


#: Smallest relative uncertainty a plan may aim at: one part in 10⁹, far finer than any sweep
#: reaches (a target of 1e-300 made the plan's design divide by zero).
TARGET_FLOOR = 1e-9


def _interval(low: float | None, high: float | None, low_open: bool, unit: str) -> str:
    lo = "-inf" if low is None else f"{low:g}"
    hi = "inf" if high is None else f"{high:g}"
    return f"{'(' if low_open else '['}{lo}, {hi}]" + (f" {unit}" if unit else "")


@dataclass(frozen=True)
class Field:
    """One field of a table.

    Parameters
    ----------
    name
        The key in the file.
    kind
        ``text``, ``choice``, ``name`` (text matching ``pattern``), ``number``, ``integer``,
        ``boolean``, ``band`` (``[low, high]`` in Hz), ``level`` (acceleration with its unit)
        or ``targets`` (a table of parameter names and relative uncertainties, each in
        ``(low, high]``).
    doc
        What it means, for the reference.
    default
        :data:`REQUIRED`, ``None`` (not set), or the value used when absent.
    unit
        Of a number (the name carries it too: ``band_hz``).
    low, high, low_open
        The range of a number, integer or band; ``low_open`` excludes ``low``.
    choices
        Of a choice.
    pattern, rule
        Of a name: the regular expression and how to say it.
    example
        The value as TOML text, for the reference and hints.
    in_defaults
        May be given in a sequence's ``[defaults]``.
    default_note
        The default as the reference shows it, when the rule is more than a value (a field
        required by one kind of step only).
    """

    name: str
    kind: str
    doc: str
    default: Any = REQUIRED
    unit: str = ""
    low: float | None = None
    high: float | None = None
    low_open: bool = False
    choices: tuple[str, ...] = ()
    pattern: re.Pattern[str] | None = None
    rule: str = ""
    example: str = ""
    in_defaults: bool = False
    default_note: str = ""

    @property
    def required(self) -> bool:
        return self.default is REQUIRED

    # -- reading -------------------------------------------------------------------------------
    def convert(self, value: object) -> Any:
        """The value the program uses, from what the file holds.

        Raises
        ------
        FieldError
            The value is refused; the error says why and, where it can, what was meant.
        """
        reader: Callable[[object], Any] = getattr(self, f"_{self.kind}")
        return reader(value)

    def _text(self, value: object) -> str:
        if not isinstance(value, str):
            raise FieldError(f"expected text, got {kind_name(value)} {quoted(value)}",
                             f"write it in quotes, e.g. {self.name} = {self.example}")
        if not value.strip() and self.default != "":
            raise FieldError("must not be empty")
        if len(value) > MAX_TEXT_CHARACTERS:
            raise FieldError(f"{len(value)} characters; at most {MAX_TEXT_CHARACTERS}")
        control = first_control(value)
        if control is not None:
            raise FieldError(f"holds the control character U+{ord(control):04X} at "
                             f"{value.index(control) + 1}", "text, line breaks and tabs only")
        return value

    def _choice(self, value: object) -> str:
        text = self._text(value)
        if text not in self.choices:
            raise FieldError(f"{quoted(text)} is not one of {', '.join(self.choices)}",
                             did_you_mean(text, self.choices, cutoff=0.5))
        return text

    def _name(self, value: object) -> str:
        text = self._text(value)
        if self.pattern is not None and not self.pattern.fullmatch(text):
            raise FieldError(f"{quoted(text)} is not {self.rule}")
        return text

    def _number(self, value: object) -> float:
        if isinstance(value, bool) or not isinstance(value, int | float):
            hint = ""
            if isinstance(value, str):
                hint = (f"write a number without quotes or unit (the unit is in the name), e.g. "
                        f"{self.name} = {self.example}")
            raise FieldError(f"expected a number, got {kind_name(value)} {quoted(value)}", hint)
        number = float(value)
        below = self.low is not None and (number <= self.low if self.low_open
                                          else number < self.low)
        above = self.high is not None and number > self.high
        if not math.isfinite(number) or below or above:
            raise FieldError(f"{quoted(number)} is outside "
                             f"{_interval(self.low, self.high, self.low_open, self.unit)}")
        return number

    def _integer(self, value: object) -> int:
        if isinstance(value, bool) or not isinstance(value, int):
            raise FieldError(f"expected a whole number, got {kind_name(value)} {quoted(value)}")
        if (self.low is not None and value < self.low) or (
                self.high is not None and value > self.high):
            raise FieldError(f"{value} is outside [{self.low:g}, {self.high:g}]")
        return value

    def _boolean(self, value: object) -> bool:
        if not isinstance(value, bool):
            raise FieldError(f"expected true or false, got {kind_name(value)} {quoted(value)}")
        return value

    def _band(self, value: object) -> tuple[float, float]:
        if (not isinstance(value, list) or len(value) != 2
                or any(isinstance(v, bool) or not isinstance(v, int | float) for v in value)):
            raise FieldError(f"expected [low, high] in Hz, got {quoted(value)}",
                             f"e.g. {self.name} = {self.example}")
        lo, hi = float(value[0]), float(value[1])
        high = MAX_FREQUENCY_HZ if self.high is None else self.high
        if not (math.isfinite(lo) and math.isfinite(hi) and min(lo, hi) >= MIN_FREQUENCY_HZ
                and max(lo, hi) <= high):
            raise FieldError(f"[{lo:g}, {hi:g}] Hz must satisfy {MIN_FREQUENCY_HZ:g} <= low < "
                             f"high <= {high:g}", "the analyser's lowest and highest frequency")
        if lo > hi:
            sweep = self.in_defaults  # a sweep's band: its direction says which end is first
            raise FieldError(
                f"[{lo:g}, {hi:g}] Hz is written high to low",
                f"write {self.name} = [{hi:g}, {lo:g}]"
                + (" and direction = \"down\" to sweep downwards" if sweep else ""),
            )
        if lo == hi:
            raise FieldError(f"[{lo:g}, {hi:g}] Hz must satisfy {MIN_FREQUENCY_HZ:g} <= low < "
                             f"high <= {high:g}",
                             "a band needs two different frequencies")
        return lo, hi

    def _targets(self, value: object) -> dict[str, float]:
        if not isinstance(value, Mapping) or not value:
            raise FieldError(f"expected a table of parameter names and relative uncertainties, "
                             f"got {kind_name(value)} {quoted(value)}", f"e.g. {self.name} = "
                             f"{self.example}")
        targets: dict[str, float] = {}
        for name, number in value.items():
            if isinstance(number, bool) or not isinstance(number, int | float):
                raise FieldError(f"{name}: expected a number, got {kind_name(number)} "
                                 f"{quoted(number)}",
                                 f"e.g. {self.name} = {self.example}")
            number = float(number)
            if not (math.isfinite(number) and (self.low or 0.0) < number <= (self.high or 1.0)):
                raise FieldError(f"{name}: {quoted(number)} is outside "
                                 f"{_interval(self.low, self.high, True, '')}",
                                 "a relative standard uncertainty: 1e-3 is 0.1 %")
            targets[str(name)] = number
        return targets

    def _numbers(self, value: object) -> tuple[float, ...]:
        if not isinstance(value, list) or not value:
            raise FieldError(f"expected a non-empty array of numbers, got {quoted(value)}",
                             f"e.g. {self.name} = {self.example}")
        numbers = []
        for index, item in enumerate(value):
            try:
                numbers.append(self._number(item))
            except FieldError as error:
                raise FieldError(f"[{index}]: {error.message}", error.hint) from None
        seen: set[float] = set()
        for number in numbers:
            if number in seen:
                raise FieldError(f"names {number:g} twice", "each value once")
            seen.add(number)
        return tuple(numbers)

    def _levels(self, value: object) -> tuple[tuple[float, str], ...]:
        if not isinstance(value, list) or not value:
            raise FieldError(f"expected a non-empty array of levels, got {quoted(value)}",
                             f"e.g. {self.name} = {self.example}")
        levels = []
        for index, item in enumerate(value):
            try:
                levels.append(self._level(item))
            except FieldError as error:
                raise FieldError(f"[{index}]: {error.message}", error.hint) from None
        return tuple(levels)

    def _level(self, value: object) -> tuple[float, str]:
        try:
            level = parse_level(value)  # type: ignore[arg-type]
        except ValueError as error:
            message, _, hint = str(error).partition("; ")
            raise FieldError(message, hint) from None
        if level > MAX_LEVEL_M_PER_S2:
            raise FieldError(
                f"{level:g} m/s^2 peak is beyond any shaker rig (max {MAX_LEVEL_M_PER_S2:g})")
        return level, value  # type: ignore[return-value]

    # -- describing ----------------------------------------------------------------------------
    def type_text(self) -> str:
        """The type as the reference shows it."""
        return {
            "text": "text", "name": "text", "boolean": "true/false", "integer": "whole number",
            "number": "number", "band": "[low, high]", "level": "text: number and unit",
            "targets": "table: name = number", "numbers": "array of numbers",
            "levels": "array of texts: number and unit",
            "choice": " | ".join(f'"{choice}"' for choice in self.choices),
        }[self.kind]

    def unit_text(self) -> str:
        """The unit as the reference shows it."""
        if self.kind in ("level", "levels"):
            return "m/s^2, m/s2, m/s², mm/s^2, g, mg; peak unless `rms` follows"
        if self.kind == "band":
            return "Hz"
        return self.unit

    def default_text(self) -> str:
        """The default as the reference shows it."""
        if self.default_note:
            return self.default_note
        if self.required:
            return "required" + (" (or in `[defaults]`)" if self.in_defaults else "")
        if self.default is None:
            return "not set"
        if isinstance(self.default, bool):
            return "true" if self.default else "false"
        if isinstance(self.default, str):
            return f'"{self.default}"'
        if isinstance(self.default, float) and math.isnan(self.default):
            return "unknown"
        return f"{self.default:g}" if isinstance(self.default, float) else str(self.default)

    def range_text(self) -> str:
        """The range as the reference shows it."""
        if self.kind in ("number", "integer"):
            return _interval(self.low, self.high, self.low_open, "")
        if self.kind == "numbers":
            return "each " + _interval(self.low, self.high, self.low_open, "")
        if self.kind == "levels":
            return f"each (0, {MAX_LEVEL_M_PER_S2:g}] m/s^2 peak"
        if self.kind == "targets":
            return "each " + _interval(self.low, self.high, True, "")
        if self.kind == "band":
            return f"{MIN_FREQUENCY_HZ:g} <= low < high <= {MAX_FREQUENCY_HZ:g}"
        if self.kind == "level":
            return f"(0, {MAX_LEVEL_M_PER_S2:g}] m/s^2 peak"
        if self.kind == "name":
            return self.rule
        return ""


@dataclass(frozen=True)
class TableSchema:
    """The fields of one table: a step type, or a section of a file."""

    name: str
    doc: str
    fields: tuple[Field, ...]
    required: bool = True
    """For a section of a file: must it be there?"""

    def field(self, name: str) -> Field:
        return next(item for item in self.fields if item.name == name)

    @property
    def names(self) -> tuple[str, ...]:
        return tuple(item.name for item in self.fields)


@dataclass
class ReadTable:
    """What :func:`read_table` found: converted values, and where each came from."""

    values: dict[str, Any] = field(default_factory=dict)
    origin: dict[str, Path] = field(default_factory=dict)
    failed: set[str] = field(default_factory=set)
    """Fields given but refused, or required and missing."""

    @property
    def ok(self) -> bool:
        return not self.failed

    def __getitem__(self, name: str) -> Any:
        return self.values[name]


def read_table(
    problems: Problems,
    path: Path,
    table: object,
    schema: TableSchema,
    *,
    defaults: Mapping[str, Any] | None = None,
    defaults_path: Path = (),
    also_known: tuple[str, ...] = (),
) -> ReadTable:
    """Read one table against its schema; record every problem, stop at none.

    Parameters
    ----------
    problems
        Where problems go.
    path
        The table's path in the file (``("steps", 3)``).
    table
        The table as parsed.
    schema
        Its fields.
    defaults, defaults_path
        Values for the fields allowed in defaults, and where they are written.
    also_known
        Keys read elsewhere (``type``), not unknown.
    """
    result = ReadTable()
    if not isinstance(table, Mapping):
        problems.add(path, f"expected a table, got {kind_name(table)}")
        result.failed.add("")
        return result
    known = (*also_known, *schema.names)
    unknown = [key for key in table if key not in known]
    meant: set[str] = set()
    for key in unknown:
        hint = did_you_mean(key, known)
        if hint:
            meant.add(hint.split("'")[1])
        elif defaults is not None:
            hint = f"{schema.name} steps take: {', '.join(schema.names)}"
        else:
            hint = f"known here: {', '.join(known)}"
        problems.add((*path, key), "unknown key", hint)
        result.failed.add(key)
    defaults = defaults or {}
    for item in schema.fields:
        if item.name in table:
            value, origin = table[item.name], (*path, item.name)
        elif item.in_defaults and item.name in defaults:
            value, origin = defaults[item.name], (*defaults_path, item.name)
        elif item.required:
            if item.name not in meant:  # a misspelt key already says so
                example = f"e.g. {item.name} = {item.example}" if item.example else ""
                problems.add((*path, item.name), "missing", example)
            result.failed.add(item.name)
            continue
        else:
            result.values[item.name] = item.default
            continue
        result.origin[item.name] = origin
        try:
            result.values[item.name] = item.convert(value)
        except FieldError as error:
            problems.add(origin, error.message, error.hint)
            result.failed.add(item.name)
    return result


# -- the sequence file ---------------------------------------------------------------------------

#: How a sweep step measures its run.
PLANS = ("full", "adaptive")
FULL_ONLY = 'required (or in `[defaults]`); for plan = "adaptive" an optional bound'
ADAPTIVE_ONLY = 'required for plan = "adaptive" (or in `[defaults]`)'

def _sweep_fields() -> tuple[Field, ...]:
    number = "number"
    return (
        Field("run", "name", "Name of the run in the campaign file; unique in the sequence.",
              pattern=layout.NAME, rule=f"a run name ({layout.NAME_RULE})", example='"soft-0"'),
        Field("specimen", "text", 'What is mounted, free text; "none" for the bare table.',
              example='"soft"', in_defaults=True),
        Field("hardness_shore_a", number, "Hardness of the specimens (not for the bare table).",
              default=math.nan, unit="Shore A", low=0.0, high=100.0, example="25.0",
              in_defaults=True),
        Field("preload_strain", number, "Static normal strain of the specimens: 0 without "
              "preload, 0.104 for the paper's 10 % (not for the bare table).", default=0.0,
              low=0.0, high=0.5, example="0.104", in_defaults=True),
        Field("temperature_c", number, "Room temperature, recorded with the run.",
              default=math.nan, unit="°C", low=-40.0, high=150.0, example="25.0",
              in_defaults=True),
        Field("band_hz", "band", "First and last frequency; always low to high (the "
              "direction says which end comes first).", example="[20.0, 120.0]",
              in_defaults=True),
        Field("resolution_hz", number, "Frequency step; the band must be a whole number of "
              "steps. For an adaptive plan, the spacing of the frequencies it may choose.",
              default=None, default_note=FULL_ONLY, unit="Hz", low=MIN_RESOLUTION_HZ,
              high=1000.0, example="0.25", in_defaults=True),
        Field("settle_cycles", "integer", "Periods the analyser waits at each frequency before "
              "measuring. For an adaptive plan, the most any point may wait (the plan settles "
              "each point for the damping it identifies).", default=None,
              default_note=FULL_ONLY, low=0, high=100_000, example="100", in_defaults=True),
        Field("integrate_cycles", "integer", "Periods the analyser integrates over at each "
              "frequency. For an adaptive plan, the most any point may integrate.",
              default=None, default_note=FULL_ONLY, low=1, high=100_000, example="100",
              in_defaults=True),
        Field("level", "level", "Reference acceleration held at every point: the disc's on a "
              "specimen run, the table's on a bare-table run. Always written with its unit.",
              example='"1.4 m/s^2"', in_defaults=True),
        Field("tolerance_db", number, "Auto-level tolerance around the level; points outside "
              "it are flagged.", default=1.0, unit="dB", low=0.1, high=20.0, example="1.0",
              in_defaults=True),
        Field("direction", "choice", "Sweep upwards or downwards through the band.",
              default="up", choices=layout.DIRECTIONS, example='"down"', in_defaults=True),
        Field("segment_s", number, "Longest test time between two commits to the campaign "
              "file.", default=segments.DEFAULT_SEGMENT_S, unit="s", low=1.0, high=3600.0,
              example="60", in_defaults=True),
        Field("segment_points", "integer", "Most points per commit (one analyser sweep holds "
              "at most 801).", default=segments.ANALYSER_MAX_POINTS, low=1,
              high=segments.ANALYSER_MAX_POINTS, example="401", in_defaults=True),
        Field("plan", "choice", '"full": every frequency of the band at the resolution, the '
              'same settle and integration at each. "adaptive": a first look, then the '
              "frequencies, settle and integration that teach the model's parameters most per "
              "second of rig time, until every target_uncertainty is met (or dwell_limit_s).",
              default="full", choices=PLANS, example='"adaptive"', in_defaults=True),
        Field("model", "text", "Model spec the adaptive plan fits and chooses points for "
              '(`voigt`, `maxwell(2)`, `fractional+load_cell`; `table` on the bare table).',
              default=None, default_note=ADAPTIVE_ONLY, example='"voigt"', in_defaults=True),
        Field("target_uncertainty", "targets", "Relative standard uncertainty wanted for each "
              "named parameter of the model; the plan stops when every one is met.",
              default=None, default_note=ADAPTIVE_ONLY, low=TARGET_FLOOR, high=1.0,
              example="{ K_v = 1e-3, C_v = 2e-3 }", in_defaults=True),
        Field("dwell_limit_s", number, "Rig time an adaptive plan may use at most, first look "
              "included.", default=None, unit="s", low=0.0, low_open=True, high=LONGEST_S,
              example="1800", in_defaults=True),
        Field("over_limit", "choice", "A run whose predicted shaker force exceeds the limit: "
              '"refuse" it, or "reduce" its level to 90 % of what the limit allows '
              "(`viscorig run --over-limit` overrides it).", default="refuse",
              choices=("refuse", "reduce"), example='"reduce"', in_defaults=True),
    )


PROMPT = TableSchema("prompt", "Show an instruction to the operator and wait for Enter.", (
    Field("message", "text", "The instruction (mount, preload, check...).",
          example='"Mount the SOFT specimens, no preload. Press Enter."'),
    Field("simulated_rig", "name", "On the embedded simulated rig, the rig preset "
          "(`sim/rigs/NAME.toml`) mounted at this prompt; ignored on a real rig. A sweep of a "
          "specimen needs a prompt naming a preset with that specimen before it.",
          default=None, pattern=PRESET_NAME, rule="a rig preset name (table, soft-0, ...)",
          example='"soft-0"'),
))
WAIT = TableSchema("wait", "Wait a fixed time (thermal settling after mounting, for example); "
                   "not waited on the simulated rig, whose clock is test time.", (
    Field("seconds", "number", "How long.", unit="s", low=0.0, high=LONGEST_S, low_open=True,
          example="600"),
    Field("message", "text", "Shown while waiting.", default="Waiting",
          example='"Let the rubber reach room temperature."'),
))
SWEEP = TableSchema("sweep", "Measure one run: a stepped-sine sweep at constant reference "
                    "acceleration, committed to the campaign file segment by segment.",
                    _sweep_fields())
IDENTIFY_TABLE = TableSchema("identify_table", "Identify the table's M_s, K_s, C_s from an "
                             "earlier bare-table run and store the fit in the file.", (
    Field("run", "name", "An earlier sweep with specimen \"none\".", pattern=layout.NAME,
          rule=f"a run name ({layout.NAME_RULE})", example='"table"'),
    Field("band_hz", "band", "Fit only this band (within the run's).", default=None,
          example="[15.0, 25.0]"),
))

#: The coldest and hottest set point any chamber step may name (the station's limits narrow it).
MIN_SET_POINT_C = -100.0
MAX_SET_POINT_C = 300.0


def _soak_fields() -> tuple[Field, ...]:
    return (
        Field("ramp_c_per_min", "number", "Rate at which the controller moves its set point "
              "(its set-point rate limit); 0 jumps to the set point.", default=0.0,
              unit="°C/min", low=0.0, high=100.0, example="2.0"),
        Field("soak_band_k", "number", "The specimen is soaked when its thermocouple stays "
              "within ± this of the set point; later points outside the band are flagged "
              "(flag 16).", default=1.0, unit="K", low=0.0, low_open=True, high=20.0,
              example="0.5"),
        Field("soak_minutes", "number", "How long the specimen must stay within the band "
              "before the next step.", default=10.0, unit="min", low=0.0, high=1440.0,
              example="10"),
        Field("time_limit_minutes", "number", "The chamber fault is declared (exit 3, the "
              "chamber set to the station's safe set point) when the soak is not done by "
              "then.", default=240.0, unit="min", low=0.0, low_open=True, high=10_080.0,
              example="120"),
    )


TEMPERATURE = TableSchema("temperature", "Bring the specimens to a temperature: write the "
                          "chamber's set point (within the station's limits), ramp, and wait "
                          "until the specimen's own thermocouple has stayed in the soak band "
                          "for the soak time.", (
    Field("set_point_c", "number", "The temperature wanted at the specimen.", unit="°C",
          low=MIN_SET_POINT_C, high=MAX_SET_POINT_C, example="-20.0"),
    *_soak_fields(),
))
REPEAT = TableSchema("repeat", "Repeat the steps of its own `[[steps.steps]]` list for each "
                     "temperature of `temperatures_c` (a temperature step before each round, "
                     "with this table's ramp and soak) and/or each level of `levels` (the "
                     "sweeps' level). In the inner steps' text, `{temperature_c}` and "
                     "`{level_index}` (1, 2, ...) are replaced, so each run gets its own name; "
                     "each sweep records the round's set point as its `temperature_c`. With "
                     "both lists, levels repeat inside each temperature.", (
    Field("temperatures_c", "numbers", "Set points, in the order measured.", default=None,
          unit="°C", low=MIN_SET_POINT_C, high=MAX_SET_POINT_C,
          example="[-20.0, 0.0, 25.0, 50.0]"),
    Field("levels", "levels", "Reference levels of the sweeps (strain amplitudes), in the "
          "order measured.", default=None, example='["0.5 m/s^2", "2 m/s^2", "6 m/s^2"]'),
    *_soak_fields(),
))

#: Every step type, by the ``type`` that names it.
STEP_TYPES: dict[str, TableSchema] = {
    schema.name: schema for schema in (PROMPT, WAIT, SWEEP, IDENTIFY_TABLE, TEMPERATURE, REPEAT)
}

SEQUENCE = TableSchema("sequence", "The top level of a sequence file.", (
    Field("name", "text", "Name of the sequence.", default="sequence", example='"paper"'),
    Field("description", "text", "One line on what it measures.", default="",
          example='"Soft, medium and hard rubber at 0 and 10 % preload."'),
))

#: The fields ``[defaults]`` may set: any sweep field but ``run``.
DEFAULTS = TableSchema("defaults", "Values every sweep step takes unless it gives its own.",
                       tuple(item for item in SWEEP.fields if item.in_defaults))


# -- the station file ----------------------------------------------------------------------------

def _sensitivity(name: str, unit: str, what: str, example: str) -> Field:
    return Field(name, "number", what, unit=unit, low=1e-6, high=10.0, example=example)


STATION_TOP = TableSchema("station", "The analyser.", (
    Field("resource", "name", "VISA resource of the 35670A.", pattern=VISA_RESOURCE,
          rule='a VISA resource like "GPIB0::11::INSTR"', example='"GPIB0::11::INSTR"'),
    Field("adapter", "name", "A Prologix adapter to open first (ends with ::INTFC).",
          default=None, pattern=VISA_RESOURCE, rule='a VISA resource like '
          '"PRLGX-ASRL::/dev/ttyUSB0::INTFC"', example='"PRLGX-ASRL::/dev/ttyUSB0::INTFC"'),
))
STATION_SECTIONS: tuple[TableSchema, ...] = (
    TableSchema("channels", "Analyser input (1-4) of each transducer; REF PAIR takes input 1 "
                "as reference of 2 and 3 of 4.", tuple(
        Field(name, "integer", what, low=1, high=4, example=str(number))
        for number, (name, what) in enumerate((
            ("excitation_force", "F_e, force transducer between shaker and table."),
            ("table_acceleration", "Table accelerometer."),
            ("device_force", "F_v, load cell between table and disc."),
            ("device_acceleration", "Disc accelerometer (the auto-level reference)."),
        ), start=1)
    )),
    TableSchema("sensitivity", "Transducer sensitivities, from their calibration sheets.", (
        _sensitivity("excitation_force_v_per_n", "V/N", "F_e transducer.", "0.01124"),
        _sensitivity("table_acceleration_v_per_m_s2", "V/(m/s^2)", "Table accelerometer.",
                     "0.0102"),
        _sensitivity("device_force_v_per_n", "V/N", "F_v load cell.", "0.01124"),
        _sensitivity("device_acceleration_v_per_m_s2", "V/(m/s^2)", "Disc accelerometer.",
                     "0.0102"),
    )),
    TableSchema("shaker", "The shaker and its amplifier.", (
        Field("force_limit_n", "number", "Peak force the shaker may give.", unit="N", low=0.0,
              high=1e5, low_open=True, example="100.0"),
        Field("gain_n_per_v", "number", "Force per source volt, if known: the source limit is "
              "then capped at force_limit_n / gain_n_per_v. Adaptive plans measure it before "
              "each run and check this value against it.", default=None, unit="N/V",
              low=0.0, high=1e6, low_open=True, example="50.0"),
    )),
    TableSchema("source", "The analyser's source.", (
        Field("limit_v", "number", "Source limit, V peak.", unit="V", low=0.0, high=5.0,
              low_open=True, example="2.0"),
        Field("slew_v_per_s", "number", "Ramp rate of the source (SOUR:VOLT:SLEW) at the start "
              "and end of each sweep, and so when a pause, hold or abort stops it; 0 stops it "
              "at once.", default=1.0, unit="V/s", low=0.0, high=10000.0, example="1.0"),
    )),
    TableSchema("table", "Optional: the table's known suspension, used when a campaign has no "
                "bare-table run of its own.", (
        Field("mass_kg", "number", "M_s.", unit="kg", low=0.0, high=1e4, low_open=True,
              example="3.4"),
        Field("stiffness_n_per_m", "number", "K_s.", unit="N/m", low=0.0, high=1e10,
              low_open=True, example="50194.0"),
        Field("damping_ns_per_m", "number", "C_s.", unit="N s/m", low=0.0, high=1e7,
              example="5.05"),
    ), required=False),
    TableSchema("chamber", "Optional: the temperature chamber's controller (a Eurotherm "
                "3200-class controller over Modbus RTU or TCP); needed by temperature steps.", (
        Field("address", "text", "Modbus TCP `tcp://HOST:PORT` or the serial port of the RTU "
              "line.", example='"/dev/ttyUSB0"'),
        Field("unit", "integer", "Modbus unit address of the controller.", default=1, low=1,
              high=247, example="1"),
        Field("specimen_unit", "integer", "Unit address of a second 3200 whose thermocouple is "
              "on the specimens; without it the chamber's own thermocouple stands for them.",
              default=None, low=1, high=247, example="2"),
        Field("baudrate", "integer", "RTU line speed (8 data bits, no parity, 1 stop bit).",
              default=19200, low=1200, high=115200, example="19200"),
        Field("decimals", "integer", "Decimal places the controllers are configured for (their "
              "values are integers scaled by them): 1 is 0.1 °C, 2 is 0.01 °C.", default=1,
              low=0, high=2, example="2"),
        Field("low_limit_c", "number", "No set point below this is ever written.",
              unit="°C", low=MIN_SET_POINT_C, high=MAX_SET_POINT_C, example="-40.0"),
        Field("high_limit_c", "number", "No set point above this is ever written.",
              unit="°C", low=MIN_SET_POINT_C, high=MAX_SET_POINT_C, example="90.0"),
        Field("safe_set_point_c", "number", "Where the chamber is left when a sequence ends, "
              "is interrupted or fails.", unit="°C", low=MIN_SET_POINT_C, high=MAX_SET_POINT_C,
              example="25.0"),
        Field("specimen_time_constant_s", "number", "How slowly the specimens follow the air "
              "(first-order lag), for `viscorig plan`'s soak times.", default=600.0, unit="s",
              low=0.0, high=LONGEST_S, example="600"),
        Field("heating_rate_k_per_min", "number", "How fast the chamber's air can heat, for "
              "`viscorig plan`'s soak times (not set: as fast as the ramp asks).", default=None,
              unit="K/min", low=0.0, low_open=True, high=1000.0, example="5.0"),
        Field("cooling_rate_k_per_min", "number", "How fast the chamber's air can cool (as "
              "heating_rate_k_per_min).", default=None, unit="K/min", low=0.0, low_open=True,
              high=1000.0, example="3.0"),
    ), required=False),
    TableSchema("specimen", "Optional: specimen geometry, for E' = Re(K*)/θ in reports.", (
        Field("diameter_m", "number", "Cylinder diameter.", unit="m", low=0.0, high=1.0,
              low_open=True, example="0.02"),
        Field("height_m", "number", "Cylinder height.", unit="m", low=0.0, high=1.0,
              low_open=True, example="0.012"),
        Field("count", "integer", "How many cylinders.", low=1, high=16, example="2"),
        Field("geometry_factor_m", "number", "θ, if set explicitly; otherwise computed from "
              "the arrangement.", default=None, unit="m", low=0.0, high=100.0, low_open=True,
              example="0.0131"),
    ), required=False),
    TableSchema("bench", "Optional: the bench page (viscorig bench serve) and its automatic "
                "holds.", (
        Field("address", "text", "Interface the bench page is served on; anything but "
              "127.0.0.1 lets other machines reach it (with the token).", default="127.0.0.1",
              example='"127.0.0.1"'),
        Field("hold_resume", "choice", "After an automatic hold clears: resume by itself "
              '("auto") or wait for the technician.', default="technician",
              choices=("auto", "technician"), example='"technician"'),
        Field("hold_level_points", "integer", "Hold when the level is not held for this many "
              "points in a row.", default=5, low=1, high=10000, example="5"),
        Field("hold_overload_points", "integer", "Hold when an input overloads on this many "
              "points in a row.", default=3, low=1, high=10000, example="3"),
        Field("hold_force_fraction", "number", "Hold when the force reaches this fraction of "
              "the shaker's limit.", default=0.97, low=0.0, high=1.0, low_open=True,
              example="0.97"),
        Field("hold_temperature_points", "integer", "With a chamber: hold when the specimen "
              "is outside its soak band on this many points in a row.", default=3, low=1,
              high=10000, example="3"),
        Field("hold_retry_s", "number", "With hold_resume = \"auto\": wait this long before "
              "trying again after a level, overload or force hold.", default=60.0, unit="s",
              low=0.0, high=LONGEST_S, example="60.0"),
    ), required=False),
)
