"""``viscorig identify`` and ``viscorig summary`` on campaign files of simulated runs."""

from __future__ import annotations

import json
import re
import shutil
import subprocess
import sys
from pathlib import Path

import h5py
import numpy as np
import pytest
from simdata import DEFAULT_NOISE, SimulatedRun, rig_text, simulate_run

from viscorig.cli import main
from viscorig.storage import CampaignFile, RunSettings, Segment

VOIGT = {"mass_kg": 0.25, "model": "voigt", "stiffness_n_per_m": 1.5e5, "damping_ns_per_m": 114.59}


def add_run(campaign: CampaignFile, name: str, run: SimulatedRun, specimen: str,
            preload_strain: float = 0.0) -> None:
    settings = RunSettings(
        specimen=specimen,
        preload_strain=preload_strain,
        level_m_per_s2=1.0,
        direction="up",
        settle_cycles=100,
        integrate_cycles=100,
        resolution_hz=0.25,
        simulated=True,
    )
    campaign.start_run(name, settings)
    campaign.append_segment(
        name,
        Segment(
            run.frequency_hz,
            run.time_s,
            run.accelerance_table,
            run.accelerance_support,
            run.reference_amplitude,
            np.ones_like(run.time_s),
            run.force_amplitude,
            run.flags,
        ),
    )
    campaign.finish_run(name)


@pytest.fixture(scope="module")
def campaign_file(tmp_path_factory: pytest.TempPathFactory) -> Path:
    path = tmp_path_factory.mktemp("campaign") / "paper.h5"
    with CampaignFile.create(path, sequence_text="", durable=False) as campaign:
        add_run(campaign, "table", simulate_run(rig_text(noise=DEFAULT_NOISE), seed=1), "none")
        add_run(campaign, "soft-0", simulate_run("soft-0", seed=2), "soft")
    return path


