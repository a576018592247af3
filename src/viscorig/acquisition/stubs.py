"""Small plan steps: each yields the messages of one thing done to the rig, the file or the
operator, and returns what it produced (in the manner of Bluesky's ``plan_stubs``).

Larger plans (:mod:`viscorig.acquisition.plans`) are compositions of these with ``yield from``.
Every message carries the name of the step that sent it (its metadata), so a log or an error
says which step of which run asked for what.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np
from numpy.typing import NDArray

from viscorig.acquisition.engine import MeasureRequest, Msg, Plan
from viscorig.acquisition.protocol import MeasuredSegment
from viscorig.acquisition.sweep import SweepSettings, no_data
from viscorig.errors import InstrumentError
from viscorig.storage import Segment

__all__ = [
    "annotate", "checkpoint", "close_run", "commit", "compute", "configure", "measure_segment",
    "mount", "open_run", "pausing", "probe", "prompt", "read_run", "resume_run", "say", "status",
    "wait", "warn",
]


def say(text: str, step: str = "") -> Plan:
    """A message line for the operator."""
    yield Msg("say", (text,), step=step)


def warn(text: str, step: str = "") -> Plan:
    """A warning line."""
    yield Msg("warn", (text,), step=step)


def prompt(message: str, step: str = "") -> Plan:
    """An instruction for the operator; waits for Enter."""
    yield Msg("prompt", (message,), step=step)


def wait(seconds: float, message: str, step: str = "") -> Plan:
    """Wait (on a real rig); returns whether it waited."""
    return (yield Msg("sleep", (seconds, message), step=step))


def mount(preset: str, step: str = "") -> Plan:
    """On the simulated rig, mount a rig preset (a technician's work at a prompt)."""
    yield Msg("mount", (preset,), step=step)


def checkpoint(step: str = "") -> Plan:
    """A safe place to stop: the engine stops here when asked."""
    yield Msg("checkpoint", step=step)


def pausing(step: str = "") -> Plan:
    """Whether a pause waits for the next checkpoint (commit what is measured first)."""
    return bool((yield Msg("pausing", step=step)))


def status(run: str, step: str = "") -> Plan:
    """The run's status in the file (``None``: no such run)."""
    return (yield Msg("status", (run,), step=step))


def read_run(run: str, step: str = "") -> Plan:
    """The run as stored."""
    return (yield Msg("read_run", (run,), step=step))


def open_run(run: str, settings: Any, step: str = "") -> Plan:
    """Create the run in the file (status "running")."""
    yield Msg("open_run", (run, settings), step=step)


def resume_run(run: str, step: str = "") -> Plan:
    """Set a stored run running again; returns its points."""
    return (yield Msg("resume_run", (run,), step=step))


def annotate(run: str, attributes: dict, dataset: str | None = None, step: str = "") -> Plan:
    """Descriptive attributes of the run (or of one of its datasets)."""
    yield Msg("annotate", (run, attributes), {"dataset": dataset}, step=step)


def commit(run: str, segment: Segment, attributes: dict | None = None, step: str = "") -> Plan:
    """Append a segment (and set run attributes) in one atomic commit, then offer to stop.
    Returns the points the run holds."""
    total = yield Msg("commit", (run, segment, attributes), step=step)
    yield from checkpoint(step)
    return total


def close_run(run: str, status_: str, step: str = "") -> Plan:
    """Mark the run "complete" or "aborted"."""
    yield Msg("close_run", (run, status_), step=step)


def compute(function: Callable[..., Any], *args: Any, step: str = "") -> Plan:
    """``function(campaign, *args)``: computation on what the file holds (a fit)."""
    return (yield Msg("compute", (function, *args), step=step))


def configure(settings: SweepSettings, step: str = "", **grid: Any) -> Plan:
    """Set the analyser up for a run (source limit first)."""
    yield Msg("configure", (settings,), grid, step=step)


def probe(settings: SweepSettings, step: str = "") -> Plan:
    """The low-level probe of a newly mounted rig; returns its readings."""
    return (yield Msg("probe", (settings,), step=step))


def measure_segment(request: MeasureRequest, check: Callable[[MeasuredSegment], None],
                    step: str = "") -> Plan:
    """One analyser sweep, once more if an input overloaded (flagged if again) or a point came
    without data (refused if again: never stored as a measurement).

    ``check(measured)`` raises when the analyser measured other frequencies than asked.
    Returns ``(measured, remeasured)``.

    Raises
    ------
    InstrumentError
        No data twice in a row.
    """
    measured = yield Msg("measure", (request,), step=step)
    check(measured)
    if not measured.overload_channels and not no_data(measured).any():
        return measured, False
    measured = yield Msg("measure", (request,), step=step)
    check(measured)
    missing = no_data(measured)
    if missing.any():
        frequencies: NDArray[np.float64] = np.asarray(measured.frequency_hz)
        where = ", ".join(f"{f:g}" for f in frequencies[missing][:5])
        raise InstrumentError(
            f"{request.resource}: the analyser gave no data at {missing.sum()} point(s) "
            f"({where} Hz) twice in a row"
        )
    return measured, True
