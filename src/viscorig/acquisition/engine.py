"""The run engine: executes a plan of messages against the rig, the campaign file and the
operator, with an explicit lifecycle.

In the manner of Bluesky's ``RunEngine``: a *plan* is a generator that yields :class:`Msg`
objects and is sent back what each one produced (a measured segment, the number of points a
commit left in the run, a run read from the file). Plans decide; only the engine touches the
analyser, the campaign file, the clock and the console. A plan can therefore be read, composed
and tested without any of them, and everything that happens to the rig passes through one
place that knows when to stop.

Lifecycle (:class:`EngineState`)::

    idle ──► running ──► done
              │ ▲  │ ╰───► refused   (a step refused to measure: nothing of it was measured)
              │ │  │ ╰───► faulted   (the analyser failed: every committed segment is kept)
              │ │  ╰──► stopping ──► stopped   (Ctrl-C, SIGTERM, :meth:`RunEngine.request_stop`)
              │ ╰── paused ◄── pausing     (:meth:`RunEngine.request_pause`, then resume)
              ╰──► held ──► running        (a hold condition, until it clears)

Pausing and holds. :meth:`RunEngine.request_pause` (from any thread) pauses at the point: an
analyser that can end a sweep at a point boundary (``end_after_point``, the 35670A driver's
sweeps, linear or point by point) is asked to, for a plan that takes such a segment (a full
plan's, an adaptive plan's), so the point being measured is finished, the sweep ends before the
next one and the segment returned holds the points measured so far, which the plan commits;
otherwise the segment being measured is finished and committed. At the checkpoint that follows
the commit, the engine switches the source off (the analyser's abort, which ramps it down at
the analyser's slew rate) and waits. :meth:`RunEngine.request_resume` goes on; the analyser is
configured again first (the source starts from its start level and the controller levels again)
and the plan continues from where it was, as if nothing had happened. Hold conditions
(:mod:`viscorig.acquisition.holds`, pluggable) see every committed segment and every analyser
error of a measurement: one that answers with a reason holds the run at the next checkpoint
(or, for an error, at once: the segment in flight is dropped and measured again after the
hold). A hold ends when its condition clears (``hold_resume = "auto"``) or when the technician
resumes. Each pause, hold and resume is written to the campaign's journal
(:mod:`viscorig.storage.journal`) with its reason.

Stopping. The first Ctrl-C (or SIGTERM) while the analyser measures only asks it to stop: the
next poll aborts the analyser and the segment in flight is dropped, so no partial segment is
ever written; at a prompt or a wait it interrupts at once, during a write to the campaign file
as the write ends; a second Ctrl-C always does. A plan marks where stopping is safe with
``checkpoint`` messages (after each commit); the engine stops there when asked. On any ending
other than ``done`` the engine throws the exception into the plan, whose cleanup (marking its
run "aborted" in the file) yields messages like any other; then the plan ends. Resuming is
reading the file again: plans continue from what it holds.
"""

from __future__ import annotations

import contextlib
import enum
import signal
import threading
import time
from collections.abc import Callable, Generator, Iterator
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from viscorig.acquisition.console import Console
from viscorig.acquisition.probe import measure_probe
from viscorig.acquisition.protocol import Analyser, MeasuredSegment, SweepProgressReport
from viscorig.acquisition.sweep import (
    SweepHooks,
    SweepInterrupted,
    SweepSettings,
    Wiring,
    configure,
)
from viscorig.storage import CampaignFile

__all__ = ["EngineState", "Msg", "Plan", "RunEngine", "RunRefused", "StopRequest"]

#: Messages that read or write the campaign file: run under the engine's file lock, so that
#: another thread (the bench page's notes) can write to the same file between them.
FILE_COMMANDS = frozenset({"status", "read_run", "fits", "open_run", "resume_run", "annotate",
                           "commit", "close_run", "store_fit", "compute"})
#: How often a paused or held engine looks at its requests and conditions, s.
WAIT_POLL_S = 0.1


class RunRefused(Exception):  # noqa: N818 (an outcome, not a fault)
    """A step does not measure; the message says why and what to do."""


