"""The bench page's JSON API and run control on the embedded simulated rig: queue, prompts on
the page, pause (no point measured while paused, the points measured committed), resume,
notes in the file, abort (data kept, file resumable), automatic holds from injected faults."""

from __future__ import annotations

import re
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest
from benchrig import SMALL_SEQUENCE, Client, bench_server, small_sequence, wait_until
from rigsim.faults import parse_fault_spec

from viscorig.bench import API_STATES, BenchError, BenchService
from viscorig.bench.app import create_app
from viscorig.cli import build_parser
from viscorig.cli.bench import served
from viscorig.sequences.station import BenchSettings
from viscorig.storage import CampaignFile

#: Simulated seconds per wall-clock second where a test must act while a run is going on: the
#: 81 points of the small sequence then take about three seconds, where unpaced they ended
#: between seeing a run go on and aborting it on a loaded machine.
PACE = 40.0


def test_queue_prompt_pause_note_resume_abort_over_the_api(tmp_path) -> None:
    small_sequence(tmp_path)
    with bench_server(tmp_path, sim_pace=PACE) as server:
        client = Client(server)
        first = client.post("/api/queue", {"sequence": "small.toml", "out": "a.h5"})
        assert first.status_code == 200, first.text
        assert first.json()["problems"] == [] and first.json()["plan_s"] > 60
        second = client.post("/api/queue", {"sequence": "small.toml", "out": "b.h5"}).json()
        third = client.post("/api/queue", {"sequence": "small.toml", "out": "c.h5"}).json()
        # reorder and remove before anything starts
        assert client.post(f"/api/queue/{third['id']}/move", {"position": 0}).status_code == 200
        assert [q["out"][-4:] for q in client.state()["queue"]] == ["c.h5", "a.h5", "b.h5"]
        assert client.http.delete(f"/api/queue/{third['id']}").status_code == 200
        assert client.http.delete(f"/api/queue/{second['id']}").status_code == 200
        assert client.http.delete("/api/queue/999").status_code == 404
        assert [q["id"] for q in client.state()["queue"]] == [first.json()["id"]]

        assert client.post("/api/start").status_code == 200
        prompt = wait_until(lambda: client.state()["prompt"], what="a prompt")
        state = client.state()
        assert state["state"] == "waiting_for_operator"
        assert prompt["text"] == "Mount the soft specimens."
        assert client.post("/api/answer", {"prompt_id": prompt["id"] + 7,
                                           "answer": "done"}).status_code == 409
        assert client.post("/api/answer", {"prompt_id": prompt["id"],
                                           "answer": "later"}).status_code == 400
        assert client.post("/api/answer", {"prompt_id": prompt["id"],
                                           "answer": "done"}).status_code == 200
        wait_until(lambda: client.state()["points_done"] >= 8, what="a first segment")
        assert client.post("/api/pause").status_code == 200
        paused = wait_until(lambda: (s := client.state())["state"] == "paused" and s,
                            what="paused")
        path = tmp_path / "a.h5"
        committed = CampaignFile.open(path).run("soft-0").points
        assert committed == paused["points_done"] and 0 < committed < 81
        time.sleep(0.6)
        assert CampaignFile.open(path).run("soft-0").points == committed  # nothing while paused
        assert client.post("/api/notes", {"text": "specimen warm to the touch"}).status_code == 200
        assert client.post("/api/pause").status_code == 409
        assert client.post("/api/resume").status_code == 200
        wait_until(lambda: client.state()["points_done"] >= committed + 8, what="going on")
        assert client.post("/api/abort").status_code == 200
        wait_until(lambda: client.state()["state"] == "stopped", what="stopped")
        assert "viscorig resume" in client.state()["message"]
        journal = client.http.get("/api/journal").json()["entries"]
        # the next item starts without the last one's words
        client.post("/api/queue", {"sequence": "small.toml", "out": "d.h5"})
        assert client.post("/api/start").status_code == 200
        prompt = wait_until(lambda: client.state()["prompt"], what="the next item's prompt")
        assert client.state()["message"] == ""
        client.post("/api/answer", {"prompt_id": prompt["id"], "answer": "abort"})
        client.close()
    with CampaignFile.open(path) as campaign:
        run = campaign.run("soft-0")
        assert run.metadata.status == "aborted" and committed < run.points < 81
        kinds = [(entry.kind, entry.run) for entry in campaign.journal]
        assert kinds == [("pause", "soft-0"), ("note", "soft-0"), ("resume", "soft-0"),
                         ("abort", "soft-0")]
        assert campaign.journal[1].text == "specimen warm to the touch"
        assert re.fullmatch(r"\d{4}-\d\d-\d\dT\d\d:\d\d:\d\dZ", campaign.journal[1].time_utc)
    assert [entry["kind"] for entry in journal] == ["pause", "note", "resume", "abort"]


def test_an_overloading_input_holds_the_run_and_it_goes_on_when_the_fault_clears(
        tmp_path) -> None:
    small_sequence(tmp_path)
    service = BenchService(root=tmp_path, bench=BenchSettings(
        hold_resume="auto", hold_retry_s=0.05, hold_overload_points=3))
    service.add("small.toml", "held.h5")
    service.start()
    states = set()
    prompt = wait_until(lambda: service.state()["prompt"], what="a prompt")
    service.answer(prompt["id"], "done")
    wait_until(lambda: service.state()["points_done"] >= 8, what="a first segment")
    faults = service.opened.server.faults
    faults.add(parse_fault_spec("range=4:-51"))  # the reference input's range stuck small
    held = wait_until(lambda: service.state()["held_because"], what="a hold")
    assert "input overloading for " in held
    states.add(service.state()["state"])
    faults.analyser.front_end.reset()  # the cable fixed
    while service.busy:
        states.add(service.state()["state"])
        time.sleep(0.01)
    assert service.state()["state"] == "complete", service.state()["message"]
    assert states <= set(API_STATES) and "held" in states
    with CampaignFile.open(tmp_path / "held.h5") as campaign:
        assert campaign.run("soft-0").points == 81
        kinds = [entry.kind for entry in campaign.journal]
        assert kinds[0] == "hold" and "hold_cleared" in kinds
        assert campaign.journal[0].text == held


