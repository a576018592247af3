"""Sequence files: steps, defaults, levels with units, and one clear error per problem."""

from __future__ import annotations

import math
import re
from pathlib import Path

import numpy as np
import pytest
from tomlwrite import dumps

from viscorig.errors import InputError
from viscorig.sequences import (
    FileCheckError,
    IdentifyTableStep,
    PromptStep,
    SweepStep,
    WaitStep,
    load_sequence,
    parse_level,
    parse_sequence,
)
from viscorig.sequences.station import parse_station

ROOT = Path(__file__).resolve().parents[1]


def document() -> dict:
    return {
        "name": "lab",
        "defaults": {
            "band_hz": [20.0, 30.0], "resolution_hz": 0.25, "settle_cycles": 10,
            "integrate_cycles": 10, "level": "1.4 m/s^2",
        },
        "steps": [
            {"type": "prompt", "message": "Remove the device.", "simulated_rig": "table"},
            {"type": "sweep", "run": "table", "specimen": "none", "band_hz": [10, 30]},
            {"type": "identify_table", "run": "table", "band_hz": [15.0, 25.0]},
            {"type": "wait", "seconds": 30, "message": "Let the rubber reach room temperature."},
            {"type": "sweep", "run": "soft-0", "specimen": "soft", "hardness_shore_a": 25,
             "preload_strain": 0.104, "level": "0.15 g", "direction": "down"},
        ],
    }


def parse(doc: dict) -> object:
    return parse_sequence(dumps(doc), source="lab.toml")


def test_steps_are_typed_and_defaults_are_overridden() -> None:
    sequence = parse(document())
    prompt, table, identify, wait, soft = sequence.steps
    assert prompt == PromptStep("Remove the device.", "table")
    assert isinstance(table, SweepStep) and table.band_hz == (10.0, 30.0) and table.points == 81
    assert table.bare_table and math.isnan(table.hardness_shore_a)
    assert identify == IdentifyTableStep("table", (15.0, 25.0))
    assert wait == WaitStep(30.0, "Let the rubber reach room temperature.")
    assert soft.band_hz == (20.0, 30.0) and soft.level_m_per_s2 == pytest.approx(1.4709975)
    assert soft.level == "0.15 g" and soft.preload_strain == 0.104
    np.testing.assert_allclose(soft.frequencies_hz()[[0, -1]], [30.0, 20.0])
    assert sequence.run_names == ("table", "soft-0")
    assert sequence.sweep("soft-0") is soft


def test_over_limit_comes_from_the_step_then_the_defaults_then_refuse() -> None:
    assert [step.over_limit for step in parse(document()).sweeps] == ["refuse", "refuse"]
    doc = change(document(), "defaults.over_limit", "reduce")
    change(doc, "steps.1.over_limit", "refuse")
    assert [step.over_limit for step in parse(doc).sweeps] == ["refuse", "reduce"]
    paper = load_sequence(ROOT / "sequences" / "paper.toml")
    assert {step.run: step.over_limit for step in paper.sweeps if step.over_limit != "refuse"} \
        == {"hard-10": "reduce"}


@pytest.mark.parametrize(
    ("text", "expected"),
    [("1.5 m/s^2", 1.5), ("15 mm/s^2", 0.015), ("15 cm/s²", 0.15), ("0.15 g", 1.4709975),
     ("1 m/s^2 rms", math.sqrt(2)), ("2 mg peak", 0.0196133), ("1e1 m/s**2", 10.0)],
)
def test_levels_are_converted_to_peak_si(text: str, expected: float) -> None:
    assert parse_level(text) == pytest.approx(expected)


@pytest.mark.parametrize("text", ["15", "1.5 ft/s^2", "-1 g", "0 m/s^2", "g", "1.5 m/s^2 max"])
def test_levels_without_a_valid_unit_or_value_are_refused(text: str) -> None:
    with pytest.raises(ValueError):
        parse_level(text)


def change(doc: dict, path: str, value: object) -> dict:
    """Set (or delete, with value ...) a field given as 'steps.4.level' or 'defaults.level'."""
    *parents, last = path.split(".")
    target = doc
    for part in parents:
        target = target[int(part)] if isinstance(target, list) else target[part]
    if value is ...:
        del target[last]
    else:
        target[last] = value
    return doc


