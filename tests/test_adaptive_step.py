"""The adaptive sweep step of a sequence, as a lab runs it: a station whose analyser is the virtual
35670A measuring a simulated rig, reached through the real driver over pyvisa-py.

The rig is a Voigt damper on the paper's table with a rigid link (the model is exact), so the
plan can meet its targets; the run is then read back as every analysis command reads it.
"""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pytest
from planning_rig import ADAPTIVE_SEQUENCE, VOIGT_RIG, VOIGT_TRUTH
from reliability_campaign import station_text

from viscorig.cli import main
from viscorig.storage import CampaignFile

server_module = pytest.importorskip("rigsim.server")

TARGETS = {"K_v": 2e-5, "C_v": 1e-4}


@pytest.fixture
def voigt_rig():
    from rigsim.rigfile import parse_rig

    with server_module.SimulatedAnalyserServer(parse_rig(VOIGT_RIG, "voigt rig"),
                                               seed=7) as server:
        yield server


def files(tmp_path: Path, server, extra: str = "", targets=None) -> tuple[str, str, str]:
    station = tmp_path / "station.toml"
    station.write_text(station_text(server.resource, preset="soft-0"))
    sequence = tmp_path / "adaptive.toml"
    sequence.write_text(ADAPTIVE_SEQUENCE.format(extra=extra, **(targets or TARGETS)))
    return str(sequence), str(station), str(tmp_path / "out.h5")


def relative(fit: dict, name: str) -> float:
    parameter = fit["parameters"][name]
    return parameter["stderr"] / abs(parameter["value"])


@pytest.mark.slow
def test_an_adaptive_step_meets_its_targets_and_identify_reads_them_back(
    tmp_path, voigt_rig, capsys
) -> None:
    sequence, station, out = files(tmp_path, voigt_rig)
    assert main(["run", sequence, "--station", station, "--out", out, "--yes"]) == 0
    printed = capsys.readouterr().out
    assert "steps[1] adaptive sweep voigt" in printed and "or more" in printed  # forecast
    assert "first look: 10 points" in printed
    assert re.search(r"run 'voigt' complete \(adaptive plan: targets met\): \d+ points at "
                     r"\d+ frequencies", printed), printed
    campaign = CampaignFile.open(out)
    run = campaign.run("voigt")
    attributes = campaign.run_attributes("voigt")
    assert attributes["plan"] == "adaptive" and attributes["plan_reason"] == "targets met"
    assert attributes["plan_targets"] == "K_v=2e-05 C_v=0.0001"
    # every point stored in measurement order, with its own settle and integration
    assert run.settle_cycles is not None and run.integrate_cycles is not None
    assert np.unique(run.settle_cycles).size > 1 and np.unique(run.integrate_cycles).size > 1
    assert np.all(run.integrate_cycles <= 234)
    assert np.unique(run.frequency_hz).size < run.points  # repeats of the chosen frequencies
    # time_s is the running sum of each point's rig time: settle and integration (test clock)
    rig_time = (run.settle_cycles + run.integrate_cycles) / run.frequency_hz
    np.testing.assert_allclose(np.diff(np.r_[0.0, run.time_s]), rig_time, rtol=1e-9)
    assert attributes["test_time_s"] == pytest.approx(run.time_s[-1])
    assert attributes["test_time_s"] < 0.45 * 1433.0  # far below the paper plan's dwell
    # the run attributes hold the bounds, the run's merged reading one point per frequency
    merged = run.merged()
    assert merged.points == np.unique(run.frequency_hz).size
    assert np.all(np.diff(merged.frequency_hz) > 0)
    # identify (the project's estimator) reports what the plan reached
    assert main(["identify", out, "--run", "voigt", "--frf", "both", "--json",
                 "--no-store"]) == 0
    import json

    fit = json.loads(capsys.readouterr().out)
    assert fit["weighting"] == "noise" and fit["points"] == merged.points
    for name, target in TARGETS.items():
        assert relative(fit, name) <= 1.1 * target, (name, relative(fit, name))
        value, stderr = fit["parameters"][name]["value"], fit["parameters"][name]["stderr"]
        assert abs(value - VOIGT_TRUTH[name]) < 4 * stderr, name
    # show and summary read it as any run
    assert main(["show", out]) == 0
    listing = capsys.readouterr().out
    assert re.search(rf"voigt: adaptive plan for voigt \(K_v=2e-05 C_v=0.0001\): targets met; "
                     rf"{run.points} points at {merged.points} frequencies, rig time", listing)
    assert main(["summary", out, "--json"]) == 0


