"""The operator's console: prompts, messages and the progress display of a running sequence.

On a terminal, progress is one line redrawn in place that always fits the terminal's width
(:func:`progress_line` drops the least useful parts first: the bar, then force and level, then
the campaign's time left); values not yet measured are left out, never shown as ``nan``. When
the output is not a terminal (a log file, CI, a pipe), nothing is redrawn: each committed
segment writes one plain line.
"""

from __future__ import annotations

import collections
import math
import os
import sys
import threading
import time
from dataclasses import dataclass
from typing import TextIO, TypedDict

import numpy as np

from viscorig.acquisition.sweep import SegmentDone
from viscorig.storage import FLAG_NAMES, count_flags

#: Columns assumed when the output's width cannot be read.
DEFAULT_WIDTH = 80
#: The progress bar's width, at most and at least (below, it is left out).
BAR_COLUMNS = (8, 30)


def single_line(text: str) -> str:
    """A message that spans lines (as some VISA libraries write them) as one line: its lines
    joined with "; "."""
    return "; ".join(line.strip() for line in str(text).splitlines() if line.strip())


def format_duration(seconds: float) -> str:
    """``h:mm:ss`` (or ``m:ss`` under an hour)."""
    total = max(round(float(seconds)), 0)
    hours, rest = divmod(total, 3600)
    minutes, secs = divmod(rest, 60)
    return f"{hours}:{minutes:02d}:{secs:02d}" if hours else f"{minutes}:{secs:02d}"


def _number(value: float, unit: str, digits: int = 3) -> str:
    """``1.4 m/s^2``; "" when the value is not a finite number (never ``nan``)."""
    return f"{value:.{digits}g} {unit}" if math.isfinite(value) else ""


class ConsoleView(TypedDict, total=False):
    """:meth:`PageConsole.snapshot`: what the bench page shows."""

    prompt: dict[str, object] | None
    run: str
    points_done: int
    points_total: int
    flagged: int
    frequency_hz: float | None
    run_left_s: float | None
    messages: list[dict[str, object]]


@dataclass
class Progress:
    """What the progress line shows; NaN for what is not measured yet."""

    run: str = ""
    frequency_hz: float = math.nan
    points_done: int = 0
    points_total: int = 0
    level_m_per_s2: float = math.nan
    force_n: float = math.nan
    flagged: int = 0
    run_left_s: float = math.nan
    all_left_s: float = math.nan
    time_label: str = "left"


def progress_line(progress: Progress, width: int) -> str:
    """The progress line, at most ``width - 1`` columns (the last column is left free so that
    no terminal wraps it).

    Parts, most useful first: run name, frequency, time left in the run, points done, the
    achieved level and force, the campaign's time left, flags, and a bar that takes what room
    is left. Parts
    are dropped from the least useful until the line fits; a part whose value is unknown is
    not shown.
    """
    p = progress
    frequency = _number(p.frequency_hz, "Hz", 6)
    level = _number(p.level_m_per_s2, "m/s^2")
    force = _number(p.force_n, "N")
    run_left = (f"{p.time_label} {format_duration(p.run_left_s)}"
                if math.isfinite(p.run_left_s) else "")
    all_left = f"all {format_duration(p.all_left_s)}" if math.isfinite(p.all_left_s) else ""
    points = f"{p.points_done}/{p.points_total}" if p.points_total else ""
    # (rank: lower is dropped later, text)
    parts = [
        (0, p.run[:24]), (1, frequency), (2, run_left), (3, points), (4, level), (5, force),
        (6, all_left), (7, f"{p.flagged} flagged"),
    ]
    parts = [(rank, text) for rank, text in parts if text]
    room = max(width - 1, 1)
    bar_at = 3  # the bar stands before the point count
    while parts:
        line = "  ".join(text for _, text in parts)
        spare = room - len(line) - 2
        if spare >= BAR_COLUMNS[0] + 2 and p.points_total:
            inner = min(spare, BAR_COLUMNS[1] + 2) - 2
            filled = round(inner * min(p.points_done / p.points_total, 1.0))
            bar = "[" + "#" * filled + "." * (inner - filled) + "]"
            texts = [text for _, text in parts]
            index = next((i for i, (rank, _) in enumerate(parts) if rank >= bar_at), len(texts))
            return "  ".join([*texts[:index], bar, *texts[index:]])
        if len(line) <= room:
            return line
        parts.remove(max(parts, key=lambda part: part[0]))
    return ""


