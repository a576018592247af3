"""The reference of sequence and station files, generated from :mod:`viscorig.sequences.schema`.

``sequences/README.md`` is this text (a test fails when it drifts); ``viscorig check --fields``
prints it. Regenerate the file with::

    viscorig check --fields > sequences/README.md
"""

from __future__ import annotations

from viscorig.sequences.levels import UNIT_SPELLINGS
from viscorig.sequences.schema import (
    DEFAULTS,
    SEQUENCE,
    STATION_SECTIONS,
    STATION_TOP,
    STEP_TYPES,
    TableSchema,
)

_INTRO = """\
# Test sequences

<!-- Generated from src/viscorig/sequences/schema.py by `viscorig check --fields`; edit the
schema, not this file (a test fails when they differ). -->

A sequence is a TOML file: a name, `[defaults]` for the sweeps, then a list of `[[steps]]` run
in order. The steps are `prompt` (an instruction to the operator), `wait`, `sweep` (one run,
measured and stored), `identify_table`, `temperature` (the chamber to a set point, then a soak)
and `repeat` (steps written once, measured per temperature and per level). Check a sequence
before taking it to the rig:

```
viscorig check my-test.toml                      # every problem at once, with its line
viscorig check my-test.toml --station lab.toml   # the station file too
```

`viscorig run` checks the same before its first prompt and measures nothing while a problem is
left. Each problem names the file, the line and the field, and what was probably meant:

```
my-test.toml:17: steps[1].specimin: unknown key; did you mean 'specimen'?
my-test.toml:18: steps[1].band_hz: [120, 20] Hz is written high to low; write band_hz =
[20, 120] and direction = "down" to sweep downwards
```

In this folder: `paper.toml` (the paper's campaign), `separate-effects.toml` (the runs that tell
amplitude dependence and drift from frequency dependence), `adaptive.toml` (a run measured by an
adaptive plan), `station-example.toml` (a commented station file to copy).

## A small sequence

```toml
name = "soft-check"
description = "Bare table, then the soft specimens without preload."

[defaults]
band_hz = [20.0, 120.0]
resolution_hz = 0.25
settle_cycles = 100
integrate_cycles = 100
level = "1.4 m/s^2"

[[steps]]
type = "prompt"
message = "Remove the damper device: the table must move alone. Press Enter."
simulated_rig = "table"

[[steps]]
type = "sweep"
run = "table"
specimen = "none"
band_hz = [12.0, 28.0]
resolution_hz = 0.125
settle_cycles = 200

[[steps]]
type = "identify_table"
run = "table"

[[steps]]
type = "prompt"
message = "Mount the SOFT specimens (25 Shore A), no preload. Press Enter."
simulated_rig = "soft-0"

[[steps]]
type = "sweep"
run = "soft-0"
specimen = "soft"
hardness_shore_a = 25.0
```

"""

_ADAPTIVE = """\
## Adaptive plans

A sweep step with `plan = "adaptive"` does not measure a fixed grid: it looks at the band (ten
points), fits its `model`, and then measures the frequencies, settle and integration that teach
the parameters named in `target_uncertainty` most per second of rig time, refitting after each
batch, until every target is met, the model turns out not to fit (the band is then covered for
`viscorig diagnose`), or `dwell_limit_s` is reached. `resolution_hz` is the spacing of the
frequencies it may choose, `settle_cycles` and `integrate_cycles` the most any point may use.
A specimen plan needs the table (an `identify_table` step after the bare-table sweep, or a
`[table]` in the station). Each point starts the analyser's level controller at the source
level it needs, the force over the shaker's gain: the gain is measured before the run (force
per source volt at the band's edges, the level controller off) and stored with it; a station's
`gain_n_per_v` is then a check, with a warning when it disagrees.

```toml
[[steps]]
type = "sweep"
run = "soft-0"
specimen = "soft"
plan = "adaptive"
model = "voigt"
target_uncertainty = { K_v = 1e-3, C_v = 2e-3 }   # relative standard uncertainty
dwell_limit_s = 1800
```

`viscorig plan SEQUENCE.toml` prints each step's predicted test time (an adaptive plan's as a
range, with the floor of the rig beside it) before anything is measured.
"""

_LEVELS = f"""\
## Levels

A level is text: a number and its unit, `peak` (the default) or `rms` after it, e.g.
`"1.4 m/s^2"`, `"1.4 m/s2"`, `"1400 mm/s^2"`, `"0.143 g"`, `"1 m/s^2 rms"`. Units:
{", ".join(f"`{unit}`" for unit in UNIT_SPELLINGS)} (also `²` for `^2`, and `cm`). `g` is standard
gravity, 9.80665 m/s². A bare number is refused: the paper's own level is ambiguous by a factor
of a thousand.
"""

_SIMULATED = """\
## On the embedded simulated rig

Without `--station`, `viscorig run` measures a simulated rig. A prompt's `simulated_rig` mounts
a preset (`table`, `soft-0`, `soft-10`, `medium-0`, `medium-10`, `hard-0`, `hard-10`, or any
file in `sim/rigs/`), standing in for the technician. Before anything is measured, every sweep
is matched with the rig mounted at that point: a bare-table run (`specimen = "none"`) needs a
rig without specimens, a specimen run a rig with specimens whose hardness and preload agree
with the step's `hardness_shore_a` and `preload_strain`, and a run of another specimen than the
one before needs a prompt that mounts it. A mismatch is refused with the preset to name.
"""


def _cell(text: str) -> str:
    return text.replace("|", "\\|").replace("\n", " ")


def _table(schema: TableSchema, *, type_row: bool = False) -> str:
    rows = ["| field | type | unit | default | range | example | meaning |",
            "|---|---|---|---|---|---|---|"]
    if type_row:
        rows.append(f'| `type` | text |  | required |  | `"{schema.name}"` | this step type |')
    for item in schema.fields:
        rows.append("| " + " | ".join(_cell(cell) for cell in (
            f"`{item.name}`", item.type_text(), item.unit_text(), item.default_text(),
            item.range_text(), f"`{item.example}`" if item.example else "", item.doc,
        )) + " |")
    return "\n".join(rows) + "\n"


def reference_markdown() -> str:
    """The whole reference, as Markdown."""
    parts = [_INTRO, "## Top level\n\n", _table(SEQUENCE),
             "\n`[defaults]` may set any sweep field but `run`: "
             + ", ".join(f"`{name}`" for name in DEFAULTS.names)
             + ". A step's own value wins.\n\n## Steps\n"]
    for schema in STEP_TYPES.values():
        parts.append(f"\n### `type = \"{schema.name}\"`\n\n{schema.doc}\n\n")
        parts.append(_table(schema, type_row=True))
    parts += ["\n", _ADAPTIVE, "\n", _LEVELS, "\n", _SIMULATED,
              "\n## Station file\n\nWhat is attached to the analyser in your lab "
              "(`viscorig run SEQUENCE --station FILE`; `station-example.toml` is a template). "
              "Top level:\n\n", _table(STATION_TOP)]
    for section in STATION_SECTIONS:
        need = "" if section.required else " (optional)"
        parts.append(f"\n### `[{section.name}]`{need}\n\n{section.doc}\n\n")
        parts.append(_table(section))
    return "".join(parts)
