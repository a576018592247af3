"""The bench page in a real headless browser (Chromium from the distribution, driven by
Playwright): the paper's sequence on the embedded simulated rig, every prompt answered on the
page, a pause during a sweep (nothing measured while paused, the points measured committed),
resume, a note, an automatic hold when the simulated analyser stops answering and its clearing,
a second browser that is read-only, the browser closed mid-run (the run goes on), an abort, and
``viscorig resume`` completing the file: the campaign equals one measured without
interruption, within the noise of two measurements of the same rig.
"""

from __future__ import annotations

import os
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
from benchrig import Client, bench_server, wait_until
from browser import CHROMIUM
from rigsim.faults import parse_fault_spec

from viscorig.storage import CampaignFile

playwright = pytest.importorskip("playwright.sync_api")
pytestmark = [pytest.mark.slow,
              pytest.mark.skipif(CHROMIUM is None, reason="chromium is not installed")]

ROOT = Path(__file__).resolve().parents[1]
PAPER = ROOT / "sequences" / "paper.toml"
#: Where the README's screenshot is written (set VISCORIG_SCREENSHOT=1 to refresh it).
SCREENSHOT = ROOT / "docs" / "images" / "bench.png"
LAUNCH_ARGS = ["--no-sandbox", "--disable-gpu", "--disable-background-networking"]


def viscorig(*args: str, cwd: Path) -> subprocess.Popen:
    return subprocess.Popen([sys.executable, "-m", "viscorig", *args], cwd=cwd,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)


def test_the_paper_sequence_from_the_page(tmp_path) -> None:
    reference = viscorig("run", str(PAPER), "--yes", "--out", "reference.h5", cwd=tmp_path)
    path = tmp_path / "paper.h5"
    server = bench_server(tmp_path)
    api = Client(server, "reader")
    state = api.state

    def at(run: str, points: int = 1) -> bool:
        s = state()
        return s["run"] == run and s["points_done"] >= points and s["state"] == "measuring"

    with playwright.sync_playwright() as driver:
        browser = driver.chromium.launch(executable_path=CHROMIUM, args=LAUNCH_ARGS)
        context = browser.new_context(viewport={"width": 1400, "height": 1000})
        page = context.new_page()
        page.on("dialog", lambda dialog: dialog.accept())
        page.goto(server.url)
        assert page.url == f"{server.base}/"  # the token left the address bar for a cookie
        page.fill("#sequence", str(PAPER))
        page.fill("#out", "paper.h5")
        page.click("#queue-add")
        page.wait_for_selector("#plan:has-text('predicted test time')")
        assert page.inner_text("#problems") == ""
        page.click("#start")

        answered = []

        def answer_prompts_until(condition, what: str, timeout_s: float = 120) -> None:
            deadline = time.monotonic() + timeout_s
            while not condition():
                if page.is_visible("#prompt"):
                    answered.append(page.inner_text("#prompt-text"))
                    page.click("#prompt-done")
                    wait_until(lambda: not page.is_visible("#prompt") or page.inner_text(
                        "#prompt-text") != answered[-1], 30, "the prompt answered", 0.1)
                assert time.monotonic() < deadline, what
                time.sleep(0.1)

        # pause during the table's sweep
        answer_prompts_until(lambda: at("table", 20), "the table run measuring")
        page.click("#pause")
        page.wait_for_selector("#state[data-state='paused']", timeout=30_000)
        done = state()["points_done"]
        committed = CampaignFile.open(path).run("table").points
        assert committed == done and 0 < done < 129
        time.sleep(1.5)
        assert CampaignFile.open(path).run("table").points == committed  # nothing while paused
        assert state()["state"] == "paused"
        page.fill("#note-text", "table paused to check the shaker's fixing bolts")
        page.click("#note-add")
        page.wait_for_selector("#journal li:has-text('fixing bolts')")
        page.click("#resume")
        wait_until(lambda: at("table", committed + 1), 60, "going on after the pause", 0.1)

        # a second browser is read-only, and says so
        other = browser.new_context().new_page()
        other.goto(server.url)
        other.wait_for_selector("#control:not([hidden])")
        assert other.is_disabled("#pause") and other.is_disabled("#abort")

        # the analyser stops answering during soft-0: the run is held, then goes on
        answer_prompts_until(lambda: at("soft-0", 10), "soft-0 measuring")
        # a reply lost where the driver cannot ask again (reading the error queue clears it)
        server.service.opened.server.faults.add(parse_fault_spec("no_reply@SYST:ERR?"))
        page.wait_for_selector("#held:not([hidden])", timeout=30_000)
        assert "analyser not answering" in page.inner_text("#held-text")
        assert page.get_attribute("#state", "data-state") == "held"
        page.click("#resume")
        page.wait_for_selector("#held", state="hidden", timeout=30_000)

        # the browser is closed mid-run: the run goes on; a new page picks it up
        page.close()
        other.close()
        time.sleep(1.0)
        assert state()["state"] in ("measuring", "waiting_for_operator")
        page = context.new_page()
        page.on("dialog", lambda dialog: dialog.accept())
        page.goto(f"{server.base}/")  # the cookie holds the token
        page.wait_for_selector("#state:not([data-state='idle'])")

        answer_prompts_until(lambda: at("medium-0", 100), "medium-0 measuring")
        page.frame_locator("#live").locator("#points:not([data-points='0'])").wait_for(
            timeout=20_000)
        if os.environ.get("VISCORIG_SCREENSHOT"):
            page.screenshot(path=str(SCREENSHOT), full_page=True)

        # abort during medium-10: committed points kept, the file resumable
        answer_prompts_until(lambda: at("medium-10", 30), "medium-10 measuring")
        page.click("#abort")
        page.wait_for_selector("#state[data-state='stopped']", timeout=30_000)
        assert "viscorig resume" in page.inner_text("#message")
        browser.close()
    api.close()
    server.close()

    with CampaignFile.open(path) as campaign:
        assert campaign.run("medium-10").metadata.status == "aborted"
        kinds = [entry.kind for entry in campaign.journal]
    assert kinds == ["pause", "note", "resume", "hold", "hold_cleared", "abort"], kinds
    assert len(answered) == 5 and all(text.strip() for text in answered)

    resumed = subprocess.run([sys.executable, "-m", "viscorig", "resume", str(path), "--yes"],
                             cwd=tmp_path, capture_output=True, text=True, timeout=600)
    assert resumed.returncode == 0, resumed.stderr
    _, err = reference.communicate(timeout=600)
    assert reference.returncode == 0, err
    with CampaignFile.open(path) as campaign, CampaignFile.open(tmp_path / "reference.h5") as base:
        assert campaign.run_names == base.run_names
        for name in base.run_names:
            run, uninterrupted = campaign.run(name), base.run(name)
            assert run.metadata.status == "complete"
            np.testing.assert_array_equal(run.frequency_hz, uninterrupted.frequency_hz)
            ratio = run.accelerance_table / uninterrupted.accelerance_table
            # the same rig measured twice: agreement within the noise (about 1e-3)
            assert np.median(np.abs(ratio - 1)) < 5e-3, name
            assert np.max(np.abs(ratio - 1)) < 5e-2, name
        assert len(campaign.fits("table")) == 1
