"""What the command handlers and the controller's session need of the instrument.

A structural protocol, so that :mod:`rigsim.analyser.commands` and
:mod:`rigsim.analyser.session` depend on this page and not on
:mod:`rigsim.analyser.instrument` (which imports them): no import cycle.
"""

from __future__ import annotations

import threading
from typing import Protocol

from rigsim.analyser.fft import FftMeasurement
from rigsim.analyser.inputs import InputView
from rigsim.analyser.run import Run
from rigsim.analyser.settings import SettingStore
from rigsim.analyser.sine import SweptSine
from rigsim.analyser.status import StatusRegisters
from rigsim.analyser.traces import Register
from rigsim.faults import FrontEnd
from rigsim.scpi import CommandTree

__all__ = ["Host"]


class Host(Protocol):
    """The virtual analyser as its commands see it."""

    lock: threading.RLock
    changed: threading.Condition
    status: StatusRegisters
    store: SettingStore
    run: Run
    inputs: InputView
    sine: SweptSine
    fft: FftMeasurement
    front_end: FrontEnd
    tree: CommandTree
    registers: dict[int, Register]
    idn: str

    @property
    def options(self) -> tuple[str, ...]:
        """Installed options."""

    @property
    def mode(self) -> str:
        """The instrument mode."""

    def v_per_eu(self, channel: int) -> float | None:
        """Volts per engineering unit of an input in engineering units."""

    def reset(self, kind: str) -> None:
        """``*RST`` (``"RST"``) or ``SYST:PRES`` (``"PRES"``)."""

    def initiate(self) -> None:
        """``INIT[:IMM]``: start a new measurement in the current mode."""

    def abort(self) -> None:
        """``ABOR``: stop the measurement."""

    def set_continuous(self, on: bool) -> None:
        """``INIT:CONT``: pause, resume, or add averages."""

    def trace(self, number: int) -> Register:
        """The current data of trace ``number`` (1..4)."""

    def settings_changed(self, what: str) -> None:
        """A measurement setting changed (the mode's limits may move)."""

    def calibrate_now(self) -> None:
        """``*CAL?``, ``CAL:AUTO ONCE``: calibrate now (between points if measuring)."""
