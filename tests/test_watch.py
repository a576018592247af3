"""The live view: a page on 127.0.0.1 that follows a campaign written by another process.

The browser test runs ``viscorig run`` in a subprocess on the embedded simulated rig, serves
the file it writes, loads the page in headless Chromium and sees new points arrive, the level
and force against their limits, flagged points and the state of the run, with nothing loaded
from anywhere but the server.
"""

from __future__ import annotations

import http.client
import json
import math
import os
import re
import shutil
import socket
import subprocess
import sys
import time
import urllib.error
import urllib.request
from pathlib import Path

import numpy as np
import pytest
from browser import CHROMIUM, Browser
from campaigndata import add_run

from viscorig.cli import main
from viscorig.storage import CampaignFile, RunSettings, Segment, writelock
from viscorig.watch import WatchServer, page_html, read_snapshot

ROOT = Path(__file__).resolve().parents[1]

# Three runs (bare table, soft rubber without and with preload) on a coarse grid, so that a
# simulated run lasts seconds: long enough to watch, short enough for the test suite.
LIVE = """\
name = "live"
[defaults]
resolution_hz = 1.0
settle_cycles = 10
integrate_cycles = 10
segment_s = 4
level = "1.4 m/s^2"

[[steps]]
type = "prompt"
message = "Remove the damper device."
simulated_rig = "table"

[[steps]]
type = "sweep"
run = "table"
specimen = "none"
band_hz = [12.0, 28.0]
resolution_hz = 0.25

[[steps]]
type = "identify_table"
run = "table"

[[steps]]
type = "prompt"
message = "Mount the SOFT specimens, no preload."
simulated_rig = "soft-0"

[[steps]]
type = "sweep"
run = "soft-0"
specimen = "soft"
hardness_shore_a = 25.0
band_hz = [20.0, 120.0]

[[steps]]
type = "prompt"
message = "Tighten the preload screws."
simulated_rig = "soft-10"

[[steps]]
type = "sweep"
run = "soft-10"
specimen = "soft"
hardness_shore_a = 25.0
preload_strain = 0.104
band_hz = [20.0, 120.0]
"""


def get(url: str, host: str | None = None) -> tuple[int, dict, bytes]:
    request = urllib.request.Request(url, headers={"Host": host} if host else {})
    try:
        with urllib.request.urlopen(request, timeout=10) as answer:
            return answer.status, dict(answer.headers), answer.read()
    except urllib.error.HTTPError as error:
        return error.code, dict(error.headers), error.read()


def measuring_campaign(path: Path) -> Path:
    """A campaign whose second run is being measured: 5 of 41 points, one flagged."""
    campaign = CampaignFile.create(path, sequence_text=LIVE.replace("resolution_hz = 1.0",
                                                                "resolution_hz = 2.5"))
    add_run(campaign, "table")
    settings = RunSettings(specimen="soft", level_m_per_s2=1.4, direction="up",
                           settle_cycles=10, integrate_cycles=10, resolution_hz=2.5,
                           simulated=True)
    campaign.start_run("soft-0", settings)
    frequency = 20.0 + 2.5 * np.arange(5)
    campaign.append_segment("soft-0", Segment(
        frequency_hz=frequency, time_s=np.arange(1.0, 6.0),
        accelerance_table=np.full(5, 0.01 + 0.002j), accelerance_support=np.full(5, 0.1j),
        reference_amplitude=np.array([1.4, 1.41, math.nan, 1.39, 1.0]),
        source_amplitude=np.full(5, math.nan), force_amplitude=np.array([60, 55, 50, 45, 40.0]),
        flags=np.array([0, 0, 0, 0, 1])))
    return path


def test_the_snapshot_is_the_committed_state_in_json(tmp_path) -> None:
    path = measuring_campaign(tmp_path / "c.h5")
    before = path.read_bytes()
    with CampaignFile.open(path, "a", durable=False):  # a writer measuring into it
        snapshot = read_snapshot(path)
    assert path.read_bytes() == before  # only read
    text = json.dumps(snapshot, allow_nan=False)  # no NaN reaches the page
    assert snapshot["state"] == "measuring" and snapshot["current"] == "soft-0"
    soft = snapshot["runs"][1]
    assert (soft["points"], soft["planned"], soft["flagged"]) == (5, 41, 1)
    assert soft["reference_m_per_s2"][2] is None and soft["flags"] == [0, 0, 0, 0, 1]
    assert soft["table_magnitude"][0] == pytest.approx(abs(0.01 + 0.002j), rel=1e-5)
    assert soft["table_phase_deg"][0] == pytest.approx(math.degrees(math.atan2(0.002, 0.01)),
                                                       rel=1e-4)
    assert soft["requested_level_m_per_s2"] == 1.4 and soft["tolerance_db"] == 1.0
    # time left: the 36 points still to measure in soft-0, then the whole of soft-10
    grid = 20.0 + 2.5 * np.arange(41)
    expected = (20 / grid[5:]).sum() + (20 / grid).sum()
    assert snapshot["time_left_s"] == pytest.approx(expected)
    assert [run["name"] for run in snapshot["to_come"]] == ["soft-10"]
    assert "nan" not in text.lower()


