"""Crash consistency of a whole campaign: ``viscorig run`` killed with SIGKILL, again and again.

A loop runs a small simulated campaign (bare table, table identification, one specimen run; 25
segments) as separate ``viscorig`` processes: run, SIGKILL after a random delay, resume, SIGKILL
again, ... until at least :data:`KILLS` kills have landed (starting a new campaign whenever one
completes). After every kill the file must open (or not exist yet, if the kill came before it
was created) and hold, for every run, a prefix of the planned grid with no gap and no duplicate
frequency, with every point that was there before the kill still there bit for bit. Finally
``resume`` completes each campaign, and its runs agree with an uninterrupted run of the same
campaign: the same frequency grids, accelerances within the scatter of two uninterrupted runs.
"""

from __future__ import annotations

import random
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path

import numpy as np
import pytest
import reliability_tally as tally
from reliability_campaign import check_prefix, points_lost, snapshot
from smallcampaign import GRIDS, SEQUENCE

from viscorig.storage import CampaignFile

KILLS = 20


class Viscorig:
    """A ``viscorig`` process; :attr:`working` is set at its first line of output (the
    campaign file is open and the analyser connected), after the interpreter's start-up."""

    def __init__(self, *arguments: object, log: Path) -> None:
        self.started = time.monotonic()
        with log.open("a") as handle:
            self.process = subprocess.Popen(
                [sys.executable, "-m", "viscorig", *map(str, arguments)],
                stdout=subprocess.PIPE, stderr=handle, text=True)
        self.working = threading.Event()
        threading.Thread(target=self._drain, daemon=True).start()

    def _drain(self) -> None:
        assert self.process.stdout is not None
        for _ in self.process.stdout:
            self.working.set()
        self.working.set()


def complete(sequence: Path, path: Path, log: Path, resume: bool = False) -> float:
    """Run (or resume) a campaign to its end; return the seconds it worked after start-up."""
    command = Viscorig("resume", path, "--yes", log=log) if resume else Viscorig(
        "run", sequence, "--yes", "--out", path, log=log)
    command.working.wait(120)
    working_from = time.monotonic()
    assert command.process.wait(timeout=120) == 0, log.read_text()
    return time.monotonic() - working_from


def wait_for_commit(path: Path, stamp: int | None, process: subprocess.Popen) -> None:
    """Wait until the campaign file changes (a commit) or the process ends."""
    deadline = time.monotonic() + 60
    while process.poll() is None and time.monotonic() < deadline:
        if path.exists() and path.stat().st_mtime_ns != stamp:
            return
        time.sleep(0.005)


def check_file(path: Path) -> None:
    """The file opens and every run is a gap-free, duplicate-free prefix of its grid."""
    if not path.exists():
        return
    with CampaignFile.open(path) as campaign:
        names = campaign.run_names
    assert set(names) <= set(GRIDS)
    for name in names:
        check_prefix(path, name, GRIDS[name])


def relative_rms(a: np.ndarray, b: np.ndarray) -> float:
    return float(np.sqrt(np.nanmean(np.abs(a / b - 1.0) ** 2)))


@pytest.mark.slow
def test_sigkill_at_random_moments_then_resume_loses_nothing(tmp_path: Path) -> None:
    sequence = tmp_path / "crash.toml"
    sequence.write_text(SEQUENCE)
    log = tmp_path / "stderr.log"
    reference, second = tmp_path / "reference.h5", tmp_path / "second.h5"
    work_s = max(complete(sequence, reference, log), complete(sequence, second, log))

    rng = random.Random(20240611)
    kills, campaigns, outcomes = 0, [], {"before the file": 0, "in a run": 0, "between runs": 0}
    while kills < KILLS:
        path = tmp_path / f"campaign-{len(campaigns)}.h5"
        campaigns.append(path)
        while kills < KILLS:
            before = snapshot(path)
            stamp = path.stat().st_mtime_ns if path.exists() else None
            command = (Viscorig("resume", path, "--yes", log=log) if path.exists()
                       else Viscorig("run", sequence, "--yes", "--out", path, log=log))
            if rng.random() < 0.1:  # now and then during start-up
                command.working.wait(rng.uniform(0.0, 3.0))
            else:  # mostly while it works: after its first commit, at a random moment
                command.working.wait(120)
                wait_for_commit(path, stamp, command.process)
                time.sleep(rng.uniform(0.0, 0.25 * work_s))
            if command.process.poll() is not None:  # the campaign ended before the kill
                assert command.process.returncode == 0, log.read_text()
                break
            command.process.send_signal(signal.SIGKILL)
            command.process.wait(timeout=10)
            kills += 1
            check_file(path)
            after = snapshot(path)
            lost = points_lost(before, after)
            tally.add("points lost", lost)
            assert lost == 0, f"kill {kills}: {lost} committed points lost"
            tally.add("kills survived")
            if not path.exists():
                outcomes["before the file"] += 1
            elif any(0 < len(a["frequency_hz"]) < GRIDS[n].size for n, a in after.items()):
                outcomes["in a run"] += 1
            else:
                outcomes["between runs"] += 1
    for path in campaigns:
        if path.exists():
            complete(sequence, path, log, resume=True)
        else:
            complete(sequence, path, log)

    with CampaignFile.open(reference) as one, CampaignFile.open(second) as two:
        noise = {name: relative_rms(two.run(name).accelerance_table,
                                    one.run(name).accelerance_table) for name in GRIDS}
    for path in campaigns:
        with CampaignFile.open(path) as campaign, CampaignFile.open(reference) as base:
            assert campaign.run_names == base.run_names
            for name in GRIDS:
                run, expected = campaign.run(name), base.run(name)
                assert run.metadata.status == "complete"
                np.testing.assert_allclose(run.frequency_hz, expected.frequency_hz, atol=1e-9)
                scatter = relative_rms(run.accelerance_table, expected.accelerance_table)
                assert scatter <= 3.0 * noise[name] + 1e-4, (path.name, name, scatter, noise)
            assert any(fit.model == "table" for fit in campaign.fits("table"))
    print(f"\n{kills} kills over {len(campaigns)} campaigns: {outcomes}; "
          f"noise between uninterrupted runs {noise}")
    assert outcomes["in a run"] >= KILLS // 3, outcomes
