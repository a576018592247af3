"""An adaptive plan pauses at the point too: the point being measured is finished and committed,
no point is measured while paused, and the plan goes on from the next point it had asked for.
On the embedded simulated rig, paced, through the real driver over loopback."""

from __future__ import annotations

import time
from pathlib import Path

from benchrig import ADAPTIVE_TABLE_SEQUENCE, configure_soft_sweep, wait_until

from viscorig.bench import BenchService
from viscorig.storage import CampaignFile

SEQUENCE = ADAPTIVE_TABLE_SEQUENCE
PACE = 60.0


def test_an_adaptive_plan_pauses_after_the_point_being_measured(tmp_path: Path) -> None:
    (tmp_path / "adaptive.toml").write_text(SEQUENCE)
    service = BenchService(root=tmp_path, sim_pace=PACE)
    service.add("adaptive.toml", "out.h5")
    service.start()
    try:
        prompt = wait_until(lambda: service.state()["prompt"], what="a prompt")
        analyser = service.opened.server.analyser
        revealed: list[tuple[float, float]] = []  # (wall time, frequency) of each point
        analyser.on_point = lambda count: revealed.append(
            (time.monotonic(), analyser.sine.points.frequency_hz[-1]))
        service.answer(prompt["id"], "done")
        # two probe points, two of the shaker gain, then the first look's: pause inside it
        wait_until(lambda: service.state()["points_total"] and len(revealed) >= 5, 30,
                   "points of the first look")
        asked = time.monotonic()
        service.pause()
        paused = wait_until(lambda: (s := service.state())["state"] == "paused" and s, 10,
                            "paused")
        paused_at = time.monotonic()
        committed = CampaignFile.open(tmp_path / "out.h5").run("table")
        time.sleep(0.3)  # several points' time
        after_request = [f for t, f in revealed if t > asked]
        assert [f for t, f in revealed if t > paused_at] == []  # nothing measured while paused
        assert CampaignFile.open(tmp_path / "out.h5").run("table").points == committed.points
        assert committed.points == paused["points_done"] > 0
        assert paused["points_done"] < paused["points_total"]  # inside the request, not after
        assert len(after_request) <= 1  # at most the point being measured
        if after_request:  # which is the last one committed
            assert after_request[0] == committed.frequency_hz[-1]
        count = len(revealed)
        service.resume()
        wait_until(lambda: len(revealed) > count, 10, "a point after the resume")
        # the plan goes on with the next point of its first look (rising): none measured twice
        assert revealed[count][1] > committed.frequency_hz[-1]
        service.abort()
        wait_until(lambda: not service.busy, 30, "the end")
        with CampaignFile.open(tmp_path / "out.h5") as campaign:
            kinds = [entry.kind for entry in campaign.journal]
            assert kinds[:2] == ["pause", "resume"]
    finally:
        service.shutdown()


def test_point_by_point_measurements_end_after_the_point_in_flight() -> None:
    from agilent35670a import Agilent35670A
    from rigsim.rigfile import load_preset
    from rigsim.server import SimulatedAnalyserServer

    with SimulatedAnalyserServer(load_preset("soft-0"), pace=PACE) as server:
        analyser = Agilent35670A.open(server.socket_resource, timeout_s=5.0)
        try:
            configure_soft_sweep(analyser)
            frequencies = [20.0, 21.5, 23.0, 24.5, 26.0, 27.5]
            revealed: list[int] = []
            server.analyser.on_point = lambda count: revealed.append(count)
            asked: list[int] = []

            def progress(report) -> None:  # once the first point is measured
                if revealed and not asked:
                    asked.append(len(revealed))
                    analyser.end_after_point()

            cut = analyser.measure_points(frequencies, progress=progress)
            # the points measured when it was asked, and at most the one in flight
            assert cut.ended_early and asked[0] <= len(cut) <= asked[0] + 1 < len(frequencies)
            assert len(cut) == len(revealed)  # no point measured after the end
            assert list(cut.frequency_hz) == frequencies[:len(cut)]
            whole = analyser.measure_points(frequencies[:2])  # the next call is whole again
            assert not whole.ended_early and len(whole) == 2
        finally:
            analyser.close()