@dataclass(frozen=True)
class Msg:
    """One instruction of a plan to the engine.

    Attributes
    ----------
    command
        What to do (the engine's vocabulary: :meth:`RunEngine.commands`).
    args, kwargs
        Its arguments.
    step
        The plan step that sent it (its metadata: kind, run, purpose), for logs and errors.
    """

    command: str
    args: tuple[Any, ...] = ()
    kwargs: dict[str, Any] = field(default_factory=dict)
    step: str = ""


#: A plan: yields messages, is sent what each produced, returns its result.
Plan = Generator[Msg, Any, Any]


class EngineState(enum.Enum):
    """Lifecycle of the engine (module text)."""

    IDLE = "idle"
    RUNNING = "running"
    PAUSING = "pausing"
    PAUSED = "paused"
    HELD = "held"
    STOPPING = "stopping"
    DONE = "done"
    REFUSED = "refused"
    FAULTED = "faulted"
    STOPPED = "stopped"


_ENDINGS = {EngineState.STOPPING, EngineState.DONE, EngineState.REFUSED, EngineState.FAULTED,
            EngineState.STOPPED}
_ENGINE_TRANSITIONS = {
    EngineState.IDLE: {EngineState.RUNNING},
    EngineState.RUNNING: {*_ENDINGS, EngineState.PAUSING, EngineState.PAUSED, EngineState.HELD},
    EngineState.PAUSING: {*_ENDINGS, EngineState.RUNNING, EngineState.PAUSED, EngineState.HELD},
    EngineState.PAUSED: {EngineState.RUNNING, EngineState.STOPPING, EngineState.STOPPED,
                         EngineState.FAULTED},
    EngineState.HELD: {EngineState.RUNNING, EngineState.PAUSED, EngineState.STOPPING,
                       EngineState.STOPPED, EngineState.FAULTED},
    EngineState.STOPPING: {EngineState.STOPPED, EngineState.FAULTED, EngineState.REFUSED},
    EngineState.DONE: set(),
    EngineState.REFUSED: set(),
    EngineState.FAULTED: set(),
    EngineState.STOPPED: set(),
}


class StopRequest:
    """Ctrl-C (SIGINT) and SIGTERM while a plan runs (the module text says what each does)."""

    def __init__(self, console: Console) -> None:
        self.console = console
        self.requested = threading.Event()
        self.measuring = [False]
        self.writing = False
        """True while the campaign file is written: a first signal then waits for the write."""
        self.deferred = False
        """A first signal came while the file was written; it interrupts once the write ends."""
        self.signalled = ""
        """The name of the signal that asked for the stop ("" when none did)."""

    def asked(self) -> bool:
        """Has a stop been asked for?"""
        return self.requested.is_set()

    def __call__(self, signum: int, frame: object) -> None:
        self.signalled = self.signalled or signal.Signals(signum).name
        if self.writing and not self.requested.is_set():
            self.requested.set()
            self.deferred = True
            return
        if self.requested.is_set() or not self.measuring[0]:
            self.requested.set()
            raise KeyboardInterrupt
        self.requested.set()
        self.console.say("Stopping: aborting the analyser; committed segments are kept ...")

    @contextlib.contextmanager
    def file_written(self) -> Iterator[None]:
        """Hold a first signal off while the block writes the campaign file (an HDF5 write cut
        in its middle leaves the engine's record of the file behind it); it interrupts as the
        block ends."""
        self.writing = True
        try:
            yield
        finally:
            self.writing, deferred, self.deferred = False, self.deferred, False
        if deferred:
            raise KeyboardInterrupt

    @contextlib.contextmanager
    def installed(self) -> Iterator[None]:
        """Handle the signals while the block runs (main thread only)."""
        if threading.current_thread() is not threading.main_thread():
            yield
            return
        previous = {sig: signal.signal(sig, self) for sig in (signal.SIGINT, signal.SIGTERM)}
        try:
            yield
        finally:
            for sig, handler in previous.items():
                signal.signal(sig, handler)


@dataclass
class Rig:
    """What the engine drives: the analyser and its wiring, and how to stand in for the
    technician on a simulated rig."""

    analyser: Analyser
    wiring: Wiring
    mount: Callable[[str], None] | None = None
    real_time_waits: bool = True
    poll_interval_s: float = 0.2


