"""Bad input, fuzzed: campaign files damaged in every way, and command-line values.

Every case goes through the command line (``viscorig.cli.main``, in-process, as the console
script runs it) and must end in exit status 0 (the damage did not matter) or 2 with one line on
stderr naming what is wrong, never a traceback, and never a changed input file (its SHA-256 is
compared before and after, also for commands that would write a fit).
"""

from __future__ import annotations

import hashlib
import io
import shutil
import tempfile
from contextlib import redirect_stderr, redirect_stdout
from pathlib import Path

import h5py
import numpy as np
import pytest
import reliability_tally as tally
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from simdata import DEFAULT_NOISE, rig_text, simulate_run

from viscorig.cli import main
from viscorig.errors import InputError
from viscorig.storage import CampaignFile, RunSettings, Segment

RUNS = ("table", "soft-0")
DATASETS = ("frequency_hz", "time_s", "accelerance_table", "accelerance_support",
            "reference_amplitude", "source_amplitude", "force_amplitude", "flags")
RUN_ATTRIBUTES = ("status", "started", "finished", "specimen", "hardness_shore_a",
                  "preload_strain", "temperature_c", "level_m_per_s2", "direction",
                  "settle_cycles", "integrate_cycles", "resolution_hz", "instrument", "resource",
                  "simulated")


