"""Reading a sequence file (TOML): defaults at the top, a list of steps, each validated.

::

    name = "paper"
    description = "..."

    [defaults]                 # any sweep field but run; a step's own value wins
    band_hz = [20.0, 120.0]
    level = "1.4 m/s^2"

    [[steps]]
    type = "prompt"            # prompt | wait | sweep | identify_table | temperature | repeat
    message = "Mount the soft specimens, no preload."
    simulated_rig = "soft-0"

    [[steps]]
    type = "sweep"
    run = "soft-0"
    specimen = "soft"

The fields are those of :mod:`viscorig.sequences.schema` (``sequences/README.md`` lists
them). Every problem of a file is found in one reading and reported together
(:class:`~viscorig.sequences.problems.FileCheckError`), each as ``paper.toml:57:
steps[3].level: ...`` (steps count from 0), with a did-you-mean for a misspelt name.
"""

from __future__ import annotations

import math
import tomllib
from collections.abc import Mapping
from pathlib import Path
from typing import Any

from viscorig.errors import InputError
from viscorig.sequences import schema, segments
from viscorig.sequences.problems import Problems, did_you_mean, field_name, quoted
from viscorig.sequences.repeat import expand
from viscorig.sequences.schema import (
    DEFAULTS,
    SEQUENCE,
    STEP_TYPES,
    SWEEP,
    FieldError,
    ReadTable,
    read_table,
)
from viscorig.sequences.steps import (
    IdentifyTableStep,
    PromptStep,
    Sequence,
    Step,
    SweepStep,
    TemperatureStep,
    WaitStep,
)
from viscorig.storage import layout

#: Kept for callers that name them here.
PRESET_NAME = schema.PRESET_NAME
MAX_FREQUENCY_HZ = schema.MAX_FREQUENCY_HZ
MIN_RESOLUTION_HZ = schema.MIN_RESOLUTION_HZ
SWEEP_FIELDS = SWEEP.names
#: A sanity limit on one run: the campaign file's (100 000 points, over a day of dwell).
MAX_RUN_POINTS = layout.MAX_RUN_POINTS


#: Largest sequence or station file, bytes (the paper's sequence is under 4 kB).
MAX_FILE_BYTES = 1 << 20


def read_text(path: str | Path) -> str:
    """A file's text.

    Raises
    ------
    InputError
        The file is missing, unreadable, larger than :data:`MAX_FILE_BYTES` or not UTF-8.
    """
    try:
        with Path(path).open("rb") as handle:
            data = handle.read(MAX_FILE_BYTES + 1)
        if len(data) > MAX_FILE_BYTES:
            raise InputError(f"over {MAX_FILE_BYTES} bytes; a sequence or station file is "
                             "text of a few kilobytes", str(path))
        # as text mode reads it: Windows and classic Mac line ends become "\n"
        return data.decode("utf-8").replace("\r\n", "\n").replace("\r", "\n")
    except FileNotFoundError:
        raise InputError("no such file", str(path)) from None
    except IsADirectoryError:
        raise InputError("not a file", str(path)) from None
    except UnicodeDecodeError as error:
        raise InputError(f"not UTF-8 text (byte 0x{error.object[error.start]:02x} at offset "
                         f"{error.start})", str(path)) from None
    except OSError as error:
        raise InputError(f"cannot be read ({error.strerror or error})", str(path)) from None


def load_sequence(path: str | Path) -> Sequence:
    """Read and validate a sequence file.

    Raises
    ------
    InputError
        The file is missing or unreadable, or not TOML.
    FileCheckError
        Fields are wrong: every one of them, with file and line.
    """
    return parse_sequence(read_text(path), source=str(path))


#: Keys only a station file has at its top: a file with one of them and no steps, given as a
#: sequence, is a station file in the sequence's place.
STATION_MARKS = ("resource", "adapter", "channels", "sensitivity")


