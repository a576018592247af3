"""The adaptive step in a sequence file (its fields, ``viscorig check``) and ``viscorig plan``:
the test time of each step and the total, known before anything is measured."""

from __future__ import annotations

import json
import math
import re
from pathlib import Path

import pytest

from viscorig.acquisition import probe_test_time_s
from viscorig.cli import main
from viscorig.sequences import FileCheckError, load_sequence, parse_sequence

ROOT = Path(__file__).resolve().parents[1]
ADAPTIVE = ROOT / "sequences" / "adaptive.toml"
PAPER = ROOT / "sequences" / "paper.toml"

STEP = """
name = "t"
[defaults]
band_hz = [20.0, 120.0]
level = "1.4 m/s^2"
[[steps]]
type = "sweep"
run = "soft-0"
specimen = "soft"
{fields}
"""


def problems(text: str) -> list[str]:
    with pytest.raises(FileCheckError) as caught:
        parse_sequence(text, "t.toml")
    return [str(problem) for problem in caught.value.problems]


def test_an_adaptive_step_reads_its_model_targets_and_bounds() -> None:
    step = parse_sequence(STEP.format(fields='plan = "adaptive"\nmodel = "voigt"\n'
                                      "target_uncertainty = { K_v = 1e-3, C_v = 2e-3 }\n"
                                      "dwell_limit_s = 900\nsettle_cycles = 300")).sweeps[0]
    assert step.adaptive and step.model == "voigt"
    assert step.targets == {"K_v": 1e-3, "C_v": 2e-3}
    assert step.dwell_limit_s == 900.0 and step.settle_cycles == 300
    assert step.resolution_hz is None and step.integrate_cycles is None  # bounds: optional


@pytest.mark.parametrize(("fields", "expected"), [
    # a target naming a parameter the model does not fit, with a did-you-mean
    ('plan = "adaptive"\nmodel = "voigt"\ntarget_uncertainty = { K_v = 1e-3, Cv = 2e-3 }',
     r"t.toml:12: steps\[0\].target_uncertainty: 'Cv' is not a parameter 'voigt' fits; did "
     r"you mean 'C_v'\?"),
    # the table's parameters come from the bare-table run: not a specimen plan's targets
    ('plan = "adaptive"\nmodel = "voigt"\ntarget_uncertainty = { K_s = 1e-3 }',
     r"'K_s' is not a parameter 'voigt' fits"),
    ('plan = "adaptive"\nmodel = "voigtt"\ntarget_uncertainty = { K_v = 1e-3 }',
     r"t.toml:11: steps\[0\].model: unknown term 'voigtt'"),
    ('plan = "adaptive"\nmodel = "table"\ntarget_uncertainty = { K_s = 1e-3 }',
     r"model: 'table' is a model of the bare table"),
    ('plan = "adaptive"\nmodel = "voigt"',
     r"target_uncertainty: missing for plan = \"adaptive\"; e.g. target_uncertainty = "),
    ('plan = "adaptive"\ntarget_uncertainty = { K_v = 1e-3 }',
     r"model: missing for plan = \"adaptive\""),
    ('plan = "adaptive"\nmodel = "voigt"\ntarget_uncertainty = { K_v = 2.0 }',
     r"K_v: 2.0 is outside \(1e-09, 1\]"),
    ('plan = "adptive"', r"'adptive' is not one of full, adaptive; did you mean 'adaptive'\?"),
    # a full plan: the grid is required, the adaptive fields are not its own
    ('resolution_hz = 0.25\nsettle_cycles = 10\nintegrate_cycles = 10\n'
     'target_uncertainty = { K_v = 1e-3 }',
     r"target_uncertainty: only for plan = \"adaptive\""),
    ("settle_cycles = 10\nintegrate_cycles = 10",
     r"resolution_hz: missing; e.g. resolution_hz = 0.25, or plan = \"adaptive\""),
])
def test_check_names_each_mistake_of_an_adaptive_step(fields: str, expected: str) -> None:
    found = problems(STEP.format(fields=fields))
    assert any(re.search(expected, line) for line in found), found


def test_a_bare_table_plan_fits_the_table(tmp_path) -> None:
    text = STEP.format(fields='plan = "adaptive"\nmodel = "table"\n'
                       "target_uncertainty = { K_s = 1e-3 }").replace('"soft"', '"none"')
    assert parse_sequence(text).sweeps[0].targets == {"K_s": 1e-3}
    found = problems(text.replace('model = "table"', 'model = "voigt"'))
    assert any("'voigt' is a model of a specimen" in line for line in found), found