class NoAnswer(Exception):  # noqa: N818 (an outcome, not a fault)
    """A prompt could not be answered (input closed and no ``--yes``)."""


class Console:
    """Talks to the operator.

    Parameters
    ----------
    yes
        Answer every prompt (CI, demos); the prompt is still printed.
    out
        Where messages and progress go (default stdout).
    interactive
        Redraw one progress line in place; default: ``out`` is a terminal.
    read_line
        Reads the operator's answer (default :func:`input`).
    width
        Columns of the progress line; default: the terminal's width at each redraw.
    """

    def __init__(
        self,
        *,
        yes: bool = False,
        out: TextIO | None = None,
        interactive: bool | None = None,
        read_line=input,
        width: int | None = None,
    ) -> None:
        self.yes = yes
        self.out = out or sys.stdout
        self.interactive = self.out.isatty() if interactive is None else interactive
        self.read_line = read_line
        self.width = width
        self._line_open = False
        self._last_draw = 0.0
        self.progress = Progress()
        self.campaign_left_s = 0.0
        """Test time of the sweeps and waits after the current run, s (set by the runner)."""

    @property
    def time_label(self) -> str:
        """How the time left is named: "left", or "test time left" on a simulated rig."""
        return self.progress.time_label

    @time_label.setter
    def time_label(self, label: str) -> None:
        self.progress.time_label = label

    def columns(self) -> int:
        """The width to fit: as given, else the terminal's now (it may have been resized)."""
        if self.width is not None:
            return self.width
        try:
            return os.get_terminal_size(self.out.fileno()).columns or DEFAULT_WIDTH
        except (AttributeError, OSError, ValueError):
            return DEFAULT_WIDTH

    # -- plain output -------------------------------------------------------------------------
    def _end_line(self) -> None:
        if self._line_open:
            self.out.write("\n")
            self._line_open = False

    def say(self, text: str) -> None:
        """One message line."""
        self._end_line()
        self.out.write(text + "\n")
        self.out.flush()

    def warn(self, text: str) -> None:
        """A warning line."""
        self.say(f"WARNING: {text}")

    def prompt(self, message: str) -> None:
        """Show an operator instruction and wait for Enter (answered at once with ``yes``).

        Raises
        ------
        NoAnswer
            The input is closed and ``yes`` is not set.
        """
        self._end_line()
        if self.yes:
            self.say(f">>> {message} [--yes]")
            return
        self.out.write(f">>> {message} ")
        self.out.flush()
        try:
            self.read_line()
        except EOFError:
            self.say("")
            raise NoAnswer(message) from None

    # -- progress -----------------------------------------------------------------------------
    def start_run(self, run: str, points_done: int, points_total: int, flags: int = 0) -> None:
        """A run starts (or continues)."""
        self.progress = Progress(run=run, points_done=points_done, points_total=points_total,
                                 flagged=flags, time_label=self.progress.time_label)

    def poll(self, frequency_hz: float, run_left_s: float) -> None:
        """Called while the analyser measures; redraws at most ten times a second."""
        if not self.interactive:
            return
        now = time.monotonic()
        if now - self._last_draw < 0.1:
            return
        self._last_draw = now
        self._draw(frequency_hz, run_left_s)

    def _draw(self, frequency_hz: float, run_left_s: float) -> None:
        self.progress.frequency_hz = frequency_hz
        self.progress.run_left_s = run_left_s
        self.progress.all_left_s = run_left_s + self.campaign_left_s
        width = self.columns()
        line = progress_line(self.progress, width)
        self.out.write("\r" + line.ljust(max(width - 1, 0)))
        self.out.flush()
        self._line_open = True

    def segment(self, done: SegmentDone) -> None:
        """A segment was committed."""
        progress = self.progress
        progress.points_done = done.points_done
        progress.flagged += int(np.count_nonzero(done.flags))
        progress.level_m_per_s2 = float(done.reference_amplitude[-1])
        progress.force_n = float(done.force_amplitude[-1])
        if self.interactive:
            self._draw(float(done.frequency_hz[-1]), done.seconds_left)
            return
        counts = count_flags(done.flags)
        flagged = ", ".join(f"{FLAG_NAMES[flag]} {n}" for flag, n in counts.items() if n)
        self.say(
            f"{done.run} [{done.number}/{done.count}] "
            f"{done.frequency_hz.min():.3f}-{done.frequency_hz.max():.3f} Hz  "
            f"level {_span(done.reference_amplitude, 'm/s^2')}  "
            f"force max {_span(done.force_amplitude, 'N', upper_only=True)}  "
            f"points {done.points_done}/{done.points_total}"
            + (f"  flagged: {flagged}" if flagged else "")
            + ("  (measured again after an input overload)" if done.remeasured else "")
            + f"  {self.time_label}: run {format_duration(done.seconds_left)}, "
            f"all {format_duration(done.seconds_left + self.campaign_left_s)}"
        )


