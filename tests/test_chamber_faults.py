"""The chamber's controller misbehaving, over a real Modbus link to the simulated controller:
bad replies, a controller that stops answering. Whatever happens the chamber is left at the
station's safe set point when the controller takes it (tried again on a bad reply), the
operator reads one line that names the chamber's controller and where the sequence stopped (and
says so when the chamber could NOT be set safe), and the measured data is kept."""

from __future__ import annotations

import time
from pathlib import Path

import numpy as np
import pytest
from eurotherm3200 import ChamberError, Eurotherm3200
from rigsim.chamber import Chamber, ChamberParameters
from rigsim.chamber_server import RATE, TARGET, ChamberServer
from test_temperature_runner import lab_files

from viscorig.acquisition.chamber import (
    SAFE_BUDGET_S,
    ChamberMonitor,
    ChamberNotSafeError,
)
from viscorig.sequences import ChamberStation
from viscorig.storage import CampaignFile

FAST = {"timeout_s": 0.3, "retries": 0}
SAFE_C = 20.0


class FaultyController(ChamberServer):
    """The simulated controller with a fault of a given length: ``garble`` or ``silent``
    replies ``count`` times (None: for good) from the ``after``-th reply on, or from the
    moment the safe set point is written (``at_safe``). It records the writes it receives."""

    def __init__(self, chamber: Chamber, **kwargs) -> None:
        super().__init__(chamber, **kwargs)
        self.plan: tuple[str, int | None, int | None] = ("none", None, None)
        self.replies = 0
        self.faulted = 0
        self.writes: list[tuple[int, int]] = []
        self.at_safe: str | None = None

    def arm(self, fault: str, count: int | None, after: int = 0) -> None:
        self.plan = (fault, count, self.replies + after)
        self.faulted = 0

    def _trace(self, sending: bool, data: bytes) -> bytes:
        if not sending:
            return data
        self.replies += 1
        fault, count, after = self.plan
        if after is not None and self.replies > after and (count is None
                                                           or self.faulted < count):
            self.faulted += 1
            self.fault = fault
            try:
                return super()._trace(sending, data)
            finally:
                self.fault = "none"
        return super()._trace(sending, data)

    async def _action(self, sensor, function_code, start_address, address, count, registers,
                      values):
        if values is not None and function_code in (6, 16):
            self.writes.append((address, values[0]))
            if self.at_safe and address == TARGET and values[0] == round(SAFE_C * 10):
                self.arm(self.at_safe, None)
        return await super()._action(sensor, function_code, start_address, address, count,
                                     registers, values)


def _station(address: str) -> ChamberStation:
    return ChamberStation(address=address, low_limit_c=-30.0, high_limit_c=60.0,
                          safe_set_point_c=SAFE_C, specimen_unit=2)


@pytest.fixture(params=["tcp", "rtu"])
def served(request):
    chamber = Chamber(ChamberParameters(start_temperature_c=23.0))
    with FaultyController(chamber, transport=request.param) as server, Eurotherm3200.open(
            server.address, specimen_unit=2, limits_c=(-30.0, 60.0), **FAST) as controller:
        controller.set_rate_limit(0.5)
        controller.set_target(23.0)
        server.writes.clear()
        monitor = ChamberMonitor(controller, _station(server.address), errors=(ChamberError,))
        yield chamber, server, controller, monitor


def test_safe_set_point_written_through_bad_replies(served) -> None:
    """Two corrupted replies in a row (the audit's case): the safe set point is written first
    and tried again, then the ramp-rate limit is cleared; the controller's registers say so."""
    chamber, server, controller, monitor = served
    server.arm("garble", 2)
    assert monitor.to_safe() == (SAFE_C, "")
    assert server.faulted == 2
    assert controller.target_c() == SAFE_C and chamber.target_c == SAFE_C
    assert controller.rate_limit_c_per_min() == 0.0
    # the set point first; each write again after a bad reply (on TCP the corrupted reply's
    # write has landed, on RTU the frame is dropped: a missing reply, the same remedy)
    addresses = [address for address, _ in server.writes]
    assert addresses[0] == TARGET and addresses[-1] == RATE
    assert addresses.count(TARGET) == 3 and addresses.count(RATE) == 1


