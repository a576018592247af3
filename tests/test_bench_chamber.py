"""A chamber sequence from the bench's JSON API on the embedded rig (a reduced copy of
sequences/temperature-strain.toml: one set point, one sweep): the chamber's air thermocouple
breaks mid-sweep (the simulated controller then stops regulating and the air drifts to the
room), the specimen leaves its soak band, the run holds by itself and says why; nothing is
measured while held; the thermocouple repaired, the chamber brings the specimen back and the run
goes on by itself (``hold_resume = "auto"``) to complete."""

from __future__ import annotations

import time

import numpy as np
import pytest
from benchrig import Client, bench_server, wait_until

from viscorig.sequences.station import BenchSettings
from viscorig.storage import CampaignFile

SEQUENCE = """
name = "chamber-hold"
[[steps]]
type = "prompt"
message = "Mount the MEDIUM specimens in the chamber, thermocouple on a specimen."
simulated_rig = "medium-chamber"
[[steps]]
type = "temperature"
set_point_c = 0.0
soak_band_k = 0.5
soak_minutes = 1.0
time_limit_minutes = 60.0
[[steps]]
type = "sweep"
run = "medium_0C"
specimen = "medium"
hardness_shore_a = 33.0
band_hz = [12.0, 40.0]
resolution_hz = 0.5
settle_cycles = 30
integrate_cycles = 30
level = "0.5 m/s^2"
over_limit = "reduce"
segment_points = 8
"""


@pytest.mark.slow
def test_a_chamber_fault_holds_the_run_until_the_specimen_is_back_in_its_band(tmp_path) -> None:
    (tmp_path / "chamber.toml").write_text(SEQUENCE)
    bench = BenchSettings(hold_resume="auto", hold_temperature_points=3)
    with bench_server(tmp_path, bench=bench) as server:
        client = Client(server)
        queued = client.post("/api/queue", {"sequence": "chamber.toml", "out": "chamber.h5"})
        assert queued.status_code == 200 and queued.json()["problems"] == [], queued.text
        assert client.post("/api/start").status_code == 200
        prompt = wait_until(lambda: client.state()["prompt"], what="the mounting prompt")
        assert client.post("/api/answer", {"prompt_id": prompt["id"],
                                           "answer": "done"}).status_code == 200
        wait_until(lambda: (s := client.state())["run"] == "medium_0C"
                   and s["points_done"] >= 1, 120, "the sweep after the soak")
        chamber = server.service.opened.server.analyser.simulator.chamber
        chamber.break_thermocouple("air")  # the controller stops regulating
        held = wait_until(lambda: client.state()["held_because"], 120, "a hold")
        assert held.startswith("specimen out of its temperature band for ")
        state = client.state()
        assert state["state"] == "held"
        points_held = state["points_done"]
        time.sleep(0.5)  # the air still drifts: held, nothing measured
        assert client.state()["state"] == "held"
        assert client.state()["points_done"] == points_held
        chamber.repair()
        wait_until(lambda: client.state()["state"] in ("complete", "failed", "stopped"), 300,
                   "the end")
        final = client.state()
        client.close()
    assert final["state"] == "complete", final["message"]
    with CampaignFile.open(tmp_path / "chamber.h5") as campaign:
        run = campaign.run("medium_0C")
        journal = campaign.journal
    temperature, units = run.extra["temperature_c"]
    assert units == "degC" and run.points == 57 and run.metadata.status == "complete"
    outside = np.abs(temperature - 0.0) > 0.5
    flagged = (run.flags & 16) != 0
    np.testing.assert_array_equal(flagged, outside)  # flagged exactly where it was out
    assert flagged.sum() >= 3 and not flagged[points_held:].any()  # back in its band after
    assert [(entry.kind, entry.run) for entry in journal] == [
        ("hold", "medium_0C"), ("hold_cleared", "medium_0C")]
    assert journal[0].text == held