def test_a_run_left_running_by_a_writer_that_is_gone_is_interrupted_not_measuring(
        tmp_path) -> None:
    # a crashed or killed writer leaves its run "running": the page said "measuring" for ever
    # on a simulated rig (no stall clock there), and until the stall time on a real one
    path = measuring_campaign(tmp_path / "c.h5")
    snapshot = read_snapshot(path)
    assert snapshot["state"] == "stopped"
    assert snapshot["detail"] == ("run 'soft-0' was interrupted after 5 of 41 points and no "
                                  "writer holds the file: continue with viscorig resume")
    lock = writelock.lock_path(path)
    lock.write_text(json.dumps({"command": "viscorig run", "pid": 4242, "host": "lab-pc",
                                "since": "2024-05-01T12:00:00Z"}))
    an_hour_ago = time.time() - 3600.0  # (an unreadable record this old would be stale)
    os.utime(lock, (an_hour_ago, an_hour_ago))
    assert read_snapshot(path)["state"] == "measuring"  # another host's writer: not checkable
    dead = subprocess.run([sys.executable, "-c", "import os; print(os.getpid())"],
                          capture_output=True, text=True, check=True)
    lock.write_text(json.dumps({"command": "viscorig run", "pid": int(dead.stdout),
                                "host": socket.gethostname(), "since": "2024-05-01T12:00:00Z"}))
    assert read_snapshot(path)["state"] == "stopped"  # this host's, and its process is gone


def test_the_server_serves_loopback_only_offline_and_answers_unchanged(tmp_path) -> None:
    path = measuring_campaign(tmp_path / "c.h5")
    with WatchServer(path, port=0) as server:
        assert server.url.startswith("http://127.0.0.1:")
        status, headers, body = get(server.url)
        assert status == 200 and body.decode() == page_html()
        assert "default-src 'none'" in headers["Content-Security-Policy"]
        status, _, body = get(server.url + "state.json")
        first = json.loads(body)
        assert first["snapshot"]["runs"][1]["points"] == 5
        _, _, body = get(server.url + f"state.json?version={first['version']}")
        assert json.loads(body) == {"version": first["version"], "error": None,
                                    "unchanged": True}
        # a page of another site, reaching the port through a name of its own
        assert get(server.url + "state.json", host="attacker.example:80")[0] == 403
        assert get(server.url + "etc/passwd")[0] == 404
    page = page_html()
    assert not re.search(r"(src|href)\s*=\s*[\"']?(https?:)?//", page)  # nothing from outside
    assert "@import" not in page and "url(" not in page


