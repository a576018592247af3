"""Sequences a technician can write: every problem at once with its line and a did-you-mean,
level units as people write them, a reference generated from the schema the reader uses,
``viscorig check``, and the simulated rig matched with every sweep before anything runs."""

from __future__ import annotations

import dataclasses
import json
import re
import subprocess
import sys
from pathlib import Path

import pytest

from viscorig.cli import main
from viscorig.sequences import FileCheckError, SweepStep, load_sequence, parse_level
from viscorig.sequences.reference import reference_markdown
from viscorig.sequences.schema import DEFAULTS, STATION_SECTIONS, STEP_TYPES, SWEEP

ROOT = Path(__file__).resolve().parents[1]
PAPER = ROOT / "sequences" / "paper.toml"

# The sequence of the report: a misspelt key, "1.4 m/s2", and a band given high to low, in a
# file a technician wrote by hand. Before, it took three runs to learn of the three, the
# misspelt key came last without a suggestion, and "m/s2" was refused.
THREE_MISTAKES = """\
name = "bench"

[defaults]
resolution_hz = 0.25
settle_cycles = 100
integrate_cycles = 100
level = "1.4 m/s2"

[[steps]]
type = "prompt"
message = "Mount the soft specimens, no preload."
simulated_rig = "soft-0"

[[steps]]
type = "sweep"
run = "soft-0"
specimin = "soft"
band_hz = [120.0, 20.0]
hardness_shore_a = 25.0
"""


def write(tmp_path: Path, text: str, name: str = "bench.toml") -> Path:
    path = tmp_path / name
    path.write_text(text, encoding="utf-8")
    return path


def test_three_mistakes_are_reported_at_once_each_with_line_field_and_fix(tmp_path) -> None:
    path = write(tmp_path, THREE_MISTAKES)
    with pytest.raises(FileCheckError) as caught:
        load_sequence(path)
    lines = [str(problem) for problem in caught.value.problems]
    assert lines == [
        f"{path}:17: steps[1].specimin: unknown key; did you mean 'specimen'?",
        f"{path}:18: steps[1].band_hz: [120, 20] Hz is written high to low; write band_hz = "
        "[20, 120] and direction = \"down\" to sweep downwards",
    ]  # "1.4 m/s2" is accepted; the missing specimen is the misspelt key, said once
    assert "(and 1 more problem" in str(caught.value) and "\n" not in str(caught.value)


def test_files_saved_with_a_byte_order_mark_read_as_without(tmp_path, capsys) -> None:
    """Windows Notepad saves UTF-8 with a byte-order mark: such a sequence was 'not valid TOML:
    Invalid statement (at line 1, column 1)', a station file too; the lines of its problems
    stay where they are."""
    sequence = tmp_path / "paper.toml"
    sequence.write_text("\ufeff" + PAPER.read_text(encoding="utf-8"), encoding="utf-8")
    station = tmp_path / "station.toml"
    station.write_text("\ufeff" + (ROOT / "sequences" / "station-example.toml").read_text(
        encoding="utf-8"), encoding="utf-8")
    assert main(["check", str(sequence), "--station", str(station)]) == 0
    assert "OK, 15 steps, 7 runs" in capsys.readouterr().out
    assert load_sequence(sequence).steps == load_sequence(PAPER).steps
    mistaken = write(tmp_path, "\ufeff" + THREE_MISTAKES)
    with pytest.raises(FileCheckError) as caught:
        load_sequence(mistaken)
    assert str(caught.value.problems[0]).startswith(f"{mistaken}:17: steps[1].specimin")


def test_check_prints_every_problem_and_exits_2(tmp_path, capsys) -> None:
    path = write(tmp_path, THREE_MISTAKES.replace('"up"', '"upp"') + 'direction = "upp"\n')
    assert main(["check", str(path)]) == 2
    out = capsys.readouterr().out.splitlines()
    assert [re.match(r".*?:(\d+): (\S+):", line).groups() for line in out] == [
        ("17", "steps[1].specimin"), ("18", "steps[1].band_hz"), ("20", "steps[1].direction")]
    assert out[2].endswith("'upp' is not one of up, down; did you mean 'up'?")


def test_check_json_lists_problems_with_file_line_field_message_and_hint(tmp_path,
                                                                         capsys) -> None:
    path = write(tmp_path, THREE_MISTAKES)
    assert main(["check", str(path), "--json"]) == 2
    report = json.loads(capsys.readouterr().out)
    assert report["ok"] is False and report["runs"] == []
    assert report["problems"][0] == {
        "file": str(path), "line": 17, "field": "steps[1].specimin", "message": "unknown key",
        "hint": "did you mean 'specimen'?"}


