"""Safety of a campaign: limits before the source, sweeps over the shaker limit, bad files.

- The source limit derived from the station's shaker (``min(source limit, force limit / gain)``)
  and the input limit (the force limit) are sent before every sweep starts (in swept sine the
  sweep drives the source: there is no ``OUTP``), and the sweep ends stopped: checked on the
  commands a recording loopback server received from ``viscorig run``.
- A sweep whose estimated force exceeds the shaker limit is refused (exit 2, nothing measured,
  the source never switched on) or run at a reduced level (``--over-limit reduce``), as the
  user chooses; the reduced run stays within the limit.
- Sequence and station files damaged at random: ``viscorig run`` answers one line with exit
  status 2 (3 when a valid station's analyser cannot be reached), never creates the campaign
  file and never changes the inputs.
"""

from __future__ import annotations

import hashlib
import re
from pathlib import Path

import pytest
import reliability_tally as tally
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from reliability_campaign import cli, one_clear_line, station_text, sweep_sequence
from rigsim.rigfile import load_preset
from rigsim.server import SimulatedAnalyserServer
from test_reliability_replies import DamagedAnalyser

from viscorig.storage import CampaignFile, PointFlag

REPO = Path(__file__).resolve().parents[1]


# -- limits before the source -------------------------------------------------------------------


@pytest.mark.parametrize(("limit_v", "force_limit_n", "expected_vpk"),
                         [(2.0, 100.0, 2.0), (5.0, 40.0, 0.8), (0.5, 100.0, 0.5)])
def test_limits_precede_every_source_switch_on(tmp_path: Path, limit_v: float,
                                               force_limit_n: float, expected_vpk: float) -> None:
    with DamagedAnalyser("", "", b"", 0) as server:  # a recording 35670A, nothing damaged
        station = tmp_path / "station.toml"
        station.write_text(station_text(server.resource, source_limit_v=limit_v,
                                        force_limit_n=force_limit_n))
        sequence = tmp_path / "sequence.toml"
        sequence.write_text(sweep_sequence(band=(20.0, 21.0), segment_points=801))
        status, _, err = cli(["run", sequence, "--station", station,
                              "--out", tmp_path / "c.h5", "--yes"])
        commands = server.commands(0.02)
    assert status == 0, err
    switch_ons = [i for i, c in enumerate(commands) if c == ":INIT:IMM"]
    assert switch_ons and not any(c.startswith("OUTP") for c in commands)
    limit = f"SOUR:VOLT:LIM {expected_vpk:.10g} VPK"
    input_limit = f"SOUR:VOLT:LIM:INP {force_limit_n:.10g} EU"
    for index in switch_ons:
        assert limit in commands[:index], commands[:index]
        assert input_limit in commands[:index]
        assert "SOUR:VOLT:AUTO ON" in commands[:index]
    limits = [c for c in commands if c.startswith("SOUR:VOLT:LIM ")]
    assert set(limits) == {limit}, "the source limit was changed to another value"
    assert commands[-1] == "ABOR"


# -- sweeps over the shaker limit: refused or reduced ------------------------------------------


@pytest.fixture
def heavy(tmp_path: Path):
    """The bare table at 50 m/s^2 from 15 Hz: about 112 N by the table's own parameters."""
    with SimulatedAnalyserServer(load_preset("table"), seed=5) as server:
        station = tmp_path / "station.toml"
        station.write_text(station_text(server.socket_resource, preset="table"))
        sequence = tmp_path / "sequence.toml"
        sequence.write_text(sweep_sequence(run="table", specimen="none", band=(15.0, 25.0),
                                           level="50 m/s^2", segment_points=20))
        yield server, station, sequence, tmp_path / "campaign.h5"


def check_reduced(path: Path) -> None:
    with CampaignFile.open(path) as campaign:
        run = campaign.run("table")
    assert run.metadata.status == "complete" and run.points == 41
    assert 30.0 < run.metadata.level_m_per_s2 < 50.0
    assert run.force_amplitude.max() <= 100.0 * 1.01
    assert not run.flagged(PointFlag.FORCE_ABOVE_SHAKER_LIMIT).any()


def test_a_sweep_over_the_shaker_limit_is_refused_then_reduced_on_resume(heavy) -> None:
    server, station, sequence, path = heavy
    status, _, err = cli(["run", sequence, "--station", station, "--out", path, "--yes"])
    assert status == 2
    line = one_clear_line(err)
    assert "exceeds the shaker limit 100 N" in line and "--over-limit reduce" in line
    assert re.search(r"estimated force 1[01]\d N", line), line
    with CampaignFile.open(path) as campaign:
        assert campaign.run_names == []  # nothing measured
    assert server.analyser.source_on is False and server.analyser.points_measured == 0
    status, _, err = cli(["resume", path, "--yes", "--over-limit", "reduce"])
    assert status == 0, err
    check_reduced(path)
    tally.add("faults tried")
    tally.add("faults recovered")


