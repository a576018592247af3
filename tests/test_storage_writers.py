"""One writer per campaign file: a second writer is refused at once, naming the holder; a lock
left by a killed writer is taken over; readers keep working during a run.

Before the lock, ``viscorig resume`` started during a ``run`` (or two resumes of one file) both
wrote, and the file ended with duplicated frequencies.
"""

from __future__ import annotations

import errno
import os
import signal
import socket
import subprocess
import sys
import textwrap
import time
from pathlib import Path

import numpy as np
import pytest
import reliability_tally as tally
from reliability_campaign import cli, one_clear_line
from smallcampaign import GRIDS, SEQUENCE

from viscorig.storage import CampaignFile, writelock
from viscorig.storage.writelock import CampaignInUseError, Holder, lock_path

HOLDER = textwrap.dedent(
    """
    import sys
    from viscorig.storage import CampaignFile
    campaign = CampaignFile.open(sys.argv[1], "a")
    print("holding", flush=True)
    sys.stdin.read()
    """
)


def viscorig(*arguments: object, **options) -> subprocess.Popen:
    return subprocess.Popen([sys.executable, "-m", "viscorig", *map(str, arguments)],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, **options)


def holder(path: Path) -> subprocess.Popen:
    process = subprocess.Popen([sys.executable, "-c", HOLDER, str(path)], stdin=subprocess.PIPE,
                               stdout=subprocess.PIPE, text=True)
    assert process.stdout is not None and process.stdout.readline().strip() == "holding"
    return process


@pytest.fixture()
def campaign(tmp_path: Path) -> Path:
    path = tmp_path / "c.h5"
    with CampaignFile.create(path, sequence_text="", durable=False):
        pass
    return path


def test_a_second_writer_is_refused_at_once_naming_the_holder(campaign: Path) -> None:
    first = holder(campaign)
    try:
        before = campaign.read_bytes()
        started = time.monotonic()
        with pytest.raises(CampaignInUseError) as refused:
            CampaignFile.open(campaign, "a")
        assert time.monotonic() - started < 1.0
        message = str(refused.value)
        assert f"pid {first.pid} on {socket.gethostname()}, since 20" in message, message
        assert message.startswith(f"{campaign}: in use by another writer: python -c")
        assert campaign.read_bytes() == before
        tally.add("writers refused")
        with CampaignFile.open(campaign) as reader:  # a reader is not refused
            assert reader.run_names == []
        table = campaign.with_name("frf.csv")
        table.write_text("frequency_hz,time_s,accelerance_table_real_m_per_s2_per_n,"
                         "accelerance_table_imag_m_per_s2_per_n,"
                         "accelerance_support_real_m_per_s2_per_n,"
                         "accelerance_support_imag_m_per_s2_per_n,flags\n"
                         "20,,1,2,,,0\n21,,1,2,,,0\n")
        status, _, err = cli(["import", campaign, "--run", "x", "--csv", table,
                              "--specimen", "none"])
        assert status == 2 and "in use by another writer" in one_clear_line(err)
        assert campaign.read_bytes() == before
    finally:
        first.kill()
        first.wait()


def test_a_lock_left_by_a_killed_writer_is_taken_over(campaign: Path) -> None:
    first = holder(campaign)
    first.send_signal(signal.SIGKILL)
    first.wait()
    stale = writelock.read_holder(campaign)
    assert stale is not None and stale.pid == first.pid  # its record is still there
    started = time.monotonic()
    with CampaignFile.open(campaign, "a") as second:
        assert time.monotonic() - started < 1.0
        assert writelock.read_holder(campaign).pid == os.getpid()
        second.start_run("after-kill", _settings())
    assert not lock_path(campaign).exists()  # released and removed on close
    tally.add("kills survived")


def _settings():
    from viscorig.storage import RunSettings

    return RunSettings(specimen="none", level_m_per_s2=1.0, direction="up", settle_cycles=1,
                       integrate_cycles=1, resolution_hz=0.25)


def test_one_process_is_one_writer_and_close_releases(campaign: Path) -> None:
    one, two = CampaignFile.open(campaign, "a"), CampaignFile.open(campaign, "a")
    one.close()
    assert writelock.holds(campaign)  # the second object still writes
    two.start_run("r", _settings())
    two.close()
    assert not writelock.holds(campaign)
    other = holder(campaign)  # another process may now write
    other.kill()
    other.wait()


