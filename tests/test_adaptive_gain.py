"""Adaptive plans on a station that does not give the shaker's gain: the rig measures it.

The station files here leave out (or misstate) ``[shaker] gain_n_per_v``; the analyser is the
virtual 35670A on a simulated Voigt rig, reached through the real driver over pyvisa-py. The
gain the run stores is checked against the rig file's shaker (``force_n_per_v``), a number the
code under test never reads.
"""

from __future__ import annotations

import math
import re
from pathlib import Path

import numpy as np
import pytest
from planning_rig import ADAPTIVE_SEQUENCE, VOIGT_RIG
from reliability_campaign import station_text

from viscorig.acquisition.gain import estimate_gain
from viscorig.cli import main
from viscorig.storage import CampaignFile

server_module = pytest.importorskip("rigsim.server")

LOOSE = {"K_v": 1e-4, "C_v": 5e-4}
#: A short plan for the tests of the gain alone: the gain is measured before the plan starts.
SHORT = "dwell_limit_s = 5"
#: The paper plan's dwell on this band (20-120 Hz every 0.25 Hz, 100 + 100 periods), s.
PAPER_DWELL_S = 1433.0


def _true_gain() -> float:
    return float(re.search(r"force_n_per_v = ([0-9.eE+-]+)", VOIGT_RIG).group(1))


@pytest.fixture
def voigt_rig():
    from rigsim.rigfile import parse_rig

    with server_module.SimulatedAnalyserServer(parse_rig(VOIGT_RIG, "voigt rig"),
                                               seed=7) as server:
        yield server


def _station(server, gain: float | None) -> str:
    text = station_text(server.resource, preset="soft-0")
    lines = [line for line in text.splitlines() if not line.startswith("gain_n_per_v")]
    if gain is not None:
        lines.insert(lines.index("[shaker]") + 1, f"gain_n_per_v = {gain}")
    return "\n".join(lines) + "\n"


def _run(tmp_path: Path, server, gain: float | None, targets=LOOSE, name: str = "out",
         extra: str = SHORT):
    station = tmp_path / f"{name}-station.toml"
    station.write_text(_station(server, gain))
    sequence = tmp_path / f"{name}.toml"
    sequence.write_text(ADAPTIVE_SEQUENCE.format(extra=extra, **targets))
    out = tmp_path / f"{name}.h5"
    status = main(["run", str(sequence), "--station", str(station), "--out", str(out), "--yes"])
    return status, out


def test_a_station_without_the_gain_runs_an_adaptive_plan_and_stores_the_gain(
        tmp_path, voigt_rig, capsys) -> None:
    status, out = _run(tmp_path, voigt_rig, gain=None)
    printed = capsys.readouterr()
    assert status == 0, printed.err
    assert "WARNING" not in printed.out and "gain_n_per_v" not in printed.err
    assert re.search(r"run 'voigt': shaker gain [0-9.]+ ± [0-9.e-]+ N/V \(measured at 20 and "
                     r"120 Hz", printed.out), printed.out
    campaign = CampaignFile.open(out)
    attributes = campaign.run_attributes("voigt")
    assert attributes["plan_reason"] == "dwell limit" and campaign.run("voigt").points >= 10
    gain, stderr = attributes["shaker_gain_n_per_v"], attributes["shaker_gain_stderr_n_per_v"]
    assert 0 < stderr < 0.01 * gain
    assert abs(gain - _true_gain()) < 4 * stderr, (gain, stderr)
    assert "auto level off" in attributes["shaker_gain_basis"]


def test_a_station_gain_that_disagrees_is_warned_about_and_the_measured_one_used(
        tmp_path, voigt_rig, capsys) -> None:
    status, out = _run(tmp_path, voigt_rig, gain=0.8 * _true_gain())
    printed = capsys.readouterr()
    assert status == 0, printed.err
    warning = next(line for line in printed.out.splitlines() if "disagrees" in line)
    assert warning.startswith("WARNING: run 'voigt': the station file's [shaker]")
    assert f"gain_n_per_v = {0.8 * _true_gain():g} N/V disagrees with the" in warning
    assert "the measured gain is used" in warning
    gain = CampaignFile.open(out).run_attributes("voigt")["shaker_gain_n_per_v"]
    assert gain == pytest.approx(_true_gain(), rel=0.01)


def test_a_station_gain_within_the_uncertainty_is_not_warned_about(tmp_path, voigt_rig,
                                                                   capsys) -> None:
    status, _ = _run(tmp_path, voigt_rig, gain=_true_gain())
    printed = capsys.readouterr()
    assert status == 0 and "disagrees" not in printed.out + printed.err, printed.err


@pytest.mark.slow
def test_the_measured_gain_keeps_the_plans_efficiency(tmp_path, voigt_rig, capsys) -> None:
    """With the tight targets the paper plan's stderr sets, the plan on a station without the
    gain takes as little rig time as with the gain given (0.40 of the paper plan's dwell)."""
    tight = {"K_v": 2e-5, "C_v": 1e-4}
    times = {}
    for name, gain in (("given", _true_gain()), ("measured", None)):
        status, out = _run(tmp_path, voigt_rig, gain, tight, name, extra="")
        assert status == 0, capsys.readouterr().err
        attributes = CampaignFile.open(out).run_attributes("voigt")
        assert attributes["plan_reason"] == "targets met"
        times[name] = float(attributes["test_time_s"])
    print(f"\nrig time: gain given {times['given']:.1f} s, measured {times['measured']:.1f} s "
          f"({times['measured'] / PAPER_DWELL_S:.2f} of the paper plan's dwell)")
    assert times["measured"] < 0.45 * PAPER_DWELL_S
    assert times["measured"] < 1.15 * times["given"]


def test_the_gain_is_the_mean_force_per_volt_with_the_larger_of_noise_and_scatter() -> None:
    # two points at 0.01 V: 0.50 N and 0.52 N, each with a 0.1 % amplitude noise
    estimate = estimate_gain([20.0, 120.0], [0.50, 0.52], 0.01, [1e-6, 1e-6])
    assert estimate is not None
    assert estimate.value_n_per_v == pytest.approx(51.0)
    assert estimate.stderr_n_per_v == pytest.approx(1.0)  # scatter: std 1.414 / sqrt 2
    quiet = estimate_gain([20.0, 120.0], [0.5, 0.5], 0.01, [4e-6, 4e-6])
    assert quiet.stderr_n_per_v == pytest.approx(math.sqrt(2 * (50 * 2e-3) ** 2) / 2)
    assert estimate_gain([20.0], [np.nan], 0.01) is None  # no force: amplifier off
    assert estimate_gain([20.0, 120.0], [0.0, 0.5], 0.01).frequency_hz == (120.0,)