def test_identify_json_follows_the_design_and_stores_the_fit(
    campaign_file: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    assert main(["identify", str(campaign_file), "--run", "soft-0", "--model", "maxwell",
                 "--band", "20:120", "--json"]) == 0  # fmt: skip
    document = json.loads(capsys.readouterr().out)
    assert set(document) >= {"run", "model", "band_hz", "points", "rms_error", "noise_floor"}
    assert document["run"] == "soft-0"
    assert document["model"].startswith("maxwell(")
    assert document["band_hz"] == [20.0, 120.0]
    assert document["points"] == 401
    assert document["parameters"]["K_0"]["unit"] == "N/m"
    # The table is held fixed at the bare-table run's values, with that fit's uncertainty.
    assert main(["identify", str(campaign_file), "--run", "table", "--no-store", "--json"]) == 0
    table = json.loads(capsys.readouterr().out)
    for name in ("M_s", "K_s", "C_s"):
        assert document["parameters"][name]["stderr"] == pytest.approx(
            table["parameters"][name]["stderr"], rel=1e-9)
    assert document["uncertainty"]["inherited"] == ["M_s", "K_s", "C_s"]
    assert document["uncertainty"]["inherited_from"] == "run 'table'"
    names = document["correlation"]["parameters"]
    rho = np.array(document["correlation"]["matrix"])
    assert names[-3:] == ["M_s", "K_s", "C_s"] and "K_0" in names
    assert np.allclose(np.diag(rho), 1.0) and np.allclose(rho, rho.T)
    with CampaignFile.open(campaign_file) as campaign:
        stored = campaign.fits("soft-0")[-1]
    assert stored.model == document["model"]
    assert stored.parameters["K_0"].value == pytest.approx(document["parameters"]["K_0"]["value"])
    assert stored.parameters["K_0"].stderr == pytest.approx(document["parameters"]["K_0"]["stderr"])
    assert stored.parameters["M_s"].stderr == pytest.approx(table["parameters"]["M_s"]["stderr"])
    assert stored.correlation is not None and list(stored.correlation[0]) == names
    assert np.allclose(stored.correlation[1], rho, atol=1e-6)
    # the stored spec is accepted as is
    assert main(["identify", str(campaign_file), "--run", "soft-0", "--model", stored.model,
                 "--no-store", "--json"]) == 0  # fmt: skip
    again = json.loads(capsys.readouterr().out)
    assert again["rms_error"] == pytest.approx(document["rms_error"], rel=1e-3)


def test_identify_bare_table_defaults_to_the_table_model(
    campaign_file: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    assert main(["identify", str(campaign_file), "--run", "table", "--no-store"]) == 0
    out = capsys.readouterr().out
    assert "model table" in out
    assert re.search(r"M_s = 3\.(39|40)", out), out


def test_summary_prints_both_tables_beside_the_paper(
    campaign_file: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    assert main(["summary", str(campaign_file)]) == 0
    out = capsys.readouterr().out
    assert "Table 1" in out and "Table 2" in out
    assert "149986.61" in out  # the paper's K_v beside ours
    assert "M_v < 0" in out  # the paper's own inconsistency is said
    soft = next(line for line in out.splitlines() if line.strip().startswith("soft-0"))
    assert float(soft.split()[1]) == pytest.approx(149986.61, rel=0.01)


@pytest.mark.slow
@pytest.mark.parametrize(
    ("arguments", "words"),
    [
        (["--run", "soft-0", "--model", "voigt+wobble"], "unknown term 'wobble'"),
        (["--run", "soft-0", "--band", "20-120"], "--band"),
        (["--run", "soft-0", "--band", "50:50.5"], "at least"),
        (["--run", "table", "--model", "voigt"], "bare-table run"),
        (["--run", "nope"], "nope"),
    ],
)
def test_bad_input_is_one_line_and_exit_status_2(
    campaign_file: Path, arguments: list[str], words: str
) -> None:
    result = subprocess.run(
        [sys.executable, "-m", "viscorig", "identify", str(campaign_file), *arguments,
         "--no-store"],
        capture_output=True, text=True, check=False,
    )  # fmt: skip
    assert result.returncode == 2, result.stderr
    assert len(result.stderr.strip().splitlines()) == 1, result.stderr
    assert words in result.stderr


def test_summary_notes_name_only_the_runs_in_the_campaign(
    campaign_file: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    assert main(["summary", str(campaign_file)]) == 0
    notes = capsys.readouterr().out.split("Notes on the paper's numbers:")[1]
    assert "soft-0 3.25 kg" in notes
    for absent in ("soft-10", "medium-0", "hard-0", "hard-10"):
        assert absent not in notes


def test_summary_json_gives_every_number_with_its_uncertainty(
    campaign_file: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    assert main(["summary", str(campaign_file), "--json"]) == 0
    document = json.loads(capsys.readouterr().out)
    assert document["table"]["source"] == "run 'table'"
    assert document["table"]["parameters"]["K_s"]["stderr"] > 0
    (soft,) = document["runs"]
    assert soft["run"] == "soft-0"
    for group in ("parameters", "system"):
        for name, number in soft[group].items():
            assert set(number) == {"value", "stderr", "unit"}, name
            assert number["stderr"] > 0, name
    assert soft["system"]["f_r"]["unit"] == "Hz"
    assert soft["paper"]["K_v"] == pytest.approx(149986.61)
    assert soft["fits_noise"] is False  # Voigt on the fractional preset rubber
    assert document["variations"] == []  # no preloaded run here
    assert all("hard-10" not in note for note in document["notes"])


def cut(run: SimulatedRun, points: int) -> SimulatedRun:
    """The run's first ``points`` points: a sweep stopped there."""
    fields = {name: getattr(run, name)[:points] for name in (
        "frequency_hz", "time_s", "accelerance_table", "accelerance_support",
        "reference_amplitude", "force_amplitude", "flags")}
    return SimulatedRun(**fields, rig=run.rig)


@pytest.fixture(scope="module")
def stopped_campaign(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The table, a whole soft-0, a soft-10 stopped below its resonance (20-29 Hz), and a
    medium-0 aborted after three points."""
    path = tmp_path_factory.mktemp("stopped") / "stopped.h5"
    with CampaignFile.create(path, sequence_text="", durable=False) as campaign:
        add_run(campaign, "table", simulate_run(rig_text(noise=DEFAULT_NOISE), seed=1), "none")
        add_run(campaign, "soft-0", simulate_run("soft-0", seed=2), "soft")
        add_run(campaign, "soft-10", cut(simulate_run("soft-10", seed=3), 37), "soft", 0.104)
        add_run(campaign, "medium-0", cut(simulate_run("medium-0", seed=4), 3), "medium")
    return path


def test_summary_leaves_out_a_run_too_short_to_fit_and_marks_one_fitted_over_part_of_the_band(
    stopped_campaign: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """One aborted run of three points used to refuse the whole summary; a run stopped below its
    resonance showed the last point measured as the measured peak, without a word."""
    assert main(["summary", str(stopped_campaign)]) == 0
    out = capsys.readouterr().out
    table_1 = out.split("Table 1")[1].split("Table 2")[0]
    assert "soft-0 " in table_1 and "medium-0" not in table_1
    soft_10 = next(line for line in table_1.splitlines() if line.strip().startswith("soft-10"))
    assert soft_10.rstrip().endswith("†") or "† " in soft_10
    assert "† fitted over part of the 20–120 Hz band only, where the run has points (soft-10 " \
           "20–29 Hz)" in table_1
    table_2 = out.split("Table 2")[1]
    row = next(line for line in table_2.splitlines() if line.strip().startswith("soft-10"))
    assert re.search(r"\sn/a\s+n/a\s", row), row  # no peak inside 20-29 Hz: none measured
    assert "Left out of the tables:\n  - run 'medium-0', band 20:20.5 Hz: 3 points, a fit " \
           "needs at least 10" in out
    assert "soft-0 → soft-10 †" in out
    assert main(["summary", str(stopped_campaign), "--json"]) == 0
    document = json.loads(capsys.readouterr().out)
    assert document["left_out"] == [{"run": "medium-0", "reason": "run 'medium-0', band "
                                     "20:20.5 Hz: 3 points, a fit needs at least 10"}]
    runs = {entry["run"]: entry for entry in document["runs"]}
    assert runs["soft-10"]["band_hz"] == [20.0, 29.0]
    assert runs["soft-10"]["measured"]["peak_hz"] is None
    assert runs["soft-0"]["measured"]["peak_hz"] == pytest.approx(39.1, abs=0.5)


def test_a_run_whose_every_point_overloaded_is_named_not_mistaken_for_a_bare_table(
    stopped_campaign: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """Every point of soft-0 flagged as an input overload: the summary crashed on an empty
    band, and identify said the run had no table FRF (a bare-table run?)."""
    path = tmp_path / "overloaded.h5"
    shutil.copyfile(stopped_campaign, path)
    with h5py.File(path, "r+") as h5:
        h5["runs/soft-0/flags"][...] = 2
    said = "run 'soft-0': every one of its 401 points overloaded an input (flags bit 2)"
    assert main(["identify", str(path), "--run", "soft-0", "--no-store"]) == 2
    assert said in capsys.readouterr().err
    assert main(["summary", str(path), "--json"]) == 0
    document = json.loads(capsys.readouterr().out)
    assert [entry["run"] for entry in document["left_out"]] == ["soft-0", "medium-0"]
    assert said in document["left_out"][0]["reason"]


def test_identify_says_what_the_uncertainty_includes(
    campaign_file: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    assert main(["identify", str(campaign_file), "--run", "soft-0", "--no-store"]) == 0
    out = capsys.readouterr().out
    assert re.search(r"K_s = 5\d+\.?\d* +± [\d.]+ \(inherited\)", out), out
    assert "does not fit to the noise" in out  # Voigt on a fractional rubber with fixtures
    assert "band-average" in out
    assert "noise: table: white rms" in out
    assert main(["identify", str(campaign_file), "--run", "soft-0", "--no-store",
                 "--model", "fractional+load_cell+fixture(38)+fixture(58)+fixture(92)"]) == 0
    out = capsys.readouterr().out
    assert "± are standard uncertainties" in out, out


def test_identify_says_what_the_uncertainty_leaves_out(
    campaign_file: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    assert main(["identify", str(campaign_file), "--run", "soft-0", "--no-store", "--json",
                 "--frf", "table"]) == 0
    excludes = json.loads(capsys.readouterr().out)["uncertainty"]["excludes"]
    assert any("calibration" in text for text in excludes)
    assert any("frame(M_f)" in text for text in excludes)
    assert any("load_cell" in text for text in excludes)  # X_s/F_e alone cannot tell
    assert not any("K_c reads stiffer" in text for text in excludes)
    # the frame the paper's band cannot see biases a load cell's K_c too: +1.8 and +2.2
    # standard errors on average over four simulated soft-0 and hard-0 runs, +0.1 and +0.3
    # with the frame taken out of the simulated rig
    assert main(["identify", str(campaign_file), "--run", "soft-0", "--no-store", "--json",
                 "--model", "fractional+load_cell"]) == 0
    excludes = json.loads(capsys.readouterr().out)["uncertainty"]["excludes"]
    assert any("frame(M_f)" in text and "K_c reads stiffer" in text for text in excludes)
    assert main(["identify", str(campaign_file), "--run", "soft-0", "--no-store", "--json",
                 "--model", "voigt+load_cell+frame(2000)"]) == 0
    excludes = json.loads(capsys.readouterr().out)["uncertainty"]["excludes"]
    assert len(excludes) == 1 and "calibration" in excludes[0]


def test_the_report_keeps_its_tables_beside_a_run_too_short_to_fit(
    stopped_campaign: Path, tmp_path: Path
) -> None:
    """The report's Tables 1 and 2 were refused whole for one aborted run of three points."""
    out = tmp_path / "report"
    assert main(["report", str(stopped_campaign), "--out", str(out), "--no-ladder"]) == 0
    page = (out / "index.html").read_text(encoding="utf-8")
    assert "Table 1 and 2 not computed" not in page
    table_1 = page.split("Table 1: Voigt fit")[1].split("Table 2")[0]
    assert "soft-0" in table_1 and "medium-0" not in table_1
    assert "fitted over 20–29 Hz only, where the run has points" in table_1
    assert "run medium-0: 3 points, too few to fit; shown as measured" in page
    assert "left out of Tables 1 and 2" not in page  # (said once, by the note above)


def with_outliers(path: Path, points) -> Path:
    """The table and soft-0, with the table FRF of soft-0 off by half its value (real part
    x 1.5, imaginary x 0.5) at the points ``points(size)`` picks: outliers written with plain
    h5py, as a glitch would leave them."""
    with CampaignFile.create(path, sequence_text="", durable=False) as campaign:
        add_run(campaign, "table", simulate_run(rig_text(noise=DEFAULT_NOISE), seed=1), "none")
        add_run(campaign, "soft-0", simulate_run("soft-0", seed=2), "soft")
    with h5py.File(path, "r+") as h5:
        dataset = h5["runs/soft-0/accelerance_table"]
        values = dataset[()]
        spoilt = points(values.size)
        values[spoilt] = 1.5 * values[spoilt].real + 0.5j * values[spoilt].imag
        dataset[...] = values
    return path


def test_a_few_outlier_points_are_not_the_floor_a_model_is_judged_against(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """Twenty points of the table FRF off by half their value: each outlier's noise power is
    its own error, so they made the whole noise floor 200 times the others', and Voigt, 240
    times from the noise of the other points, was called at the noise floor."""
    path = with_outliers(tmp_path / "outliers.h5",
                         lambda size: np.arange(10, size, size // 20)[:20])  # isolated points
    assert main(["diagnose", str(path), "--run", "soft-0", "--json"]) == 0
    document = json.loads(capsys.readouterr().out)
    assert document["outlier_points"] >= 20
    assert document["noise_floor_without_outliers"] < document["noise_floor"] / 20
    assert document["rms_error_without_outliers"] > 50 * document["noise_floor_without_outliers"]
    assert document["at_noise_floor"] is False
    assert main(["diagnose", str(path), "--run", "soft-0"]) == 0
    second = capsys.readouterr().out.splitlines()[1]
    assert re.search(r"\(\d+\.\d\d x floor; \d+\.\d\d x without its \d+ outlier points\)$",
                     second), second


def test_glitches_of_two_points_are_left_out_where_they_are(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """Ten glitches of two points side by side: each pair showed on its two outer neighbours,
    which were left out in its place. The model the clean run reaches was then called 14.6
    times the noise of the other points with nothing missing: its uniform fit, pulled off them
    by the glitches, where the likelihood fit leaves noise; and where it fails was read off
    that uniform fit."""
    path = with_outliers(tmp_path / "pairs.h5",
                         lambda size: (np.arange(30, size - 30, (size - 60) // 10)[:10, None]
                                       + np.arange(2)).ravel())
    model = "fractional+load_cell+fixture(38)+fixture(58)+fixture(92)"
    assert main(["diagnose", str(path), "--run", "soft-0", "--model", model, "--json"]) == 0
    document = json.loads(capsys.readouterr().out)
    assert document["outlier_points"] == 20
    floor = document["noise_floor_without_outliers"]
    assert document["rms_error_without_outliers"] > 5 * floor
    assert document["likelihood_rms_error_without_outliers"] < 1.25 * floor
    assert document["pulled_by_outliers"] is True
    # where it fails is read off the likelihood fit: the uniform fit's bands are the glitches'
    assert document["failures"] == []
    assert main(["diagnose", str(path), "--run", "soft-0", "--model", model]) == 0
    text = capsys.readouterr().out
    assert "where it fails (weighed by its noise): nowhere" in text
    assert "outliers: its 20 outlier points pull the uniform fit" in text
    assert "--weights noise" in text
    assert "nothing significant is missing: weighed by its noise, what is left is noise." in text


def test_the_ladder_reaches_the_clean_runs_model_through_two_point_glitches(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """With ten two-point glitches the ladder ended at a sensor gain and delay in place of the
    clean run's load cell: the load cell's fit started from a uniform fit the glitches dragged
    into a valley (Δχ² 8,111 where the clean run gives 28,240). Such a start is now joined by
    one from the current model."""
    path = with_outliers(tmp_path / "pairs.h5",
                         lambda size: (np.arange(30, size - 30, (size - 60) // 10)[:10, None]
                                       + np.arange(2)).ravel())
    assert main(["diagnose", str(path), "--run", "soft-0", "--auto", "--json"]) == 0
    final = json.loads(capsys.readouterr().out)["final"]
    assert "load_cell" in final["model"] and "gain" not in final["model"], final["model"]
    assert final["pulled_by_outliers"] is True


def test_a_uniform_fit_says_when_outlier_points_pull_it(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """The paper's weighting (every point the same) on a run with ten two-point glitches: K_c
    came out 15 ± 6 MN/m (10.36 ± 0.05 on the clean run), the ± spread by the glitches, with
    nothing said of them. Weighted by the noise, or on the clean run, there is nothing to say."""
    glitches = lambda size: (np.arange(30, size - 30, (size - 60) // 10)[:10, None]  # noqa: E731
                             + np.arange(2)).ravel()
    model = "fractional+load_cell+fixture(38)+fixture(58)+fixture(92)"
    said = []
    for name, points in (("pairs", glitches), ("clean", lambda size: np.arange(0))):
        path = with_outliers(tmp_path / f"{name}.h5", points)
        for weights in ("uniform", "noise"):
            assert main(["identify", str(path), "--run", "soft-0", "--model", model,
                         "--weights", weights, "--no-store"]) == 0
            said.append("outlier points (far outside the noise) hold" in capsys.readouterr().out)
    assert said == [True, False, False, False]


def test_a_whole_band_candidate_is_not_dragged_by_outliers_far_below_the_model_without_it(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """A new K* or load cell starts from an identify fit, which weighs every point alike: twenty
    outlier points dragged the load cell's start where its likelihood fit ended worse than the
    model without it (Δχ² −33,910), as if the data refused a term that can only add."""
    path = with_outliers(tmp_path / "outliers.h5",
                         lambda size: np.random.default_rng(5).choice(size, 20, replace=False))
    for model in ("voigt", "fractional+fixture(37.3)+fixture(58)+fixture(92)+gain(x_v)"):
        assert main(["diagnose", str(path), "--run", "soft-0", "--model", model, "--json"]) == 0
        findings = json.loads(capsys.readouterr().out)["findings"]
        # a few χ² short of the model without the term is a first fit stopping at its
        # tolerance near the term's limit (a load cell's rigid link, χ² of 10⁵ here); tens of
        # thousands is a fit dragged elsewhere
        worst = min(findings, key=lambda f: f["delta_chi2"])
        assert worst["delta_chi2"] > -100, (worst["model"], worst["delta_chi2"])


def test_a_run_with_the_table_frf_alone_is_identified_and_reported(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """A run imported with ẍ_s/F_e only: identify refused it by default ('has no
    accelerance_support') though its --frf help says "default: all available", and the report
    of any campaign holding it stopped with the same error."""
    soft = simulate_run("soft-0", seed=2)
    soft.accelerance_support = np.full(soft.frequency_hz.size, np.nan + 0j)
    path = tmp_path / "table-only.h5"
    with CampaignFile.create(path, sequence_text="", durable=False) as campaign:
        add_run(campaign, "table", simulate_run(rig_text(noise=DEFAULT_NOISE), seed=1), "none")
        add_run(campaign, "soft-0", soft, "soft")
    assert main(["identify", str(path), "--run", "soft-0", "--no-store"]) == 0
    assert "FRFs table," in capsys.readouterr().out
    assert main(["identify", str(path), "--run", "soft-0", "--frf", "both", "--no-store"]) == 2
    assert "has no accelerance_support" in capsys.readouterr().err
    out = tmp_path / "report"
    assert main(["report", str(path), "--out", str(out), "--no-ladder"]) == 0
    page = (out / "index.html").read_text(encoding="utf-8")
    assert "(diagnosed here, the table FRF alone)" in page
    assert "no ẍ_v/F_v: K* from Eq. 5 not computed" in page


def test_diagnose_names_a_band_that_misses_the_run_not_a_missing_frf(
    stopped_campaign: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    # it said "run 'soft-10': has no FRF to diagnose" of a run with both FRFs over 20-29 Hz
    assert main(["diagnose", str(stopped_campaign), "--run", "soft-10", "--band", "50:100"]) == 2
    assert capsys.readouterr().err == ("viscorig: run 'soft-10': the band 50:100 Hz holds none "
                                       "of its points (it spans 20-29 Hz)\n")


@pytest.mark.parametrize(("field", "model"), [("time_s", "voigt+drift"),
                                               ("reference_amplitude", "voigt+amplitude")])
def test_a_term_that_needs_what_some_points_lack_is_refused_in_one_line(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], field: str, model: str
) -> None:
    """Four points without a time (or a level), as a file written elsewhere may hold them:
    a drift fit ended in a traceback ('Residuals are not finite in the initial point'), and the
    diagnosis fitted drift and amplitude candidates to NaN, printing numpy's warnings."""
    path = with_outliers(tmp_path / "holes.h5", lambda size: np.arange(0))
    with h5py.File(path, "r+") as h5:
        values = h5[f"runs/soft-0/{field}"][()]
        values[5:9] = np.nan
        h5[f"runs/soft-0/{field}"][...] = values
    assert main(["identify", str(path), "--run", "soft-0", "--model", model, "--no-store"]) == 2
    error = capsys.readouterr().err
    assert f"needs {field}, which the run lacks at 4 of its points" in error
    assert "Traceback" not in error
    assert main(["diagnose", str(path), "--run", "soft-0", "--json"]) == 0
    out, error = capsys.readouterr()
    assert "Warning" not in error
    needing = model.split("+")[1]
    assert [f["model"] for f in json.loads(out)["findings"] if needing in f["model"]] == []


def test_a_bare_table_fit_that_determines_no_mass_is_refused(tmp_path: Path,
                                                             capsys) -> None:
    """A frame of 1 kg under a 3.4 kg table left M_s = 0.0 ± 1.1 kg, which every specimen
    fit then held fixed: K_v = 0 ± 2.2e9 N/m printed as the result."""
    from campaigndata import paper_campaign

    path = paper_campaign(tmp_path / "c.h5", runs=("table", "soft-0"))
    assert main(["identify", str(path), "--run", "soft-0", "--table-model",
                 "table+frame(1)", "--no-store"]) == 2
    err = capsys.readouterr().err
    assert "the bare-table fit (table+frame(1)) leaves M_s undetermined" in err, err
    assert main(["identify", str(path), "--run", "soft-0", "--no-store"]) == 0