@pytest.mark.parametrize(
    ("path", "value", "where", "what"),
    [
        ("steps.4.level", 1.4, "steps[4].level", "text with its unit"),
        ("steps.4.level", "1.4", "steps[4].level", "has no unit"),
        ("defaults.level", "14 furlongs", "defaults.level", "not one of"),
        ("steps.4.level", "900 m/s^2", "steps[4].level", "beyond any shaker"),
        ("steps.4.run", "table", "steps[4].run", "duplicate run name 'table' (also steps[1])"),
        ("steps.4.run", "soft/0", "steps[4].run", "letters, digits"),
        ("steps.4.run", "soft-0\n", "steps[4].run", "letters, digits"),  # '$' before a newline
        ("steps.4.colour", "red", "steps[4].colour", "unknown key"),
        ("steps.0.level", "1 g", "steps[0].level", "unknown key"),
        ("steps.4.type", "dance", "steps[4].type", "not one of prompt, wait, sweep"),
        ("steps.4.specimen", ..., "steps[4].specimen", "missing"),
        ("steps.4.hardness_shore_a", 120, "steps[4].hardness_shore_a", "outside [0, 100]"),
        ("steps.4.hardness_shore_a", "25", "steps[4].hardness_shore_a", "expected a number"),
        ("steps.4.preload_strain", -0.1, "steps[4].preload_strain", "outside"),
        ("steps.1.preload_strain", 0.1, "steps[1].preload_strain", "bare table"),
        ("steps.4.temperature_c", math.nan, "steps[4].temperature_c", "outside"),
        ("steps.4.settle_cycles", 10.5, "steps[4].settle_cycles", "whole number"),
        ("steps.4.integrate_cycles", 0, "steps[4].integrate_cycles", "outside [1,"),
        ("steps.4.direction", "sideways", "steps[4].direction", "not one of up, down"),
        ("steps.4.band_hz", [30, 20], "steps[4].band_hz", "high to low; write band_hz = [20, 30]"
         ' and direction = "down"'),
        ("steps.4.band_hz", [20, 20], "steps[4].band_hz", "0.015625 <= low < high"),
        ("steps.4.band_hz", [20], "steps[4].band_hz", "expected [low, high]"),
        ("steps.4.band_hz", [20, 30000], "steps[4].band_hz", "25600"),
        ("defaults.resolution_hz", 0.3, "defaults.resolution_hz", "whole number of"),
        ("steps.4.resolution_hz", 0.001, "steps[4].resolution_hz", "outside"),
        ("steps.4.segment_points", 1601, "steps[4].segment_points", "outside [1, 801]"),
        ("steps.4.tolerance_db", 40.0, "steps[4].tolerance_db", "outside [0.1, 20] dB"),
        ("defaults.over_limit", "ignore", "defaults.over_limit", "'ignore' is not one of refuse,"
         " reduce"),
        ("steps.4.over_limit", True, "steps[4].over_limit", "expected text"),
        ("steps.0.over_limit", "reduce", "steps[0].over_limit", "unknown key"),
        ("steps.2.run", "soft-0", "steps[2].run", "no earlier sweep"),
        ("steps.2.band_hz", [5.0, 25.0], "steps[2].band_hz", "outside the run's band"),
        ("steps.3.seconds", -5, "steps[3].seconds", "outside"),
        ("steps.0.simulated_rig", "../x", "steps[0].simulated_rig", "not a rig preset"),
        ("defaults.run", "x", "defaults.run", "unknown default"),
        ("name", 3, "name", "expected text"),
        ("steps", [], "steps", "non-empty array"),
    ],
)
def test_each_problem_is_one_input_error_naming_file_and_field(
    path: str, value: object, where: str, what: str
) -> None:
    with pytest.raises(InputError) as caught:
        parse(change(document(), path, value))
    message = str(caught.value)
    assert re.match(rf"lab\.toml(:\d+)?: {re.escape(where)}: ", message), message
    assert what in message, message


def test_more_points_than_a_run_may_hold_says_which_limit_applies() -> None:
    doc = change(document(), "steps.4.band_hz", [1.0, 25000.0])
    doc = change(doc, "steps.4.resolution_hz", 0.125)
    with pytest.raises(InputError, match=r"steps\[4\].resolution_hz: .*801-point limit applies"):
        parse(doc)


def test_bad_files_are_input_errors(tmp_path: Path) -> None:
    with pytest.raises(InputError, match=r"absent\.toml: no such file"):
        load_sequence(tmp_path / "absent.toml")
    broken = tmp_path / "broken.toml"
    broken.write_text("[[steps]\ntype = 'prompt'\n")
    with pytest.raises(InputError, match=r"broken.toml: not valid TOML.*line 1"):
        load_sequence(broken)
    binary = tmp_path / "binary.toml"
    binary.write_bytes(b"\xff\xfe\x00")
    with pytest.raises(InputError, match=r"binary.toml: not UTF-8 text \(byte 0xff at offset 0"):
        load_sequence(binary)
    # a file of any size was read whole (a 1 GB one took 2 GB of memory at the bench)
    huge = tmp_path / "huge.toml"
    huge.write_bytes(b"# " + b"x" * (1 << 20) + b"\n")
    with pytest.raises(InputError, match=r"huge.toml: over 1048576 bytes; a sequence or"):
        load_sequence(huge)
    crlf = tmp_path / "crlf.toml"
    paper = ROOT / "sequences" / "paper.toml"
    crlf.write_bytes(paper.read_bytes().replace(b"\n", b"\r\n"))
    assert load_sequence(crlf).run_names == load_sequence(paper).run_names


