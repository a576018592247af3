"""The Prologix GPIB-Ethernet / GPIB-USB adapter in controller mode, in front of the virtual 35670A.

:class:`PrologixAdapter` speaks the adapter's protocol over any byte transport (a socket or a
pseudo-terminal; :mod:`rigsim.server` gives it one): lines starting with ``++`` are adapter
commands, other lines, ESC-unescaped, go to the device at ``++addr``, whose response waits in
its output queue until ``++read``, as on GPIB. :class:`GpibDevice` is that device: the analyser
behind a bounded message queue, served by a thread of its own.
"""

from __future__ import annotations

import queue
import threading
from collections import deque
from collections.abc import Callable

from rigsim.analyser import ScpiSession, VirtualAnalyser
from rigsim.faults import FaultInjector, garble
from rigsim.scpi import MessageTooLong
from rigsim.service import POLL_SETTLE_S, READ_TIMEOUT_FLOOR_S, ServiceLimits

__all__ = ["GpibDevice", "PrologixAdapter"]

_ESC, _CR, _LF = 0x1B, 0x0D, 0x0A


class GpibDevice:
    """The analyser as seen through GPIB: input messages, one output message, device clear.

    Messages execute on the device's own thread, so the adapter keeps answering ``++spoll``,
    ``++clr`` and ``++read`` timeouts while the device waits on ``*OPC?``.
    """

    def __init__(self, analyser: VirtualAnalyser, faults: FaultInjector,
                 on_drop: Callable[[], None], queued_messages: int = 64) -> None:
        self.analyser = analyser
        self.faults = faults
        self.on_drop = on_drop
        self.session: ScpiSession = analyser.session()
        self.closed = False
        self.inbox: queue.Queue[str | None] = queue.Queue(maxsize=queued_messages)
        self.cond = threading.Condition()
        self.output: bytes | None = None
        self.busy = 0  # messages written and not yet executed
        self.reply_lost = False
        self.thread = threading.Thread(target=self._loop, name="35670A-gpib", daemon=True)
        self.thread.start()

    def write(self, message: str) -> None:
        """Queue a message; while the queue is full the caller waits (GPIB handshake)."""
        with self.cond:
            self.busy += 1
        while not self.closed:
            try:
                self.inbox.put(message, timeout=0.5)
                return
            except queue.Full:
                continue

    def read(self, timeout_s: float) -> bytes | None:
        """Address the device to talk: its response once every message written is handled,
        or ``None`` after ``timeout_s``."""
        with self.cond:
            self.cond.wait_for(lambda: self.busy == 0, timeout_s)
            output, self.output = self.output, None
            if output is None and self.busy == 0:
                if self.reply_lost:
                    self.reply_lost = False
                else:  # addressed to talk with nothing to say (IEEE 488.2, inferred for 35670A)
                    self.analyser.push_error(-420, "Query UNTERMINATED")
            return output

    def has_output(self) -> bool:
        """Message available, once the messages already written are parsed (a device that
        waits on ``*OPC?`` answers the poll anyway, after at most :data:`POLL_SETTLE_S`)."""
        with self.cond:
            self.cond.wait_for(lambda: self.busy == 0, POLL_SETTLE_S)
            return self.output is not None

    def clear(self) -> None:
        """Selected device clear: input and output queues emptied, ``*OPC?`` waits end."""
        with self.cond:
            while True:
                try:
                    if self.inbox.get_nowait() is not None:
                        self.busy -= 1
                except queue.Empty:
                    break
            self.output = None
        self.session.device_clear()

    def close(self) -> None:
        self.closed = True
        self.session.device_clear()
        while True:  # make room for the stop message
            try:
                self.inbox.get_nowait()
            except queue.Empty:
                break
        self.inbox.put(None)

    def _loop(self) -> None:
        while True:
            message = self.inbox.get()
            if message is None:
                return
            kinds = self.faults.take(message)
            if "drop" in kinds:
                with self.cond:
                    self.busy = 0
                self.on_drop()
                return
            with self.cond:
                if self.output is not None:
                    # a new message while a response is unread (IEEE 488.2: query interrupted)
                    self.output = None
                    self.analyser.push_error(-410, "Query INTERRUPTED")
            response = self.session.execute(message)
            with self.cond:
                self.busy = max(0, self.busy - 1)
                self.reply_lost = False
                if response is not None:
                    if "no_reply" in kinds:
                        self.reply_lost = True
                    else:
                        self.output = garble(response) if "garble" in kinds else response
                self.cond.notify_all()


