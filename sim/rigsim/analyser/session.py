"""One controller's connection to the virtual analyser: message parsing, header path, waits.

A socket server and in-process code can share one instrument, each through its own
:class:`ScpiSession`.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from rigsim.scpi import ProgramUnit, ScpiError, parse_unit, split_units

if TYPE_CHECKING:
    from rigsim.analyser.instrument import VirtualAnalyser

__all__ = ["ScpiSession"]


class _DeviceCleared(Exception):  # noqa: N818 - a signal, not an error
    """A device clear ended a ``*OPC?`` or ``*WAI`` wait."""


class ScpiSession:
    """One controller's connection: its own header path; the instrument is shared.

    :meth:`execute` runs one program message and returns the response message (bytes ending
    with a line feed) or ``None`` when the message held no query.
    """

    def __init__(self, analyser: VirtualAnalyser) -> None:
        self.analyser = analyser
        self._cleared = 0

    def device_clear(self) -> None:
        """IEEE 488.2 device clear: pending ``*OPC?``/``*WAI`` waits of this session end."""
        with self.analyser.changed:
            self._cleared += 1
            self.analyser.changed.notify_all()

    def execute(self, message: str | bytes) -> bytes | None:
        """Run a program message (newline and/or EOI already stripped or not)."""
        a = self.analyser
        if isinstance(message, bytes):
            message = message.decode("latin-1")
        message = message.strip("\r\n")
        if not message.strip():
            return None
        responses: list[bytes] = []
        path: list[str] = []
        try:
            units = list(split_units(message))
        except ScpiError as error:
            a.push_error(error.code, error.message)
            return None
        for text in units:
            try:
                unit = parse_unit(text)
                answer = self._execute_unit(unit, path)
            except _DeviceCleared:
                return None  # the rest of the message and its responses are gone
            except ScpiError as error:
                a.push_error(error.code, error.message)
                if -199 <= error.code <= -100:
                    break  # a command error ends the message
                continue
            if answer is not None:
                responses.append(answer if isinstance(answer, bytes) else answer.encode())
        if not responses:
            return None
        return b";".join(responses) + b"\n"

    def _execute_unit(self, unit: ProgramUnit, path: list[str]) -> str | bytes | None:
        a = self.analyser
        header = unit.header
        if header.startswith("*"):
            name = header.upper()
            if name == "*OPC" and unit.is_query:
                self._wait_idle()
                return "+1"
            if name == "*WAI" and not unit.is_query:
                self._wait_idle()
                return None
            with a.lock:
                return a.tree.resolve_common(header, unit.is_query)(unit.params, None)
        absolute = header.startswith(":")
        tokens = [t for t in header.lstrip(":").split(":")]
        if any(not t for t in tokens):
            raise ScpiError(-102, unit.text)
        full = tokens if absolute else [*path, *tokens]
        path[:] = full[:-1]
        if a.mode == "SINE" and full[0].upper() in ("TRIG", "TRIGGER", "ARM"):
            raise ScpiError(-221, f"{':'.join(full)} not valid in swept sine")
        resolved = a.tree.resolve(full, unit.is_query)
        with a.lock:
            return resolved.handler(unit.params, resolved.suffix)

    def _wait_idle(self) -> None:
        a = self.analyser
        with a.changed:
            cleared = self._cleared
            while a.state != "IDLE" and self._cleared == cleared:
                a.changed.wait()
            if self._cleared != cleared:
                raise _DeviceCleared
