"""The virtual 35670A itself: its parts put together, and what in-process code may ask of it."""

from __future__ import annotations

import threading
import time
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from rigsim.analyser.commands import (
    CommonCommands,
    InputCommands,
    RunCommands,
    SenseCommands,
    SourceCommands,
    TraceCommands,
)
from rigsim.analyser.limits import DEFAULT_IDN, DEFAULT_OPTIONS
from rigsim.analyser.session import ScpiSession
from rigsim.analyser.status import StatusRegisters
from rigsim.analyser.worker import Simulator
from rigsim.measurement import CHANNEL_COUNT
from rigsim.scpi import CommandTree

__all__ = ["VirtualAnalyser", "build_simulator"]


def _load_rig(rig: Any) -> Any:
    """A ``Rig`` as given, or loaded from a rig file path or a preset name."""
    from rigsim import rigfile

    if isinstance(rig, Path) or (isinstance(rig, str) and rig.endswith(".toml")):
        return rigfile.load_rig(rig)
    if isinstance(rig, str):
        return rigfile.load_preset(rig)
    return rig


def build_simulator(rig: Any, seed: int | None = None) -> Simulator:
    """Make a rig simulator from a ``Rig``, a rig file path, or a preset name."""
    from rigsim import engine  # the engine is heavy; import on first use

    return engine.RigSimulator(_load_rig(rig), seed=seed)


class VirtualAnalyser(
    CommonCommands, SenseCommands, InputCommands, SourceCommands, TraceCommands, RunCommands
):
    """A simulated 35670A measuring a simulated rig.

    The command handlers come from :mod:`rigsim.analyser.commands` (one mixin per SCPI
    subsystem), the measurement from :class:`rigsim.analyser.worker.SweepWorker`, the state they
    share from :class:`rigsim.analyser.state.InstrumentState`; ``status`` is the error queue and
    status registers (:class:`rigsim.analyser.status.StatusRegisters`).

    Parameters
    ----------
    simulator
        The rig simulator (``rigsim.engine.RigSimulator`` or anything with its ``sweep``,
        ``mount`` and ``clock_s``).
    pace
        ``None``: measure as fast as the computer allows. A number: simulated seconds of test
        time per wall-clock second, so a client sees the measuring bit, can pause or abort
        mid-sweep, and a long sweep really outlasts a VISA timeout.
    options
        Installed options for ``*OPT?`` (``1D2`` swept sine, ``AY6`` four channels).
    idn
        The ``*IDN?`` answer.
    """

    def __init__(
        self,
        simulator: Simulator,
        *,
        pace: float | None = None,
        options: Sequence[str] = DEFAULT_OPTIONS,
        idn: str = DEFAULT_IDN,
    ) -> None:
        if pace is not None and not pace > 0:
            raise ValueError(f"pace must be positive (simulated seconds per second), got {pace}")
        self.options = tuple(o.upper() for o in options)
        self.idn = idn
        self.lock = threading.RLock()
        self.changed = threading.Condition(self.lock)
        self.status = StatusRegisters(self.changed)
        self._init_sweep(simulator, pace)
        self.tree = CommandTree()
        self._register_commands()
        self._reset(preset=False)

    def _register_commands(self) -> None:
        t = self.tree
        self._register_common_commands(t)
        self._register_mode_commands(t)
        self._register_sense_commands(t)
        self._register_input_commands(t)
        self._register_source_commands(t)
        self._register_trace_commands(t)
        self._register_run_commands(t)
        self._register_status_commands(t)

    # ---------------------------------------------------------------- in-process API

    def mount(self, rig: Any) -> None:
        """Mount another rig (new specimens) on the simulator. **In-process only, not SCPI.**

        Parameters
        ----------
        rig
            A ``rigsim.rigfile.Rig``, a rig file path or a preset name.

        Raises
        ------
        RuntimeError
            A sweep is running or paused: abort it first.
        """
        rig = _load_rig(rig)
        with self.lock:
            if self.state != "IDLE":
                raise RuntimeError("cannot change the specimens while a sweep is running or paused")
            self.simulator.mount(rig)

    def session(self) -> ScpiSession:
        """A new controller connection (its own parser state)."""
        return ScpiSession(self)

    def push_error(self, code: int, message: str) -> None:
        """Put an error in the queue (5 entries; on overflow the oldest stay, the last says so)."""
        self.status.push_error(code, message)

    def status_byte(self, mav: bool = False) -> int:
        """``*STB?``: bit 3 questionable, 4 message available (``mav``), 5 standard event,
        6 MSS, 7 operation."""
        return self.status.status_byte(mav)

    def force_overload(self, channel: int, points: int | None = None) -> None:
        """Flag an input overload on ``channel`` (1..4) for the next ``points`` measured points
        (all points of the next sweep when ``None``), as if the signal exceeded the range."""
        if not 1 <= channel <= CHANNEL_COUNT:
            raise ValueError(f"channel must be 1..4, got {channel}")
        with self.lock:
            self._forced_overload[channel] = points

    def wait_until_idle(self, timeout_s: float | None = None) -> bool:
        """Block until no sweep runs (a paused sweep counts as running). True if idle."""
        deadline = None if timeout_s is None else time.monotonic() + timeout_s
        with self.changed:
            while self.state != "IDLE":
                remaining = None if deadline is None else deadline - time.monotonic()
                if remaining is not None and remaining <= 0:
                    return False
                self.changed.wait(remaining)
        return True

    @property
    def points_measured(self) -> int:
        """Points of the current or last sweep measured so far."""
        return self._measured.count

    def close(self) -> None:
        """Stop any sweep (the worker thread ends)."""
        with self.lock:
            self._abort()
