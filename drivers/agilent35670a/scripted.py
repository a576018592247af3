"""A scripted SCPI endpoint on loopback that records what it receives.

For protocol tests and benchmarks of the driver: it listens on ``127.0.0.1`` (port chosen by the
OS), records every message the driver sends, and answers queries from a script of canned replies.
It speaks either a raw SCPI socket (``TCPIP::127.0.0.1::<port>::SOCKET``) or the Prologix
GPIB-Ethernet protocol (``PRLGX-TCPIP::127.0.0.1::<port>::INTFC`` then ``GPIB0::11::INSTR``):
``++`` commands configure the adapter and are recorded apart, ESC escapes are removed, and a reply
is sent only on ``++read``. The driver talks to it through pyvisa-py's real socket code, as it
would to hardware; it simulates nothing of the analyser beyond the script.

Replies are looked up by the whole message (after upper-casing): a ``str`` (sent with a line
feed), ``bytes`` (sent as they are), a list of those (one per query, the last repeated), or a
callable taking the message and returning one of those or ``None`` (no reply). ``SYST:ERR?``
pops :attr:`ScriptedSCPIServer.errors` and answers ``+0,"No error"`` when it is empty.

A query with no scripted reply is answered from the settings received (``FREQ:STAR 10 HZ``
then ``FREQ:STAR?`` answers ``+1.00000000000E+001`` and ``FREQ:STAR? UNIT`` answers ``"HZ"``;
``ON``/``OFF`` as ``+1``/``+0``; keywords and strings as sent), so that a driver reading its
settings back sees what a compliant instrument answers; ``defaults`` answer settings never sent.
"""

from __future__ import annotations

import socket
import threading
import time
from collections.abc import Callable
from typing import Any

Reply = str | bytes | list | Callable[[str], Any] | None

NO_ERROR = '+0,"No error"'


