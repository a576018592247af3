"""Reading a sequence file (TOML): defaults at the top, a list of steps, each validated.

::

    name = "paper"
    description = "..."

    [defaults]                 # any sweep field; a step's own value wins
    band_hz = [20.0, 120.0]
    level = "1.4 m/s^2"
    over_limit = "refuse"      # or "reduce": a sweep whose predicted force exceeds the shaker
                               # limit (viscorig run --over-limit overrides it)

    [[steps]]
    type = "prompt"            # prompt | wait | sweep | identify_table
    message = "Mount the soft specimens, no preload."
    simulated_rig = "soft-0"

    [[steps]]
    type = "sweep"
    run = "soft-0"
    specimen = "soft 25 Shore A"

Errors name the file and the field, ``paper.toml: steps[3].level: ...`` (steps count from 0).
"""

from __future__ import annotations

import math
import re
import tomllib
from collections.abc import Mapping
from pathlib import Path
from typing import Any

from viscorig.errors import InputError
from viscorig.sequences import segments
from viscorig.sequences.fields import TableReader, kind_name
from viscorig.sequences.levels import parse_level
from viscorig.sequences.steps import (
    OVER_LIMIT_CHOICES,
    IdentifyTableStep,
    PromptStep,
    Sequence,
    Step,
    SweepStep,
    WaitStep,
)
from viscorig.storage import layout

PRESET_NAME = re.compile(r"^[A-Za-z0-9][A-Za-z0-9._-]{0,63}$")

SWEEP_FIELDS = (
    "run", "specimen", "hardness_shore_a", "preload_strain", "temperature_c", "band_hz",
    "resolution_hz", "settle_cycles", "integrate_cycles", "level", "tolerance_db", "direction",
    "segment_s", "segment_points", "over_limit",
)
#: The analyser's highest frequency with four channels, Hz.
MAX_FREQUENCY_HZ = 25_600.0
#: Frequencies are set in steps of 15.625 mHz.
MIN_RESOLUTION_HZ = 0.015625
#: A sanity limit on one run (100 000 points is over a day of dwell at 100+100 cycles).
MAX_RUN_POINTS = 100_000


def load_sequence(path: str | Path) -> Sequence:
    """Read and validate a sequence file.

    Raises
    ------
    InputError
        The file is missing or unreadable, not TOML, or any field is wrong; the message names
        the file and the field.
    """
    path = Path(path)
    try:
        text = path.read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as error:
        raise InputError(f"cannot be read ({type(error).__name__}: {error})", str(path)) from None
    return parse_sequence(text, source=str(path))


def parse_sequence(text: str, source: str = "sequence") -> Sequence:
    """Validate a sequence given as TOML text; ``source`` names it in messages."""
    document = parse_toml(text, source)
    top = TableReader(document, source, top_level=True)
    name = top.text("name", "sequence")
    description = top.raw("description", "")
    if not isinstance(description, str):
        raise top.fail("description", f"expected text, got {kind_name(description)}")
    defaults = top.subtable("defaults", required=False) or {}
    for key in defaults:
        if key not in SWEEP_FIELDS or key == "run":
            allowed = ", ".join(field for field in SWEEP_FIELDS if field != "run")
            raise InputError(f"unknown default (allowed: {allowed})", f"{source}: defaults.{key}")
    raw_steps = top.raw("steps")
    if not isinstance(raw_steps, list) or not raw_steps:
        raise top.fail("steps", "expected a non-empty array of tables ([[steps]])")
    top.finish()

    steps: list[Step] = []
    run_steps: dict[str, int] = {}
    for index, raw in enumerate(raw_steps):
        where = f"{source}: steps[{index}]"
        step = _parse_step(raw, where, defaults, f"{source}: defaults", steps)
        if isinstance(step, SweepStep):
            if step.run in run_steps:
                raise InputError(
                    f"duplicate run name {step.run!r} (also steps[{run_steps[step.run]}])",
                    f"{where}.run",
                )
            run_steps[step.run] = index
        steps.append(step)
    return Sequence(name=name, description=description, steps=tuple(steps), source=source)


def parse_toml(text: str, source: str) -> dict[str, Any]:
    """TOML text as a dict; syntax errors become InputErrors naming the file and line."""
    if not isinstance(text, str):
        raise InputError("expected TOML text", source)
    try:
        return tomllib.loads(text)
    except tomllib.TOMLDecodeError as error:
        raise InputError(f"not valid TOML: {error}", source) from None


def _parse_step(
    raw: object, where: str, defaults: Mapping[str, Any], defaults_where: str, before: list[Step]
) -> Step:
    if not isinstance(raw, Mapping):
        raise InputError(f"expected a table, got {kind_name(raw)}", where)
    kind = TableReader(raw, where).text(
        "type", choices=("prompt", "wait", "sweep", "identify_table")
    )
    if kind == "sweep":
        fields = TableReader(raw, where, defaults, defaults_where)
        fields.used.add("type")
        step: Step = _parse_sweep(fields)
    else:
        fields = TableReader(raw, where)
        fields.used.add("type")
        if kind == "prompt":
            step = _parse_prompt(fields)
        elif kind == "wait":
            step = WaitStep(
                seconds=fields.number("seconds", low=0.0, high=86_400.0, low_open=True, unit="s"),
                message=fields.text("message", "Waiting"),
            )
        else:
            step = _parse_identify_table(fields, before)
    fields.finish()
    return step


