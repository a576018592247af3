"""Running a measurement: start, wait by polling status, pause, resume, abort, deadline.

A swept sine lasts minutes to hours, behind a GPIB adapter whose reads time out in a fraction of
a second: the driver never blocks on ``*OPC?``. It starts with ``ABOR;:INIT:IMM;*OPC``, then
polls ``*STB?`` (answered at once) until the standard-event summary bit says the operation is
complete or an error came, and ``STAT:OPER:COND?`` for progress. Time the analyser spends
auto-calibrating (``STAT:OPER`` bit 0) and time paused do not count against the deadline.

Ending at a point. :meth:`Runner.end_after_point` (from the progress callback or another thread)
asks the sweep to end at the next point boundary: a point being integrated (``STAT:OPER``
measuring without settling) is let finish, and as soon as the analyser settles at the next
frequency, or at once when it is already settling, ``ABOR`` stops it there (and the source with
it, in swept sine). The points measured so far stay in the traces (the rest hold the no-data
marker) and the caller reads them. ``ABOR`` rather than the instrument's pause (``INIT:CONT
OFF``): a paused measurement still counts as running for ``*WAI``, which every trace read uses,
and the source would stay on. While such an end is awaited the status is polled every
:data:`END_POLL_S` so that a short settle is not missed. That the 35670A's settling bit rises as
a new point starts, after the point before it reached its trace, is inferred from the
programming guide's description of the bits: check it on hardware.
"""

from __future__ import annotations

import threading
import time
from collections.abc import Callable

from .errors import InstrumentTimeout, MeasurementAborted, SCPIError
from .segment import SweepProgress
from .status import (
    ESR_ERRORS,
    ESR_OPERATION_COMPLETE,
    OPER_CALIBRATING,
    OPER_MEASURING,
    OPER_RANGING,
    OPER_SETTLING,
    STB_EVENT_SUMMARY,
    Status,
)

__all__ = ["END_POLL_S", "FIRST_POLL_S", "START", "Runner"]

#: First wait between polls (s); the wait doubles up to the caller's poll interval.
FIRST_POLL_S = 0.001
#: Poll interval while an end at the next point boundary is awaited (s).
END_POLL_S = 0.005
#: The message that starts a measurement.
START = "ABOR;:INIT:IMM;*OPC"


class Runner:
    """Starts measurements and waits for them.

    Parameters
    ----------
    write
        Sends a message as is.
    status
        The analyser's status registers and error queue.
    resource
        Named in errors.
    """

    def __init__(self, write: Callable[[str], None], status: Status, resource: str) -> None:
        self.write = write
        self.status = status
        self.resource = resource
        self.aborted = threading.Event()
        self.end_requested = threading.Event()
        self.ended_early = False
        """The last measurement ended at a point boundary (:meth:`end_after_point`)."""
        self._paused_since: float | None = None
        self._paused_s = 0.0
        self.calibrating_s = 0.0

    def run(self, expected_s: float, deadline_s: float,
            progress: Callable[[SweepProgress], None] | None,
            poll_interval_s: float, *, may_end_early: bool = False) -> tuple[float, float]:
        """Start a measurement and wait for it; return its wall-clock start and end times.
        With ``may_end_early``, :meth:`end_after_point` ends it at a point boundary (module
        text); otherwise such a request is ignored.

        Raises
        ------
        MeasurementAborted, InstrumentTimeout, SCPIError
        """
        self.aborted.clear()
        self.ended_early = False  # a request to end made before the start still counts
        self._paused_since = None
        self._paused_s = 0.0
        self.calibrating_s = 0.0
        self.status.arm()
        started = time.time()
        self.write(START)
        self._wait(started, expected_s, deadline_s, progress, poll_interval_s, may_end_early)
        return started, time.time()

    def _wait(self, started: float, expected_s: float, deadline_s: float,
              progress: Callable[[SweepProgress], None] | None, poll_interval_s: float,
              may_end_early: bool = False) -> None:
        wait_s = min(FIRST_POLL_S, poll_interval_s)
        last = time.time()
        while True:
            if self.aborted.is_set():
                raise MeasurementAborted("the measurement was aborted", self.resource)
            if self.status.status_byte() & STB_EVENT_SUMMARY:
                events = self.status.event_status()
                if events & ESR_ERRORS:
                    self.status.check_errors(START)
                    raise SCPIError(0, f"*ESR? reported errors ({events}) with an empty queue",
                                    "*ESR?", self.resource)
                if events & ESR_OPERATION_COMPLETE:
                    return
            condition = self.status.operation_condition()
            at_boundary = bool(condition & OPER_SETTLING) or not condition & OPER_MEASURING
            if may_end_early and self.end_requested.is_set() and at_boundary:
                self.write("ABOR")  # before the point now settling is measured
                self.ended_early = True
                return
            now = time.time()
            if condition & OPER_CALIBRATING:
                self.calibrating_s += now - last
            last = now
            paused_s = self._paused_s + (now - self._paused_since
                                         if self._paused_since is not None else 0.0)
            if now - started - paused_s - self.calibrating_s > deadline_s:
                self.write("ABOR")
                raise InstrumentTimeout(
                    f"the measurement did not complete within {deadline_s:g} s "
                    f"(expected {expected_s:.1f} s; {self.calibrating_s:.1f} s calibrating and "
                    f"{paused_s:.1f} s paused not counted); aborted",
                    self.resource,
                )
            if progress is not None:
                progress(SweepProgress(
                    elapsed_s=now - started, expected_s=expected_s,
                    paused=self._paused_since is not None,
                    settling=bool(condition & OPER_SETTLING),
                    ranging=bool(condition & OPER_RANGING),
                    measuring=bool(condition & OPER_MEASURING),
                    calibrating=bool(condition & OPER_CALIBRATING),
                    calibrating_s=self.calibrating_s,
                ))
            if not self.aborted.is_set():
                if may_end_early and self.end_requested.is_set():
                    time.sleep(min(END_POLL_S, poll_interval_s))  # the point in flight ends
                elif may_end_early:
                    self.end_requested.wait(wait_s)  # a request to end is looked at at once
                else:
                    time.sleep(wait_s)
                wait_s = min(2.0 * wait_s, poll_interval_s)

    def pause(self) -> None:
        """``INIT:CONT OFF``; the deadline stops counting."""
        self.write("INIT:CONT OFF")
        if self._paused_since is None:
            self._paused_since = time.time()

    def resume(self) -> None:
        """``INIT:CONT ON``."""
        self.write("INIT:CONT ON")
        if self._paused_since is not None:
            self._paused_s += time.time() - self._paused_since
            self._paused_since = None

    def end_after_point(self) -> None:
        """End the running measurement at the next point boundary (module text); the waiting
        :meth:`run` then returns and :attr:`ended_early` is true."""
        self.end_requested.set()

    def abort(self) -> None:
        """Stop the measurement (``ABOR``); a waiting :meth:`run` raises
        :class:`MeasurementAborted`."""
        self.aborted.set()
        self.write("ABOR")
