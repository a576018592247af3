"""The sequence runner on a station: the virtual 35670A on loopback, through the real driver.

Each test starts a simulated analyser server, writes a station file naming its socket, and
runs ``viscorig run``/``resume`` in process, as a lab station would be used.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from viscorig.cli import main
from viscorig.storage import (
    FORCE_ABOVE_SHAKER_LIMIT,
    INPUT_OVERLOAD,
    LEVEL_NOT_REACHED,
    SOURCE_AT_LIMIT,
    Campaign,
)

server_module = pytest.importorskip("rigsim.server")

STATION = """
resource = "{resource}"
[channels]
excitation_force = 1
table_acceleration = 2
device_force = 3
device_acceleration = 4
[sensitivity]
excitation_force_v_per_n = 0.01124
table_acceleration_v_per_m_s2 = 0.0102
device_force_v_per_n = 0.01124
device_acceleration_v_per_m_s2 = 0.0102
[shaker]
force_limit_n = {force_limit}
gain_n_per_v = 50.0
[source]
limit_v = {source_limit}
[table]
mass_kg = 3.4
stiffness_n_per_m = 50194.0
damping_ns_per_m = 5.05
"""

SEQUENCE = """
name = "short"
[defaults]
resolution_hz = 0.25
settle_cycles = 10
integrate_cycles = 10
segment_s = 3
level = "{level}"
[[steps]]
type = "prompt"
message = "Mount the specimens."
[[steps]]
type = "sweep"
run = "{run}"
specimen = "{specimen}"
band_hz = [{lo}, {hi}]
"""


@pytest.fixture
def rig(request):
    preset = getattr(request, "param", "soft-0")
    with server_module.SimulatedAnalyserServer(preset, seed=5) as server:
        yield server


def write_files(tmp_path, server, *, level="1.4 m/s^2", force_limit=100.0, source_limit=2.0,
                run="soft-0", specimen="soft", band=(20.0, 24.0)):
    station = tmp_path / "station.toml"
    station.write_text(STATION.format(resource=server.resource, force_limit=force_limit,
                                      source_limit=source_limit))
    sequence = tmp_path / "short.toml"
    sequence.write_text(SEQUENCE.format(level=level, run=run, specimen=specimen, lo=band[0],
                                        hi=band[1]))
    return str(sequence), str(station), str(tmp_path / "out.h5")


def run_cli(*args: str) -> int:
    return main(["run", *args, "--yes"])


def test_a_station_run_is_recorded_with_its_metadata(tmp_path, rig, capsys) -> None:
    sequence, station, out = write_files(tmp_path, rig)
    assert run_cli(sequence, "--station", station, "--out", out) == 0
    campaign = Campaign.open(out)
    run = campaign.run("soft-0")
    assert run.points == 17 and run.metadata.status == "complete"
    assert run.metadata.resource == rig.resource and not run.metadata.simulated
    assert "35670A" in run.metadata.instrument
    assert not run.flags.any()
    assert np.all(np.abs(20 * np.log10(run.reference_amplitude / 1.4)) <= 1.0)
    assert campaign.station_text is not None and rig.resource in campaign.station_text
    assert campaign.rig["table_mass_kg"] == 3.4
    printed = capsys.readouterr().out
    assert "Mount the specimens. [--yes]" in printed
    assert "estimated force up to" in printed and "shaker limit 100 N" in printed
    # time_s is the wall clock since the run started on a station, increasing
    assert np.all(np.diff(run.time_s) > 0)


def test_a_level_the_source_cannot_reach_is_flagged_as_source_limited(tmp_path, rig) -> None:
    # 0.02 V is 1 N of shaker force; the soft rig needs about 13 N at 20 Hz for 1.4 m/s^2
    sequence, station, out = write_files(tmp_path, rig, source_limit=0.02)
    assert run_cli(sequence, "--station", station, "--out", out) == 0
    run = Campaign.open(out).run("soft-0")
    assert np.all(run.flags == LEVEL_NOT_REACHED | SOURCE_AT_LIMIT)
    assert np.all(run.force_amplitude < 1.1)


def test_a_level_held_back_by_the_shaker_limit_is_flagged_but_not_as_source_limited(
    tmp_path, rig
) -> None:
    """The analyser's input limit is the last defence when a force prediction is wrong: the
    runner would refuse this sweep (13 N predicted, 5 N limit), so the sweep layer measures it
    directly, configured as the runner configures every sweep."""
    from agilent35670a import Agilent35670A

    from viscorig.acquisition import SweepMeasurement, SweepSettings, Wiring, configure
    from viscorig.sequences import load_sequence, load_station
    from viscorig.storage import RunSettings

    # the station's shaker takes 5 N (0.1 V at 50 N/V); the soft rig needs about 13 N at 20 Hz
    sequence, station, out = write_files(tmp_path, rig, force_limit=5.0, source_limit=5.0)
    step = load_sequence(sequence).sweep("soft-0")
    wiring = Wiring.from_station(load_station(station))
    settings = SweepSettings(step=step, level_m_per_s2=1.4, force_limit_n=5.0,
                             source_limit_v=0.1, time_base="test", poll_interval_s=0.01)
    campaign = Campaign.create(out, sequence_text=Path(sequence).read_text(), durable=False)
    campaign.start_run("soft-0", RunSettings(specimen="soft", level_m_per_s2=1.4, direction="up",
                                             settle_cycles=10, integrate_cycles=10,
                                             resolution_hz=0.25))
    analyser = Agilent35670A.open(rig.resource, timeout_s=5.0)
    try:
        configure(analyser, wiring, settings)
        SweepMeasurement(campaign, analyser, wiring, settings).run()
    finally:
        analyser.close()
    run = Campaign.open(out).run("soft-0")
    assert run.points == 17
    assert np.all(run.force_amplitude <= 5.0 * 1.01)
    assert np.all(run.flags == LEVEL_NOT_REACHED)
    assert np.all(run.reference_amplitude < 1.4 * 10 ** (-1 / 20))


@pytest.mark.parametrize("rig", ["table"], indirect=True)
def test_a_sweep_over_the_shaker_limit_is_refused_and_nothing_is_measured(
    tmp_path, rig, capsys
) -> None:
    sequence, station, out = write_files(tmp_path, rig, level="300 m/s^2", run="table",
                                         specimen="none", band=(12.0, 14.0))
    assert run_cli(sequence, "--station", station, "--out", out) == 2
    error = capsys.readouterr().err
    assert "exceeds the shaker limit 100 N" in error and "--over-limit reduce" in error
    assert Campaign.open(out).run_names == []


@pytest.mark.parametrize("rig", ["table"], indirect=True)
def test_a_sweep_over_the_shaker_limit_can_run_at_a_reduced_level(tmp_path, rig) -> None:
    sequence, station, out = write_files(tmp_path, rig, level="300 m/s^2", run="table",
                                         specimen="none", band=(12.0, 14.0))
    assert run_cli(sequence, "--station", station, "--out", out, "--over-limit", "reduce") == 0
    campaign = Campaign.open(out)
    run = campaign.run("table")
    assert run.metadata.level_m_per_s2 < 300.0
    assert np.all(run.force_amplitude < 100.0)
    assert not (run.flags & (LEVEL_NOT_REACHED | FORCE_ABOVE_SHAKER_LIMIT)).any()
    import h5py

    with h5py.File(out, "r") as h5:
        attributes = h5["runs/table"].attrs
        assert attributes["requested_level_m_per_s2"] == 300.0
        assert attributes["estimated_peak_force_n"] > 100.0
        assert "NaN" in h5["runs/table/source_amplitude"].attrs["note"]


def test_an_input_overload_is_measured_again_or_flagged(tmp_path, rig) -> None:
    sequence, station, out = write_files(tmp_path, rig)
    rig.analyser.force_overload(4, points=2)  # a transient: gone when measured again
    assert run_cli(sequence, "--station", station, "--out", out) == 0
    assert not (Campaign.open(out).run("soft-0").flags & INPUT_OVERLOAD).any()
    out2 = str(tmp_path / "again.h5")
    rig.analyser.force_overload(4, points=10_000)  # persistent: flagged
    assert run_cli(sequence, "--station", station, "--out", out2) == 0
    assert np.all(Campaign.open(out2).run("soft-0").flags & INPUT_OVERLOAD)


def test_an_instrument_fault_mid_sweep_keeps_the_data_and_resume_completes(
    tmp_path, rig, capsys
) -> None:
    sequence, station, out = write_files(tmp_path, rig, band=(20.0, 26.0))
    seen = []

    def fault_after_some_points(count: int) -> None:
        seen.append(count)
        if len(seen) == 9:
            rig.analyser.push_error(-310, "System error; hardware fault")

    rig.analyser.on_point = fault_after_some_points
    assert run_cli(sequence, "--station", station, "--out", out) == 3
    error = capsys.readouterr().err
    assert error.count("\n") == 1 and "hardware fault" in error and rig.resource in error
    assert f"viscorig resume {out}" in error
    run = Campaign.open(out).run("soft-0")
    assert run.metadata.status == "aborted" and 0 < run.points < 25
    kept = run.frequency_hz.copy()

    rig.analyser.on_point = None
    assert main(["resume", out, "--yes"]) == 0
    run = Campaign.open(out).run("soft-0")
    assert run.metadata.status == "complete"
    np.testing.assert_allclose(run.frequency_hz, 20.0 + 0.25 * np.arange(25))
    np.testing.assert_array_equal(run.frequency_hz[: kept.size], kept)
    assert "continuing run 'soft-0' from point" in capsys.readouterr().out
    assert main(["resume", out, "--yes"]) == 0  # nothing left to do


def test_an_unreachable_analyser_is_exit_3_and_writes_nothing(tmp_path, rig, capsys) -> None:
    sequence, station, out = write_files(tmp_path, rig)
    text = (tmp_path / "station.toml").read_text().replace(rig.resource,
                                                          "TCPIP::127.0.0.1::1::SOCKET")
    (tmp_path / "station.toml").write_text(text)
    assert run_cli(sequence, "--station", station, "--out", out) == 3
    assert "TCPIP::127.0.0.1::1::SOCKET" in capsys.readouterr().err
    assert not (tmp_path / "out.h5").exists()
