"""``repeat`` steps: a list of steps measured once per temperature and/or per level, written once.

A repeat step is unrolled before the steps are read, into the steps it stands for, each keeping
the path of the table it was written in (so a problem is reported once, at its line)::

    [[steps]]
    type = "repeat"
    temperatures_c = [-20.0, 0.0, 25.0]
    ramp_c_per_min = 2.0
    soak_band_k = 0.5
    soak_minutes = 10

      [[steps.steps]]
      type = "sweep"
      run = "medium_T{temperature_c}"

becomes a ``temperature`` step (set point -20, the repeat's ramp and soak) and the sweep
``medium_T-20`` with ``temperature_c = -20``, then the same at 0 and 25 °C. With ``levels``,
each round's sweeps take the round's level, and ``{level_index}`` (1, 2, ...) names them.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

from viscorig.sequences.problems import Path, Problems
from viscorig.sequences.schema import REPEAT, kind_name, read_table

__all__ = ["PLACEHOLDERS", "expand"]

#: What the inner steps' text may name.
PLACEHOLDERS = ("{temperature_c}", "{level_index}")
_SOAK = ("ramp_c_per_min", "soak_band_k", "soak_minutes", "time_limit_minutes")


def expand(problems: Problems, raw_steps: list[Any]) -> list[tuple[Path, Any]]:
    """The steps of a sequence with every repeat unrolled: (path written at, table)."""
    entries: list[tuple[Path, Any]] = []
    for index, raw in enumerate(raw_steps):
        path: Path = ("steps", index)
        if isinstance(raw, Mapping) and raw.get("type") == "repeat":
            entries += _unroll(problems, path, raw)
        else:
            entries.append((path, raw))
    return entries


def _unroll(problems: Problems, path: Path, raw: Mapping[str, Any]) -> list[tuple[Path, Any]]:
    fields = read_table(problems, path, raw, REPEAT, also_known=("type", "steps"))
    inner = raw.get("steps")
    if not isinstance(inner, list) or not inner:
        problems.add((*path, "steps"), "expected a non-empty array of tables ([[steps.steps]])",
                     "write the steps to repeat under [[steps.steps]]")
        return []
    temperatures = fields.values.get("temperatures_c")
    levels = fields.values.get("levels")
    if not fields.ok:
        return []
    if temperatures is None and levels is None:
        problems.add(path, "repeats nothing", "give temperatures_c, levels, or both")
        return []
    for number, step in enumerate(inner):
        where = (*path, "steps", number)
        if not isinstance(step, Mapping):
            problems.add(where, f"expected a table, got {kind_name(step)}")
            return []
        if step.get("type") in ("repeat", "temperature"):
            problems.add((*where, "type"), f"a {step.get('type')} step cannot be repeated "
                         "inside a repeat", "the repeat's temperatures_c sets the temperature")
            return []
        if step.get("type") == "sweep":
            for key, given in (("temperature_c", temperatures), ("level", levels)):
                if given is not None and key in step:
                    problems.add((*where, key), "set by the repeat for each round",
                                 f"remove {key} from this step")
                    return []
    soak = {key: fields.values[key] for key in _SOAK}
    entries: list[tuple[Path, Any]] = []
    for temperature in temperatures if temperatures is not None else (None,):
        if temperature is not None:
            entries.append(((*path, "temperatures_c"),
                            {"type": "temperature", "set_point_c": temperature, **soak}))
        for number, level in enumerate(levels if levels is not None else (None,), start=1):
            for step_number, step in enumerate(inner):
                entries.append(((*path, "steps", step_number),
                                _round(step, temperature, number if level else None, level)))
    return entries


def _round(step: Mapping[str, Any], temperature: float | None, level_index: int | None,
           level: tuple[float, str] | None) -> dict[str, Any]:
    """One inner step as a round measures it."""
    values = {"{temperature_c}": "" if temperature is None else f"{temperature:g}",
              "{level_index}": "" if level_index is None else str(level_index)}

    def fill(value: Any) -> Any:
        if isinstance(value, str):
            for placeholder, text in values.items():
                value = value.replace(placeholder, text)
        return value

    table = {key: fill(value) for key, value in step.items()}
    if table.get("type") == "sweep":
        if temperature is not None:
            table["temperature_c"] = temperature
        if level is not None:
            table["level"] = level[1]
    return table