def test_paper_sequence_reproduces_the_paper_campaign() -> None:
    sequence = load_sequence(ROOT / "sequences" / "paper.toml")
    assert sequence.run_names == (
        "table", "soft-0", "soft-10", "medium-0", "medium-10", "hard-0", "hard-10",
    )
    table, *specimens = sequence.sweeps
    assert table.bare_table and table.band_hz[0] < 19.3 < table.band_hz[1]
    for step in specimens:
        assert (step.band_hz, step.resolution_hz) == ((20.0, 120.0), 0.25)
        assert (step.settle_cycles, step.integrate_cycles) == (100, 100)
        assert step.preload_strain == (0.104 if step.run.endswith("-10") else 0.0)
    presets = [step.simulated_rig for step in sequence.steps if isinstance(step, PromptStep)]
    assert presets == ["table", *[step.run for step in specimens]]
    assert any(isinstance(step, IdentifyTableStep) for step in sequence.steps)


def shaker_force_n(step: SweepStep, frequency_hz: float, stiffness: float, damping: float,
                   device_mass_kg: float) -> float:
    """|F_e| of the rigid-link rig (physics.md) at the step's reference acceleration."""
    omega = 2 * np.pi * frequency_hz
    m_s, k_s, c_s = 3.4, 50194.0, 5.05
    impedance = k_s + stiffness - omega**2 * (m_s + device_mass_kg) + 1j * omega * (c_s + damping)
    return abs(impedance) * step.level_m_per_s2 / omega**2


@pytest.mark.parametrize("device_mass_kg", [0.0, 0.25, 0.73])
def test_paper_level_brings_the_hardest_specimen_close_to_but_below_the_shaker_limit(
    device_mass_kg: float,
) -> None:
    sequence = load_sequence(ROOT / "sequences" / "paper.toml")
    hard = sequence.sweep("hard-10")
    force = shaker_force_n(hard, 20.0, 1_104_445.91, 102.72, device_mass_kg)
    assert 90.0 < force < 100.0
    soft = shaker_force_n(sequence.sweep("soft-0"), 20.0, 149_986.61, 114.59, device_mass_kg)
    assert 10.0 < soft < 15.0


@pytest.mark.parametrize("nested", ["x = " + "[" * 600 + "]" * 600,
                                    "x = " + "{a = " * 600 + "1" + "}" * 600])
def test_toml_nested_past_the_reader_s_depth_is_one_input_error(nested: str) -> None:
    """tomllib recurses once per level: 500 levels ended in a RecursionError traceback from
    check, plan, run and import --station."""
    with pytest.raises(InputError, match=r"deep\.toml: arrays or tables nested too deeply"):
        parse_sequence(nested + "\n", "deep.toml")
    with pytest.raises(InputError, match=r"deep\.toml: arrays or tables nested too deeply"):
        parse_station(nested + "\n", "deep.toml")


@pytest.mark.parametrize(("field", "value", "said"), [
    ("steps.4.specimen", "a\u0000b", "steps[4].specimen: holds the control character U+0000"),
    ("steps.4.specimen", "S" * 100_000, "steps[4].specimen: 100000 characters; at most 4096"),
    ("steps.0.message", "\u001b[2JRemove", "steps[0].message: holds the control character U+001B"),
])
def test_a_text_no_campaign_file_or_terminal_takes_is_refused_by_check(field, value, said):
    """A specimen with a NUL passed the check and crashed the run in h5py; one of 100,000
    characters was measured, then stored where no reader takes it; a prompt's escape sequences
    reached the terminal raw."""
    with pytest.raises(FileCheckError) as caught:
        parse(change(document(), field, value))
    assert said in str(caught.value)
    parse(change(document(), "steps.0.message", "Remove the device.\n\tThen press Enter."))


def test_a_band_below_the_analyser_s_lowest_frequency_is_refused_by_check():
    """[1e-300, 1e-299] Hz passed the check; plan predicted hours with 300 digits and the run
    ended as an instrument fault."""
    with pytest.raises(FileCheckError) as caught:
        parse(change(document(), "defaults.band_hz", [1e-300, 1e-299]))
    assert "defaults.band_hz: [1e-300, 1e-299] Hz must satisfy 0.015625 <= low < high <= " \
        "25600" in str(caught.value)
    assert parse(change(document(), "defaults.band_hz", [0.015625, 2.015625])).sweeps


@pytest.mark.parametrize(("value", "example"), [
    (2.0, '"2 m/s^2"'), (math.nan, '"1.4 m/s^2"'), (-1.0, '"1.4 m/s^2"'),
    (math.inf, '"1.4 m/s^2"')])
def test_a_level_without_its_unit_is_shown_how_to_write_it(value: float, example: str) -> None:
    """'level = nan' was told to write "nan m/s^2", which is refused in its turn."""
    with pytest.raises(ValueError, match=re.escape(f"e.g. {example}, not")):
        parse_level(value)