def _parse_prompt(fields: TableReader) -> PromptStep:
    preset = fields.raw("simulated_rig", None)
    if preset is not None:
        preset = fields.text("simulated_rig")
        if not PRESET_NAME.match(preset):
            raise fields.fail("simulated_rig", f"{preset!r} is not a rig preset name")
    return PromptStep(message=fields.text("message"), simulated_rig=preset)


def _band(fields: TableReader, key: str) -> tuple[float, float]:
    value = fields.raw(key)
    if (
        not isinstance(value, list)
        or len(value) != 2
        or any(isinstance(item, bool) or not isinstance(item, int | float) for item in value)
    ):
        raise fields.fail(key, f"expected [low, high] in Hz, got {value!r}")
    lo, hi = float(value[0]), float(value[1])
    if not (math.isfinite(lo) and math.isfinite(hi) and 0.0 < lo < hi <= MAX_FREQUENCY_HZ):
        raise fields.fail(key, f"[{lo:g}, {hi:g}] Hz must satisfy 0 < low < high <= 25600")
    return lo, hi


def _parse_sweep(fields: TableReader) -> SweepStep:
    run = fields.text("run")
    if not layout.NAME.match(run):  # run names become HDF5 group names in the campaign file
        raise fields.fail("run", f"{run!r}: use {layout.NAME_RULE}")
    specimen = fields.text("specimen")
    band = _band(fields, "band_hz")
    resolution = fields.number("resolution_hz", low=MIN_RESOLUTION_HZ, high=1000.0, unit="Hz")
    try:
        points = segments.point_count(band, resolution)
    except ValueError as error:
        raise fields.fail("resolution_hz", str(error)) from None
    if points > MAX_RUN_POINTS:
        raise fields.fail(
            "resolution_hz",
            f"{points} points in one run; at most {MAX_RUN_POINTS} (the analyser's 801-point "
            "limit applies per segment, and runs are split into segments)",
        )
    level_text = fields.raw("level")
    try:
        level = parse_level(level_text)
    except ValueError as error:
        raise fields.fail("level", str(error)) from None
    if level > 500.0:
        raise fields.fail("level", f"{level:g} m/s^2 peak is beyond any shaker rig (max 500)")
    hardness = fields.number("hardness_shore_a", math.nan, low=0.0, high=100.0)
    preload = fields.number("preload_strain", 0.0, low=0.0, high=0.5)
    if specimen == "none":
        if not math.isnan(hardness):
            raise fields.fail("hardness_shore_a", "the bare table (specimen \"none\") has none")
        if preload != 0.0:
            raise fields.fail("preload_strain", "the bare table (specimen \"none\") has none")
    segment_points = fields.integer(
        "segment_points", segments.ANALYSER_MAX_POINTS, low=1, high=segments.ANALYSER_MAX_POINTS
    )
    return SweepStep(
        run=run,
        specimen=specimen,
        band_hz=band,
        resolution_hz=resolution,
        settle_cycles=fields.integer("settle_cycles", low=0, high=100_000),
        integrate_cycles=fields.integer("integrate_cycles", low=1, high=100_000),
        level_m_per_s2=level,
        level=level_text,
        tolerance_db=fields.number("tolerance_db", 1.0, low=0.1, high=20.0, unit="dB"),
        direction=fields.text("direction", "up", choices=("up", "down")),
        hardness_shore_a=hardness,
        preload_strain=preload,
        temperature_c=fields.number("temperature_c", math.nan, low=-40.0, high=150.0),
        segment_s=fields.number("segment_s", segments.DEFAULT_SEGMENT_S, low=1.0, high=3600.0,
                                unit="s"),
        segment_points=segment_points,
        over_limit=fields.text("over_limit", "refuse", choices=OVER_LIMIT_CHOICES),
    )


def _parse_identify_table(fields: TableReader, before: list[Step]) -> IdentifyTableStep:
    run = fields.text("run")
    sweep = next((step for step in before if isinstance(step, SweepStep) and step.run == run),
                 None)
    if sweep is None:
        raise fields.fail("run", f"no earlier sweep step measures run {run!r}")
    if not sweep.bare_table:
        raise fields.fail("run", f"run {run!r} has specimen {sweep.specimen!r}, not \"none\"")
    band = None
    if fields.raw("band_hz", None) is not None:
        band = _band(fields, "band_hz")
        lo, hi = sorted(sweep.band_hz)
        if band[0] < lo or band[1] > hi:
            raise fields.fail("band_hz", f"outside the run's band {lo:g}-{hi:g} Hz")
    return IdentifyTableStep(run=run, band_hz=band)