class ScriptedSCPIServer:
    """A recording SCPI server with canned replies, as a context manager.

    Parameters
    ----------
    replies
        Message (upper case, without terminator) to reply; see the module docstring.
    prologix
        Speak the Prologix GPIB-Ethernet protocol instead of a raw SCPI socket.
    gpib_address
        GPIB address the Prologix side answers for.
    board
        VISA board number used in :attr:`resource` and :attr:`adapter` (Prologix only). Two
        Prologix servers used at the same time need different boards, because pyvisa-py keys
        its Prologix interfaces by board.
    """

    def __init__(
        self,
        replies: dict[str, Reply] | None = None,
        *,
        prologix: bool = False,
        gpib_address: int = 11,
        board: int = 0,
        defaults: dict[str, str] | None = None,
    ) -> None:
        self.replies: dict[str, Reply] = {k.upper(): v for k, v in (replies or {}).items()}
        self.defaults: dict[str, str] = {k.upper(): v for k, v in (defaults or {}).items()}
        self.settings: dict[str, str] = {}
        self.prologix = prologix
        self.gpib_address = gpib_address
        self.board = board
        self.received: list[str] = []
        self.adapter_commands: list[str] = []
        self.errors: list[str] = []
        self.drop_next_connection_on: str | None = None
        self._listener = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
        self._listener.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        self._listener.bind(("127.0.0.1", 0))
        self._listener.listen(4)
        self._listener.settimeout(0.05)  # here, not in the thread: close() may come first
        self.port = self._listener.getsockname()[1]
        self._stop = threading.Event()
        self._threads: list[threading.Thread] = []
        self._lock = threading.Lock()

    # -- addresses ---------------------------------------------------------------------------
    @property
    def resource(self) -> str:
        """The VISA resource string of the (simulated) instrument."""
        if self.prologix:
            return f"GPIB{self.board}::{self.gpib_address}::INSTR"
        return f"TCPIP::127.0.0.1::{self.port}::SOCKET"

    @property
    def adapter(self) -> str | None:
        """The Prologix interface resource to open first, or ``None`` for a raw socket."""
        if self.prologix:
            return f"PRLGX-TCPIP{self.board}::127.0.0.1::{self.port}::INTFC"
        return None

    def commands(self, quiet_s: float = 0.05) -> list[str]:
        """Every command received, messages split at ``;`` (the order is kept).

        Waits until nothing new has arrived for ``quiet_s`` seconds, so a command written just
        before (with no reply to wait for) is in the list.
        """
        count = -1
        while count != len(self.received):
            count = len(self.received)
            time.sleep(quiet_s)
        return [part for message in self.received for part in message.split(";")]

    # -- lifecycle ---------------------------------------------------------------------------
    def __enter__(self) -> ScriptedSCPIServer:
        thread = threading.Thread(target=self._accept_loop, daemon=True)
        thread.start()
        self._threads.append(thread)
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def close(self) -> None:
        """Stop listening and end every connection."""
        self._stop.set()
        self._listener.close()
        for thread in self._threads:
            thread.join(timeout=2.0)

    def _accept_loop(self) -> None:
        while not self._stop.is_set():
            try:
                connection, _ = self._listener.accept()
            except TimeoutError:
                continue
            except OSError:
                return
            thread = threading.Thread(target=self._serve, args=(connection,), daemon=True)
            thread.start()
            self._threads.append(thread)

    # -- protocol ----------------------------------------------------------------------------
    def _serve(self, connection: socket.socket) -> None:
        connection.settimeout(0.05)
        buffer = bytearray()
        pending: list[bytes] = []  # Prologix: replies waiting for ++read
        with connection:
            while not self._stop.is_set():
                try:
                    chunk = connection.recv(65536)
                except TimeoutError:
                    continue
                except OSError:
                    return
                if not chunk:
                    return
                buffer.extend(chunk)
                for raw in self._split_messages(buffer):
                    if self.prologix and raw.startswith(b"++"):
                        command = raw.decode("ascii").strip()
                        self.adapter_commands.append(command)
                        if command.startswith("++read") and pending:
                            connection.sendall(pending.pop(0))
                        continue
                    message = raw.decode("ascii").strip()
                    self.received.append(message)
                    if self.drop_next_connection_on and message.upper() == (
                        self.drop_next_connection_on
                    ):
                        self.drop_next_connection_on = None
                        return
                    reply = self._reply_to(message)
                    if reply is None:
                        continue
                    if self.prologix:
                        pending[:] = [reply]  # the analyser holds one response message
                    else:
                        connection.sendall(reply)

    def _split_messages(self, buffer: bytearray) -> list[bytes]:
        """Cut complete messages out of the buffer; in Prologix mode remove ESC escapes."""
        messages: list[bytes] = []
        while True:
            end = _unescaped_newline(buffer) if self.prologix else buffer.find(b"\n")
            if end < 0:
                return messages
            raw = bytes(buffer[:end])
            del buffer[: end + 1]
            if self.prologix and not raw.startswith(b"++"):
                raw = _unescape(raw)
            messages.append(raw.rstrip(b"\r"))

    def _remember(self, message: str) -> None:
        """Keep the parameters of each setting received, by header."""
        for unit in message.split(";"):
            header, _, params = unit.strip().partition(" ")
            if header and not header.endswith("?") and not header.startswith("*") and params:
                self.settings[header.lstrip(":").upper()] = params.strip()

    def _echo(self, key: str) -> bytes | None:
        """Answer a setting query from the settings received (or the defaults)."""
        header, _, argument = key.partition("?")
        header = header.lstrip(":")
        value = self.settings.get(header)
        if value is None:
            default = self.defaults.get(key)
            return None if default is None else default.encode("ascii") + b"\n"
        first, _, unit = value.partition(" ")
        if argument.strip() == "UNIT":
            return f'"{unit.strip().upper()}"'.encode("ascii") + b"\n"
        if value[:1] in "'\"":
            return b'"' + value[1:-1].encode("ascii") + b'"\n'
        word = first.upper()
        if word in ("ON", "OFF"):
            return b"+1\n" if word == "ON" else b"+0\n"
        try:
            number = float(first)
        except ValueError:
            return word.encode("ascii") + b"\n"
        return f"{number:+.11E}".encode("ascii") + b"\n"

    def _reply_to(self, message: str) -> bytes | None:
        key = message.upper()
        self._remember(message)
        if key == "SYST:ERR?" and key not in self.replies:
            with self._lock:
                text = self.errors.pop(0) if self.errors else NO_ERROR
            return text.encode("ascii") + b"\n"
        reply: Any = self.replies.get(key)
        if isinstance(reply, list):
            reply = reply.pop(0) if len(reply) > 1 else reply[0]
        if callable(reply):
            reply = reply(message)
        if reply is None and key not in self.replies and "?" in key and ";" not in key:
            return self._echo(key)
        if reply is None:
            return None
        if isinstance(reply, str):
            return reply.encode("ascii") + b"\n"
        return bytes(reply)


def _unescaped_newline(buffer: bytearray) -> int:
    index = 0
    while index < len(buffer):
        byte = buffer[index]
        if byte == 0x1B:
            index += 2
            continue
        if byte == 0x0A:
            return index
        index += 1
    return -1


def _unescape(raw: bytes) -> bytes:
    out = bytearray()
    escaped = False
    for byte in raw:
        if byte == 0x1B and not escaped:
            escaped = True
            continue
        escaped = False
        out.append(byte)
    return bytes(out)
