"""Pause at the point, not the segment: the point being measured is finished and committed, no
point is measured while paused, the sweep goes on from the next frequency, and the file equals
one measured without a pause. On the embedded simulated rig, paced so that a point takes tens of
milliseconds, through the real driver over loopback."""

from __future__ import annotations

import time
from pathlib import Path

import numpy as np
import pytest
from agilent35670a import Agilent35670A
from benchrig import configure_soft_sweep, soft_sweep_sequence, wait_until
from rigsim.rigfile import load_preset
from rigsim.server import SimulatedAnalyserServer

from viscorig.bench import BenchService
from viscorig.storage import CampaignFile

#: 13 points in segments of 8; at pace 60 a point takes about 25 ms of wall time.
SEQUENCE = soft_sweep_sequence("pause-at-a-point", 23.0)
PACE = 60.0


def _measure(folder: Path, out: str, pause_after: int | None) -> dict:
    """Run the sequence on the bench service; with ``pause_after``, pause once that many points
    are committed (and a little more time has passed), wait, resume. Returns what was seen."""
    service = BenchService(root=folder, sim_pace=PACE)
    service.add("pause.toml", out)
    service.start()
    seen: dict = {}
    try:
        prompt = wait_until(lambda: service.state()["prompt"], what="a prompt")
        analyser = service.opened.server.analyser
        revealed: list[tuple[float, float]] = []  # (wall time, frequency) of each point measured
        analyser.on_point = lambda count: revealed.append(
            (time.monotonic(), analyser.sine.points.frequency_hz[-1]))
        service.answer(prompt["id"], "done")
        if pause_after is not None:
            wait_until(lambda: service.state()["points_done"] >= pause_after, what="points")
            time.sleep(0.04)  # into the next segment
            asked = time.monotonic()
            service.pause()
            paused = wait_until(lambda: (s := service.state())["state"] == "paused" and s,
                                what="paused")
            paused_at = time.monotonic()
            seen["committed"] = CampaignFile.open(folder / out).run("soft-0").points
            seen["points_done"] = paused["points_done"]
            time.sleep(0.3)  # a dozen points' time
            seen["after_request"] = [f for t, f in revealed if t > asked]
            seen["while_paused"] = [f for t, f in revealed if t > paused_at]
            seen["still_committed"] = CampaignFile.open(folder / out).run("soft-0").points
            count = len(revealed)
            service.resume()
            wait_until(lambda: len(revealed) > count, what="a point after the resume")
            seen["first_after_resume"] = revealed[count][1]
        wait_until(lambda: not service.busy, 60, "the end")
        seen["state"] = service.state()["state"]
    finally:
        service.shutdown()
    return seen


@pytest.mark.slow
def test_a_pause_ends_the_sweep_at_a_point_and_the_file_equals_an_uninterrupted_one(
        tmp_path) -> None:
    (tmp_path / "pause.toml").write_text(SEQUENCE)
    reference = _measure(tmp_path, "straight.h5", None)
    paused = _measure(tmp_path, "paused.h5", 8)
    assert reference["state"] == paused["state"] == "complete"

    committed = paused["committed"]
    assert committed == paused["points_done"] == paused["still_committed"]
    assert 8 <= committed < 13  # inside the second segment: not at a segment's end
    assert len(paused["after_request"]) <= 1  # at most the point being measured
    assert paused["while_paused"] == []
    with CampaignFile.open(tmp_path / "paused.h5") as campaign:
        run = campaign.run("soft-0")
        kinds = [entry.kind for entry in campaign.journal]
        # the point measured after the request, if any, is the last one committed
        assert paused["after_request"] in ([], [run.frequency_hz[committed - 1]])
        # the sweep goes on from the next frequency
        assert paused["first_after_resume"] == run.frequency_hz[committed]
        assert run.metadata.status == "complete" and kinds == ["pause", "resume"]
        with CampaignFile.open(tmp_path / "straight.h5") as straight:
            other = straight.run("soft-0")
            np.testing.assert_array_equal(run.frequency_hz, other.frequency_hz)
            np.testing.assert_array_equal(run.flags, other.flags)
            for name in ("accelerance_table", "accelerance_support"):
                a, b = getattr(run, name), getattr(other, name)
                # the simulated noise is a few 1e-4 of the response here; a point measured
                # twice or out of place would be off by percent (0.25 Hz steps near resonance)
                assert np.max(np.abs(a / b - 1)) < 3e-3, name


def test_the_driver_returns_the_points_measured_before_the_boundary(tmp_path) -> None:
    with SimulatedAnalyserServer(load_preset("soft-0"), pace=PACE) as server:
        analyser = Agilent35670A.open(server.socket_resource, timeout_s=5.0)
        try:
            configure_soft_sweep(analyser)
            asked: list[int] = []

            def progress(report) -> None:
                if report.elapsed_s > 0.1 and not asked:
                    asked.append(server.analyser.points_measured)
                    analyser.end_after_point()

            cut = analyser.measure(20.0, 24.0, progress=progress)
            measured = server.analyser.points_measured
            assert cut.ended_early and len(cut) == measured and 0 < measured < 17
            assert measured - asked[0] <= 1
            np.testing.assert_allclose(cut.frequency_hz, 20.0 + 0.25 * np.arange(measured))
            assert not np.asarray(cut.no_data).any() and np.isfinite(cut.frf_43).all()
            assert not server.analyser.source_on  # stopped with the sweep
            whole = analyser.measure(20.0, 24.0)  # the next sweep is whole again
            assert not whole.ended_early and len(whole) == 17
        finally:
            analyser.close()


def test_an_unpaced_analyser_told_in_process_ends_at_a_point_too(tmp_path) -> None:
    """Unpaced, a sweep outruns the driver's polls; the virtual analyser's in-process
    ``end_after_point`` holds it at the next boundary so the driver's end at a point is seen.
    The sweep is long (401 points), so that a loaded machine's first poll still comes before
    its end; the cut comes within a point of the request, however many were measured by then
    (a 41-point sweep sometimes ended before the first poll)."""
    with SimulatedAnalyserServer(load_preset("soft-0")) as server:  # as fast as possible
        analyser = Agilent35670A.open(server.socket_resource, timeout_s=5.0)
        try:
            configure_soft_sweep(analyser)
            asked: list[int] = []

            def progress(report) -> None:
                if not asked:
                    server.analyser.end_after_point()
                    asked.append(server.analyser.points_measured)
                analyser.end_after_point()

            cut = analyser.measure(20.0, 120.0, progress=progress)
            assert cut.ended_early and 1 <= len(cut) < 401
            assert len(cut) - asked[0] <= 1
            np.testing.assert_allclose(cut.frequency_hz, 20.0 + 0.25 * np.arange(len(cut)))
            assert not server.analyser.source_on
        finally:
            analyser.close()