class PrologixAdapter:
    """Prologix controller-mode protocol over a byte transport (socket or pseudo-terminal)."""

    def __init__(self, analyser: VirtualAnalyser, faults: FaultInjector, address: int,
                 send: Callable[[bytes], None], version: str,
                 on_drop: Callable[[], None], limits: ServiceLimits,
                 read_timeout_floor_s: float = READ_TIMEOUT_FLOOR_S) -> None:
        self.analyser = analyser
        self.address = address
        self.send = send
        self.version = version
        self.limits = limits
        self.read_timeout_floor_s = read_timeout_floor_s
        self.settings: dict[str, int] = {}
        self.reset()
        self.device = GpibDevice(analyser, faults, on_drop, limits.queued_messages)
        self.buffer = bytearray()
        #: The adapter commands received (``++`` removed), the latest last (bounded).
        self.log: deque[str] = deque(maxlen=1000)

    def reset(self) -> None:
        self.settings = {"mode": 1, "auto": 0, "read_tmo_ms": 500, "eos": 0, "eoi": 1,
                         "eot_enable": 0, "eot_char": 0, "addr": 0}

    def close(self) -> None:
        self.device.close()

    def feed(self, data: bytes) -> None:
        """Bytes from the host: split into lines (unescaped CR/LF end a line).

        Raises
        ------
        MessageTooLong
            More than the message bound arrived without a line end.
        """
        self.buffer += data
        while True:
            line = self._next_line()
            if line is None:
                if len(self.buffer) > self.limits.max_message_bytes:
                    self.buffer.clear()
                    raise MessageTooLong("line too long")
                return
            raw, text = line
            if not raw:
                continue
            if raw.startswith(b"++"):
                self._command(raw[2:].decode("latin-1").strip())
            else:
                self._data(text)

    def _next_line(self) -> tuple[bytes, bytes] | None:
        buf = self.buffer
        if _ESC not in buf:
            positions = [p for p in (buf.find(b"\n"), buf.find(b"\r")) if p >= 0]
            if not positions:
                return None
            end = min(positions)
            raw = bytes(buf[:end])
            del buf[: end + 1]
            return raw, raw
        text = bytearray()
        i = 0
        while i < len(buf):
            byte = buf[i]
            if byte == _ESC:
                if i + 1 >= len(buf):
                    return None  # the escaped byte has not arrived yet
                text.append(buf[i + 1])
                i += 2
                continue
            if byte in (_CR, _LF):
                raw = bytes(buf[:i])
                del buf[: i + 1]
                return raw, bytes(text)
            text.append(byte)
            i += 1
        return None

    def _data(self, text: bytes) -> None:
        if self.settings["addr"] != self.address or self.settings["mode"] != 1:
            return  # nobody listens at that address
        self.device.write(text.decode("latin-1"))
        if self.settings["auto"]:
            self._read()

    def _read(self) -> None:
        if self.settings["addr"] != self.address:
            return
        timeout = max(self.settings["read_tmo_ms"] / 1000.0, self.read_timeout_floor_s)
        output = self.device.read(timeout)
        if output is not None:
            if self.settings["eot_enable"]:
                output += bytes([self.settings["eot_char"]])
            self.send(output)

    def _reply(self, text: str) -> None:
        self.send(text.encode("latin-1") + b"\r\n")

    def _command(self, line: str) -> None:
        self.log.append(line)
        name, _, arg = line.partition(" ")
        name, arg = name.lower(), arg.strip()
        if name == "read":
            self._read()
        elif name in self.settings:
            if not arg:
                self._reply(str(self.settings[name]))
                return
            try:
                self.settings[name] = int(arg.split()[0])
            except ValueError:
                return  # the adapter ignores malformed arguments
        elif name == "ver":
            self._reply(self.version)
        elif name == "clr":
            if self.settings["addr"] == self.address:
                self.device.clear()
        elif name == "spoll":
            target = int(arg.split()[0]) if arg else self.settings["addr"]
            if target == self.address:
                self._reply(str(self.analyser.status_byte(mav=self.device.has_output())))
        elif name == "srq":
            self._reply("1" if self.analyser.status_byte() & 64 else "0")
        elif name == "trg":
            if self.settings["addr"] == self.address:
                self.device.write("*TRG")
        elif name == "rst":
            self.reset()
        elif name == "help":
            self._reply("Simulated Prologix adapter: ++addr ++auto ++clr ++eoi ++eos "
                        "++eot_enable ++eot_char ++ifc ++llo ++loc ++mode ++read ++read_tmo_ms "
                        "++rst ++savecfg ++spoll ++srq ++trg ++ver")
        # ++ifc, ++llo, ++loc, ++savecfg, ++lon, ++status: accepted, nothing to simulate


# --------------------------------------------------------------------------------------------
# the server