def test_a_forked_child_is_another_writer(campaign: Path) -> None:
    with CampaignFile.open(campaign, "a"):
        child = os.fork()
        if child == 0:  # pragma: no cover - in the child
            try:
                CampaignFile.open(campaign, "a")
            except CampaignInUseError:
                os._exit(7)
            os._exit(0)
        _, status = os.waitpid(child, 0)
        assert os.waitstatus_to_exitcode(status) == 7


def test_without_file_system_locks_a_record_decides(campaign: Path, monkeypatch) -> None:
    def no_locks(descriptor: int) -> None:
        raise OSError(errno.ENOLCK, "No locks available")

    monkeypatch.setattr(writelock, "_os_lock", no_locks)
    lock = lock_path(campaign)
    gone = subprocess.run([sys.executable, "-c", "import os; print(os.getpid())"],
                          capture_output=True, text=True, check=True)
    dead = Holder("viscorig run x.toml", int(gone.stdout), socket.gethostname(), "2024-01-01")
    alive = Holder("viscorig run x.toml", os.getppid(), socket.gethostname(), "2024-01-01")
    remote = Holder("viscorig run x.toml", 4242, "another-host", "2024-01-01")
    for record, taken in ((dead, True), (alive, False), (remote, False)):
        lock.write_text(__import__("json").dumps(record.__dict__))
        if taken:
            with CampaignFile.open(campaign, "a"):
                assert writelock.read_holder(campaign).pid == os.getpid()
            assert not lock.exists()
            continue
        with pytest.raises(CampaignInUseError) as refused:
            CampaignFile.open(campaign, "a")
        assert record.describe() in str(refused.value)
        assert ("delete" in str(refused.value)) == (record is remote)
    lock.unlink()


def _wait_for_points(path: Path, process: subprocess.Popen, points: int = 1) -> None:
    deadline = time.monotonic() + 60
    while time.monotonic() < deadline and process.poll() is None:
        try:
            with CampaignFile.open(path) as reader:
                if sum(reader.run(name).points for name in reader.run_names) >= points:
                    return
        except Exception:  # not created yet
            pass
        time.sleep(0.05)
    raise AssertionError("the run committed nothing")


def _check_no_duplicates(path: Path) -> None:
    with CampaignFile.open(path) as done:
        for name, grid in GRIDS.items():
            run = done.run(name)
            assert run.metadata.status == "complete"
            np.testing.assert_allclose(run.frequency_hz, grid, atol=0.008)


@pytest.mark.slow
def test_resume_during_a_run_is_refused_and_readers_keep_working(tmp_path: Path) -> None:
    sequence, path = tmp_path / "s.toml", tmp_path / "c.h5"
    sequence.write_text(SEQUENCE)
    run = viscorig("run", sequence, "--yes", "--out", path, "--sim-pace", 150)
    try:
        _wait_for_points(path, run, 9)
        before = path.read_bytes()
        resume = viscorig("resume", path, "--yes")
        _, err = resume.communicate(timeout=60)
        line = one_clear_line(err)
        assert resume.returncode == 2
        assert f"viscorig run {sequence}" in line and f"(pid {run.pid} on " in line, line
        identify = viscorig("identify", path, "--run", "table")
        assert identify.wait(timeout=60) == 2  # storing a fit is writing: refused too
        show = viscorig("show", path)
        out, err = show.communicate(timeout=60)
        assert show.returncode == 0 and "table" in out, err
        assert path.read_bytes() == before or run.poll() is None  # only the run wrote
        tally.add("writers refused", 2)
    finally:
        assert run.wait(timeout=120) == 0, run.stderr.read() if run.stderr else ""
    _check_no_duplicates(path)


@pytest.mark.slow
def test_two_resumes_at_once_one_is_refused_and_nothing_is_duplicated(tmp_path: Path) -> None:
    sequence, path = tmp_path / "s.toml", tmp_path / "c.h5"
    sequence.write_text(SEQUENCE)
    run = viscorig("run", sequence, "--yes", "--out", path, "--sim-pace", 300)
    _wait_for_points(path, run, 9)
    run.send_signal(signal.SIGKILL)
    run.wait()
    resumes = [viscorig("resume", path, "--yes", "--sim-pace", 50) for _ in range(2)]
    results = [(process.wait(timeout=120), process.stderr.read()) for process in resumes]
    statuses = sorted(status for status, _ in results)
    assert statuses == [0, 2], results
    refused = next(err for status, err in results if status == 2)
    assert "in use by another writer: viscorig resume" in one_clear_line(refused)
    _check_no_duplicates(path)
    tally.add("writers refused")