def test_a_sweep_over_the_shaker_limit_runs_reduced_when_asked(heavy) -> None:
    _, station, sequence, path = heavy
    status, _, err = cli(["run", sequence, "--station", station, "--out", path, "--yes",
                          "--over-limit", "reduce"])
    assert status == 0, err
    check_reduced(path)
    tally.add("faults tried")


# -- damaged sequence and station files through viscorig run --------------------------------------

PAPER = (REPO / "sequences" / "paper.toml").read_text(encoding="utf-8")
UNREACHABLE = "TCPIP::127.0.0.1::1::SOCKET"  # port 1: nothing listens there
STATION = station_text(UNREACHABLE)


@st.composite
def damaged_text(draw: st.DrawFn, text: str) -> str:
    """``text`` cut, with characters replaced or inserted, or lines dropped or repeated."""
    lines = text.splitlines(keepends=True)
    for _ in range(draw(st.integers(1, 3))):
        action = draw(st.sampled_from(["cut", "replace", "insert", "drop", "repeat"]))
        joined = "".join(lines)
        at = draw(st.integers(0, max(len(joined) - 1, 0)))
        if action == "cut":
            lines = [joined[:at]]
        elif action in ("replace", "insert"):
            junk = draw(st.text(st.sampled_from('=[]"\\#.-+0123456789 \nabcxyz\u00e9\x00'),
                                min_size=1, max_size=6))
            lines = [joined[:at] + junk + joined[at + (action == "replace"):]]
        elif lines:
            index = draw(st.integers(0, len(lines) - 1))
            lines = lines[:index] + ([lines[index]] * 2 if action == "repeat" else []) \
                + lines[index + 1:]
        lines = "".join(lines).splitlines(keepends=True)
    return "".join(lines)


def run_damaged(folder: Path, sequence_text: str, station: str) -> None:
    sequence, station_file = folder / "sequence.toml", folder / "station.toml"
    sequence.write_bytes(sequence_text.encode("utf-8", "surrogatepass"))
    station_file.write_text(station)
    hashes = [hashlib.sha256(p.read_bytes()).hexdigest() for p in (sequence, station_file)]
    out = folder / "campaign.h5"
    status, _, err = cli(["run", sequence, "--station", station_file, "--out", out, "--yes"])
    assert status in (2, 3), err  # 3: valid files, and the analyser cannot be reached
    line = one_clear_line(err)
    if status == 3:
        assert "cannot reach the analyser" in line
    assert not out.exists(), "a campaign file was created from bad input"
    assert [hashlib.sha256(p.read_bytes()).hexdigest()
            for p in (sequence, station_file)] == hashes
    tally.add("inputs fuzzed")


@settings(max_examples=60, deadline=None,
          suppress_health_check=[HealthCheck.too_slow, HealthCheck.function_scoped_fixture])
@given(text=damaged_text(PAPER))
def test_damaged_sequence_file_through_run(tmp_path_factory, text: str) -> None:
    run_damaged(tmp_path_factory.mktemp("seq"), text, STATION)


@settings(max_examples=60, deadline=None,
          suppress_health_check=[HealthCheck.too_slow, HealthCheck.function_scoped_fixture])
@given(text=damaged_text(STATION))
def test_damaged_station_file_through_run(tmp_path_factory, text: str) -> None:
    run_damaged(tmp_path_factory.mktemp("station"), PAPER, text)


@pytest.mark.parametrize("arguments", [
    ["run", "{missing}", "--yes"],
    ["run", "{folder}", "--yes"],
    ["run", "{paper}", "--station", "{folder}", "--yes", "--out", "{out}"],
    ["run", "{paper}", "--station", "{missing}", "--yes", "--out", "{out}"],
    ["run", "{paper}", "--yes", "--out", "{folder}"],
    ["run", "{paper}", "--yes", "--out", "{missing_folder}"],
    ["run", "{paper}", "--yes", "--sim-pace", "0"],
    ["run", "{paper}", "--yes", "--over-limit", "ignore"],
    ["resume", "{missing}", "--yes"],
    ["resume", "{folder}", "--yes"],
    ["resume", "{paper}", "--yes"],
])
def test_bad_run_and_resume_arguments(tmp_path: Path, arguments: list[str]) -> None:
    paths = {"missing": tmp_path / "missing.toml", "folder": tmp_path / "folder",
             "paper": REPO / "sequences" / "paper.toml", "out": tmp_path / "out.h5",
             "missing_folder": tmp_path / "nowhere" / "out.h5"}
    paths["folder"].mkdir()
    before = hashlib.sha256(paths["paper"].read_bytes()).hexdigest()
    status, _, err = cli([part.format(**paths) for part in arguments])
    assert status == 2, err
    one_clear_line(err)
    assert not paths["out"].exists() and not paths["missing_folder"].parent.exists()
    assert hashlib.sha256(paths["paper"].read_bytes()).hexdigest() == before
    assert sorted(p.name for p in tmp_path.iterdir()) == ["folder"]
    tally.add("inputs fuzzed")