def sha256(path: Path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest() if path.is_file() else "absent"


def run_cli(arguments: list[str]) -> tuple[int, str, str]:
    """Run the command line in-process; any exception escaping it fails the test."""
    out, err = io.StringIO(), io.StringIO()
    with redirect_stdout(out), redirect_stderr(err):
        try:
            status = main(arguments)
        except SystemExit as exit_:  # argparse usage errors
            status = int(exit_.code or 0)
    return status, out.getvalue(), err.getvalue()


def assert_clean_outcome(status: int, err: str, allowed: tuple[int, ...] = (0, 2)) -> None:
    assert status in allowed, (status, err)
    assert "Traceback" not in err
    if status != 0:
        lines = err.strip().splitlines()
        assert len(lines) == 1, err
        assert lines[0].startswith(("viscorig:", "viscorig ")), err
        assert len(lines[0]) > len("viscorig: ") + 5, err


# -- a valid campaign to damage -----------------------------------------------------------------


def add_run(campaign: CampaignFile, name: str, specimen: str, rig: str, seed: int) -> None:
    run = simulate_run(rig, seed=seed, start_hz=15.0, stop_hz=25.0, step_hz=0.25)
    campaign.start_run(name, RunSettings(
        specimen=specimen, level_m_per_s2=1.0, direction="up", settle_cycles=100,
        integrate_cycles=100, resolution_hz=0.25, simulated=True))
    campaign.append_segment(name, Segment(
        run.frequency_hz, run.time_s, run.accelerance_table, run.accelerance_support,
        run.reference_amplitude, np.ones_like(run.time_s), run.force_amplitude, run.flags))
    campaign.finish_run(name)


@pytest.fixture(scope="module")
def good_campaign(tmp_path_factory: pytest.TempPathFactory) -> bytes:
    path = tmp_path_factory.mktemp("good") / "campaign.h5"
    with CampaignFile.create(path, sequence_text="name = 'x'", durable=False) as campaign:
        add_run(campaign, "table", "none", rig_text(noise=DEFAULT_NOISE), 1)
        add_run(campaign, "soft-0", "soft", "soft-0", 2)
    status, _, err = run_cli(["show", str(path)])
    assert status == 0, err
    return path.read_bytes()


# -- damage -------------------------------------------------------------------------------------


def damage(path: Path, how: str, target: str, detail: int) -> None:
    """Damage the campaign file at ``path`` in one way (``target`` picks the object)."""
    if how == "truncate":
        data = path.read_bytes()
        path.write_bytes(data[: detail % len(data)])
        return
    with h5py.File(path, "r+") as h5:
        run = h5["runs"][RUNS[detail % 2]]
        if how == "delete_group":
            del h5[{"runs": "runs", "run": run.name, "rig": "rig", "setup": "setup"}.get(
                target, run.name)]
        elif how == "delete_dataset":
            del run[target]
        elif how == "delete_attribute":
            owner, name = (h5, target) if target in ("format", "format_version") else (run, target)
            del owner.attrs[name]
        elif how == "wrong_attribute":
            owner, name = (h5, target) if target in ("format", "format_version") else (run, target)
            owner.attrs[name] = ["text", 3.5, np.arange(3), "", -1][detail % 5]
        elif how in ("wrong_dtype", "wrong_shape", "wrong_length", "wrong_units", "no_units",
                     "nan_values"):
            values = run[target][()]
            units = run[target].attrs.get("units", "")
            del run[target]
            if how == "wrong_dtype":
                values = [np.array([b"x"] * len(values)), values.astype(np.int8)
                          if values.dtype.kind != "c" else values.real,
                          values.astype(np.complex64) if values.dtype.kind != "c"
                          else np.abs(values)][detail % 3]
            elif how == "wrong_shape":
                values = np.stack([values, values]) if detail % 2 else np.asarray(values[0])
            elif how == "wrong_length":
                values = values[: max(0, len(values) - 1 - detail % 5)]
            elif how == "nan_values" and values.dtype.kind in "fc":
                values = values.copy()
                values[detail % len(values)] = np.nan
            dataset = run.create_dataset(target, data=values)
            if how == "wrong_units":
                dataset.attrs["units"] = "furlongs"
            elif how != "no_units":
                dataset.attrs["units"] = units
        elif how == "replace_with_group":
            del run[target]
            run.create_group(target)
        elif how == "extra_objects":
            run.create_dataset("junk", data=np.zeros((2, 2)))
            run.create_group("fits").create_group("0001").attrs["band_hz"] = "x"


HOW = ("truncate", "delete_group", "delete_dataset", "delete_attribute", "wrong_attribute",
       "wrong_dtype", "wrong_shape", "wrong_length", "wrong_units", "no_units", "nan_values",
       "replace_with_group", "extra_objects")


@st.composite
def damages(draw: st.DrawFn) -> tuple[str, str, int]:
    how = draw(st.sampled_from(HOW))
    detail = draw(st.integers(0, 10**6))
    if how == "delete_group":
        target = draw(st.sampled_from(["runs", "run", "rig", "setup"]))
    elif how in ("delete_attribute", "wrong_attribute"):
        target = draw(st.sampled_from(["format", "format_version", *RUN_ATTRIBUTES]))
    else:
        target = draw(st.sampled_from(DATASETS))
    return how, target, detail


COMMANDS = (
    ["show", "{file}"],
    ["identify", "{file}", "--run", "table"],  # would store a fit: the file must still not change
    ["identify", "{file}", "--run", "soft-0", "--model", "voigt", "--no-store"],
)


@pytest.mark.slow
@settings(max_examples=60, deadline=None,
          suppress_health_check=[HealthCheck.too_slow, HealthCheck.function_scoped_fixture])
@given(case=damages(), command=st.sampled_from(COMMANDS))
def test_damaged_campaign_file_is_one_clear_message_and_stays_unchanged(
    good_campaign: bytes, case: tuple[str, str, int], command: list[str]
) -> None:
    how, target, detail = case
    with tempfile.TemporaryDirectory() as folder:
        path = Path(folder) / "campaign.h5"
        path.write_bytes(good_campaign)
        damage(path, how, target, detail)
        before = sha256(path)
        arguments = [part.replace("{file}", str(path)) for part in command]
        status, _, err = run_cli(arguments)
        assert_clean_outcome(status, err)
        if status == 0 and "--no-store" not in arguments and arguments[0] == "identify":
            return  # a harmless damage: the fit was stored as asked
        assert sha256(path) == before, f"{how} {target}: the input file changed"
        tally.add("inputs fuzzed")


@pytest.mark.parametrize("how", HOW)
def test_each_damage_to_the_first_run_is_reported(good_campaign: bytes, tmp_path: Path,
                                                  how: str) -> None:
    path = tmp_path / "campaign.h5"
    path.write_bytes(good_campaign)
    target = {"delete_group": "run", "delete_attribute": "status",
              "wrong_attribute": "level_m_per_s2"}.get(how, "accelerance_table")
    damage(path, how, target, 4000 if how == "truncate" else 0)
    before = sha256(path)
    status, _, err = run_cli(["show", str(path)])
    assert_clean_outcome(status, err)
    if how not in ("nan_values", "extra_objects", "delete_group"):  # those leave a valid file
        assert status == 2, f"{how}: {err}"
    assert sha256(path) == before
    tally.add("inputs fuzzed")


@pytest.mark.parametrize("how", [h for h in HOW if h not in ("truncate", "delete_group")])
@pytest.mark.parametrize("target", ["frequency_hz", "accelerance_table", "flags"])
def test_a_file_damaged_after_it_was_opened_is_checked_when_a_run_is_read(
        good_campaign: bytes, tmp_path: Path, how: str, target: str) -> None:
    """Opening checks the whole file; a writer may replace it afterwards. Reading a run then
    checks what it reads again: the run, or one InputError naming the object."""
    path = tmp_path / "campaign.h5"
    path.write_bytes(good_campaign)
    campaign = CampaignFile.open(path)
    damaged = tmp_path / "damaged.h5"
    damaged.write_bytes(good_campaign)
    attribute = {"delete_attribute": "status", "wrong_attribute": "settle_cycles"}.get(how)
    damage(damaged, how, attribute or target, 3)  # detail 3: the run "soft-0", a bad variant
    damaged.replace(path)
    try:
        run = campaign.run("soft-0")
    except InputError as error:
        assert "\n" not in str(error) and "soft-0" in str(error), str(error)
    else:
        # only a damage that leaves the run readable: NaN values, or objects it does not read
        assert how in ("nan_values", "extra_objects"), how
        assert run.points == len(run.frequency_hz) > 0


def _with_point(good_campaign: bytes, tmp_path: Path, column: str, value: float) -> Path:
    """A copy of the good campaign whose run soft-0 holds ``value`` at point 11 of ``column``."""
    path = tmp_path / "campaign.h5"
    path.write_bytes(good_campaign)
    with h5py.File(path, "r+") as h5:
        stored = h5[f"runs/soft-0/{column}"]
        values = stored[()]
        values[10] = value
        stored[...] = values
    return path


@pytest.mark.parametrize("value", [1e300, 1e-300, 3e9])
@pytest.mark.parametrize("command", [["identify", "--model", "maxwell(2)+load_cell"],
                                     ["diagnose"]])
def test_a_value_no_analyser_can_measure_is_named_not_fitted(
        good_campaign: bytes, tmp_path: Path, value: float, command: list[str]) -> None:
    path = _with_point(good_campaign, tmp_path, "accelerance_support", value)
    frequency = float(CampaignFile.open(path).run("soft-0").frequency_hz[10])
    status, _, err = run_cli([command[0], str(path), "--run", "soft-0", *command[1:]])
    assert_clean_outcome(status, err)
    assert status == 2
    assert "ẍ_v/F_v" in err and "1 value(s)" in err and f"at {frequency:g} Hz" in err


@pytest.mark.parametrize("scale", [1e300, 1e-300])
def test_an_frf_scaled_out_of_any_unit_is_named_not_fitted(
        good_campaign: bytes, tmp_path: Path, scale: float) -> None:
    """Every value of an FRF 1e300 times too large (or small): the median-relative test saw
    nothing, and the fit ended in a traceback (scipy: residuals not finite), the summary and
    the report too."""
    path = tmp_path / "campaign.h5"
    path.write_bytes(good_campaign)
    with h5py.File(path, "r+") as h5:
        frf = h5["runs/soft-0/accelerance_support"]
        frf[...] = frf[()] * scale
    for command in (["identify", "--model", "voigt"], ["diagnose"]):
        status, _, err = run_cli([command[0], str(path), "--run", "soft-0", *command[1:]])
        assert_clean_outcome(status, err)
        assert status == 2 and "not a measurement in SI units" in err
    for command in (["summary", str(path)],
                    ["report", str(path), "--out", str(tmp_path / "report"), "--no-ladder",
                     "--jobs", "1"]):
        status, _, err = run_cli(command)
        assert_clean_outcome(status, err)
        assert err == ""


@pytest.mark.parametrize("frequency_hz", [1.043e-309, 2.37e305])
def test_a_frequency_no_analyser_measures_is_named_not_fitted(
        good_campaign: bytes, tmp_path: Path, frequency_hz: float) -> None:
    path = _with_point(good_campaign, tmp_path, "frequency_hz", frequency_hz)
    for command in (["identify", "--model", "voigt"], ["diagnose"]):
        status, _, err = run_cli([command[0], str(path), "--run", "soft-0", *command[1:]])
        assert_clean_outcome(status, err)
        assert status == 2 and "soft-0" in err
        assert "/runs/soft-0/frequency_hz: 1 of " in err
        assert "frequencies are not numbers from 1e-06 to 1e+06 Hz" in err
        assert f"{frequency_hz:g}" in err


def test_a_report_names_a_value_no_analyser_can_measure_and_draws_the_rest(
        good_campaign: bytes, tmp_path: Path) -> None:
    path = tmp_path / "campaign.h5"
    path.write_bytes(good_campaign)
    with h5py.File(path, "r+") as h5:
        frf = h5["runs/soft-0/accelerance_support"]
        values = frf[()]
        values[int(np.argmin(np.abs(h5["runs/soft-0/frequency_hz"][()] - 60.0)))] = 1e300
        frf[...] = values
    status, _, err = run_cli(["report", str(path), "--out", str(tmp_path / "report"),
                              "--no-ladder", "--jobs", "1"])
    assert status == 0 and err == ""
    page = (tmp_path / "report" / "index.html").read_text(encoding="utf-8")
    assert "not a measurement" in page
    assert (tmp_path / "report" / "frf-soft-0.png").stat().st_size > 0


# -- command-line values ------------------------------------------------------------------------

BAD_VALUES = [
    (["identify", "{file}", "--run", "soft-0", "--band", "50:20"], "--band"),
    (["identify", "{file}", "--run", "soft-0", "--band", "x"], "--band"),
    (["identify", "{file}", "--run", "soft-0", "--band", "nan:inf"], "--band"),
    (["identify", "{file}", "--run", "soft-0", "--band", "-5:10"], "--band"),
    (["identify", "{file}", "--run", "soft-0", "--band", "20:30:40"], "--band"),
    (["identify", "{file}", "--run", "soft-0", "--band", "200:300"], "band"),
    (["identify", "{file}", "--run", "soft-0", "--model", "wobble"], "wobble"),
    (["identify", "{file}", "--run", "soft-0", "--model", ""], "model"),
    (["identify", "{file}", "--run", "soft-0", "--model", "voigt+maxwell"], "voigt"),
    (["identify", "{file}", "--run", "soft-0", "--model", "maxwell(0)"], "maxwell"),
    (["identify", "{file}", "--run", "soft-0", "--model", "maxwell(x)"], "maxwell"),
    (["identify", "{file}", "--run", "soft-0", "--model", "voigt+fixture(-3)"], "fixture"),
    (["identify", "{file}", "--run", "nope"], "nope"),
    (["identify", "{file}", "--run", ""], "run"),
    (["identify", "{file}", "--run", "x\nviscorig: done"], "x\\nviscorig"),  # no forged line
    (["identify", "{file}", "--run", "soft-0", "--frf", "elbow"], "frf"),
    (["identify", "{missing}", "--run", "soft-0"], "no such file"),
    (["identify", "{folder}", "--run", "soft-0"], "not a file"),
    (["show", "{missing}"], "no such file"),
    (["show", "{folder}"], "not a file"),
    (["show", "{text}"], "HDF5"),
    (["show", "/dev/null"], "/dev/null"),
    (["summary", "{text}"], "HDF5"),
    (["summary", "{folder}"], "not a file"),
    (["sim", "serve", "--rig", "{missing}"], "missing"),
    (["sim", "serve", "--rig", "{folder}"], "rig"),
    (["sim", "serve", "--rig", "{text}"], "rig"),
    (["sim", "serve", "--preset", "nope"], "nope"),
    (["sim", "serve", "--port", "70000"], "port"),
    (["sim", "serve", "--pace", "-1"], "pace"),
    (["sim", "serve", "--fault", "explode"], "explode"),
    (["no-such-command"], "invalid choice"),
    # numpy's 'expected non-negative integer' traceback; a pace so slow its times overflowed,
    # reported as an instrument fault (exit 3) with a campaign file left behind
    (["run", "{sequence}", "--yes", "--out", "{missing}", "--sim-seed", "-1"], "--sim-seed"),
    (["run", "{sequence}", "--yes", "--out", "{missing}", "--sim-pace", "1e-12"], "--sim-pace"),
    (["run", "{sequence}", "--yes", "--out", "{missing}", "--sim-pace", "inf"], "--sim-pace"),
]


@pytest.fixture
def files(good_campaign: bytes, tmp_path: Path) -> dict[str, Path]:
    paths = {"file": tmp_path / "campaign.h5", "missing": tmp_path / "missing.h5",
             "folder": tmp_path / "folder.h5", "text": tmp_path / "notes.txt",
             "sequence": Path(__file__).resolve().parents[1] / "sequences" / "paper.toml"}
    paths["file"].write_bytes(good_campaign)
    paths["folder"].mkdir()
    paths["text"].write_text("not a campaign = [\n")
    return paths


@pytest.mark.parametrize(("arguments", "words"), BAD_VALUES)
def test_bad_command_line_values_are_one_line_and_exit_status_2(
    files: dict[str, Path], arguments: list[str], words: str
) -> None:
    hashes = {name: sha256(path) for name, path in files.items()}
    status, _, err = run_cli([part.format(**files) for part in arguments])
    assert_clean_outcome(status, err, allowed=(2,))
    assert words.lower() in err.lower(), err
    assert {name: sha256(path) for name, path in files.items()} == hashes
    assert not files["missing"].exists()
    tally.add("inputs fuzzed")


@pytest.mark.slow
@settings(max_examples=80, deadline=None,
          suppress_health_check=[HealthCheck.too_slow, HealthCheck.function_scoped_fixture])
@given(band=st.one_of(
    st.text(max_size=12),
    st.builds(lambda a, b: f"{a}:{b}", st.floats(allow_nan=True), st.floats(allow_nan=True)),
), model=st.one_of(st.none(), st.text(st.sampled_from("voigtmaxwel()+0123fixture,-x "),
                                      max_size=16)))
def test_fuzzed_band_and_model_values_never_escape(files: dict[str, Path], band: str,
                                                   model: str | None) -> None:
    before = sha256(files["file"])
    arguments = ["identify", str(files["file"]), "--run", "soft-0", "--band", band, "--no-store"]
    if model is not None:
        arguments += ["--model", model]
    status, _, err = run_cli(arguments)
    assert_clean_outcome(status, err)
    assert sha256(files["file"]) == before
    tally.add("inputs fuzzed")


def test_an_unwritable_campaign_file_is_an_input_error_and_unchanged(
    files: dict[str, Path], tmp_path: Path
) -> None:
    folder = tmp_path / "readonly"
    folder.mkdir()
    path = folder / "campaign.h5"
    shutil.copyfile(files["file"], path)
    folder.chmod(0o500)
    try:
        before = sha256(path)
        status, _, err = run_cli(["identify", str(path), "--run", "table"])
        if status == 0:
            pytest.skip("running as a user who may write anywhere")
        assert_clean_outcome(status, err, allowed=(2,))
        assert sha256(path) == before
    finally:
        folder.chmod(0o700)
