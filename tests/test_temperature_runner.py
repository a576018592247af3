"""Temperature steps on the embedded simulated rig: soaks through the chamber's Modbus
controller, the specimen temperature of every point, the soak-band flag, and the chamber left
at its safe set point on Ctrl-C and on a broken thermocouple (data kept)."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from stationfile import station_toml

from viscorig.acquisition import Console, Outcome, Runner, RunnerOptions
from viscorig.acquisition.chamber import ChamberMonitor
from viscorig.sequences import parse_sequence
from viscorig.stations.opening import simulated_station
from viscorig.storage import CampaignFile

HEAD = """\
name = "chamber"
[defaults]
band_hz = [20.0, 120.0]
resolution_hz = 20.0
settle_cycles = 20
integrate_cycles = 20
level = "1 m/s^2"
specimen = "medium"
hardness_shore_a = 33.0
segment_points = 2

[[steps]]
type = "prompt"
message = "Mount."
simulated_rig = "medium-chamber"
"""


def _run(tmp_path: Path, text: str, monitor: type[ChamberMonitor] | None = None,
         prepare=None):
    """Run ``text`` on the embedded rig in this process; (result, campaign path, chamber)."""
    sequence = parse_sequence(text, source="chamber.toml")
    out = tmp_path / "chamber.h5"
    with simulated_station(sequence) as opened:
        chamber = opened.mount.__self__.simulator.chamber  # the simulated chamber itself
        link = opened.chamber
        if monitor is not None:
            link = monitor(link.controller, link.station, link.pass_time)
            link.simulated = chamber
        if prepare is not None:
            prepare(opened.analyser, chamber)
        campaign = CampaignFile.create(out, sequence_text=text, sequence_file="chamber.toml",
                                   station_text=None, station_file="",
                                   rig=opened.station.rig_attributes())
        options = RunnerOptions(simulated=True, time_base="test", real_time_waits=False,
                                mount=opened.mount, instrument_errors=opened.instrument_errors,
                                chamber=link)
        runner = Runner(campaign, sequence, opened.station, opened.analyser,
                        Console(yes=True), options)
        result = runner.run()
        target = chamber.target_c
    return result, out, target



def lab_files(tmp_path: Path, analyser, rig, address: str) -> tuple[Path, Path]:
    """A lab station (the simulated analyser and chamber controller at ``address``) and a
    sequence that soaks at 23 °C and sweeps one run, written in ``tmp_path``."""
    station = tmp_path / "lab.toml"
    station.write_text(station_toml(
        analyser.socket_resource, force_v_per_n=rig.sensors.force_v_per_n,
        acceleration_v_per_m_s2=rig.sensors.acceleration_v_per_m_s2,
        gain_n_per_v=rig.shaker.force_n_per_v) + f"""\
[chamber]
address = "{address}"
specimen_unit = 2
low_limit_c = -30.0
high_limit_c = 60.0
safe_set_point_c = 20.0
""")
    sequence = tmp_path / "lab-seq.toml"
    sequence.write_text(HEAD + """
[[steps]]
type = "temperature"
set_point_c = 23.0
soak_minutes = 0

[[steps]]
type = "sweep"
run = "lab"
temperature_c = 23.0
""")
    return station, sequence


def test_soak_then_every_point_has_its_temperature(tmp_path: Path, capsys) -> None:
    text = HEAD + """
[[steps]]
type = "temperature"
set_point_c = 30.0
ramp_c_per_min = 5.0
soak_band_k = 1.0
soak_minutes = 1

[[steps]]
type = "sweep"
run = "hot"
temperature_c = 30.0
"""
    result, out, target = _run(tmp_path, text)
    assert result.outcome is Outcome.COMPLETE, result.message
    printed = capsys.readouterr().out
    assert "chamber set to 30 °C, ramp 5 °C/min" in printed and "soaked: specimen" in printed
    assert target == 25.0 and "chamber left at the safe set point 25 °C" in printed
    run = CampaignFile.open(out).run("hot")
    values, units = run.extra["temperature_c"]
    assert units == "degC" and values.size == run.points == 6
    assert np.all(np.abs(values - 30.0) <= 1.0)
    assert not np.any(run.flags & 16)
    assert run.metadata.temperature_c == 30.0


def test_points_outside_the_soak_band_are_flagged(tmp_path: Path) -> None:
    """A chamber that drifts after the soak (its set point changed at the front panel): the
    specimen warms during the sweep, its temperature is recorded, the points beyond the band
    are flagged 16."""

    def disturb_at_the_first_segment(opened_analyser, chamber) -> None:
        for name in ("measure", "measure_point"):
            measure = getattr(opened_analyser, name)

            def measure_and_disturb(*args, measure=measure, **kwargs):
                chamber.set_target(60.0)  # the front panel, not the sequence
                return measure(*args, **kwargs)

            setattr(opened_analyser, name, measure_and_disturb)

    text = HEAD.replace("settle_cycles = 20", "settle_cycles = 4000") + """
[[steps]]
type = "temperature"
set_point_c = 20.0
soak_band_k = 0.5
soak_minutes = 1