@pytest.mark.parametrize(("name", "content", "said"), [
    ("missing.toml", None, "no such file"),
    ("folder", "", "not a file"),
    ("latin1.toml", b'specimen = "Gr\xfcn"\n', "not UTF-8 text (byte 0xfc at offset 14)"),
])
def test_a_file_check_cannot_read_is_one_line_and_with_json_still_json(
        tmp_path, capsys, name: str, content: bytes | str | None, said: str) -> None:
    """A missing sequence printed Python's own words ('FileNotFoundError: [Errno 2]...'), and
    with --json no JSON at all."""
    path = tmp_path / name
    if content == "":
        path.mkdir()
    elif content is not None:
        path.write_bytes(content)
    assert main(["check", str(path)]) == 2
    assert capsys.readouterr().err == f"viscorig: {path}: {said}\n"
    assert main(["check", str(path), "--json"]) == 2
    report = json.loads(capsys.readouterr().out)
    assert report["ok"] is False and report["runs"] == []
    assert report["problems"] == [
        {"file": str(path), "line": None, "field": "", "message": said, "hint": ""}]


def test_the_paper_sequence_checks_clean_on_the_simulated_rig_and_with_a_station(capsys) -> None:
    assert main(["check", str(PAPER), "--json"]) == 0
    report = json.loads(capsys.readouterr().out)
    assert report["ok"] and report["problems"] == [] and len(report["runs"]) == 7
    assert report["test_time_s"] == pytest.approx(load_sequence(PAPER).duration_s())
    station = ROOT / "sequences" / "station-example.toml"
    assert main(["check", str(PAPER), "--station", str(station)]) == 0
    assert "OK, 15 steps, 7 runs" in capsys.readouterr().out


def test_a_station_file_with_several_mistakes_gets_them_all(tmp_path, capsys) -> None:
    text = (ROOT / "sequences" / "station-example.toml").read_text(encoding="utf-8")
    text = text.replace("force_limit_n = 100.0", "force_limt_n = 100.0").replace(
        "limit_v = 2.0", "limit_v = 9.0")
    station = write(tmp_path, text, "station.toml")
    assert main(["check", str(PAPER), "--station", str(station)]) == 2
    out = capsys.readouterr().out
    assert "shaker.force_limt_n: unknown key; did you mean 'force_limit_n'?" in out
    assert "source.limit_v: 9.0 is outside (0, 5] V" in out
    assert "force_limit_n: missing" not in out


@pytest.mark.parametrize("command", ["check", "plan", "run"])
def test_a_station_file_and_a_sequence_given_in_each_other_s_place_are_named(
        command: str, tmp_path: Path, capsys) -> None:
    """One line saying which file is which, where each table of the one read as the other was
    an unknown key (eight problems, none naming the mix-up)."""
    station = ROOT / "sequences" / "station-example.toml"
    extra = ["--yes", "--out", str(tmp_path / "x.h5")] if command == "run" else []
    assert main([command, str(station), *extra]) == 2
    err = capsys.readouterr()
    text = err.out + err.err
    assert "a station file (resource, [channels], [sensitivity]), not a test sequence: give a " \
           "sequence first and this file with --station" in text
    assert "unknown key" not in text
    assert main([command, str(PAPER), "--station", str(PAPER), *extra]) == 2
    err = capsys.readouterr()
    assert "paper.toml: a test sequence ([[steps]]), not a station file" in err.out + err.err
    assert not (tmp_path / "x.h5").exists()


@pytest.mark.parametrize(("text", "expected"), [
    ("1.4 m/s2", 1.4), ("1.4 m/s²", 1.4), ("1.4 m/s^2", 1.4), ("1.4 m/s**2", 1.4),
    ("1.4 m s^-2", 1.4), ("1.4 m·s⁻²", 1.4), ("1.4 m/s/s", 1.4), ("1400 mm/s2", 1.4),
    ("140 cm/s²", 1.4), ("0.1 g", 0.980665), ("100 mg", 0.980665), ("1.4 M/S2 PEAK", None),
    ("1 m/s2 rms", 2**0.5), ("1 m/s2 RMS", 2**0.5),
])
def test_unit_spellings_convert_to_peak_si(text: str, expected: float | None) -> None:
    if expected is None:  # "M" is not metres
        with pytest.raises(ValueError):
            parse_level(text)
    else:
        assert parse_level(text) == pytest.approx(expected, rel=1e-12)