def parse_toml(text: str, source: str) -> dict[str, Any]:
    """TOML text as a dict; syntax errors become InputErrors naming the file and line. A
    byte-order mark before the text (Windows Notepad saves UTF-8 with one) is no part of it."""
    if not isinstance(text, str):
        raise InputError("expected TOML text", source)
    try:
        return tomllib.loads(text.removeprefix("\ufeff"))
    except tomllib.TOMLDecodeError as error:
        raise InputError(f"not valid TOML: {error}", source) from None
    except RecursionError:  # tomllib's parser recurses once per level of nesting
        raise InputError("arrays or tables nested too deeply to read", source) from None


def parse_sequence(text: str, source: str = "sequence") -> Sequence:
    """Validate a sequence given as TOML text; ``source`` names it in messages.

    Raises
    ------
    InputError
        Not TOML.
    FileCheckError
        Every problem of the file.
    """
    document = parse_toml(text, source)
    if "steps" not in document and any(key in document for key in STATION_MARKS):
        raise InputError("a station file (resource, [channels], [sensitivity]), not a test "
                         "sequence: give a sequence first and this file with --station "
                         "(viscorig run SEQUENCE.toml --station STATION.toml)", source)
    problems = Problems(source, text)
    top = read_table(problems, (), document, SEQUENCE, also_known=("defaults", "steps"))
    defaults = document.get("defaults", {})
    if not isinstance(defaults, Mapping):
        problems.add(("defaults",), f"expected a table ([defaults]), got "
                     f"{schema.kind_name(defaults)}")
        defaults = {}
    _check_defaults(problems, defaults)
    raw_steps = document.get("steps")
    if not isinstance(raw_steps, list) or not raw_steps:
        problems.add(("steps",), "expected a non-empty array of tables ([[steps]])",
                     "add a [[steps]] table with type = \"sweep\" (see sequences/README.md)")
        raw_steps = []

    steps: list[Step | _Unread | None] = []
    run_steps: dict[str, str] = {}
    for path, raw in expand(problems, raw_steps):
        step = _parse_step(problems, path, raw, defaults, steps)
        if step is None and isinstance(raw, Mapping) and raw.get("type") == "sweep":
            steps.append(_Unread(raw.get("run")))  # no second problem about its run
            continue
        if isinstance(step, SweepStep):
            if step.run in run_steps:
                problems.add((*path, "run"), f"duplicate run name {quoted(step.run)} (also "
                             f"{run_steps[step.run]})")
            run_steps.setdefault(step.run, field_name(path))
        steps.append(step)
    problems.raise_if_any()
    return Sequence(name=top["name"], description=top["description"],
                    steps=tuple(steps), source=source)  # type: ignore[arg-type]


class _Unread:
    """A sweep step with problems, standing in for it while the later steps are read."""

    def __init__(self, run: object) -> None:
        self.run = run


def _check_defaults(problems: Problems, defaults: Mapping[str, Any]) -> None:
    """Unknown keys of ``[defaults]``, and each default's value, reported once here."""
    for key, value in defaults.items():
        if key in DEFAULTS.names:
            try:
                DEFAULTS.field(key).convert(value)
            except FieldError as error:
                problems.add(("defaults", key), error.message, error.hint)
            continue
        hint = did_you_mean(key, DEFAULTS.names)
        if not hint:
            hint = ("the run is named in each sweep step" if key == "run"
                    else f"allowed: {', '.join(DEFAULTS.names)}")
        problems.add(("defaults", key), "unknown default", hint)