def test_watch_refuses_a_busy_port_in_one_line(tmp_path, capsys) -> None:
    path = measuring_campaign(tmp_path / "c.h5")
    with WatchServer(path, port=0) as server:
        assert main(["watch", str(path), "--port", str(server.port), "--no-browser"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "--port" in err and "choose another" in err


def start_run(folder: Path, *extra: str) -> subprocess.Popen:
    (folder / "live.toml").write_text(LIVE)
    return subprocess.Popen([sys.executable, "-m", "viscorig", "run", "live.toml", "--yes",
                             "--out", "live.h5", *extra], cwd=folder, stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True)


@pytest.mark.slow
def test_run_live_serves_the_campaign_while_it_runs(tmp_path) -> None:
    process = start_run(tmp_path, "--live", "--no-browser", "--sim-pace", "100")
    line = ""
    while "live view:" not in line:
        line = process.stdout.readline()
        assert line, process.communicate()
    url = re.search(r"http://127\.0\.0\.1:\d+/", line).group(0)
    seen, last = [], None
    while process.poll() is None:
        try:
            snapshot = json.loads(get(url + "state.json")[2])["snapshot"]
        except (OSError, http.client.HTTPException):  # the run ended and stopped its live
            break  # view, perhaps mid-request (a body cut short: IncompleteRead)
        if snapshot is not None:
            last = snapshot
            seen.append(sum(run["points"] for run in snapshot["runs"]))
        time.sleep(0.3)
    _, err = process.communicate()
    assert process.returncode == 0, err
    assert len(set(seen)) >= 3 and seen == sorted(seen), seen  # points arriving
    assert last["state"] == "complete" and seen[-1] == 65 + 101 + 101  # the end, shown
    assert "live view: http://127.0.0.1:" in line and not (tmp_path / ".live.h5.commit").exists()


@pytest.mark.slow
@pytest.mark.skipif(CHROMIUM is None, reason="chromium is not installed")
def test_the_live_page_in_chromium_shows_points_arriving_during_a_simulated_run(tmp_path):
    """Another process measures; the page, loaded in headless Chromium, follows it."""
    process = start_run(tmp_path, "--sim-pace", "25")
    path = tmp_path / "live.h5"
    try:
        with WatchServer(path, port=0) as server, Browser(tmp_path / "profile",
                                                          size=(1280, 1000)) as browser:
            browser.open(server.url)
            points = "Number(document.getElementById('points').dataset.points)"
            first = browser.wait_for(f"{points} > 0 && {points}", timeout_s=60)
            later = browser.wait_for(f"{points} > {first} + 20 && {points}", timeout_s=60)
            assert later > first
            browser.wait_for("document.querySelector('#runs tr[data-run=\"soft-10\"] td:nth-"
                             "child(3)').textContent === 'running' && " + points + " > 200",
                             timeout_s=90)
            state = browser.evaluate("document.getElementById('state').textContent")
            assert state == "measuring"
            traces = browser.evaluate(
                "[...document.querySelectorAll('#mag path.trace')].map(p => p.dataset.run)")
            assert traces == ["table", "soft-0", "soft-10"]
            assert browser.evaluate("document.querySelectorAll('#mag circle.now').length") == 1
            assert browser.evaluate("document.querySelectorAll('#force line.limit').length") == 1
            assert browser.evaluate("document.querySelectorAll('#level rect.band').length") == 1
            left = browser.evaluate("document.getElementById('left').textContent")
            assert re.fullmatch(r"\d+:\d\d(:\d\d)?", left), left
            shot = browser.save_screenshot(tmp_path / "watch.png")
            browser.wait_for("document.getElementById('state').textContent === 'complete'",
                             timeout_s=120)
            final = browser.evaluate(points)
            flagged_rings = browser.evaluate("document.querySelectorAll('#mag circle.flag')"
                                             ".length")
            flagged = browser.evaluate("Number(document.getElementById('flagged')"
                                       ".textContent)")
            assert browser.problems() == []
            hosts = {re.match(r"\w+://([^/]+)", url).group(1) for url in browser.requested_urls()
                     if not url.startswith("data:")}
            assert hosts == {server.url.split("/")[2]}, hosts
    finally:
        _, err = process.communicate(timeout=120)
    assert process.returncode == 0, err
    assert final == 65 + 101 + 101
    assert flagged_rings == flagged  # every flagged point ringed on the magnitude chart
    assert shot.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n" and shot.stat().st_size > 40_000
    keep = os.environ.get("VISCORIG_WATCH_SCREENSHOT")
    if keep:  # docs/images/watch.png in the README is made this way
        shutil.copy(shot, keep)


def test_a_file_not_yet_written_or_damaged_is_said_and_the_last_state_kept(tmp_path) -> None:
    path = tmp_path / "later.h5"
    with WatchServer(path, port=0) as server:
        answer = json.loads(get(server.url + "state.json")[2])
        assert answer["snapshot"] is None and "later.h5" in answer["error"]
        measuring_campaign(path)
        time.sleep(0.6)
        answer = json.loads(get(server.url + "state.json")[2])
        assert answer["error"] is None and answer["snapshot"]["current"] == "soft-0"
        path.write_bytes(b"not a campaign any more")
        time.sleep(0.6)
        damaged = json.loads(get(server.url + f"state.json?version={answer['version']}")[2])
        assert damaged["unchanged"] and "not a readable HDF5 file" in damaged["error"]


def test_watch_serves_until_ctrl_c(tmp_path) -> None:
    import signal

    path = measuring_campaign(tmp_path / "c.h5")
    process = subprocess.Popen([sys.executable, "-m", "viscorig", "watch", str(path), "--port",
                                "0", "--no-browser"], stdout=subprocess.PIPE,
                               stderr=subprocess.PIPE, text=True)
    try:
        line = process.stdout.readline()
        url = re.search(r"http://127\.0\.0\.1:\d+/", line).group(0)
        snapshot = json.loads(get(url + "state.json")[2])["snapshot"]
        assert snapshot["runs"][1]["points"] == 5
    finally:
        process.send_signal(signal.SIGINT)
        try:
            out, err = process.communicate(timeout=30)
        except subprocess.TimeoutExpired:  # never leave a server behind
            process.kill()
            out, err = process.communicate()
    assert process.returncode == 0 and "live view stopped" in out and err == ""


def test_a_file_without_sweep_runs_is_not_said_to_have_completed_them(tmp_path) -> None:
    path = tmp_path / "empty.h5"
    CampaignFile.create(path, sequence_text="", durable=False).close()
    snapshot = read_snapshot(path)
    assert (snapshot["state"], snapshot["detail"]) == ("complete", "the file holds no sweep run")
