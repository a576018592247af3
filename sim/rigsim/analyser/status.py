"""Status reporting: the error queue and the 35670A's status registers (chapters 1 and 20).

Each register group (``STAT:OPER``, ``STAT:QUES``, ``STAT:QUES:VOLT``, ``STAT:QUES:LIM``,
``STAT:DEV``, ``STAT:USER``) has a condition register set by the running instrument, positive
and negative transition filters that latch changes into the event register (read and cleared by
its query), and an enable mask whose summary goes one level up: ``QUES:VOLT`` and ``QUES:LIM``
into ``QUES`` bits 0 and 9; ``USER``, ``DEV``, ``QUES`` and ``OPER`` into the status byte's bits
0, 2, 3 and 7; the standard event register (``*ESR?``, ``*ESE``) into bit 5; a message waiting
sets bit 4; ``*SRE`` selects what raises bit 6.
"""

from __future__ import annotations

import threading
from collections import deque
from dataclasses import dataclass

from rigsim.scpi import format_string

__all__ = [
    "DEV_AUTOCAL_OFF",
    "ERROR_QUEUE_LENGTH",
    "ESR_CME",
    "ESR_DDE",
    "ESR_EXE",
    "ESR_OPC",
    "ESR_PON",
    "ESR_QYE",
    "OPER_AVERAGING",
    "OPER_CALIBRATING",
    "OPER_MEASURING",
    "OPER_RANGING",
    "OPER_SETTLING",
    "OPER_WAIT_TRIGGER",
    "QUES_CALIBRATION",
    "QUES_LIMIT",
    "QUES_VOLTAGE",
    "Register",
    "StatusRegisters",
]

ERROR_QUEUE_LENGTH = 5
# STAT:OPER condition bits
OPER_CALIBRATING = 1
OPER_SETTLING = 2
OPER_RANGING = 4
OPER_MEASURING = 16
OPER_WAIT_TRIGGER = 32
OPER_WAIT_ARM = 64
OPER_AVERAGING = 256
# STAT:QUES bits
QUES_VOLTAGE = 1
QUES_CALIBRATION = 256
QUES_LIMIT = 512
# STAT:DEV bits
DEV_AUTOCAL_OFF = 1
# *ESR bits
ESR_OPC, ESR_QYE, ESR_DDE, ESR_EXE, ESR_CME, ESR_PON = 1, 4, 8, 16, 32, 128
_ALL = 0x7FFF


@dataclass
class Register:
    """One SCPI register group: condition, event, enable, transition filters."""

    condition: int = 0
    event: int = 0
    enable: int = 0
    ptr: int = _ALL
    ntr: int = 0

    def set_condition(self, value: int) -> None:
        """New condition bits; rising bits pass ``ptr``, falling bits ``ntr`` into the event."""
        rising = value & ~self.condition
        falling = self.condition & ~value
        self.event |= (rising & self.ptr) | (falling & self.ntr)
        self.condition = value

    def pulse(self, bits: int) -> None:
        """Bits that flash on and off at once (an event with no lasting condition)."""
        self.event |= bits & self.ptr

    def read_event(self) -> int:
        """Read and clear the event register."""
        value, self.event = self.event, 0
        return value

    @property
    def summary(self) -> bool:
        """Any enabled event bit."""
        return bool(self.event & self.enable)