def _span(values: np.ndarray, unit: str, *, upper_only: bool = False) -> str:
    """``1.39-1.41 m/s^2`` over the finite values; ``not measured`` when none is finite."""
    finite = np.asarray(values, dtype=float)
    finite = finite[np.isfinite(finite)]
    if not finite.size:
        return "not measured"
    if upper_only:
        return f"{finite.max():.3g} {unit}"
    return f"{finite.min():.3g}-{finite.max():.3g} {unit}"


class PageConsole(Console):
    """The console of the bench page: the same messages, prompts and progress as the terminal's,
    kept for a web page to read (:meth:`snapshot`) and answered from it (:meth:`answer`).

    Every method is safe to call from any thread; prompts block the engine's thread until the
    page answers, or until ``stop_asked()`` turns true.

    Parameters
    ----------
    out
        Where messages are also written (default stdout); progress is never redrawn there.
    keep
        Messages kept for the page.
    """

    def __init__(self, *, out: TextIO | None = None, keep: int = 200) -> None:
        super().__init__(out=out, interactive=False)

        self._lock = threading.Condition()
        self.messages: collections.deque[tuple[float, str]] = collections.deque(maxlen=keep)
        self.prompt_id = 0
        self.prompt_text: str | None = None
        self._answer: str | None = None
        self.stop_asked = lambda: False
        """Set by the owner: a prompt stops waiting (and the run stops) when it turns true."""

    def say(self, text: str) -> None:
        with self._lock:
            self.messages.append((time.time(), single_line(text)))
        super().say(text)

    def prompt(self, message: str) -> None:
        """Show an operator instruction on the page and wait for its answer.

        Raises
        ------
        KeyboardInterrupt
            Answered "abort", or a stop was asked for while it waited.
        """
        self.say(f">>> {message}")
        with self._lock:
            self.prompt_id += 1
            self.prompt_text = message
            self._answer = None
            try:
                while self._answer is None:
                    if self.stop_asked():
                        raise KeyboardInterrupt
                    self._lock.wait(0.1)
                answer = self._answer
            finally:
                self.prompt_text = None
        if answer == "abort":
            raise KeyboardInterrupt

    def answer(self, prompt_id: int, answer: str) -> str | None:
        """Answer the open prompt ``prompt_id`` with ``"done"`` or ``"abort"``; return what is
        wrong with the answer (None when it was taken)."""
        if answer not in ("done", "abort"):
            return 'answer must be "done" or "abort"'
        with self._lock:
            if self.prompt_text is None or prompt_id != self.prompt_id:
                return f"prompt {prompt_id} is not open"
            self._answer = answer
            self._lock.notify_all()
        return None

    def wake(self) -> None:
        """Let a waiting prompt look at ``stop_asked`` now."""
        with self._lock:
            self._lock.notify_all()

    def start_run(self, run: str, points_done: int, points_total: int, flags: int = 0) -> None:
        with self._lock:
            super().start_run(run, points_done, points_total, flags)

    def poll(self, frequency_hz: float, run_left_s: float) -> None:
        with self._lock:
            self.progress.frequency_hz = frequency_hz
            self.progress.run_left_s = run_left_s

    def segment(self, done: SegmentDone) -> None:
        with self._lock:
            super().segment(done)
            self.progress.run_left_s = done.seconds_left

    def snapshot(self) -> ConsoleView:
        """What the page shows: the open prompt, progress and the last messages."""
        with self._lock:
            p = self.progress
            return {
                "prompt": (None if self.prompt_text is None
                           else {"id": self.prompt_id, "text": self.prompt_text}),
                "run": p.run, "points_done": p.points_done, "points_total": p.points_total,
                "flagged": p.flagged,
                "frequency_hz": p.frequency_hz if math.isfinite(p.frequency_hz) else None,
                "run_left_s": p.run_left_s if math.isfinite(p.run_left_s) else None,
                "messages": [{"time": t, "text": m} for t, m in self.messages][-50:],
            }