[[steps]]
type = "sweep"
run = "drifting"
temperature_c = 20.0
"""
    result, out, _ = _run(tmp_path, text, prepare=disturb_at_the_first_segment)
    assert result.outcome is Outcome.COMPLETE, result.message
    run = CampaignFile.open(out).run("drifting")
    values, _ = run.extra["temperature_c"]
    outside = np.abs(values - 20.0) > 0.5
    assert values[-1] > values[0] + 1.0  # warming through the run
    assert outside.any() and np.array_equal((run.flags & 16) != 0, outside)
    # diagnosis sees what was recorded, to explain a drift by it before inferring one
    from viscorig.diagnosis.data import recorded_temperature_range

    assert recorded_temperature_range(run) == (values.min(), values.max())


def test_broken_thermocouple_during_a_run(tmp_path: Path) -> None:
    """The specimen thermocouple breaks in the middle of a run: a fault in one line naming it,
    the segments committed before kept, the chamber at its safe set point."""

    def break_at_the_third_segment(opened_analyser, chamber) -> None:
        calls = []  # two probe points first, then the run's segments of two points
        for name in ("measure", "measure_point"):
            measure = getattr(opened_analyser, name)

            def measure_and_break(*args, measure=measure, **kwargs):
                calls.append(measure)
                if len(calls) == 5:
                    chamber.break_thermocouple("specimen")
                return measure(*args, **kwargs)

            setattr(opened_analyser, name, measure_and_break)

    text = HEAD + """
[[steps]]
type = "temperature"
set_point_c = 30.0
soak_band_k = 1.0
soak_minutes = 2

[[steps]]
type = "sweep"
run = "broken"
"""
    result, out, target = _run(tmp_path, text, prepare=break_at_the_third_segment)
    assert result.outcome is Outcome.FAULT
    assert "\n" not in result.message
    assert "sensor break on the specimen thermocouple" in result.message
    assert "TCPIP::" not in result.message  # the chamber's fault, not the analyser's
    assert "Check the chamber controller at tcp://127.0.0.1:" in result.message
    assert "Check the analyser" not in result.message
    assert "in run 'broken' after" in result.message and "(kept)" in result.message
    run = CampaignFile.open(out).run("broken")
    assert run.metadata.status == "aborted" and run.points == 4  # two segments before it
    assert target == 25.0


CTRL_C = HEAD + """
[[steps]]
type = "temperature"
set_point_c = 70.0
ramp_c_per_min = 0.05
soak_minutes = 600
time_limit_minutes = 10000
"""


@pytest.mark.slow  # a process of its own: about 10 s on a loaded machine
def test_ctrl_c_during_a_soak_leaves_the_safe_set_point(tmp_path: Path) -> None:
    sequence = tmp_path / "soak.toml"
    sequence.write_text(CTRL_C)
    process = subprocess.Popen(
        [sys.executable, "-m", "viscorig", "run", str(sequence), "--yes", "--out",
         str(tmp_path / "soak.h5"), "--sim-pace", "600"],
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, cwd=tmp_path,
        env={**os.environ, "PYTHONUNBUFFERED": "1"})
    try:
        lines = []
        for line in process.stdout:  # bounded: the soak alone lasts hours of test time
            lines.append(line)
            if line.startswith("chamber set to 70 °C"):
                break
        process.send_signal(signal.SIGINT)
        out, err = process.communicate(timeout=30)
    finally:
        if process.poll() is None:
            process.kill()
    assert process.returncode == 130, err
    assert "chamber left at the safe set point 25 °C" in out
    assert err.count("\n") == 1 and err.startswith("viscorig: interrupted")


@pytest.mark.parametrize("limit", [2])
def test_soak_past_its_time_limit_is_a_chamber_fault(tmp_path: Path, limit: int) -> None:
    text = HEAD + f"""
[[steps]]
type = "temperature"
set_point_c = -30.0
soak_band_k = 0.2
time_limit_minutes = {limit}
"""
    result, _, target = _run(tmp_path, text)
    assert result.outcome is Outcome.FAULT
    assert "not soaked within ±0.2 K of -30 °C" in result.message
    assert f"time limit {limit} min" in result.message and target == 25.0
    # where it stopped, and whose fault it is: the chamber's controller, not the analyser
    assert "Stopped during the soak at -30 °C (step 2)" in result.message
    assert "Check the chamber controller at tcp://127.0.0.1:" in result.message
    assert "Check the analyser" not in result.message


def test_a_lab_station_with_a_chamber(tmp_path: Path) -> None:
    """``run --station`` with a [chamber]: the analyser and the chamber's controller at the
    addresses the station names (here the simulated ones, on loopback), a soak already done at
    the start (no real waiting), every point's temperature recorded."""
    from rigsim.chamber import Chamber, ChamberParameters
    from rigsim.chamber_server import ChamberServer
    from rigsim.rigfile import load_preset
    from rigsim.server import SimulatedAnalyserServer

    from viscorig.cli import main

    rig = load_preset("medium-chamber")
    analyser = SimulatedAnalyserServer(rig).start()
    chamber = Chamber(ChamberParameters(start_temperature_c=23.0))
    analyser.analyser.simulator.attach_chamber(chamber)
    try:
        with ChamberServer(chamber) as controller:
            station, sequence = lab_files(tmp_path, analyser, rig, controller.address)
            out = tmp_path / "lab.h5"
            assert main(["run", str(sequence), "--station", str(station), "--yes", "--out",
                         str(out)]) == 0
            assert chamber.target_c == 20.0  # the station's safe set point, at the end
    finally:
        analyser.close()
    run = CampaignFile.open(out).run("lab")
    values, _ = run.extra["temperature_c"]
    assert values.size == run.points == 6 and np.all(np.abs(values - 23.0) < 0.1)
