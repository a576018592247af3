"""The operator's console: prompts, messages and the progress display of a running sequence.

On a terminal, progress is one line redrawn in place (current frequency, achieved level,
force, flags, time left); otherwise (a log file, CI) one line per committed segment.
"""

from __future__ import annotations

import sys
import time
from typing import TextIO

import numpy as np

from viscorig.acquisition.sweep import SegmentDone
from viscorig.storage import FLAG_NAMES, count_flags


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
    """

    def __init__(
        self,
        *,
        yes: bool = False,
        out: TextIO | None = None,
        interactive: bool | None = None,
        read_line=input,
    ) -> None:
        self.yes = yes
        self.out = out or sys.stdout
        self.interactive = self.out.isatty() if interactive is None else interactive
        self.read_line = read_line
        self._line_open = False
        self._last_draw = 0.0
        self._last: dict[str, float] = {}
        self._flags = 0
        self._run_points = 0
        self.campaign_left_s = 0.0
        """Test time of the sweeps and waits after the current run, s (set by the runner)."""
        self.time_label = "left"

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
        self._run_points = points_done
        self._flags = flags
        self._last = {}
        self._run = run
        self._total = points_total

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
        level = self._last.get("level", float("nan"))
        force = self._last.get("force", float("nan"))
        line = (
            f"{self._run}  {frequency_hz:8.3f} Hz  level {level:7.3g} m/s^2  "
            f"force {force:6.3g} N  flags {self._flags}/{self._run_points}  "
            f"{self.time_label}: run {format_duration(run_left_s)}, "
            f"all {format_duration(run_left_s + self.campaign_left_s)}"
        )
        self.out.write("\r" + line[:160].ljust(100))
        self.out.flush()
        self._line_open = True

    def segment(self, done: SegmentDone) -> None:
        """A segment was committed."""
        self._run_points = done.points_done
        self._flags += int(np.count_nonzero(done.flags))
        self._last = {
            "level": float(done.reference_amplitude[-1]),
            "force": float(done.force_amplitude[-1]),
        }
        if self.interactive:
            self._draw(float(done.frequency_hz[-1]), done.seconds_left)
            return
        counts = count_flags(done.flags)
        flagged = ", ".join(f"{FLAG_NAMES[flag]} {n}" for flag, n in counts.items() if n)
        self.say(
            f"{done.run} [{done.number}/{done.count}] "
            f"{done.frequency_hz.min():.3f}-{done.frequency_hz.max():.3f} Hz  "
            f"level {np.nanmin(done.reference_amplitude):.3g}-"
            f"{np.nanmax(done.reference_amplitude):.3g} m/s^2  "
            f"force max {np.nanmax(done.force_amplitude):.3g} N  "
            f"points {done.points_done}/{done.points_total}"
            + (f"  flagged: {flagged}" if flagged else "")
            + ("  (measured again after an input overload)" if done.remeasured else "")
            + f"  {self.time_label}: run {format_duration(done.seconds_left)}, "
            f"all {format_duration(done.seconds_left + self.campaign_left_s)}"
        )
