"""Pause and resume a run from the terminal, as the bench page's buttons do.

While ``viscorig run`` (or ``resume``) measures:

- **Ctrl-Z** (``SIGTSTP``) pauses the run at the point being measured; Ctrl-Z again resumes it
  (and resumes a run the automatic holds stopped). The process is not suspended.
- ``kill -USR1 PID`` pauses, ``kill -USR2 PID`` resumes (for scripts).

A signal only asks: the run engine (:class:`~viscorig.acquisition.engine.RunEngine`) pauses and
resumes exactly as for the page (the point being measured finished and committed, the source
off, each pause and resume in the campaign's journal). The handler hands the request to a short
thread, so the engine's lock is never taken inside a signal handler. POSIX only: where the
signals do not exist nothing is installed.
"""

from __future__ import annotations

import contextlib
import signal
import threading
from collections.abc import Callable, Iterator

from viscorig.acquisition.engine import EngineState, RunEngine

__all__ = ["PauseSignals", "signal_help"]

#: Signal name -> what it asks for.
ACTIONS = {"SIGTSTP": "toggle", "SIGUSR1": "pause", "SIGUSR2": "resume"}


def signal_help() -> str:
    """The line the terminal shows when a run starts."""
    return ("Ctrl-Z pauses at the point being measured, Ctrl-Z again resumes; Ctrl-C stops "
            "(committed points are kept)")


class PauseSignals:
    """The terminal's pause and resume (module text).

    Parameters
    ----------
    engine
        The run engine to ask.
    say
        Prints one line to the technician.
    """

    def __init__(self, engine: RunEngine, say: Callable[[str], None]) -> None:
        self.engine = engine
        self.say = say
        self.threads: list[threading.Thread] = []

    def __call__(self, signum: int, frame: object) -> None:
        action = ACTIONS.get(signal.Signals(signum).name, "toggle")
        thread = threading.Thread(target=self.act, args=(action,), name="viscorig-pause",
                                  daemon=True)
        self.threads.append(thread)
        thread.start()

    def act(self, action: str) -> bool:
        """Ask the engine to ``pause``, ``resume`` or ``toggle``; say what came of it. Returns
        whether the engine took the request."""
        engine = self.engine
        if action == "toggle":
            waiting = engine.state in (EngineState.PAUSING, EngineState.PAUSED,
                                       EngineState.HELD)
            action = "resume" if waiting else "pause"
        if action == "pause":
            taken = engine.request_pause()
            self.say("pausing at the point being measured ..." if taken
                     else f"cannot pause: the run is {engine.state.value}")
        else:
            taken = engine.request_resume()
            self.say("resuming ..." if taken
                     else f"cannot resume: the run is {engine.state.value}")
        return taken

    @contextlib.contextmanager
    def installed(self) -> Iterator[None]:
        """Handle the signals while the block runs (main thread only)."""
        if threading.current_thread() is not threading.main_thread():
            yield
            return
        previous = {}
        for name in ACTIONS:
            number = getattr(signal, name, None)
            if number is not None:
                previous[number] = signal.signal(number, self)
        try:
            yield
        finally:
            for number, handler in previous.items():
                signal.signal(number, handler)
