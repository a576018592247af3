"""Instrument faults during a campaign: what the user sees, what the file holds, how it goes on.

``viscorig run --station`` drives a simulated 35670A served on loopback (in this process)
through pyvisa-py, exactly as a lab analyser behind a socket. Each fault is injected after a
known number of segments has been committed (it arms when the analyser starts the next sweep).
For each fault the test checks:

- what the user sees: exit status 3 and one line naming the fault and ``viscorig resume`` (or,
  for faults the rig rides through, exit 0 and the points flagged);
- what the file holds: every segment committed before the fault (exactly as many points as the
  console reported), no gap, no duplicate, the run marked "aborted";
- that the analyser's source was switched off;
- how the run goes on: ``viscorig resume`` completes it, and the points measured before the
  fault are kept bit for bit (points lost: 0).
"""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pytest
import reliability_tally as tally
from reliability_campaign import (
    DelayedFaults,
    check_prefix,
    cli,
    one_clear_line,
    points_lost,
    snapshot,
    station_text,
    sweep_sequence,
)
from rigsim.faults import Fault
from rigsim.rigfile import load_preset
from rigsim.server import SimulatedAnalyserServer

from viscorig.storage import CampaignFile, PointFlag

GRID_HZ = 20.0 + 0.25 * np.arange(41)  # 20-30 Hz
SEGMENT_POINTS = 8
COMMITTED_SEGMENTS = 2


@pytest.fixture
def rig(tmp_path: Path):
    """A simulated analyser on loopback, its station file and a one-run sequence."""
    with SimulatedAnalyserServer(load_preset("soft-0"), seed=3) as server:
        station = tmp_path / "station.toml"
        station.write_text(station_text(server.socket_resource))
        sequence = tmp_path / "sequence.toml"
        sequence.write_text(sweep_sequence(segment_points=SEGMENT_POINTS))
        yield server, station, sequence, tmp_path / "campaign.h5"


def inject(server: SimulatedAnalyserServer, fault: Fault, after_sweeps: int) -> DelayedFaults:
    server.faults = DelayedFaults(server.analyser, fault, after_sweeps)
    return server.faults


def reported_points(out: str) -> int:
    """The point count of the last segment the console reported as committed."""
    counts = re.findall(r"points (\d+)/\d+", out)
    return int(counts[-1]) if counts else 0


def resume_and_check(server, station: Path, path: Path, before: dict) -> None:
    server.faults = DelayedFaults(server.analyser, None, 0)  # no more faults
    status, _, err = cli(["resume", path, "--yes"])
    assert status == 0, err
    assert check_prefix(path, "soft-0", GRID_HZ) == GRID_HZ.size
    with CampaignFile.open(path) as campaign:
        assert campaign.run("soft-0").metadata.status == "complete"
    lost = points_lost(before, snapshot(path))
    tally.add("points lost", lost)
    assert lost == 0
    tally.add("faults recovered")


STOPPING_FAULTS = {
    "garbled reply": Fault("garble", "*ESR?"),
    "error in the queue": Fault("error", "INIT", code=-310, message="System error; hardware"),
    "garbled status": Fault("garble", "STAT:QUES:VOLT:EVEN?"),
}


@pytest.mark.parametrize("name", list(STOPPING_FAULTS))
def test_a_fault_stops_the_run_keeps_its_segments_and_resume_completes_it(rig, name) -> None:
    stopping_fault(rig, STOPPING_FAULTS[name])


def stopping_fault(rig, fault: Fault) -> None:
    server, station, sequence, path = rig
    inject(server, fault, COMMITTED_SEGMENTS)
    status, out, err = cli(["run", sequence, "--station", station, "--out", path, "--yes"])
    tally.add("faults tried")

    assert status == 3, (out, err)
    line = one_clear_line(err)
    assert "instrument fault" in line and f"viscorig resume {path}" in line
    assert "kept" in line
    stored = check_prefix(path, "soft-0", GRID_HZ)
    assert stored == COMMITTED_SEGMENTS * SEGMENT_POINTS == reported_points(out)
    with CampaignFile.open(path) as campaign:
        assert campaign.run("soft-0").metadata.status == "aborted"
    assert not server.analyser.source_on, "the source was left on after the fault"
    resume_and_check(server, station, path, snapshot(path))


@pytest.mark.slow
@pytest.mark.parametrize(("kind", "match", "stops"), [
    ("no_reply", "*ESR?", True), ("no_reply", "TRAC:X?", False), ("garble", "TRAC:DATA?", False),
])
def test_a_lost_or_cut_reply_stops_or_is_retried(rig, kind: str, match: str, stops: bool) -> None:
    """A lost reply (or a block cut short, which waits for bytes that never come): a query that
    clears state (``*ESR?``) is not asked twice, so the run stops; an idempotent one is asked
    again and the run completes. Each costs the 5 s VISA timeout."""
    server, station, sequence, path = rig
    inject(server, Fault(kind, match), COMMITTED_SEGMENTS)
    status, out, err = cli(["run", sequence, "--station", station, "--out", path, "--yes"])
    tally.add("faults tried")
    if stops:
        assert status == 3, err
        assert "within the VISA timeout" in one_clear_line(err)
        assert check_prefix(path, "soft-0", GRID_HZ) == reported_points(out) == 16
        assert not server.analyser.source_on
        resume_and_check(server, station, path, snapshot(path))
    else:
        assert status == 0, err
        assert check_prefix(path, "soft-0", GRID_HZ) == GRID_HZ.size
        tally.add("faults recovered")