class StatusRegisters:
    """The error queue, ``*ESR``/``*ESE``/``*SRE`` and the register groups.

    Parameters
    ----------
    changed
        The instrument's condition: its lock guards the registers; it is notified when pending
        operations complete (``*OPC?`` and ``*WAI`` wait on it).
    """

    def __init__(self, changed: threading.Condition) -> None:
        self.changed = changed
        self.errors: deque[tuple[int, str]] = deque()
        self.esr = ESR_PON
        self.ese = 0
        self.sre = 0
        self.psc = True
        self.oper = Register()
        self.ques = Register()
        self.volt = Register()
        self.limit = Register()
        self.device = Register()
        self.user = Register()
        self.opc_armed = False
        self.preset_registers()
        # at power-on the voltage and limit enables are 0 (chapter 20); STAT:PRES sets them
        self.volt.enable = self.limit.enable = 0

    @property
    def groups(self) -> dict[str, Register]:
        """Register groups by their ``STAT`` node (``OPER``, ``QUES``, ``QUES:VOLT`` ...)."""
        return {"OPER": self.oper, "QUES": self.ques, "QUES:VOLT": self.volt,
                "QUES:LIM": self.limit, "DEV": self.device, "USER": self.user}

    # -------------------------------------------------------------------- errors

    def push_error(self, code: int, message: str) -> None:
        """Put an error in the queue (5 entries; on overflow the oldest stay, the last says so)."""
        with self.changed:
            if len(self.errors) < ERROR_QUEUE_LENGTH:
                self.errors.append((code, message))
            else:
                self.errors[-1] = (-350, "Queue overflow")
            if code <= -400:
                self.esr |= ESR_QYE
            elif code <= -300 or code > 0:
                self.esr |= ESR_DDE
            elif code <= -200:
                self.esr |= ESR_EXE
            elif code <= -100:
                self.esr |= ESR_CME

    def next_error(self) -> str:
        """``SYST:ERR?``: the oldest entry, removed from the queue, as ``code,"message"``."""
        if not self.errors:
            return '+0,"No error"'
        code, message = self.errors.popleft()
        return f"{code:+d},{format_string(message)}"

    # -------------------------------------------------------------------- summaries

    def _summaries(self) -> None:
        ques = self.ques.condition & ~(QUES_VOLTAGE | QUES_LIMIT)
        if self.volt.summary:
            ques |= QUES_VOLTAGE
        if self.limit.summary:
            ques |= QUES_LIMIT
        self.ques.set_condition(ques)

    def status_byte(self, mav: bool = False) -> int:
        """``*STB?``: bits 0 user, 2 device, 3 questionable, 4 message available, 5 standard
        event, 6 master summary, 7 operation."""
        with self.changed:
            self._summaries()
            stb = 0
            if self.user.summary:
                stb |= 1
            if self.device.summary:
                stb |= 4
            if self.ques.summary:
                stb |= 8
            if mav:
                stb |= 16
            if self.esr & self.ese:
                stb |= 32
            if self.oper.summary:
                stb |= 128
            if stb & self.sre & ~64:
                stb |= 64
            return stb

    def read_event(self, group: str) -> int:
        """Read and clear a group's event register."""
        with self.changed:
            self._summaries()
            return self.groups[group].read_event()

    def condition(self, group: str) -> int:
        """A group's condition register."""
        with self.changed:
            self._summaries()
            return self.groups[group].condition

    # -------------------------------------------------------------------- clears and presets

    def clear(self) -> None:
        """``*CLS``: empty the error queue and every event register; cancel ``*OPC``."""
        self.errors.clear()
        self.esr = 0
        for register in self.groups.values():
            register.event = 0
        self.opc_armed = False

    def preset_clear(self) -> None:
        """What ``SYST:PRES`` does to status: error queue and event registers cleared, ``*OPC``
        cancelled; enables and transition filters untouched (chapter 21)."""
        self.errors.clear()
        for register in self.groups.values():
            register.event = 0
        self.opc_armed = False

    def preset_registers(self) -> None:
        """``STAT:PRES``: ``QUES:VOLT`` and ``QUES:LIM`` enabled and positive transitions on
        all bits; ``DEV``, ``QUES``, ``OPER`` enables 0, positive transitions on; ``USER``
        enable 0."""
        for register in (self.volt, self.limit):
            register.enable, register.ptr, register.ntr = _ALL, _ALL, 0
        for register in (self.device, self.ques, self.oper):
            register.enable, register.ptr, register.ntr = 0, _ALL, 0
        self.user.enable = 0

    # -------------------------------------------------------------------- operation complete

    def operation_complete(self, idle: bool) -> None:
        """``*OPC``: set ESR bit 0 now if ``idle``, else when the running operation ends."""
        if idle:
            self.esr |= ESR_OPC
        else:
            self.opc_armed = True

    def complete_operation(self) -> None:
        """Pending operations are done: ``*OPC`` sets ESR bit 0, ``*OPC?``/``*WAI`` wake up."""
        if self.opc_armed:
            self.esr |= ESR_OPC
            self.opc_armed = False
        self.changed.notify_all()

    def read_esr(self) -> int:
        """``*ESR?``: the standard event status register, cleared by reading."""
        value, self.esr = self.esr, 0
        return value
