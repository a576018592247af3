"""The measurement thread: start, pause, resume, abort, pacing, completion.

One measurement runs at a time (swept sine or FFT). ``INIT`` starts a worker thread running the
mode's measurement; with a ``pace``, the worker waits on the wall clock as the simulated
instrument would take the time (scaled), so a client sees the status bits change, can pause
(``INIT:CONT OFF``) or abort (``ABOR``) mid-measurement, and a long sweep really outlasts a
VISA time-out.

Every start, abort or reset bumps a generation number; a worker whose generation is no longer
current stops at its next look at the state, so an aborted measurement never reveals another
point.
"""

from __future__ import annotations

import threading
import time
from collections.abc import Callable
from typing import Any, Protocol

from rigsim.analyser.inputs import InputView
from rigsim.analyser.settings import SettingStore
from rigsim.analyser.status import OPER_MEASURING, StatusRegisters
from rigsim.faults import FrontEnd
from rigsim.measurement import SweepRecord, SweepRequest

__all__ = ["Aborted", "Measurement", "Run", "Simulator"]


class Simulator(Protocol):
    """What the analyser needs of the rig simulator (``rigsim.engine.RigSimulator``)."""

    clock_s: float

    @property
    def rig(self) -> Any:
        """The rig mounted (its transducers, shaker and noise)."""

    def sweep(self, request: SweepRequest) -> SweepRecord:
        """Measure the request's points, volts at the analyser inputs."""

    def mount(self, rig: Any) -> None:
        """Replace the rig (new specimens); the clock restarts."""

    def idle(self, duration_s: float) -> None:
        """Let time pass with the source off."""


class Aborted(Exception):  # noqa: N818 - a signal that the worker's generation is over
    """The measurement the worker runs was aborted or replaced."""


class Run:
    """State of the measurement in progress, shared by the swept sine and the FFT.

    ``state`` is ``"IDLE"``, ``"RUNNING"`` or ``"PAUSED"``; a paused measurement counts as
    running for ``*OPC`` and ``*WAI``.

    Parameters
    ----------
    changed
        The instrument's condition (its lock guards the state; waits use it).
    status
        The status registers (``STAT:OPER`` condition, operation complete).
    pace
        Simulated seconds per wall second, or ``None`` (as fast as possible).
    """

    def __init__(self, changed: threading.Condition, status: StatusRegisters,
                 pace: float | None) -> None:
        self.changed = changed
        self.status = status
        self.pace = pace
        self.state = "IDLE"
        self.generation = 0
        self.operation = 0  # STAT:OPER condition bits the measurement holds now
        self.on_end: Callable[[], None] | None = None
        self._thread: threading.Thread | None = None

    # -------------------------------------------------------------------- control (lock held)

    def start(self, body: Callable[[int], None], *, paused: bool = False) -> int:
        """Run ``body(generation)`` in a new worker thread; return its generation."""
        self.generation += 1
        generation = self.generation
        self.state = "PAUSED" if paused else "RUNNING"
        self.set_operation(OPER_MEASURING if not paused else 0)
        self._thread = threading.Thread(target=self._main, args=(body, generation),
                                        name="35670A-measurement", daemon=True)
        self._thread.start()
        return generation

    def abort(self) -> None:
        """Stop the measurement (its worker ends at its next look)."""
        if self.state != "IDLE":
            self.generation += 1
            self._finish()

    def pause(self) -> None:
        """``INIT:CONT OFF`` while running."""
        if self.state == "RUNNING":
            self.state = "PAUSED"
            self.set_operation(0)
            self.changed.notify_all()

    def resume(self) -> None:
        """``INIT:CONT ON`` while paused."""
        if self.state == "PAUSED":
            self.state = "RUNNING"
            self.set_operation(OPER_MEASURING)
            self.changed.notify_all()

    def set_operation(self, bits: int) -> None:
        """The measurement's ``STAT:OPER`` condition bits (calibration bits kept apart)."""
        self.operation = bits
        self.status.oper.set_condition(bits | (self.status.oper.condition & 1))

    def _finish(self) -> None:
        self.state = "IDLE"
        self.set_operation(0)
        if self.on_end is not None:
            self.on_end()
        self.status.complete_operation()

    # -------------------------------------------------------------------- worker side

    def _main(self, body: Callable[[int], None], generation: int) -> None:
        try:
            body(generation)
        except Aborted:
            return
        except Exception as exc:  # the simulation failed: a device error, never a silent stop
            with self.changed:
                if generation == self.generation:
                    self.status.push_error(-310, f"simulator: {exc}"[:120])
                    self._finish()
            return
        with self.changed:
            if generation == self.generation and self.state != "IDLE":
                self._finish()

    def check(self, generation: int) -> None:
        """Wait while paused; raise :class:`Aborted` if the generation is over (lock held)."""
        while self.state == "PAUSED" and generation == self.generation:
            self.changed.wait()
        if generation != self.generation:
            raise Aborted

    def check_unlocked(self, generation: int) -> None:
        """Raise :class:`Aborted` if the generation is over (lock not held: no pause wait)."""
        if generation != self.generation:
            raise Aborted

    def wait(self, generation: int, simulated_s: float, bits: int | None = None) -> None:
        """Let ``simulated_s`` of instrument time pass (scaled by the pace), honouring pause
        and abort; ``bits`` are the ``STAT:OPER`` condition meanwhile. A pause restarts the
        wait from its beginning once resumed (the instrument redoes the interrupted step)."""
        with self.changed:
            self.check(generation)
            if bits is not None:
                self.set_operation(bits)
            if self.pace is None or simulated_s <= 0:
                return
            while True:
                end = time.monotonic() + simulated_s / self.pace
                while self.state == "RUNNING" and generation == self.generation:
                    remaining = end - time.monotonic()
                    if remaining <= 0:
                        return
                    self.changed.wait(remaining)
                self.check(generation)
                if bits is not None:
                    self.set_operation(bits)


class Measurement:
    """What a measurement (swept sine, FFT) works with.

    Parameters
    ----------
    store, status, run
        The instrument's settings, status registers and measurement thread.
    simulator
        The rig simulator.
    front_end
        The wiring between the rig's transducers and the inputs.
    calibrate
        Called between points or records with the worker's generation (an auto-calibration
        may be due).
    """

    def __init__(self, store: SettingStore, status: StatusRegisters, run: Run,
                 simulator: Simulator, front_end: FrontEnd,
                 calibrate: Callable[[int], None]) -> None:
        self.store = store
        self.status = status
        self.run = run
        self.simulator = simulator
        self.front_end = front_end
        self.calibrate = calibrate
        self.inputs = InputView(store)
