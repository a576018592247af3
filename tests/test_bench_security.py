"""The bench server refuses what it must, while a run goes on unharmed: no token, a wrong token,
another origin or host, a second controlling client, a 10 MB body, a hundred requests a second.
Every refusal is a 4xx with a one-line JSON error, never a traceback."""

from __future__ import annotations

import time
from concurrent.futures import ThreadPoolExecutor

import httpx
import pytest
from benchrig import Client, bench_server, small_sequence, wait_until

from viscorig.bench.app import MAX_BODY_BYTES, RATE_PER_S
from viscorig.storage import CampaignFile


def one_line_error(answer: httpx.Response, status: int) -> str:
    assert answer.status_code == status, (answer.status_code, answer.text)
    message = answer.json()["error"]
    assert message and "\n" not in message and "Traceback" not in answer.text
    return message


def flood(request, allowed: set[int], served_code: int) -> None:
    """Requests from 20 threads, in bursts of 100 until one is refused as too many (at most
    5 bursts: a slow machine may send fewer than the server's rate allows): no more are served
    than the token bucket holds, and the surplus gets 429."""
    started = time.monotonic()
    codes: list[int] = []
    with ThreadPoolExecutor(20) as pool:
        for _ in range(5):
            codes += pool.map(lambda _: request(), range(100))
            if 429 in codes:
                break
    spent = time.monotonic() - started
    assert set(codes) <= allowed, codes
    assert codes.count(served_code) <= RATE_PER_S + spent * RATE_PER_S + 1, (codes, spent)
    assert 429 in codes, (len(codes), spent)


def start_measuring(owner: Client) -> None:
    """Queue small.toml into run.h5, start it, answer its prompt; return once it measures."""
    assert owner.post("/api/queue", {"sequence": "small.toml", "out": "run.h5"}
                      ).status_code == 200
    assert owner.post("/api/start").status_code == 200
    prompt = wait_until(lambda: owner.state()["prompt"], what="a prompt")
    assert owner.post("/api/answer", {"prompt_id": prompt["id"], "answer": "done"}
                      ).status_code == 200
    wait_until(lambda: owner.state()["points_done"] > 0, what="measuring")


def refuse_everything(server, owner: Client) -> None:
    """Every refusal, one after another; ``owner`` controls the bench already."""
    with httpx.Client(base_url=server.base, timeout=10.0) as anyone:
        # no token, a wrong token (header and cookie), the token of another port
        assert "token" in one_line_error(anyone.get("/api/state"), 401)
        one_line_error(anyone.post("/api/abort"), 401)
        wrong = server.token[:-1] + ("y" if server.token.endswith("x") else "x")
        one_line_error(anyone.get("/api/state", headers={"Authorization": f"Bearer {wrong}"}),
                       401)
        one_line_error(anyone.get("/api/state", headers={
            "Cookie": f"viscorig_bench_{server.port + 1}={server.token}"}), 401)
        one_line_error(anyone.get("/?token=wrong"), 401)
        bearer = {"Authorization": f"Bearer {server.token}"}
        # another origin (a page of another site in the same browser), another host name
        assert "origin" in one_line_error(anyone.post("/api/abort", headers={
            **bearer, "Origin": "http://evil.example"}), 403)
        one_line_error(anyone.post("/api/pause", headers={
            **bearer, "Origin": f"http://localhost.evil.example:{server.port}"}), 403)
        one_line_error(anyone.get("/api/state", headers={**bearer, "Host": "rebound.example"}),
                       403)
        one_line_error(anyone.post("/api/abort", headers={
            **bearer, "Sec-Fetch-Site": "cross-site"}), 403)
        # a foreign origin before this server's own: only the last one was checked
        assert "'origin' given twice" in one_line_error(anyone.post("/api/abort", headers=[
            *bearer.items(), ("Origin", "http://evil.example"),
            ("Origin", f"http://127.0.0.1:{server.port}")]), 400)
        # 10 MB: declared, and streamed without a length
        big = b"{" + b" " * (10 * 1024 * 1024) + b"}"
        one_line_error(anyone.post("/api/notes", content=big, headers=bearer), 413)

        def chunks():
            for _ in range(160):
                yield b" " * 65536

        one_line_error(anyone.post("/api/notes", content=chunks(), headers=bearer), 413)
        one_line_error(owner.http.post("/api/notes", content=b"not json"), 400)
        one_line_error(owner.http.post("/api/nothing"), 404)
        one_line_error(owner.http.get("/api/state/"), 404)  # was an empty 307
        one_line_error(owner.http.put("/api/state"), 405)

    # a second client may read, not command, and is told so
    second = Client(server, "second")
    assert second.state()["control"] == "another client"
    assert owner.state()["control"] == "you"
    assert "read-only" in one_line_error(second.post("/api/pause"), 409)
    one_line_error(second.post("/api/abort"), 409)

    # a flood from the read-only client: bounded, and counted apart from the client in control,
    # whose next requests are served at once
    time.sleep(0.5)
    with ThreadPoolExecutor(1) as beside:
        owners = beside.submit(lambda: [owner.http.get("/api/state").status_code
                                        for _ in range(10) if time.sleep(0.05) is None])
        flood(lambda: second.http.get("/api/state").status_code, {200, 429}, 200)
        assert owners.result() == [200] * 10
    # a flood without the token is refused on its own account: the owner is not slowed
    with httpx.Client(base_url=server.base, timeout=10.0) as stranger:
        flood(lambda: stranger.get("/api/state").status_code, {401, 429}, 401)
    assert owner.http.get("/api/state").status_code == 200
    second.close()
    time.sleep(0.5)  # the bucket refills for the owner's next requests