@pytest.mark.slow
def test_a_plan_stopped_by_a_fault_resumes_from_the_points_the_file_holds(
    tmp_path, voigt_rig, capsys
) -> None:
    sequence, station, out = files(tmp_path, voigt_rig)
    seen = []

    def fault_after_the_first_look(count: int) -> None:
        seen.append(count)
        if len(seen) == 30:  # probe 2 points, look 10, then inside the first chosen batch
            voigt_rig.analyser.push_error(-310, "System error; hardware fault")

    voigt_rig.analyser.on_point = fault_after_the_first_look
    assert main(["run", sequence, "--station", station, "--out", out, "--yes"]) == 3
    assert "hardware fault" in capsys.readouterr().err
    stopped = CampaignFile.open(out).run("voigt")
    assert stopped.metadata.status == "aborted" and stopped.points >= 10
    kept = stopped.frequency_hz.copy()

    voigt_rig.analyser.on_point = None
    assert main(["resume", out, "--yes"]) == 0
    printed = capsys.readouterr().out
    assert f"its {stopped.points} points handed to the plan again" in printed
    campaign = CampaignFile.open(out)
    run = campaign.run("voigt")
    assert run.metadata.status == "complete"
    np.testing.assert_array_equal(run.frequency_hz[: kept.size], kept)  # nothing lost or redone
    assert campaign.run_attributes("voigt")["plan_reason"] == "targets met"
    assert np.all(np.diff(run.time_s) > 0)


@pytest.mark.slow
def test_an_adaptive_step_keeps_to_its_dwell_limit(tmp_path, voigt_rig, capsys) -> None:
    sequence, station, out = files(tmp_path, voigt_rig, "dwell_limit_s = 60",
                                   {"K_v": 1e-6, "C_v": 1e-5})
    assert main(["run", sequence, "--station", station, "--out", out, "--yes"]) == 0
    attributes = CampaignFile.open(out).run_attributes("voigt")
    assert attributes["plan_reason"] == "dwell limit"
    assert attributes["test_time_s"] <= 60.0
    assert "adaptive plan: dwell limit" in capsys.readouterr().out


@pytest.mark.slow
def test_an_adaptive_step_runs_on_sim_serve_through_the_driver_and_pyvisa_py(tmp_path,
                                                                               capsys) -> None:
    """The virtual analyser as a separate network service (``viscorig sim serve``), as a lab's
    analyser behind a socket is reached."""
    from simserve import sim_serve

    rig = tmp_path / "voigt.toml"
    rig.write_text(VOIGT_RIG)
    with sim_serve("--rig", str(rig), "--seed", "3") as (_, _, resource, _):
        station = tmp_path / "station.toml"
        station.write_text(station_text(resource, preset="soft-0"))
        sequence = tmp_path / "adaptive.toml"
        sequence.write_text(ADAPTIVE_SEQUENCE.format(extra="", K_v=1e-4, C_v=5e-4))
        out = tmp_path / "out.h5"
        assert main(["run", str(sequence), "--station", str(station), "--out", str(out),
                     "--yes"]) == 0
    assert "adaptive plan: targets met" in capsys.readouterr().out
    campaign = CampaignFile.open(out)
    run = campaign.run("voigt")
    assert run.metadata.resource == resource and run.metadata.status == "complete"
    assert campaign.run_attributes("voigt")["plan_reason"] == "targets met"
    assert run.points > np.unique(run.frequency_hz).size >= 40  # look, coverage, repeats


@pytest.mark.slow
def test_the_example_sequence_on_the_embedded_rig_reads_as_any_run(tmp_path, capsys) -> None:
    """``sequences/adaptive.toml`` on the embedded simulated rig (the virtual analyser through
    the driver): a Voigt plan on the paper's soft rubber stops once the band is covered, and
    every command reads the run (diagnose names the effect the full sweep's diagnosis names
    first, the report draws it)."""
    out = tmp_path / "adaptive.h5"
    example = Path(__file__).resolve().parents[1] / "sequences" / "adaptive.toml"
    assert main(["run", str(example), "--yes", "--out", str(out)]) == 0
    printed = capsys.readouterr().out
    assert printed.index("predicted test time:") < printed.index(">>> Remove the damper")
    assert "adaptive plan: model misfit" in printed
    attributes = CampaignFile.open(out).run_attributes("soft-0")
    assert attributes["plan_reason"] == "model misfit" and attributes["test_time_s"] < 120.0
    assert main(["diagnose", str(out), "--run", "soft-0", "--json"]) == 0
    import json

    diagnosis = json.loads(capsys.readouterr().out)
    first = next(item for item in diagnosis["findings"] if item["significant"])
    assert first["effect"] == "frequency_dependent_modulus"
    assert main(["summary", str(out)]) == 0
    assert main(["report", str(out), "--out", str(tmp_path / "report"), "--no-diagnosis"]) == 0
    assert (tmp_path / "report" / "frf-soft-0.png").exists()
    from viscorig.watch.snapshot import read_snapshot  # the live view of such a run

    soft = next(run for run in read_snapshot(out)["runs"] if run["name"] == "soft-0")
    assert soft["planned"] == soft["points"] and soft["left_s"] == 0.0
    assert soft["frequency_hz"] == sorted(soft["frequency_hz"])
