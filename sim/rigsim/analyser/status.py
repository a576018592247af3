"""Status reporting: the error queue and the IEEE 488.2 / SCPI status registers.

:class:`StatusRegisters` holds the error queue (``SYST:ERR?``), the standard event status
register (``*ESR?``, ``*ESE``), the service request enable (``*SRE``) and the event and enable
registers of ``STAT:OPER``, ``STAT:QUES`` and ``STAT:QUES:VOLT``. The condition registers
describe the running measurement, so the sweep worker answers them
(:meth:`rigsim.analyser.worker.SweepWorker.oper_condition`).
"""

from __future__ import annotations

import threading
from collections import deque

from rigsim.scpi import format_string

__all__ = [
    "ERROR_QUEUE_LENGTH",
    "ESR_CME",
    "ESR_DDE",
    "ESR_EXE",
    "ESR_OPC",
    "ESR_PON",
    "ESR_QYE",
    "OPER_MEASURING",
    "OPER_RANGING",
    "OPER_SETTLING",
    "VOLT_ENABLE_PRESET",
    "StatusRegisters",
]

ERROR_QUEUE_LENGTH = 5
# STAT:OPER:COND bits
OPER_SETTLING = 2
OPER_RANGING = 4
OPER_MEASURING = 16
# *ESR bits
ESR_OPC, ESR_QYE, ESR_DDE, ESR_EXE, ESR_CME, ESR_PON = 1, 4, 8, 16, 32, 128
#: ``STAT:QUES:VOLT:ENAB`` at power-on and after ``STAT:PRES``: overload and half range of
#: channels 1..4 (inferred).
VOLT_ENABLE_PRESET = 0x0F0F


class StatusRegisters:
    """The error queue and the event and enable registers; ``changed`` guards them.

    Parameters
    ----------
    changed
        The instrument's condition: its lock guards the registers, and it is notified when
        pending operations complete (``*OPC?`` and ``*WAI`` wait on it).
    """

    def __init__(self, changed: threading.Condition) -> None:
        self.changed = changed
        self.errors: deque[tuple[int, str]] = deque()
        self.esr = ESR_PON
        self.ese = 0
        self.sre = 0
        self.oper_event = 0
        self.oper_enable = 0
        self.ques_event = 0
        self.ques_enable = 0
        self.volt_event = 0
        self.volt_enable = VOLT_ENABLE_PRESET
        self.opc_armed = False

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

    def status_byte(self, mav: bool = False) -> int:
        """``*STB?``: bit 3 questionable, 4 message available, 5 standard event, 6 MSS,
        7 operation (bit 2, device state, is not simulated)."""
        with self.changed:
            stb = 0
            if self.ques_event & self.ques_enable:
                stb |= 8
            if mav:
                stb |= 16
            if self.esr & self.ese:
                stb |= 32
            if self.oper_event & self.oper_enable:
                stb |= 128
            if stb & self.sre & ~64:
                stb |= 64
            return stb

    def clear(self) -> None:
        """``*CLS``: empty the error queue and the event registers."""
        self.errors.clear()
        self.esr = 0
        self.oper_event = self.ques_event = self.volt_event = 0
        self.opc_armed = False

    def read_esr(self) -> int:
        """``*ESR?``: the standard event status register, cleared by reading."""
        value, self.esr = self.esr, 0
        return value

    def read_event(self, name: str) -> int:
        """Read and clear the event register ``name`` (``"oper_event"``, ``"ques_event"``...)."""
        value = getattr(self, name)
        setattr(self, name, 0)
        return value

    def preset(self) -> None:
        """``STAT:PRES``: the enable registers of ``STAT:OPER`` and ``STAT:QUES`` to preset."""
        self.oper_enable = self.ques_enable = 0
        self.volt_enable = VOLT_ENABLE_PRESET

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