class RunEngine:
    """Executes plans (module text).

    Parameters
    ----------
    campaign
        The campaign file (mode "a").
    rig
        The analyser, its wiring and the simulated rig's mount.
    console
        Messages, prompts and progress.
    holds
        Hold conditions (:mod:`viscorig.acquisition.holds`); none by default.
    hold_resume
        ``"auto"``: resume by itself when the condition that held the run clears;
        ``"technician"``: wait for :meth:`request_resume`.
    file_lock
        Held while the engine reads or writes the campaign file (share it with any other
        writer of the same file in this process).
    """

    def __init__(self, campaign: CampaignFile, rig: Rig, console: Console, *,
                 holds: list | None = None, hold_resume: str = "technician",
                 file_lock: threading.RLock | None = None) -> None:
        self.campaign = campaign
        self.rig = rig
        self.console = console
        self.stop = StopRequest(console)
        self.holds = list(holds or [])
        self.hold_resume = hold_resume
        self.file_lock = file_lock if file_lock is not None else threading.RLock()
        self.held_because: str | None = None
        """Why the run is held (None when it is not)."""
        self.current_run = ""
        """The run being measured ("" between runs)."""
        self.committed: tuple[str, int] = ("", 0)
        """The run of the last commit and the points it held after it."""
        self._control = threading.Condition()
        self._pause_wanted = False
        self._resume_wanted = False
        self._pending_hold: list[tuple[Any, str]] = []
        self._ending: Callable[[], None] | None = None
        self._relevel = False
        self._last_configure: tuple[tuple, dict] | None = None
        self.state = EngineState.IDLE
        self.history: list[tuple[EngineState, float]] = [(self.state, time.time())]
        self._identity: str | None = None
        self._handlers: dict[str, Callable[..., Any]] = {
            name[len("_do_"):]: getattr(self, name) for name in dir(self)
            if name.startswith("_do_")
        }

    @property
    def commands(self) -> tuple[str, ...]:
        """The messages the engine understands."""
        return tuple(sorted(self._handlers))

    def _move(self, state: EngineState) -> None:
        with self._control:
            if state not in _ENGINE_TRANSITIONS[self.state]:
                raise RuntimeError(f"engine: {self.state.value} -> {state.value} is not allowed")
            self.state = state
            self.history.append((state, time.time()))
            self._control.notify_all()

    # -- requests from any thread ----------------------------------------------------------
    def request_pause(self) -> bool:
        """Pause at the point being measured (module text), at the checkpoint after its commit.
        Returns whether the request was taken (the engine is running)."""
        with self._control:
            if self.state is not EngineState.RUNNING:
                return False
            self._pause_wanted = True
            self._move(EngineState.PAUSING)
            self._end_at_point()
            return True

    def _end_at_point(self) -> None:
        """Ask the sweep in flight, once, to end after the point being measured (when the
        analyser can)."""
        with self._control:
            end, self._ending = self._ending, None
        if end is not None:
            end()

    def request_resume(self) -> bool:
        """Go on after a pause or a hold. Returns whether the request was taken."""
        with self._control:
            if self.state not in (EngineState.PAUSED, EngineState.HELD, EngineState.PAUSING):
                return False
            if self.state is EngineState.PAUSING:  # not paused yet: simply do not pause
                self._pause_wanted = False
                self._move(EngineState.RUNNING)
                return True
            self._resume_wanted = True
            self._control.notify_all()
            return True

    def request_stop(self, reason: str = "") -> None:
        """Stop as Ctrl-C does: the analyser is aborted at its next poll (the segment in flight
        is dropped), a pause, hold or prompt ends at once; committed points are kept. A
        ``reason`` is written to the journal."""
        run = self.current_run  # read first: the stop may close the run before it is logged
        with self._control:
            self.stop.requested.set()
            self._control.notify_all()
        if reason:
            self._log("abort", reason, run)

    def _log(self, kind: str, text: str, run: str | None = None) -> None:
        """Write a journal entry about ``run`` (default: the current one); a failure to write it
        is said, never fatal."""
        try:
            with self.file_lock:
                self.campaign.add_journal_entry(kind, text,
                                                self.current_run if run is None else run)
        except Exception as error:  # the file's own commits report their failures
            self.console.warn(f"journal: {error}")

    def _source_off(self) -> str:
        """Stop the analyser's source (its abort; a silent analyser is left as it is) and say
        how: ramped down at the analyser's slew rate when it reports how long that takes
        (``source_ramp_down_s``), else off."""
        analyser = self.rig.analyser
        with contextlib.suppress(Exception):
            analyser.abort()
        ramp = getattr(analyser, "source_ramp_down_s", None)
        seconds = 0.0
        with contextlib.suppress(Exception):
            seconds = float(ramp()) if callable(ramp) else 0.0
        if seconds > 0.0:
            return f"the source ramps down to off (within {seconds:.3g} s)"
        return "the source is off"

    def _wait(self, done: Callable[[], bool]) -> None:
        """Wait until ``done()`` or a stop request.

        Raises
        ------
        KeyboardInterrupt
            A stop was asked for.
        """
        while True:  # done() may ask the analyser: never under the control lock
            if self.stop.asked():
                raise KeyboardInterrupt
            if done():
                return
            with self._control:
                self._control.wait(WAIT_POLL_S)

    def _pause(self) -> None:
        with self._control:
            if not self._pause_wanted:  # resumed before the pause took hold
                return
            self._pause_wanted = False
            self._resume_wanted = False
            self._move(EngineState.PAUSED)
        source = self._source_off()
        self.console.say(f"paused: the points measured are committed, {source}")
        self._log("pause", f"paused by the technician; {source}")
        self._wait(lambda: self._resume_wanted)
        self._go_on("resume", "resumed by the technician")

    def _hold(self, claims: list[tuple[Any, str]], fault: bool) -> None:
        """Hold for every (condition, reason) of ``claims`` until all have cleared (or the
        technician resumes; a fault's condition must have cleared even then)."""
        conditions = [condition for condition, _ in claims]
        reason = "; ".join(text for _, text in claims)
        self._source_off()
        with self._control:
            self._resume_wanted = False
            self.held_because = reason
            self._move(EngineState.HELD)
        self.console.warn(f"held: {reason}")
        self._log("hold", reason)

        def may_go_on() -> bool:
            if self._resume_wanted:
                self._resume_wanted = False
                if not fault or all(c.cleared() for c in conditions):
                    return True
                self.held_because = f"{reason}; still not cleared"
            return self.hold_resume == "auto" and all(c.cleared() for c in conditions)

        self._wait(may_go_on)
        self.held_because = None
        self._go_on("hold_cleared", f"{reason}: cleared, going on")

    def _go_on(self, kind: str, text: str) -> None:
        with self._control:
            self._resume_wanted = False
            self._move(EngineState.RUNNING)
            self._relevel = True
            if self._pause_wanted:  # asked while held: pause at the next checkpoint
                self._move(EngineState.PAUSING)
        self.console.say(text)
        self._log(kind, text)

    # -- running a plan ------------------------------------------------------------------------
    def run(self, plan: Plan, *, signals: bool = True) -> Any:
        """Run ``plan`` to its end (with the signal handlers installed unless ``signals`` is
        false); return its result.

        Raises
        ------
        KeyboardInterrupt, SweepInterrupted
            Stopped (state "stopped"), after the plan's cleanup.
        RunRefused
            A step refused (state "refused").
        Exception
            An instrument fault or any other error (state "faulted"), after the cleanup.
        """
        self._move(EngineState.RUNNING)
        with self.stop.installed() if signals else contextlib.nullcontext():
            try:
                result = self._drive(plan)
            except (KeyboardInterrupt, SweepInterrupted):
                self._move(EngineState.STOPPED)
                if self.stop.signalled:  # request_stop journals its own reason
                    how = {"SIGINT": "Ctrl-C"}.get(self.stop.signalled, self.stop.signalled)
                    self._log("abort", f"stopped at the terminal ({how})",
                              self.current_run or self.committed[0])
                raise
            except RunRefused:
                self._move(EngineState.REFUSED)
                raise
            except BaseException:
                self._move(EngineState.FAULTED)
                raise
        if self.state is EngineState.PAUSING:  # asked too late: nothing was left to pause
            self._pause_wanted = False
        self._move(EngineState.DONE)
        return result

    def _drive(self, plan: Plan) -> Any:
        reply: Any = None
        error: BaseException | None = None
        while True:
            try:
                msg = plan.throw(error) if error is not None else plan.send(reply)
            except StopIteration as end:
                return end.value
            error = None
            handler = self._handlers.get(msg.command)
            if handler is None:
                raise RuntimeError(f"engine: unknown message {msg.command!r} from "
                                   f"{msg.step or 'a plan'}")
            try:
                if msg.command in FILE_COMMANDS:
                    with self.file_lock, self.stop.file_written():
                        reply = handler(*msg.args, **msg.kwargs)
                else:
                    reply = handler(*msg.args, **msg.kwargs)
            except BaseException as caught:  # into the plan: its cleanup runs, then it ends
                if isinstance(caught, KeyboardInterrupt | SweepInterrupted):
                    self.stop.requested.set()
                    if self.state in (EngineState.RUNNING, EngineState.PAUSING,
                                      EngineState.PAUSED, EngineState.HELD):
                        self._move(EngineState.STOPPING)
                error = caught
                reply = None

    # -- the operator ---------------------------------------------------------------------------
    def _do_say(self, text: str) -> None:
        self.console.say(text)

    def _do_warn(self, text: str) -> None:
        self.console.warn(text)

    def _do_prompt(self, message: str) -> None:
        self.console.prompt(message)

    def _do_sleep(self, seconds: float, message: str) -> bool:
        """Wait (really on a real rig; a simulated rig's clock is test time). Returns whether
        it waited."""
        if not self.rig.real_time_waits:
            self.console.say(f"{message}: {seconds:g} s (simulated rig: not waited)")
            return False
        self.console.say(f"{message}: {seconds:g} s ...")
        time.sleep(seconds)
        return True

    def _do_mount(self, preset: str) -> None:
        if self.rig.mount is not None:
            self.rig.mount(preset)
            self.console.say(f"(simulated rig: {preset} mounted)")

    def _do_checkpoint(self) -> None:
        """A safe place to stop, pause or hold: do it here when asked."""
        if self.stop.asked():
            raise KeyboardInterrupt
        if self._pending_hold:
            claims, self._pending_hold = self._pending_hold, []
            self._hold(claims, fault=False)
        if self._pause_wanted:
            self._pause()

    def _do_pausing(self) -> bool:
        """Whether a pause is asked for and waits for the next checkpoint (a plan that
        measures point by point commits what it holds, so the pause comes after the point)."""
        with self._control:
            return self._pause_wanted

    def _do_progress(self, what: str, *args: Any) -> None:
        """Progress for the console: ``start_run``, ``segment``, ``campaign_left``."""
        if what == "campaign_left":
            self.console.campaign_left_s = float(args[0])
        else:
            getattr(self.console, what)(*args)

    # -- the analyser ---------------------------------------------------------------------------
    def _do_identify(self) -> str:
        if self._identity is None:
            self._identity = self.rig.analyser.identify()
        return self._identity

    def _do_supports(self, member: str) -> bool:
        """Does the analyser offer ``member`` (``measure_points`` for an adaptive plan)?"""
        return callable(getattr(self.rig.analyser, member, None))

    def _do_configure(self, settings: SweepSettings, **grid: Any) -> None:
        self._last_configure = ((settings,), grid)
        self._relevel = False
        configure(self.rig.analyser, self.rig.wiring, settings, **grid)

    def _do_probe(self, settings: SweepSettings) -> tuple:
        hooks = SweepHooks(should_stop=lambda: self.stop.asked(),
                           measuring=self.stop.measuring)  # the stop request, as the probe sees it
        return measure_probe(self.rig.analyser, self.rig.wiring, settings, hooks)

    def _do_measure(self, request: MeasureRequest) -> MeasuredSegment:
        """Measure one analyser sweep: a linear band, or chosen points in manual sweep mode.
        After a pause or a hold the analyser is configured again first (it levels anew); an
        analyser error that a hold condition claims holds the run, then the sweep is measured
        again."""
        while True:
            if self._relevel and self._last_configure is not None:
                args, grid = self._last_configure
                self._do_configure(*args, **grid)
            self._relevel = False
            try:
                return self._measure_once(request)
            except (KeyboardInterrupt, SweepInterrupted):
                raise
            except Exception as error:
                claimed = [(c, r) for c in self.holds if (r := c.fault(error)) is not None]
                if not claimed:
                    raise
                self._hold(claimed, fault=True)

    def _measure_once(self, request: MeasureRequest) -> MeasuredSegment:
        analyser = self.rig.analyser
        cumulative = np.cumsum(request.durations_s)

        end_after_point = (getattr(analyser, "end_after_point", None)
                           if request.ends_at_a_point else None)

        def progress(report: SweepProgressReport) -> None:
            if self.stop.asked():
                analyser.abort()
                return
            if self._pause_wanted and callable(end_after_point):
                end_after_point()  # again at every poll: a request made as the sweep started
            index = min(int(np.searchsorted(cumulative, report.elapsed_s)), cumulative.size - 1)
            in_flight = max(float(cumulative[-1]) - float(report.elapsed_s), 0.0)
            self.console.poll(float(request.frequency_hz[index]), request.left_after_s + in_flight)

        poll = self.rig.poll_interval_s
        self.stop.measuring[0] = True
        with self._control:
            self._ending = end_after_point if callable(end_after_point) else None
        try:
            measured = request.call(analyser, progress, poll)
        except Exception as error:
            if self.stop.asked():
                raise SweepInterrupted(request.run) from error
            raise
        finally:
            with self._control:
                self._ending = None
            self.stop.measuring[0] = False
        if self.stop.asked():  # stopped as the segment ended: drop it all the same
            raise SweepInterrupted(request.run)
        return measured

    # -- the campaign file ------------------------------------------------------------------
    def _do_status(self, run: str) -> str | None:
        if run not in self.campaign.run_names:
            return None
        return self.campaign.run_metadata(run).status

    def _do_read_run(self, run: str):
        return self.campaign.run(run)

    def _do_fits(self, run: str) -> list:
        return self.campaign.fits(run)

    def _do_open_run(self, run: str, settings) -> None:
        self.campaign.start_run(run, settings)
        self.current_run = run

    def _do_resume_run(self, run: str) -> int:
        self.current_run = run
        return self.campaign.resume_run(run)

    def _do_annotate(self, run: str, attributes: dict, dataset: str | None = None) -> None:
        self.campaign.annotate(run, attributes, dataset=dataset)

    def _do_commit(self, run: str, segment, attributes: dict | None = None) -> int:
        total = self.campaign.append_segment(run, segment, attributes)
        self.committed = (run, total)
        for condition in self.holds:
            reason = condition.observe(segment)
            if reason is not None:  # held at the checkpoint that follows
                self._pending_hold.append((condition, reason))
        return total

    def _do_close_run(self, run: str, status: str) -> None:
        self.campaign.finish_run(run, status)
        self._pending_hold = []
        for condition in self.holds:  # a new run starts counting afresh
            reset = getattr(condition, "reset", None)
            if callable(reset):
                reset()
        self.current_run = ""

    def _do_store_fit(self, run: str, result) -> str:
        # keeps the command's start fast: scipy loads only when a fit is stored
        from viscorig.identify import store_fit

        return store_fit(self.campaign, run, result)

    def _do_compute(self, function: Callable[..., Any], *args: Any) -> Any:
        """Computation that reads the campaign file (a fit of a stored run)."""
        return function(self.campaign, *args)


@dataclass(frozen=True)
class MeasureRequest:
    """One analyser sweep a plan asks for.

    Attributes
    ----------
    run
        The run it belongs to.
    resource
        The analyser's resource (named in fault messages).
    frequency_hz
        The frequencies, in measurement order (for the check and the progress line).
    durations_s
        Test time of each point (progress).
    left_after_s
        Test time of the run after this sweep (progress).
    call
        ``call(analyser, progress, poll_interval_s) -> MeasuredSegment``: the driver call.
    ends_at_a_point
        The plan takes a segment that a pause ended at a point (the first points of those
        asked for, ``ended_early``); otherwise a pause waits for the whole sweep.
    """

    run: str
    resource: str
    frequency_hz: np.ndarray
    durations_s: np.ndarray
    left_after_s: float
    call: Callable[[Analyser, Callable[[SweepProgressReport], None], float], MeasuredSegment]
    ends_at_a_point: bool = False