def test_the_example_sequence_checks_clean(capsys) -> None:
    assert main(["check", str(ADAPTIVE)]) == 0
    assert "OK" in capsys.readouterr().out


def test_plan_of_the_paper_sequence_is_its_sweeps_and_probes(capsys) -> None:
    """A full plan's time is known exactly: the sum of settle and integration periods, with
    the probe before each newly mounted specimen."""
    assert main(["plan", str(PAPER), "--json"]) == 0
    document = json.loads(capsys.readouterr().out)
    sequence = load_sequence(PAPER)
    probes = sum(probe_test_time_s(step) for step in sequence.sweeps[1:])
    table = sequence.sweeps[0]
    expected = sequence.duration_s() + probes + probe_test_time_s(table)
    assert document["total_low_s"] == pytest.approx(expected)
    assert document["total_high_s"] == pytest.approx(expected)
    assert [step["name"] for step in document["steps"]] == list(sequence.run_names)
    assert all(step["floor_s"] is None for step in document["steps"])


def test_plan_of_an_adaptive_step_gives_its_range_and_the_floor_of_its_rig(tmp_path,
                                                                            capsys) -> None:
    """On the embedded simulated rig the floor is that of the preset the prompt mounts. A Voigt
    plan on the paper's soft rubber (fractional, with load cell and fixture modes) stops once
    the band is covered: the range is the first look and the coverage."""
    assert main(["plan", str(ADAPTIVE), "--json"]) == 0
    steps = {step["name"]: step for step in json.loads(capsys.readouterr().out)["steps"]}
    soft = steps["soft-0"]
    assert soft["kind"] == "adaptive sweep" and "does not fit simulated rig 'soft-0'" in soft[
        "note"]
    assert 0 < soft["low_s"] < soft["high_s"] < 300.0
    # the same step for a model that fits that rig: the floor of the targets, beside the range
    text = ADAPTIVE.read_text().replace('model = "voigt"',
                                        'model = "maxwell(3)+load_cell+fixture(38)+fixture(58)'
                                        '+fixture(92)"').replace(
        "target_uncertainty = { K_v = 2e-3, C_v = 2e-3 }", "target_uncertainty = { K_0 = 2e-3 }")
    fitting = tmp_path / "fitting.toml"
    fitting.write_text(text)
    assert main(["plan", str(fitting)]) == 0
    printed = capsys.readouterr().out
    line = next(line for line in printed.splitlines() if "soft-0" in line)
    assert re.search(r"adaptive sweep soft-0 +[\d:]+ to [\d:]+ \(probe 0:[01]\d\); floor [\d:]+ "
                     r"\(integration at least [\d:]+\); the points it chooses within 0.9 to 1.3 "
                     r"times the floor of simulated rig 'soft-0'", line), line
    assert "total test time" in printed.splitlines()[-1]


def test_plan_with_a_station_has_no_floor_and_keeps_to_the_dwell_limit(tmp_path,
                                                                       capsys) -> None:
    station = tmp_path / "station.toml"
    station.write_text((ROOT / "sequences" / "station-example.toml").read_text())
    assert main(["plan", str(ADAPTIVE), "--station", str(station), "--json"]) == 0
    document = json.loads(capsys.readouterr().out)
    soft = next(step for step in document["steps"] if step["name"] == "soft-0")
    assert soft["floor_s"] is None and soft["high_s"] == pytest.approx(1800.0 + soft["probe_s"])
    without_limit = tmp_path / "open.toml"
    without_limit.write_text(ADAPTIVE.read_text().replace("dwell_limit_s = 1800", ""))
    assert main(["plan", str(without_limit), "--station", str(station)]) == 0
    printed = capsys.readouterr().out
    assert re.search(r"soft-0 +[\d:]+ or more", printed), printed
    assert math.isinf(float("inf"))


def test_plan_of_a_bad_sequence_is_one_line_and_exit_2(tmp_path, capsys) -> None:
    bad = tmp_path / "bad.toml"
    bad.write_text(STEP.format(fields='plan = "adaptive"\nmodel = "voigt"'))
    assert main(["plan", str(bad)]) == 2
    error = capsys.readouterr().err
    assert error.count("\n") == 1 and "target_uncertainty" in error
