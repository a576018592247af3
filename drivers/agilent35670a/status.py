"""Status reporting (chapter 20, common commands): the error queue and the registers the driver
watches while a measurement runs.

The error queue holds 5 entries; when more errors come the oldest stay and the last entry says
"Queue overflow" (-350): :meth:`Status.check_errors` reports that errors were lost. While a
measurement runs the driver polls ``*STB?`` (never blocking: it is answered at once), with
``*ESE`` set so that operation complete and every error class raise the standard-event summary
bit, and ``STAT:OPER:COND?`` for the calibrating, settling, ranging and measuring bits.
"""

from __future__ import annotations

from .errors import MalformedReply, SCPIError, parse_error_entry
from .properties import Parent, Subsystem, parse_int
from .quirks import Quirks

__all__ = [
    "ESE_MASK",
    "ESR_ERRORS",
    "ESR_OPERATION_COMPLETE",
    "OPER_CALIBRATING",
    "OPER_MEASURING",
    "OPER_RANGING",
    "OPER_SETTLING",
    "STB_EVENT_SUMMARY",
    "Status",
]

#: ``*ESR?`` bits: operation complete, and the four error bits (query, device, execution,
#: command).
ESR_OPERATION_COMPLETE = 1
ESR_ERRORS = 4 | 8 | 16 | 32
ESE_MASK = ESR_OPERATION_COMPLETE | ESR_ERRORS
#: ``*STB?`` bit 5: an enabled standard event happened.
STB_EVENT_SUMMARY = 32
#: ``STAT:OPER:COND?`` bits.
OPER_CALIBRATING, OPER_SETTLING, OPER_RANGING, OPER_MEASURING = 1, 2, 4, 16


class Status(Subsystem):
    """The error queue and the status registers.

    Parameters
    ----------
    parent
        The analyser.
    resource
        Callable giving the resource string (named in errors).
    """

    def __init__(self, parent: Parent, resource: str) -> None:
        super().__init__(parent, "status")
        self.resource = resource

    def read_errors(self) -> list[tuple[int, str]]:
        """Read ``SYST:ERR?`` until it answers no error; return the ``(code, text)`` entries."""
        entries: list[tuple[int, str]] = []
        for _ in range(Quirks.ERROR_QUEUE_READS):
            reply = self.ask("SYST:ERR?")
            code, text = parse_error_entry(reply, self.resource)
            if code == Quirks.NO_ERROR_CODE:
                return entries
            entries.append((code, text))
        raise MalformedReply(
            f"SYST:ERR? still reports errors after {Quirks.ERROR_QUEUE_READS} reads "
            f"(the queue holds 5): {entries}",
            self.resource,
        )

    def check_errors(self, after: str | None = None) -> None:
        """Raise :class:`SCPIError` (first error, the others attached) if the queue is not
        empty; the message says so when the queue overflowed and errors were lost."""
        entries = self.read_errors()
        if not entries:
            return
        (code, text), *others = entries
        raise SCPIError(code, text, after, self.resource, tuple(others))

    def arm(self) -> None:
        """Clear the event registers the measurement is judged by, and enable the summary of
        operation complete and errors in ``*STB?``."""
        self.ask("*ESR?")
        self.ask("STAT:QUES:VOLT:EVEN?")
        self.parent.configure(f"*ESE {ESE_MASK}")

    def status_byte(self) -> int:
        """``*STB?``."""
        return parse_int(self.ask("*STB?"))

    def event_status(self) -> int:
        """``*ESR?`` (reading clears it)."""
        return parse_int(self.ask("*ESR?"))

    def operation_condition(self) -> int:
        """``STAT:OPER:COND?``: 1 calibrating, 2 settling, 4 ranging, 16 measuring."""
        return parse_int(self.ask("STAT:OPER:COND?"))

    def read_overload(self) -> tuple[tuple[int, ...], tuple[int, ...]]:
        """Read and clear ``STAT:QUES:VOLT:EVEN?``: (overloaded channels, half-range channels)."""
        bits = parse_int(self.ask("STAT:QUES:VOLT:EVEN?"))
        overload = tuple(ch for ch in range(1, 5) if bits & (1 << (ch - 1)))
        half_range = tuple(ch for ch in range(1, 5) if bits & (1 << (ch + 7)))
        return overload, half_range