def test_an_unknown_unit_gets_a_suggestion() -> None:
    with pytest.raises(ValueError, match=r"did you mean \"1.4 m/s2\""):
        parse_level("1.4 m/s3")


def test_the_readme_of_sequences_is_generated_from_the_schema_the_reader_uses() -> None:
    readme = (ROOT / "sequences" / "README.md").read_text(encoding="utf-8")
    assert readme == reference_markdown(), (
        "sequences/README.md differs from the schema: viscorig check --fields > "
        "sequences/README.md")
    for schema in (*STEP_TYPES.values(), *STATION_SECTIONS):
        for item in schema.fields:
            row = next(line for line in readme.splitlines()
                       if line.startswith(f"| `{item.name}` |") and item.example in line)
            cells = [cell.strip() for cell in row.split(" | ")]
            assert len(cells) == 7 and all(cells[i] for i in (1, 3, 5)), row


def test_the_schema_covers_every_field_a_sweep_step_holds() -> None:
    derived = {"level_m_per_s2"}  # from level
    held = {item.name for item in dataclasses.fields(SweepStep)} - derived
    assert held == set(SWEEP.names)
    assert set(DEFAULTS.names) == set(SWEEP.names) - {"run"}


def test_the_readme_example_is_a_valid_sequence(tmp_path, capsys) -> None:
    readme = (ROOT / "sequences" / "README.md").read_text(encoding="utf-8")
    example = re.search(r"```toml\n(.*?)```", readme, re.S).group(1)
    assert main(["check", str(write(tmp_path, example))]) == 0, capsys.readouterr()


def test_check_fields_prints_the_reference(capsys) -> None:
    assert main(["check", "--fields"]) == 0
    assert capsys.readouterr().out == reference_markdown()


# -- the right rig on the embedded simulated rig ------------------------------------------------

def paper_without(old: str, new: str = "") -> str:
    text = PAPER.read_text(encoding="utf-8")
    assert old in text
    return text.replace(old, new, 1)


def viscorig(*args: str, cwd: Path) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "viscorig", *args], capture_output=True,
                          text=True, timeout=120, cwd=cwd)


def test_a_prompt_without_its_preset_is_refused_before_anything_is_measured(tmp_path) -> None:
    """Before, hard-0 silently measured the medium rubber still mounted under its name."""
    path = write(tmp_path, paper_without('simulated_rig = "hard-0"\n'))
    result = viscorig("run", str(path), "--yes", "--out", "x.h5", cwd=tmp_path)
    assert result.returncode == 2, result.stdout
    assert result.stdout == "" and not (tmp_path / "x.h5").exists()
    [line] = result.stderr.splitlines()
    assert re.search(r"bench\.toml:\d+: steps\[12\]\.run: run 'hard-0' \(specimen 'hard', "
                     r"48 Shore A, preload 0\) does not match the simulated rig 'medium-10' "
                     r"\(33 Shore A, preload 0.104, mounted at steps\[9\]\); add "
                     r"simulated_rig = \"hard-0\" to the prompt at steps\[11\]$", line), line


def test_a_specimen_run_with_no_specimen_mounted_is_refused_with_the_preset_to_name(
        tmp_path) -> None:
    """Before, the bare table was measured as 'hard-0', and its probe advised 1.1e-6 m/s^2."""
    text = """\
name = "no-rig"
[defaults]
band_hz = [20.0, 120.0]
resolution_hz = 0.25
settle_cycles = 100
integrate_cycles = 100
level = "1.4 m/s^2"

[[steps]]
type = "prompt"
message = "Mount the hard specimens, no preload."

[[steps]]
type = "sweep"
run = "hard-0"
specimen = "hard"
hardness_shore_a = 48.0
"""
    path = write(tmp_path, text)
    result = viscorig("run", str(path), "--yes", "--out", "x.h5", cwd=tmp_path)
    assert result.returncode == 2 and not (tmp_path / "x.h5").exists()
    assert ("bench.toml:15: steps[1].run: run 'hard-0' (specimen 'hard', 48 Shore A, preload "
            "0) would measure the bare table under its name: no simulated rig with specimens is "
            "mounted before it; add simulated_rig = \"hard-0\" to the prompt at steps[0]"
            ) in result.stderr