@pytest.mark.slow
def test_a_dropped_connection_stops_the_run_and_the_source_is_switched_off(rig) -> None:
    """The connection closes during the sweep (a cable pulled): the driver reopens it to switch
    the source off (a write to the dead socket would not have). Costs the 5 s VISA timeout."""
    stopping_fault(rig, Fault("drop", "*ESR?"))


@pytest.mark.slow
def test_a_dropped_connection_on_a_repeatable_query_is_ridden_through(rig) -> None:
    server, station, sequence, path = rig
    inject(server, Fault("drop", "TRAC:X?"), COMMITTED_SEGMENTS)
    status, _, err = cli(["run", sequence, "--station", station, "--out", path, "--yes"])
    tally.add("faults tried")
    assert status == 0, err
    assert check_prefix(path, "soft-0", GRID_HZ) == GRID_HZ.size
    tally.add("faults recovered")


@pytest.mark.parametrize(("points", "flagged"), [(None, False), (1000, True)])
def test_an_input_overload_is_remeasured_or_flagged(rig, points, flagged: bool) -> None:
    """One overloaded sweep is measured again (clean); an overload that persists is flagged."""
    server, station, sequence, path = rig
    inject(server, Fault("overload", "INIT", channel=2, points=points), COMMITTED_SEGMENTS)
    status, _, err = cli(["run", sequence, "--station", station, "--out", path, "--yes"])
    tally.add("faults tried")
    assert status == 0, err
    assert check_prefix(path, "soft-0", GRID_HZ) == GRID_HZ.size
    with CampaignFile.open(path) as campaign:
        run = campaign.run("soft-0")
    overloaded = run.flagged(PointFlag.INPUT_OVERLOAD)
    if flagged:
        assert overloaded.any() and not overloaded[: COMMITTED_SEGMENTS * SEGMENT_POINTS].any()
        status, shown, _ = cli(["show", path])
        assert "input overload" in shown
    else:
        assert not overloaded.any()
    tally.add("faults recovered")


def test_a_level_that_cannot_be_reached_is_flagged_not_hidden(tmp_path: Path) -> None:
    """A source limit too low for the level: every point the controller missed is flagged."""
    with SimulatedAnalyserServer(load_preset("soft-0"), seed=3) as server:
        station = tmp_path / "station.toml"
        station.write_text(station_text(server.socket_resource, source_limit_v=0.05))
        sequence = tmp_path / "sequence.toml"
        sequence.write_text(sweep_sequence(segment_points=20))
        path = tmp_path / "campaign.h5"
        status, _, err = cli(["run", sequence, "--station", station, "--out", path, "--yes"])
    tally.add("faults tried")
    assert status == 0, err
    with CampaignFile.open(path) as campaign:
        run = campaign.run("soft-0")
    missed = np.abs(20 * np.log10(run.reference_amplitude / 1.0)) > 1.0
    assert missed.any()
    assert np.array_equal(run.flagged(PointFlag.LEVEL_NOT_REACHED), missed)
    assert run.flagged(PointFlag.SOURCE_AT_LIMIT)[missed & (run.reference_amplitude < 1)].all()
    status, shown, _ = cli(["show", path])
    assert "level not reached" in shown


def test_a_force_the_shaker_cannot_give_is_refused_before_the_sweep(tmp_path: Path) -> None:
    """A shaker limit below what the level needs: the low-level probe before the newly mounted
    run predicts it, and the run is refused with nothing measured and the source off. (The
    analyser's input limit, which holds the drive and flags the points when a prediction is
    wrong, is tested on the sweep layer in test_runner.py.)"""
    with SimulatedAnalyserServer(load_preset("soft-0"), seed=3) as server:
        station = tmp_path / "station.toml"
        station.write_text(station_text(server.socket_resource, force_limit_n=5.0))
        sequence = tmp_path / "sequence.toml"
        sequence.write_text(sweep_sequence(segment_points=20))
        path = tmp_path / "campaign.h5"
        status, _, err = cli(["run", sequence, "--station", station, "--out", path, "--yes"])
        source_on = server.analyser.source_on
    tally.add("faults tried")
    assert status == 2, err
    line = one_clear_line(err)
    assert "exceeds the shaker limit 5 N" in line and "from a probe of the mounted rig" in line
    with CampaignFile.open(path) as campaign:
        assert campaign.run_names == []
    assert not source_on
