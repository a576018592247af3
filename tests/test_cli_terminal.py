"""The terminal does what the bench page does: pause and resume (Ctrl-Z, SIGUSR1, SIGUSR2),
notes while a run measures (``viscorig note``), automatic holds (``--holds``, the station's
``[bench]``) and a queue (``viscorig run A.toml B.toml``), over the real command line."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path

import numpy as np
import pytest
from benchrig import soft_sweep_sequence
from reliability_campaign import cli, one_clear_line, station_text, sweep_sequence
from rigsim.faults import parse_fault_spec
from rigsim.rigfile import load_preset
from rigsim.server import SimulatedAnalyserServer

from viscorig.acquisition import notebox
from viscorig.storage import CampaignFile


def _write(folder: Path, name: str, stop: float = 23.0) -> Path:
    """A soft-0 sweep from 20 Hz to ``stop`` (13 points at 23 Hz; at --sim-pace 10 a point
    takes about 0.15 s)."""
    path = folder / name
    path.write_text(soft_sweep_sequence("short", stop))
    return path


def _points(path: Path) -> int:
    with CampaignFile.open(path) as campaign:
        return campaign.run("soft-0").points if "soft-0" in campaign.run_names else 0


def _read_until(process: subprocess.Popen, text: str, lines: list[str],
                timeout_s: float = 30.0) -> None:
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        line = process.stdout.readline()
        if not line:
            break
        lines.append(line)
        if text in line:
            return
    raise AssertionError(f"no line with {text!r} in:\n{''.join(lines)}")


@pytest.mark.slow
def test_signals_pause_and_resume_a_run_and_a_note_reaches_its_journal(tmp_path) -> None:
    """The whole path in a process of its own (about 15 s: two interpreters start)."""
    sequence = _write(tmp_path, "short.toml")
    out = tmp_path / "short.h5"
    process = subprocess.Popen(
        [sys.executable, "-m", "viscorig", "run", str(sequence), "--yes", "--sim-pace", "10",
         "--out", str(out)], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
        cwd=tmp_path)
    lines: list[str] = []
    try:
        _read_until(process, "Ctrl-Z pauses", lines)
        _read_until(process, "run 'soft-0': 13 points", lines)
        time.sleep(0.4)
        process.send_signal(signal.SIGUSR1)
        _read_until(process, "paused: the points measured are committed", lines)
        committed = _points(out)
        assert 0 < committed < 13
        time.sleep(0.6)  # four points' time
        assert _points(out) == committed  # nothing measured while paused
        note = subprocess.run([sys.executable, "-m", "viscorig", "note", str(out), "bolts",
                               "checked"], capture_output=True, text=True, timeout=30)
        assert note.returncode == 0, note.stderr
        assert "handed to the run in progress" in note.stdout
        process.send_signal(signal.SIGTSTP)  # Ctrl-Z: resumes a paused run, never suspends
        stdout, stderr = process.communicate(timeout=60)
    finally:
        if process.poll() is None:
            process.kill()
            process.wait(10)
    assert process.returncode == 0, stderr
    assert "resumed by the technician" in stdout
    with CampaignFile.open(out) as campaign:
        run = campaign.run("soft-0")
        entries = [(entry.kind, entry.run, entry.text) for entry in campaign.journal]
    assert run.points == 13 and run.metadata.status == "complete"
    np.testing.assert_allclose(run.frequency_hz, 20.0 + 0.25 * np.arange(13), atol=0.008)
    assert [kind for kind, _, _ in entries] == ["pause", "note", "resume"]
    assert entries[1] == ("note", "soft-0", "bolts checked")
    assert not list(notebox.inbox(out).glob("*"))  # the mailbox is left empty


def test_in_process_signals_pause_and_resume_and_a_note_is_carried(tmp_path) -> None:
    """``main([...])`` in this process, the signals sent to it, the note from another thread."""
    from viscorig.cli import main

    sequence = _write(tmp_path, "short.toml")
    out = tmp_path / "short.h5"
    seen: dict[str, object] = {}

    def technician() -> None:
        deadline = time.monotonic() + 30
        while time.monotonic() < deadline and (not out.exists() or _points(out) < 3):
            time.sleep(0.01)
        os.kill(os.getpid(), signal.SIGUSR1)
        while time.monotonic() < deadline and not [
                e for e in CampaignFile.open(out).journal if e.kind == "pause"]:
            time.sleep(0.01)
        seen["paused_at"] = _points(out)
        seen["note"] = main(["note", str(out), "warm", "specimen"])
        time.sleep(0.3)
        seen["still"] = _points(out)
        os.kill(os.getpid(), signal.SIGUSR2)

    helper = threading.Thread(target=technician)
    helper.start()
    status, stdout, err = cli(["run", sequence, "--yes", "--sim-pace", "40", "--out", out])
    helper.join(30)
    assert status == 0, err
    assert seen["note"] == 0 and seen["still"] == seen["paused_at"]
    assert "pausing at the point being measured" in stdout and "resuming" in stdout
    with CampaignFile.open(out) as campaign:
        entries = [(entry.kind, entry.text) for entry in campaign.journal]
        assert campaign.run("soft-0").points == 13
    assert entries[0][0] == "pause" and entries[-1][0] == "resume"
    assert ("note", "warm specimen") in entries


def test_a_note_on_a_file_nobody_writes_is_stored_at_once_and_bad_ones_are_one_line(
        tmp_path) -> None:
    path = tmp_path / "c.h5"
    CampaignFile.create(path, sequence_text="").close()
    status, out, err = cli(["note", path, "humid", "today"])
    assert status == 0, err
    assert "note stored" in out
    assert [(e.kind, e.text) for e in CampaignFile.open(path).journal] == [("note", "humid today")]
    status, _, err = cli(["note", tmp_path / "missing.h5", "x"])
    assert status == 2 and "no such file" in one_clear_line(err)
    status, _, err = cli(["note", path, "x" * 2001])
    assert status == 2 and "at most 2000" in one_clear_line(err)
    assert len(CampaignFile.open(path).journal) == 1


def test_a_note_for_a_writer_that_takes_none_is_taken_back(tmp_path, monkeypatch) -> None:
    import viscorig.cli.note as note

    path = tmp_path / "c.h5"
    CampaignFile.create(path, sequence_text="").close()
    monkeypatch.setattr(note, "WAIT_S", 0.3)
    holder = subprocess.Popen(  # another process writes the file and takes no notes
        [sys.executable, "-c", "import sys, time; from viscorig.storage import CampaignFile; "
         f"c = CampaignFile.open({str(path)!r}, 'a'); print('held', flush=True); time.sleep(30)"],
        stdout=subprocess.PIPE, text=True)
    try:
        assert holder.stdout.readline().strip() == "held"
        status, _, err = cli(["note", path, "lost?"])
    finally:
        holder.kill()
        holder.wait(10)
    assert status == 2 and "did not take the note" in one_clear_line(err)
    assert not list(notebox.inbox(path).glob("*.note"))
    assert CampaignFile.open(path).journal == []


def test_a_queue_runs_in_order_and_is_checked_whole_before_anything_moves(tmp_path,
                                                                         monkeypatch) -> None:
    monkeypatch.chdir(tmp_path)
    first, second = _write(tmp_path, "first.toml", 21.0), _write(tmp_path, "second.toml", 21.0)
    bad = tmp_path / "bad.toml"
    bad.write_text('name = "bad"\n[[steps]]\ntype = "sweep"\nrun = "x"\n')

    status, _, err = cli(["run", first, bad, "--yes"])
    assert status == 2 and "bad.toml" in err
    assert not (tmp_path / "first.h5").exists()  # nothing ran: the queue is checked whole
    status, _, err = cli(["run", first, second, "--yes", "--out", tmp_path / "x.h5"])
    assert status == 2 and "--out" in one_clear_line(err)

    status, out, err = cli(["run", first, second, "--yes"])
    assert status == 0, err
    assert out.index("queue 1/2: ") < out.index("first.h5") < out.index("queue 2/2: ") < (
        out.index("second.h5"))
    for name in ("first.h5", "second.h5"):
        assert _points(tmp_path / name) == 5
    status, _, err = cli(["run", second, first, "--yes"])  # files exist: refused whole
    assert status == 2 and "never overwritten" in one_clear_line(err)


def test_holds_on_the_terminal_use_the_station_bench_settings(tmp_path) -> None:
    """An input that keeps overloading holds the run; nothing is measured while held; it goes
    on by itself after ``hold_retry_s`` once the cable is fixed (``hold_resume = "auto"``), as
    on the bench page."""
    with SimulatedAnalyserServer(load_preset("soft-0"), seed=3) as server:
        station = tmp_path / "station.toml"
        station.write_text(station_text(server.socket_resource) + (
            '[bench]\nhold_resume = "auto"\nhold_retry_s = 0.6\nhold_overload_points = 3\n'))
        sequence = tmp_path / "seq.toml"
        sequence.write_text(sweep_sequence(band=(20.0, 25.0)))
        out = tmp_path / "held.h5"
        faults = server.faults
        faults.add(parse_fault_spec("range=4:-51"))  # the reference input's range stuck small
        seen: dict[str, object] = {}

        def fix_when_held() -> None:
            deadline = time.monotonic() + 30
            while time.monotonic() < deadline:
                if out.exists() and "hold" in [e.kind for e in CampaignFile.open(out).journal]:
                    seen["held_at"] = _points(out)
                    break
                time.sleep(0.01)
            time.sleep(0.2)
            seen["while_held"] = _points(out)
            faults.analyser.front_end.reset()  # the cable fixed

        helper = threading.Thread(target=fix_when_held)
        helper.start()
        status, _, err = cli(["run", sequence, "--station", station, "--yes", "--holds",
                              "--out", out])
        helper.join(30)
    assert status == 0, err
    assert seen["while_held"] == seen["held_at"] == 8  # held after the first segment
    with CampaignFile.open(out) as campaign:
        run = campaign.run("soft-0")
        journal = campaign.journal
    assert run.points == 21 and run.metadata.status == "complete"
    assert [entry.kind for entry in journal] == ["hold", "hold_cleared"]
    assert "input overloading for 8 points in a row" in journal[0].text
    assert np.all(run.flags[:8] != 0) and np.all(run.flags[8:] == 0)


@pytest.mark.skipif(not hasattr(signal, "SIGUSR1"), reason="POSIX signals")
def test_the_signal_handlers_are_put_back_after_the_run(tmp_path) -> None:
    before = {name: signal.getsignal(getattr(signal, name))
              for name in ("SIGTSTP", "SIGUSR1", "SIGUSR2")}
    sequence = _write(tmp_path, "s.toml", 21.0)
    status, _, err = cli(["run", sequence, "--yes", "--out", tmp_path / "s.h5"])
    assert status == 0, err
    after = {name: signal.getsignal(getattr(signal, name)) for name in before}
    assert after == before


@pytest.mark.slow
def test_a_note_from_the_terminal_reaches_a_run_of_the_bench_page(tmp_path) -> None:
    """About 5 s: the note comes from a process of its own."""
    from benchrig import wait_until

    from viscorig.bench import BenchService

    _write(tmp_path, "short.toml")
    service = BenchService(root=tmp_path, sim_pace=20.0)
    service.add("short.toml", "bench.h5")
    service.start()
    try:
        prompt = wait_until(lambda: service.state()["prompt"], what="a prompt")
        service.answer(prompt["id"], "done")
        wait_until(lambda: service.state()["points_done"] >= 1, what="measuring")
        service.pause()  # the run stays in progress while the note is on its way
        wait_until(lambda: service.state()["state"] == "paused", what="paused")
        note = subprocess.run(  # another process: this one shares the service's writer lock
            [sys.executable, "-m", "viscorig", "note", str(tmp_path / "bench.h5"), "from", "the",
             "terminal"], capture_output=True, text=True, timeout=60)
        service.resume()
        wait_until(lambda: not service.busy, 60, "the end")
    finally:
        service.shutdown()
    assert note.returncode == 0 and "handed to the run in progress" in note.stdout, note.stderr
    entries = [(e.kind, e.run, e.text) for e in CampaignFile.open(tmp_path / "bench.h5").journal]
    assert entries[1] == ("note", "soft-0", "from the terminal")
    assert [kind for kind, _, _ in entries] == ["pause", "note", "resume"]