def test_a_sequence_with_problems_is_shown_and_not_started(tmp_path) -> None:
    (tmp_path / "bad.toml").write_text('name = "bad"\n[[steps]]\ntype = "sweep"\nrun = "x"\n')
    service = BenchService(root=tmp_path)
    item = service.add("bad.toml", "bad.h5")
    assert item.problems and all("\n" not in problem for problem in item.problems)
    assert service.state()["problems"] == item.problems
    with pytest.raises(Exception, match="problem"):
        service.start()
    assert not (tmp_path / "bad.h5").exists()
    (tmp_path / "folder.toml").mkdir()
    with pytest.raises(BenchError, match="a folder, not a sequence file"):
        service.add("folder.toml", "x.h5")


@pytest.mark.parametrize(("stop", "delay_s"), [
    (signal.SIGINT, 0.0), (signal.SIGINT, 0.0), (signal.SIGINT, 0.001), (signal.SIGINT, 0.003),
    (signal.SIGTERM, 0.0), (signal.SIGTERM, 0.0), (signal.SIGTERM, 1.0)])
def test_bench_serve_prints_its_address_with_the_token_first(tmp_path, stop, delay_s) -> None:
    # Ctrl-C this soon after the address lands while asyncio builds its event loop, before
    # uvicorn takes the signals: it must stop the server as cleanly as later; and so must a
    # service manager's SIGTERM, at once or once serving. The stop signals are handled
    # before the address is printed: on a loaded machine a SIGTERM right after it otherwise
    # killed the process (32 of 40 runs beside three busy processes).
    process = subprocess.Popen([sys.executable, "-m", "viscorig", "bench", "serve", "--port",
                                "0", "--no-browser"], cwd=tmp_path, stdout=subprocess.PIPE,
                               stderr=subprocess.PIPE, text=True)
    try:
        first = process.stdout.readline().strip()
        assert re.fullmatch(r"http://127\.0\.0\.1:\d+/\?token=[A-Za-z0-9_-]{20,}", first), first
        time.sleep(delay_s)
    finally:
        process.send_signal(stop)
        out, err = process.communicate(timeout=20)
    assert process.returncode == 0, err
    assert err == ""
    assert out.strip().endswith("bench page stopped")


def test_aborting_at_a_prompt_stops_before_anything_is_measured(tmp_path) -> None:
    small_sequence(tmp_path)
    service = BenchService(root=tmp_path)
    service.add("small.toml", "first.h5")
    service.add("small.toml", "second.h5")
    service.start()
    prompt = wait_until(lambda: service.state()["prompt"], what="a prompt")
    service.answer(prompt["id"], "abort")
    wait_until(lambda: not service.busy, what="the end")
    state = service.state()
    assert state["state"] == "stopped" and state["prompt"] is None
    assert [item["out"][-9:] for item in state["queue"]] == ["second.h5"]  # the queue waits
    with CampaignFile.open(tmp_path / "first.h5") as campaign:
        assert campaign.run_names == []
    # the stopped campaign is continued from the page, as 'viscorig resume' would
    (tmp_path / "other.toml").write_text(SMALL_SEQUENCE.replace('"small"', '"other"'))
    with pytest.raises(BenchError, match="holds another sequence"):
        service.add("other.toml", "first.h5")
    again = service.add("small.toml", "first.h5")
    service.move(again.id, 0)
    service.remove(state["queue"][0]["id"])
    service.start()
    prompt = wait_until(lambda: service.state()["prompt"], what="the prompt again")
    service.answer(prompt["id"], "done")
    wait_until(lambda: not service.busy, what="the end")
    assert service.state()["state"] == "complete", service.state()["message"]
    with CampaignFile.open(tmp_path / "first.h5") as campaign:
        assert campaign.run("soft-0").points == 81



def test_the_readme_api_table_names_the_apps_routes(tmp_path) -> None:
    readme = (Path(__file__).resolve().parents[1] / "README.md").read_text(encoding="utf-8")
    named = set()
    for cell in re.findall(r"(?m)^\| (`(?:GET|POST|DELETE) [^|]+)\|", readme):
        verb = ""
        for given, path in re.findall(r"`(?:(GET|POST|DELETE) )?(/api/[^`]+)`", cell):
            verb = given or verb
            named.add((verb, path.replace("/ID", "/{item}")))
    guard = create_app(BenchService(root=tmp_path), "t" * 32, 8123)
    routes = {(method, route.path) for route in guard.app.routes
              for method in (route.methods or ()) if route.path.startswith("/api/")}
    assert len(named) == 10 and named <= routes, named - routes
    assert {path for _, path in routes} - {path for _, path in named} == {"/api/journal"}


def test_hold_resume_is_chosen_on_the_command_line_for_the_embedded_rig(tmp_path) -> None:
    parse = build_parser("bench").parse_args
    service, address = served(parse(["bench", "serve", "--hold-resume", "auto"]))
    assert address == "127.0.0.1" and service.bench_override.hold_resume == "auto"
    service, _ = served(parse(["bench", "serve"]))
    assert service.bench_override is None  # the station's, or the embedded rig's default
    assert BenchSettings().hold_resume == "technician"
    with pytest.raises(SystemExit):
        parse(["bench", "serve", "--hold-resume", "later"])