def test_refusals_of_an_idle_bench(tmp_path) -> None:
    small_sequence(tmp_path)
    with bench_server(tmp_path) as server:
        owner = Client(server, "owner")
        assert owner.post("/api/queue", {"sequence": "small.toml", "out": "run.h5"}
                          ).status_code == 200
        refuse_everything(server, owner)
        assert owner.state()["queue"][0]["out"].endswith("run.h5")
        owner.close()
    assert not (tmp_path / "run.h5").exists()


@pytest.mark.slow
def test_refusals_leave_a_run_unharmed(tmp_path) -> None:
    small_sequence(tmp_path)
    with bench_server(tmp_path, sim_pace=60.0) as server:
        owner = Client(server, "owner")
        start_measuring(owner)
        refuse_everything(server, owner)
        assert owner.state()["state"] in ("measuring", "complete")
        final = wait_until(lambda: (s := owner.state())["state"] not in (
            "measuring", "checking", "waiting_for_operator") and s, 60, "the end of the run")
        assert final["state"] == "complete", final["message"]
        owner.close()
    with CampaignFile.open(tmp_path / "run.h5") as campaign:
        run = campaign.run("soft-0")
        assert run.metadata.status == "complete" and run.points == 81
        assert campaign.journal == []  # no refused request reached the file
    assert MAX_BODY_BYTES < 10 * 1024 * 1024