def _parse_step(problems: Problems, path: tuple, raw: object, defaults: Mapping[str, Any],
                before: list[Step | _Unread | None]) -> Step | None:
    if not isinstance(raw, Mapping):
        problems.add(path, f"expected a table, got {schema.kind_name(raw)}")
        return None
    kind = raw.get("type")
    if not isinstance(kind, str) or kind not in STEP_TYPES:
        if "type" not in raw:
            problems.add((*path, "type"), "missing",
                         f"one of {', '.join(STEP_TYPES)}, e.g. type = \"sweep\"")
        elif not isinstance(kind, str):
            problems.add((*path, "type"), f"expected text, got {schema.kind_name(kind)}")
        else:
            problems.add((*path, "type"), f"{quoted(kind)} is not one of {', '.join(STEP_TYPES)}",
                         did_you_mean(kind, STEP_TYPES, cutoff=0.5))
        return None
    step_schema = STEP_TYPES[kind]
    if kind == "sweep":
        fields = read_table(problems, path, raw, step_schema, defaults=defaults,
                            defaults_path=("defaults",), also_known=("type",))
        return _sweep(problems, path, fields)
    fields = read_table(problems, path, raw, step_schema, also_known=("type",))
    if kind == "identify_table":
        return _identify_table(problems, path, fields, before)
    if not fields.ok:
        return None
    if kind == "prompt":
        return PromptStep(message=fields["message"], simulated_rig=fields["simulated_rig"])
    if kind == "temperature":
        return TemperatureStep(**fields.values, origin=path)
    return WaitStep(seconds=fields["seconds"], message=fields["message"])


def _sweep(problems: Problems, path: tuple, fields: ReadTable) -> SweepStep | None:
    values = fields.values
    if values.get("plan") == "adaptive":
        _adaptive(problems, path, fields)
    else:
        _full(problems, path, fields)
    if "band_hz" in values and values.get("resolution_hz") is not None and values.get(
            "plan") != "adaptive":
        try:
            points = segments.point_count(values["band_hz"], values["resolution_hz"])
        except ValueError as error:
            lo, hi = values["band_hz"]
            problems.add(fields.origin["resolution_hz"], str(error),
                         f"make {hi:g} - {lo:g} a multiple of the resolution")
            fields.failed.add("resolution_hz")
        else:
            if points > MAX_RUN_POINTS:
                problems.add(fields.origin["resolution_hz"], (
                    f"{points} points in one run; at most {MAX_RUN_POINTS} (the analyser's "
                    "801-point limit applies per segment, and runs are split into segments)"))
                fields.failed.add("resolution_hz")
    if values.get("specimen") == "none":
        for key in ("hardness_shore_a", "preload_strain"):
            given = values.get(key)
            if key in fields.origin and given is not None and not (
                    math.isnan(given) if key == "hardness_shore_a" else given == 0.0):
                problems.add(fields.origin[key], "the bare table (specimen \"none\") has none",
                             f"remove {key} from this step")
                fields.failed.add(key)
    if not fields.ok:
        return None
    level, level_text = values["level"]
    return SweepStep(
        run=values["run"], specimen=values["specimen"], band_hz=values["band_hz"],
        resolution_hz=values["resolution_hz"], settle_cycles=values["settle_cycles"],
        integrate_cycles=values["integrate_cycles"], level_m_per_s2=level, level=level_text,
        tolerance_db=values["tolerance_db"], direction=values["direction"],
        hardness_shore_a=values["hardness_shore_a"], preload_strain=values["preload_strain"],
        temperature_c=values["temperature_c"], segment_s=values["segment_s"],
        segment_points=values["segment_points"], over_limit=values["over_limit"],
        plan=values["plan"], model=values["model"],
        target_uncertainty=tuple((values["target_uncertainty"] or {}).items()),
        dwell_limit_s=values["dwell_limit_s"],
    )


#: Fields only an adaptive plan reads.
ADAPTIVE_FIELDS = ("model", "target_uncertainty", "dwell_limit_s")
#: Fields a full plan needs (an adaptive plan takes them as bounds).
GRID_FIELDS = {"resolution_hz": "0.25", "settle_cycles": "100", "integrate_cycles": "100"}


