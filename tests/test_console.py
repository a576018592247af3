"""Progress that fits: the line fits the terminal's width, never shows nan, and becomes plain
one-line records when the output is not a terminal."""

from __future__ import annotations

import fcntl
import io
import math
import os
import pty
import re
import struct
import subprocess
import sys
import termios
import time
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from viscorig.acquisition import Console, SegmentDone
from viscorig.acquisition.console import Progress, progress_line

SHORT = """\
name = "short"
[[steps]]
type = "prompt"
message = "Remove the damper device."
simulated_rig = "table"
[[steps]]
type = "sweep"
run = "table"
specimen = "none"
band_hz = [18.0, 20.0]
resolution_hz = 0.125
settle_cycles = 50
integrate_cycles = 50
segment_s = 20
level = "1.4 m/s^2"
"""

finite = st.floats(0.001, 1e6, allow_nan=False)
maybe = st.one_of(finite, st.just(math.nan))


@settings(max_examples=300, deadline=None)
@given(width=st.integers(1, 250), run=st.text("abcdefgh-0123456789", min_size=1, max_size=64),
       frequency=maybe, level=maybe, force=maybe, left=maybe, total=st.integers(0, 100_000),
       flagged=st.integers(0, 100_000), label=st.sampled_from(["left", "test time left"]))
def test_the_progress_line_fits_any_width_and_never_shows_nan(width, run, frequency, level,
                                                               force, left, total, flagged,
                                                               label) -> None:
    progress = Progress(run=run, frequency_hz=frequency, points_done=total // 2,
                        points_total=total, level_m_per_s2=level, force_n=force,
                        flagged=flagged, run_left_s=left, all_left_s=left * 3,
                        time_label=label)
    line = progress_line(progress, width)
    assert len(line) <= max(width - 1, 1), (width, line)
    assert "nan" not in line.lower() and "inf" not in line.lower()
    if width >= 30:
        assert line.startswith(run[:24])


def test_at_80_columns_it_keeps_frequency_time_left_level_and_force() -> None:
    progress = Progress(run="hard-10", frequency_hz=87.25, points_done=123, points_total=401,
                        level_m_per_s2=1.16, force_n=85.3, flagged=2, run_left_s=754.0,
                        all_left_s=9900.0, time_label="test time left")
    line = progress_line(progress, 80)
    assert line == "hard-10  87.25 Hz  test time left 12:34  123/401  1.16 m/s^2  85.3 N"
    wide = progress_line(progress, 160)
    assert "[" in wide and "all 2:45:00" in wide and "2 flagged" in wide


def test_the_first_draw_before_any_point_shows_no_nan() -> None:
    """Before, the first redraw showed 'level nan m/s^2  force nan N'."""
    out = io.StringIO()
    console = Console(out=out, interactive=True, width=80)
    console.start_run("soft-0", 0, 401)
    console.poll(20.0, 1433.0)
    drawn = out.getvalue()
    assert "nan" not in drawn and drawn.startswith("\rsoft-0  20 Hz  left 23:53")
    assert len(drawn) == 1 + 79


def segment(points_done: int, level: float) -> SegmentDone:
    return SegmentDone(run="soft-0", number=1, count=3, points_done=points_done,
                       points_total=401, frequency_hz=np.array([20.0, 20.25]),
                       reference_amplitude=np.array([math.nan, level]),
                       force_amplitude=np.array([math.nan, math.nan]),
                       flags=np.array([1, 0], dtype=np.uint16), remeasured=False,
                       seconds_left=100.0)


def test_a_log_record_is_one_plain_line_even_for_a_segment_without_readings() -> None:
    out = io.StringIO()
    console = Console(out=out, interactive=False)
    console.start_run("soft-0", 0, 401)
    console.poll(20.0, 100.0)  # nothing is redrawn in a log
    console.segment(segment(2, math.nan))
    text = out.getvalue()
    assert "\r" not in text and text.count("\n") == 1
    assert "nan" not in text and "level not measured" in text and "force max not measured" in text


def run_in_terminal(args: list[str], cwd: Path, columns: int) -> str:
    """Run a command on a pseudo-terminal of ``columns`` columns; return what it wrote."""
    leader, follower = pty.openpty()
    fcntl.ioctl(follower, termios.TIOCSWINSZ, struct.pack("HHHH", 24, columns, 0, 0))
    process = subprocess.Popen(args, cwd=cwd, stdin=subprocess.DEVNULL, stdout=follower,
                               stderr=follower, close_fds=True)
    os.close(follower)
    chunks, deadline = [], time.monotonic() + 120
    while time.monotonic() < deadline:
        try:
            data = os.read(leader, 65536)
        except OSError:  # the process closed the terminal
            break
        if not data:
            break
        chunks.append(data)
    process.wait(timeout=30)
    os.close(leader)
    assert process.returncode == 0, b"".join(chunks).decode(errors="replace")
    return b"".join(chunks).decode("utf-8", errors="replace")


@pytest.mark.slow
def test_on_an_80_column_terminal_the_redrawn_line_never_wraps(tmp_path) -> None:
    """Before, the line was 106-112 columns: on 80 columns it wrapped and scrolled."""
    (tmp_path / "short.toml").write_text(SHORT)
    text = run_in_terminal([sys.executable, "-m", "viscorig", "run", "short.toml", "--yes",
                            "--out", "short.h5", "--sim-pace", "100"], tmp_path, 80)
    redraws = [piece for line in text.split("\n") for piece in line.split("\r")[1:]]
    assert len(redraws) >= 3, text
    drawn = [piece for piece in redraws if piece.strip()]
    assert all(len(piece) <= 79 for piece in redraws), max(redraws, key=len)
    assert "nan" not in text
    assert any(re.match(r"table  [\d.]+ Hz  test time left \d+:\d\d  ", piece) for piece in drawn)


@pytest.mark.slow
def test_through_a_pipe_each_segment_is_one_plain_record(tmp_path) -> None:
    (tmp_path / "short.toml").write_text(SHORT)
    result = subprocess.run([sys.executable, "-m", "viscorig", "run", "short.toml", "--yes",
                             "--out", "short.h5"], cwd=tmp_path, capture_output=True,
                            text=True, timeout=120)
    assert result.returncode == 0, result.stderr
    assert "\r" not in result.stdout and "nan" not in result.stdout
    records = [line for line in result.stdout.splitlines() if line.startswith("table [")]
    assert len(records) >= 3
    assert all(re.fullmatch(r"table \[\d+/\d+\] [\d.]+-[\d.]+ Hz  level [\d.]+-[\d.]+ m/s\^2  "
                            r"force max [\d.]+ N  points \d+/17( .*)?  test time left: run "
                            r"[\d:]+, all [\d:]+", line) for line in records), records