@pytest.mark.parametrize(("old", "new", "field", "wanted"), [
    # the preload screws tightened, but the prompt mounts the unloaded preset
    ('simulated_rig = "soft-10"', 'simulated_rig = "soft-0"', "steps[6].run", "soft-10"),
    # a bare-table run after specimens were mounted
    ('simulated_rig = "table"', 'simulated_rig = "soft-0"', "steps[1].run", "table"),
    # a preset that does not exist
    ('simulated_rig = "medium-0"', 'simulated_rig = "medium0"', "steps[7].simulated_rig",
     "did you mean 'medium-0'?"),
])
def test_each_mismatch_of_sweep_and_preset_names_the_fix(tmp_path, capsys, old, new, field,
                                                          wanted) -> None:
    path = write(tmp_path, paper_without(old, new))
    assert main(["check", str(path)]) == 2
    out = capsys.readouterr().out
    assert f": {field}: " in out and wanted in out, out


def test_runs_of_one_specimen_on_one_mounting_are_accepted(capsys) -> None:
    assert main(["check", str(ROOT / "sequences" / "separate-effects.toml")]) == 0


def test_a_changed_specimen_without_hardness_is_caught_by_its_name(tmp_path, capsys) -> None:
    text = paper_without('simulated_rig = "hard-0"\n').replace(
        'specimen = "hard"\nhardness_shore_a = 48.0\npreload_strain = 0.0\n',
        'specimen = "hard"\npreload_strain = 0.104\n', 1)
    text = text.replace('simulated_rig = "medium-10"', 'simulated_rig = "medium-10"', 1)
    path = write(tmp_path, text)
    assert main(["check", str(path)]) == 2
    out = capsys.readouterr().out
    assert "run 'hard-0' (specimen 'hard', preload 0.104) would be measured on the simulated " \
           "rig 'medium-10'" in out
    assert "which run 'medium-10' measured as specimen 'medium'" in out
    assert 'add simulated_rig = "hard-10"' in out


def test_a_reversed_fit_band_is_not_told_to_sweep_down(tmp_path) -> None:
    text = PAPER.read_text(encoding="utf-8").replace(
        'type = "identify_table"\nrun = "table"\n',
        'type = "identify_table"\nrun = "table"\nband_hz = [25.0, 15.0]\n')
    with pytest.raises(FileCheckError) as caught:
        load_sequence(write(tmp_path, text))
    [problem] = caught.value.problems
    assert problem.field == "steps[2].band_hz" and problem.hint == "write band_hz = [15, 25]"


def test_run_names_the_first_problem_in_one_line_and_the_command_that_lists_all(tmp_path):
    path = write(tmp_path, THREE_MISTAKES)
    result = viscorig("run", str(path), "--yes", "--out", "x.h5", cwd=tmp_path)
    assert result.returncode == 2 and not (tmp_path / "x.h5").exists()
    [line] = result.stderr.splitlines()
    assert line == (f"viscorig: {path}:17: steps[1].specimin: unknown key; did you mean "
                    f"'specimen'? (and 1 more problem: 'viscorig check {path}' lists them all)")


def test_a_problem_quotes_a_long_value_cut_not_whole(tmp_path, capsys) -> None:
    # a list of 5,000 temperatures with one repeated was quoted whole: 25 KB on one line
    temperatures = ", ".join(str(t) for t in [*range(-20, 80), -20,
                                              *(round(100 + 0.03 * i, 2) for i in range(5000))])
    path = write(tmp_path, f'name = "big"\n[[steps]]\ntype = "repeat"\n'
                           f"temperatures_c = [{temperatures}]\n" + '''  [[steps.steps]]
  type = "sweep"
  run = "s_{temperature_c}"
  specimen = "soft"
  band_hz = [20.0, 120.0]
  resolution_hz = 0.25
  level = "1.4 m/s2"
  settle_cycles = 100
  integrate_cycles = 100
  [[steps]]
  type = "''' + "x" * 10_000 + '"\n')
    assert main(["check", str(path)]) == 2
    out = capsys.readouterr().out
    assert "steps[0].temperatures_c: names -20 twice; each value once" in out
    assert max(len(line) for line in out.splitlines()) < 400
    assert "'xxxxxxxx" in out and "x" * 100 not in out


def test_a_target_uncertainty_no_sweep_reaches_is_refused_at_its_line(tmp_path) -> None:
    """A target of 1e-300 passed the check, and the plan's design then found 'no information
    about the targets' in a traceback."""
    text = (ROOT / "sequences" / "adaptive.toml").read_text(encoding="utf-8").replace(
        "target_uncertainty = { K_v = 2e-3, C_v = 2e-3 }", "target_uncertainty = { K_v = 1e-300 }")
    path = write(tmp_path, text)
    with pytest.raises(FileCheckError) as caught:
        load_sequence(path)
    assert "K_v: 1e-300 is outside (1e-09, 1]" in str(caught.value.problems[0])