def test_served_on_loopback_unless_the_station_allows_another_address(tmp_path) -> None:
    import socket
    import subprocess
    import sys

    from reliability_campaign import station_text

    from viscorig.bench import BenchService
    from viscorig.bench.app import BenchServer

    server = BenchServer(BenchService(root=tmp_path))
    try:
        assert server.socket.getsockname()[0] == "127.0.0.1"
        outside = [address for *_, (address, *_) in socket.getaddrinfo(
            socket.gethostname(), None, socket.AF_INET) if not address.startswith("127.")]
        for address in outside:  # another interface of this machine does not reach it
            with pytest.raises(OSError), socket.create_connection((address, server.port), 1):
                pass
    finally:
        server.socket.close()

    station = tmp_path / "station.toml"
    station.write_text(station_text("TCPIP::127.0.0.1::1::SOCKET")
                       + '[bench]\naddress = "127.0.0.2"\n')
    process = subprocess.Popen([sys.executable, "-m", "viscorig", "bench", "serve", "--station",
                                str(station), "--port", "0", "--no-browser"], cwd=tmp_path,
                               stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        first, second = process.stdout.readline(), process.stdout.readline()
    finally:
        process.send_signal(2)
        process.communicate(timeout=30)
    assert first.startswith("http://127.0.0.2:")
    assert second.startswith("WARNING: served on 127.0.0.2 as the station's [bench] address")


def test_idle_connections_from_anyone_neither_block_commands_nor_stay(tmp_path) -> None:
    """70 connections opened by anyone and left silent made every request, a pause and an abort
    included, a plain-text 503 for as long as they were held."""
    import socket

    from viscorig.bench.app import REQUEST_HEAD_S

    small_sequence(tmp_path)
    with bench_server(tmp_path) as server:
        owner = Client(server, "owner")
        held = [socket.create_connection(("127.0.0.1", server.port)) for _ in range(70)]
        trickle = held[0]
        trickle.sendall(b"GET /api/state HTTP/1.1\r\n")  # a head never finished
        try:
            started = time.monotonic()
            assert owner.state()["state"] == "idle"
            assert owner.post("/api/pause").status_code in (200, 409)
            assert owner.post("/api/abort").status_code in (200, 409)
            assert time.monotonic() - started < 2.0
            for connection in held:  # closed by the server once their head is overdue
                connection.settimeout(REQUEST_HEAD_S + 5.0)
                assert connection.recv(1) == b""
        finally:
            for connection in held:
                connection.close()
        owner.close()


@pytest.mark.parametrize(("path", "body", "said"), [
    ("/api/notes", b"[" * 5000 + b"]" * 5000, "JSON nested too deep"),
    ("/api/notes", b'{"text": ' + b"[" * 20000 + b"]" * 20000 + b"}", "JSON nested too deep"),
    ("/api/queue", b'{"sequence": "small.toml", "out": "\\ud800.h5"}', "lone surrogate"),
    ("/api/notes", b'{"text": "a\\u0000b"}', "control character"),
    ("/api/queue", b'{"sequence": "small.toml", "out": "' + b"x" * 300 + b'.h5"}',
     "File name too long"),
])
def test_bodies_no_file_or_note_can_hold_are_refused(tmp_path, path: str, body: bytes,
                                                     said: str) -> None:
    """Each of these was a 500 with a traceback; a lone surrogate in a queued file name made
    every later GET /api/state a 500."""
    small_sequence(tmp_path)
    with bench_server(tmp_path) as server:
        owner = Client(server, "owner")
        if path == "/api/notes":  # a note needs a campaign file
            with CampaignFile.create(tmp_path / "c.h5", sequence_text="", durable=False):
                pass
            server.service.campaign_path = tmp_path / "c.h5"
        answer = owner.http.post(path, content=body,
                                 headers={"Content-Type": "application/json"})
        assert said in one_line_error(answer, 400)
        assert owner.state()["queue"] == []
        owner.close()


@pytest.mark.slow
def test_a_pause_is_answered_while_a_queued_sequence_is_planned(tmp_path) -> None:
    """A queued sequence is checked and planned before the answer (seconds for many adaptive
    sweeps): a pause sent meanwhile, during a run, got no answer within 10 s."""
    sweep = ('[[steps]]\ntype = "sweep"\nrun = "soft-{i}"\nspecimen = "soft"\n'
             'hardness_shore_a = 25.0\nplan = "adaptive"\nmodel = "voigt"\n'
             'target_uncertainty = {{ K_v = 2e-3, C_v = 2e-3 }}\ndwell_limit_s = 1800\n'
             'resolution_hz = 0.25\nsettle_cycles = 400\n')
    (tmp_path / "many.toml").write_text(
        'name = "many"\n[defaults]\nband_hz = [20.0, 120.0]\nlevel = "1.4 m/s^2"\n'
        '[[steps]]\ntype = "prompt"\nmessage = "Mount the soft specimens."\n'
        'simulated_rig = "soft-0"\n' + "".join(sweep.format(i=i) for i in range(60)))
    small_sequence(tmp_path)
    with bench_server(tmp_path, sim_pace=60.0) as server:
        owner = Client(server, "owner")
        start_measuring(owner)
        with ThreadPoolExecutor(1) as beside:
            started = time.monotonic()
            queued = beside.submit(owner.post, "/api/queue",
                                   {"sequence": "many.toml", "out": "many.h5"})
            time.sleep(0.3)
            asked = time.monotonic()
            assert owner.post("/api/pause").status_code == 200
            answered = time.monotonic() - asked
            answer = queued.result()
            planned = time.monotonic() - started
        assert answer.status_code == 200 and answer.json()["problems"] == [], answer.text
        assert planned > 1.0 and answered < 1.0, (planned, answered)
        assert owner.post("/api/abort").status_code == 200
        owner.close()


@pytest.mark.parametrize("out", ["../run.h5", "/tmp/run.h5", "sub/../../run.h5"])
def test_campaign_files_are_written_in_the_bench_folder_only(tmp_path, out) -> None:
    """An absolute path or '..' created a campaign file anywhere the user may write."""
    folder = tmp_path / "bench"
    folder.mkdir()
    small_sequence(tmp_path)  # a sequence may be read from anywhere
    with bench_server(folder) as server:
        owner = Client(server, "owner")
        message = one_line_error(owner.post("/api/queue", {"sequence": "../small.toml",
                                                           "out": out}), 400)
        assert "not in the bench's folder" in message
        assert owner.post("/api/queue", {"sequence": str(tmp_path / "small.toml"),
                                         "out": "sub.h5"}).status_code == 200
        owner.close()
    assert not (tmp_path / "run.h5").exists()


@pytest.mark.parametrize("request_bytes", [
    b"GET /api/state HTTP/1.1\r\n\r\n",  # no Host
    b"POST /api/notes HTTP/1.1\r\nHost: x\r\nContent-Length: ten\r\n\r\n",
    b"NOT HTTP AT ALL\r\n\r\n",
])
def test_a_request_that_is_not_http_is_refused_in_json(tmp_path, request_bytes) -> None:
    """uvicorn answered these with a plain-text 'Invalid HTTP request received.'"""
    import json
    import socket

    with (bench_server(tmp_path) as server,
          socket.create_connection(("127.0.0.1", server.port), timeout=5) as connection):
        connection.sendall(request_bytes)
        answer = b""
        while chunk := connection.recv(4096):
            answer += chunk
    head, _, body = answer.partition(b"\r\n\r\n")
    assert head.startswith(b"HTTP/1.1 400") and b"application/json" in head.lower(), head
    message = json.loads(body)["error"]
    assert message.startswith("not a valid HTTP request") and "\n" not in message