def test_silent_controller_is_not_safe_within_the_budget(served) -> None:
    _, server, _, monitor = served
    server.arm("silent", None)
    started = time.monotonic()
    with pytest.raises(ChamberNotSafeError) as caught:
        monitor.to_safe()
    elapsed = time.monotonic() - started
    assert elapsed <= SAFE_BUDGET_S
    message = str(caught.value)
    assert "\n" not in message
    assert message.startswith(f"the chamber could NOT be set to its safe set point {SAFE_C:g} °C")
    assert message.endswith(f"set it to {SAFE_C:g} °C by hand at the controller")
    assert "TG.SP" in message and "3 attempts" in message
    # the ramp rate is left alone when the set point is not known to be written
    assert [address for address, _ in server.writes] == [TARGET] * 3


def _run_lab(tmp_path: Path, arm) -> tuple[int, Path, Chamber]:
    """``viscorig run --station`` on the simulated analyser and the faulty controller."""
    from rigsim.rigfile import load_preset
    from rigsim.server import SimulatedAnalyserServer

    from viscorig.cli import main

    rig = load_preset("medium-chamber")
    analyser = SimulatedAnalyserServer(rig).start()
    chamber = Chamber(ChamberParameters(start_temperature_c=23.0))
    analyser.analyser.simulator.attach_chamber(chamber)
    out = tmp_path / "lab.h5"
    try:
        with FaultyController(chamber) as server:
            arm(server)
            station, sequence = lab_files(tmp_path, analyser, rig, server.address)
            status = main(["run", str(sequence), "--station", str(station), "--yes", "--out",
                           str(out)])
    finally:
        analyser.close()
    return status, out, chamber


def test_controller_stops_answering_in_a_run(tmp_path: Path, capsys) -> None:
    """The controller goes silent in the middle of the run: exit status 3, one line on stderr
    that names the chamber's controller, where the sequence stopped, and that the chamber could
    NOT be set to its safe set point (set it by hand); the committed segments kept."""
    status, out, _ = _run_lab(tmp_path, lambda server: server.arm("silent", None, after=24))
    captured = capsys.readouterr()
    assert status == 3
    assert captured.err.count("\n") == 1, captured.err
    line = captured.err.strip()
    assert line.startswith("viscorig: instrument fault: temperature controller tcp://")
    assert f"the chamber could NOT be set to its safe set point {SAFE_C:g} °C" in line
    assert f"set it to {SAFE_C:g} °C by hand at the controller" in line
    assert "Check the chamber controller at tcp://127.0.0.1:" in line
    assert "Check the analyser" not in line and "WARNING" not in captured.out
    assert f"viscorig resume {out}" in line
    run = CampaignFile.open(out).run("lab")
    assert run.metadata.status == "aborted" and 0 < run.points < 6
    assert f"Stopped in run 'lab' after {run.points} points (kept)" in line
    values, _ = run.extra["temperature_c"]
    assert values.size == run.points and np.all(np.abs(values - 23.0) < 0.1)


def test_bad_replies_at_the_end_still_leave_the_chamber_safe(tmp_path: Path, capsys) -> None:
    """The audit's case: a corrupted reply stops the sequence before the run, and the next one
    corrupts the first write of the safe set point: written again, the chamber is at the safe
    set point; the line names the chamber's controller, not the analyser."""
    status, out, chamber = _run_lab(tmp_path, lambda server: server.arm("garble", 2, after=11))
    captured = capsys.readouterr()
    assert status == 3 and captured.err.count("\n") == 1, captured.err
    line = captured.err.strip()
    assert "bad reply" in line and "could NOT" not in line
    assert "Check the chamber controller at tcp://127.0.0.1:" in line
    assert "Check the analyser" not in line
    assert f"chamber left at the safe set point {SAFE_C:g} °C" in captured.out
    assert chamber.target_c == SAFE_C and chamber.rate_k_per_min == 0.0
    assert CampaignFile.open(out).run_names == []  # stopped before run 'lab' started


def test_controller_silent_at_the_safe_set_point_after_a_complete_sequence(
        tmp_path: Path, capsys) -> None:
    """Every step done, then the controller stops answering as the safe set point is written:
    still a fault (exit status 3) in one line, the data complete and kept."""

    def at_safe(server: FaultyController) -> None:
        server.at_safe = "silent"

    status, out, _ = _run_lab(tmp_path, at_safe)
    captured = capsys.readouterr()
    assert status == 3 and captured.err.count("\n") == 1, captured.err
    line = captured.err.strip()
    assert f"the chamber could NOT be set to its safe set point {SAFE_C:g} °C" in line
    assert "Every step is done (lab" in line and "check the chamber controller at tcp://" in line
    run = CampaignFile.open(out).run("lab")
    assert run.metadata.status == "complete" and run.points == 6
