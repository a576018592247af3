"""One controller's connection to the virtual analyser: message parsing, header path, waits.

A socket server and in-process code can share one instrument, each through its own
:class:`ScpiSession`. The session needs only what :class:`SessionHost` lists, so it does not
import the instrument (which imports it).
"""

from __future__ import annotations

import threading
from typing import Protocol

from rigsim.analyser.run import Run
from rigsim.analyser.status import StatusRegisters
from rigsim.scpi import Call, CommandTree, ProgramUnit, ScpiError, parse_unit, split_units

__all__ = ["ScpiSession", "SessionHost"]


class SessionHost(Protocol):
    """What a session needs of the instrument."""

    lock: threading.RLock
    changed: threading.Condition
    tree: CommandTree
    status: StatusRegisters
    run: Run


class _DeviceCleared(Exception):  # noqa: N818 - a signal, not an error
    """A device clear ended a ``*OPC?`` or ``*WAI`` wait."""


class ScpiSession:
    """One controller's connection: its own header path; the instrument is shared.

    :meth:`execute` runs one program message and returns the response message (bytes ending
    with a line feed) or ``None`` when the message held no query.
    """

    def __init__(self, host: SessionHost) -> None:
        self.host = host
        self._cleared = 0

    def device_clear(self) -> None:
        """IEEE 488.2 device clear: pending ``*OPC?``/``*WAI`` waits of this session end."""
        with self.host.changed:
            self._cleared += 1
            self.host.changed.notify_all()

    def execute(self, message: str | bytes) -> bytes | None:
        """Run a program message (its terminator already removed or not)."""
        host = self.host
        if isinstance(message, bytes):
            message = message.decode("latin-1")
        message = message.rstrip("\r\n")
        if not message.strip():
            return None
        responses: list[bytes] = []
        path: list[str] = []
        try:
            units = list(split_units(message))
        except ScpiError as error:
            host.status.push_error(error.code, error.message)
            return None
        for text in units:
            try:
                unit = parse_unit(text)
                answer = self._execute_unit(unit, path)
            except _DeviceCleared:
                return None  # the rest of the message and its responses are gone
            except ScpiError as error:
                host.status.push_error(error.code, error.message)
                if -199 <= error.code <= -100:
                    break  # a command error ends the message
                continue
            if answer is not None:
                responses.append(answer if isinstance(answer, bytes) else answer.encode())
        if not responses:
            return None
        return b";".join(responses) + b"\n"

    def _execute_unit(self, unit: ProgramUnit, path: list[str]) -> str | bytes | None:
        host = self.host
        header = unit.header
        if header.startswith("*"):
            name = header.upper()
            if name == "*OPC" and unit.is_query:
                self._wait_idle()
                return "+1"
            if name == "*WAI" and not unit.is_query:
                self._wait_idle()
                return None
            with host.lock:
                handler = host.tree.resolve_common(header, unit.is_query)
                return handler(Call(unit.params, (), name))
        absolute = header.startswith(":")
        tokens = header.lstrip(":").split(":")
        if any(not t for t in tokens):
            raise ScpiError(-102, unit.text[:60])
        full = tokens if absolute else [*path, *tokens]
        path[:] = full[:-1]
        resolved = host.tree.resolve(full, unit.is_query)
        with host.lock:
            return resolved.handler(Call(unit.params, resolved.suffixes, ":".join(full)))

    def _wait_idle(self) -> None:
        host = self.host
        with host.changed:
            cleared = self._cleared
            while host.run.state != "IDLE" and self._cleared == cleared:
                host.changed.wait()
            if self._cleared != cleared:
                raise _DeviceCleared
