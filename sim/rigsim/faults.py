"""Fault injection for the simulated analyser: what a flaky cable, adapter or instrument does.

Faults are queued on a :class:`FaultInjector` (one per server, ``server.faults``) and fire once,
on the next program message that matches:

``no_reply``
    The message is executed but its response is lost (the client's read times out).
``drop``
    The connection is closed when the message arrives; the message is not executed.
``garble``
    The response is corrupted: cut in the middle and followed by junk, terminator kept (a
    binary block then declares more bytes than it carries).
``error``
    An error ``code,"message"`` is put in the analyser's error queue.
``overload``
    The next points measured flag an input overload on a channel (status bits and event
    register, as when the signal exceeds the range).

``match`` is a case-insensitive substring of the program message (``"CALC1:DATA?"``). Without
it, ``no_reply`` and ``garble`` fire on the next query, ``drop`` on the next message, and
``error`` and ``overload`` at once.

Command-line form (``viscorig sim serve --fault SPEC``): ``KIND[=ARG][@MATCH]``, for example
``no_reply@*IDN?``, ``drop@INIT``, ``garble@TRAC:DATA?``, ``error=-310,Hardware fault``,
``overload=4`` (channel 4, next sweep) or ``overload=4:10`` (the next 10 points).
"""

from __future__ import annotations

import threading
from dataclasses import dataclass
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from rigsim.analyser import VirtualAnalyser

__all__ = ["FAULT_KINDS", "Fault", "FaultInjector", "FaultSpecError", "garble", "parse_fault_spec"]

FAULT_KINDS = ("no_reply", "drop", "garble", "error", "overload")
#: Faults that act on one message's transport; the others act on the instrument.
MESSAGE_FAULTS = ("no_reply", "drop", "garble")


class FaultSpecError(ValueError):
    """A fault specification cannot be read."""


@dataclass(frozen=True)
class Fault:
    """One fault to inject.

    Attributes
    ----------
    kind
        One of :data:`FAULT_KINDS`.
    match
        Case-insensitive substring of the program message that triggers the fault, or ``None``.
    code, message
        The error for ``error`` faults.
    channel, points
        Channel (1..4) and number of points for ``overload`` faults (``None``: the whole next
        sweep).
    """

    kind: str
    match: str | None = None
    code: int = -310
    message: str = "System error"
    channel: int = 1
    points: int | None = None

    def __post_init__(self) -> None:
        if self.kind not in FAULT_KINDS:
            raise FaultSpecError(f"unknown fault {self.kind!r}; faults: {', '.join(FAULT_KINDS)}")
        if not 1 <= self.channel <= 4:
            raise FaultSpecError(f"overload channel must be 1..4, got {self.channel}")

    def triggered_by(self, message: str) -> bool:
        if self.match is not None:
            return self.match.upper() in message.upper()
        return "?" in message if self.kind in ("no_reply", "garble") else True


class FaultInjector:
    """Queued faults of one server. Thread-safe; each fault fires once.

    Parameters
    ----------
    analyser
        The instrument that ``error`` and ``overload`` faults act on.
    """

    def __init__(self, analyser: VirtualAnalyser) -> None:
        self.analyser = analyser
        self._faults: list[Fault] = []
        self._lock = threading.Lock()
        self.fired: list[Fault] = []

    def add(self, fault: Fault) -> Fault:
        """Queue a fault (instrument faults without ``match`` act at once)."""
        if fault.match is None and fault.kind not in MESSAGE_FAULTS:
            self._apply(fault)
            return fault
        with self._lock:
            self._faults.append(fault)
        return fault

    def no_reply(self, match: str | None = None) -> Fault:
        """The next query (or message containing ``match``) gets no response."""
        return self.add(Fault("no_reply", match))

    def drop_connection(self, match: str | None = None) -> Fault:
        """Close the connection at the next message (or the one containing ``match``)."""
        return self.add(Fault("drop", match))

    def garble_reply(self, match: str | None = None) -> Fault:
        """Corrupt the response to the next query (or the one containing ``match``)."""
        return self.add(Fault("garble", match))

    def error(self, code: int, message: str, match: str | None = None) -> Fault:
        """Put ``code,"message"`` in the error queue now, or when ``match`` arrives."""
        return self.add(Fault("error", match, code=code, message=message))

    def overload(self, channel: int, points: int | None = None, match: str | None = None) -> Fault:
        """Flag an overload on ``channel`` for the next ``points`` points (whole next sweep)."""
        return self.add(Fault("overload", match, channel=channel, points=points))

    @property
    def pending(self) -> list[Fault]:
        """Faults not yet fired."""
        with self._lock:
            return list(self._faults)

    def clear(self) -> None:
        """Forget the faults not yet fired."""
        with self._lock:
            self._faults.clear()

    def take(self, message: str) -> set[str]:
        """Fire the faults that ``message`` triggers; return the message-fault kinds to apply."""
        if not self._faults:  # fast path, read without the lock
            return set()
        fired: list[Fault] = []
        with self._lock:
            seen: set[str] = set()
            for fault in list(self._faults):
                if fault.kind in seen or not fault.triggered_by(message):
                    continue
                seen.add(fault.kind)
                self._faults.remove(fault)
                fired.append(fault)
        kinds: set[str] = set()
        for fault in fired:
            if fault.kind in MESSAGE_FAULTS:
                kinds.add(fault.kind)
            else:
                self._apply(fault)
        self.fired.extend(fired)
        return kinds

    def _apply(self, fault: Fault) -> None:
        if fault.kind == "error":
            self.analyser.push_error(fault.code, fault.message)
        elif fault.kind == "overload":
            self.analyser.force_overload(fault.channel, fault.points)


def garble(response: bytes) -> bytes:
    """A corrupted copy of a response: cut in the middle, junk appended, terminator kept."""
    body = response[:-1] if response.endswith(b"\n") else response
    return body[: len(body) // 2] + b"\x7f?#~" + b"\n"


def parse_fault_spec(spec: str) -> Fault:
    """Read ``KIND[=ARG][@MATCH]`` (see the module docstring).

    Raises
    ------
    FaultSpecError
        The specification names no known fault or has a bad argument.
    """
    head, _, match = spec.partition("@")
    kind, _, arg = head.partition("=")
    kind = kind.strip().lower().replace("-", "_")
    if kind == "no_response":
        kind = "no_reply"
    if kind == "error":
        code_text, _, message = arg.partition(",")
        try:
            code = int(code_text)
        except ValueError:
            raise FaultSpecError(f"fault {spec!r}: error needs a code, e.g. error=-310") from None
        return Fault("error", match or None, code=code, message=message.strip() or "System error")
    if kind == "overload":
        channel_text, _, points_text = arg.partition(":")
        try:
            channel = int(channel_text)
            points = int(points_text) if points_text else None
        except ValueError:
            raise FaultSpecError(f"fault {spec!r}: overload needs a channel (overload=4)") from None
        return Fault("overload", match or None, channel=channel, points=points)
    if arg:
        raise FaultSpecError(f"fault {spec!r}: {kind} takes no argument")
    return Fault(kind, match or None)