def _full(problems: Problems, path: tuple, fields: ReadTable) -> None:
    """A full plan: the grid and timing are required; the adaptive plan's fields are not its."""
    for name, example in GRID_FIELDS.items():
        if fields.values.get(name) is None and name not in fields.failed:
            problems.add((*path, name), "missing",
                         f'e.g. {name} = {example}, or plan = "adaptive" to let a plan choose')
            fields.failed.add(name)
    for name in ADAPTIVE_FIELDS:
        if name in fields.origin and fields.origin[name][0] != "defaults":
            problems.add(fields.origin[name], 'only for plan = "adaptive"',
                         f'add plan = "adaptive", or remove {name}')
            fields.failed.add(name)


def _adaptive(problems: Problems, path: tuple, fields: ReadTable) -> None:
    """An adaptive plan: a model that parses, targets that are parameters it fits."""
    # keeps the command's start fast: the models load scipy
    from viscorig.models import parse_spec

    values = fields.values
    for name, example in (("model", '"voigt"'),
                          ("target_uncertainty", "{ K_v = 1e-3, C_v = 2e-3 }")):
        if values.get(name) is None and name not in fields.failed:
            problems.add((*path, name), 'missing for plan = "adaptive"', f"e.g. {name} = "
                         f"{example}")
            fields.failed.add(name)
    spec = values.get("model")
    if spec is None or "model" in fields.failed:
        return
    try:
        model = parse_spec(spec)
    except InputError as error:
        problems.add(fields.origin["model"], error.detail)
        fields.failed.add("model")
        return
    bare = values.get("specimen") == "none"
    has_disc = model.modulus_term is not None and model.modulus_term.has_disc
    if bare and has_disc:
        problems.add(fields.origin["model"], f"'{model.spec}' is a model of a specimen; the "
                     "bare table (specimen \"none\") needs 'table'", "model = \"table\"")
        fields.failed.add("model")
        return
    if not bare and not has_disc:
        problems.add(fields.origin["model"], f"'{model.spec}' is a model of the bare table; a "
                     "specimen run needs a specimen model", "e.g. model = \"voigt\"")
        fields.failed.add("model")
        return
    targets = values.get("target_uncertainty")
    if not targets or "target_uncertainty" in fields.failed:
        return
    candidates = model.candidates() if model.is_open else [model]
    names = {name for candidate in candidates for name in candidate.names}
    if not bare:
        names -= {"M_s", "K_s", "C_s"}  # the table's, inherited from the bare-table run
    for name in targets:
        if name not in names:
            hint = did_you_mean(name, sorted(names)) or (
                f"'{model.spec}' fits: {', '.join(sorted(names))}")
            problems.add(fields.origin["target_uncertainty"], f"{quoted(name)} is not a parameter "
                         f"'{model.spec}' fits", hint)
            fields.failed.add("target_uncertainty")


def _identify_table(problems: Problems, path: tuple, fields: ReadTable,
                    before: list[Step | _Unread | None]) -> IdentifyTableStep | None:
    if "run" not in fields.values:
        return None
    run = fields["run"]
    if any(isinstance(step, _Unread) and step.run == run for step in before):
        return None  # its sweep has problems of its own
    sweeps = [step for step in before if isinstance(step, SweepStep)]
    sweep = next((step for step in sweeps if step.run == run), None)
    if sweep is None:
        bare = [step.run for step in sweeps if step.bare_table]
        problems.add((*path, "run"), f"no earlier sweep step measures run {quoted(run)}",
                     did_you_mean(run, bare, cutoff=0.5)
                     or "identify_table follows the bare-table sweep it fits")
        return None
    if not sweep.bare_table:
        problems.add((*path, "run"), f"run {quoted(run)} has specimen "
                     f"{quoted(sweep.specimen)}, not \"none\"")
        return None
    band = fields.values.get("band_hz")
    if band is not None:
        lo, hi = sweep.band_hz
        if band[0] < lo or band[1] > hi:
            problems.add((*path, "band_hz"), f"outside the run's band {lo:g}-{hi:g} Hz")
            return None
    if not fields.ok:
        return None
    return IdentifyTableStep(run=run, band_hz=band)
