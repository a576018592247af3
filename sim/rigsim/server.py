"""Loopback servers for the virtual 35670A: raw SCPI socket, Prologix GPIB-Ethernet, GPIB-USB.

* Raw SCPI socket: ``TCPIP::127.0.0.1::<port>::SOCKET`` (pyvisa-py; use
  ``read_termination="\\n"`` and ``write_termination="\\n"``). Every line is a program message;
  responses go out at once.
* Prologix GPIB-Ethernet: open ``PRLGX-TCPIP::127.0.0.1::<port>::INTFC``, then
  ``GPIB0::11::INSTR``. Lines starting with ``++`` are adapter commands (``++mode``, ``++auto``,
  ``++read_tmo_ms``, ``++eos``, ``++eoi``, ``++eot_enable``, ``++eot_char``, ``++addr``,
  ``++read``, ``++ver``, ``++ifc``, ``++clr``, ``++spoll``, ``++srq``, ``++trg``, ``++loc``,
  ``++llo``, ``++rst``, ``++savecfg``); other lines, ESC-unescaped, go to the device at
  ``++addr``. The device's response waits in its output queue until ``++read``, as on GPIB.
* Prologix GPIB-USB on a pseudo-terminal: ``PRLGX-ASRL::/dev/pts/N::INTFC`` then
  ``GPIB0::11::INSTR`` (pyvisa-py's pyserial path), POSIX only.

Deliberate differences from the adapter: ``++read`` waits for the device at least
``read_timeout_floor_s`` (default :data:`READ_TIMEOUT_FLOOR_S`) even when ``++read_tmo_ms`` is
shorter, so a loaded CI machine does not turn into spurious timeouts (0 makes it exact);
``++eos``/``++eoi`` are stored but every line is delivered as one message.

As a network service it is bounded (:class:`ServiceLimits`): a message longer than
``max_message_bytes`` (the instrument's input buffer is finite) puts -100 in the error queue and
the connection is closed; a message begun and not ended within ``message_timeout_s`` closes the
connection (a client dripping bytes cannot hold it); at most ``max_connections`` clients at once:
when every slot is held, a new client takes the slot of the one that has gone longest without a
message handled (idle, not reading its replies, or stuck in a partial message), and is refused
only while every slot executes a message for longer than ``SLOT_WAIT_S``; a connection silent
for ``idle_timeout_s`` is closed; a client that does not read its replies for
``send_timeout_s`` is dropped; behind the Prologix adapter, messages wait in a bounded queue and
the adapter stops reading the socket while it is full (as GPIB's handshake holds a talker), so
no flood, crowd or slow client makes the server's memory grow or keeps a new client from being
answered.

Everything binds 127.0.0.1 unless a host is given.
"""

from __future__ import annotations

import contextlib
import os
import select
import socket
import sys
import threading
import time
from collections import deque
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from typing import Any

from rigsim.analyser import (
    DEFAULT_IDN,
    DEFAULT_OPTIONS,
    Simulator,
    VirtualAnalyser,
    build_simulator,
)
from rigsim.faults import FaultInjector, garble
from rigsim.prologix import PrologixAdapter
from rigsim.scpi import MessageFramer, MessageTooLong
from rigsim.service import READ_TIMEOUT_FLOOR_S, ServiceLimits

__all__ = ["READ_TIMEOUT_FLOOR_S", "ServiceLimits", "SimulatedAnalyserServer"]

#: Connections the kernel completes while the accept loop is busy (a crowd arriving at once
#: would otherwise wait a second per SYN retransmission).
LISTEN_BACKLOG = 128
#: How long a new connection waits for a slot to finish the message it executes, when every
#: slot is executing one: clients flooding short queries are each inside one most of the time.
SLOT_WAIT_S = 0.5


@dataclass
class _Slot:
    """A served connection, as the accept loop weighs it when every slot is held."""

    conn: socket.socket
    progress_at: float
    """``time.monotonic()`` of the last message executed, or of the accept."""
    busy: int = 0
    """Messages executing now (a client waiting on ``*OPC?`` is not idle)."""
    partial_since: float | None = None
    """When the message not yet ended began to arrive."""

    def handled(self) -> None:
        self.progress_at = time.monotonic()

    def pending(self, partial: bool, limits: ServiceLimits) -> bool:
        """Note whether a message is part-received; False once one is older than
        ``limits.message_timeout_s`` (close the connection). Sets the socket's time-out to
        what is left of that time (or the idle time-out)."""
        now = time.monotonic()
        if not partial:
            self.partial_since = None
            self.conn.settimeout(limits.idle_timeout_s)
            return True
        if self.partial_since is None:
            self.partial_since = now
        left = limits.message_timeout_s - (now - self.partial_since)
        if left <= 0:
            return False
        idle = limits.idle_timeout_s
        self.conn.settimeout(left if idle is None else min(left, idle))
        return True


def _too_long(analyser: VirtualAnalyser, limits: ServiceLimits) -> None:
    analyser.push_error(-100, f"Command error; input message longer than "
                              f"{limits.max_message_bytes} bytes, connection closed")
_ESC, _CR, _LF, _PLUS = 0x1B, 0x0D, 0x0A, 0x2B
_QUICKACK = getattr(socket, "TCP_QUICKACK", None)


def _configure(sock: socket.socket) -> None:
    sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)


def _quickack(sock: socket.socket) -> None:
    # Linux delays ACKs; the client (Nagle on) then holds its "++read eoi" back up to 40 ms.
    if _QUICKACK is not None:
        with contextlib.suppress(OSError):
            sock.setsockopt(socket.IPPROTO_TCP, _QUICKACK, 1)


# --------------------------------------------------------------------------------------------
# raw SCPI socket


def _received(conn: socket.socket, *, quickack: bool = False) -> Iterator[bytes]:
    """What the peer sends, chunk by chunk, until it closes the connection, falls silent past
    the socket's time-out, or the socket fails."""
    while True:
        try:
            data = conn.recv(65536)
        except OSError:  # includes socket.timeout: an idle connection is closed
            return
        if not data:
            return
        if quickack:
            _quickack(conn)
        yield data


def _send(conn: socket.socket, data: bytes, limits: ServiceLimits) -> bool:
    """Send a reply within the send time-out; False when the client does not take it."""
    try:
        conn.settimeout(limits.send_timeout_s)
        conn.sendall(data)
        conn.settimeout(limits.idle_timeout_s)
    except OSError:
        return False
    return True


def _serve_raw(slot: _Slot, analyser: VirtualAnalyser, faults: FaultInjector,
               limits: ServiceLimits) -> None:
    conn = slot.conn
    session = analyser.session()
    framer = MessageFramer(limits.max_message_bytes)
    conn.settimeout(limits.idle_timeout_s)
    with conn:
        for data in _received(conn):
            try:
                messages = framer.feed(data)
            except MessageTooLong:
                _too_long(analyser, limits)
                with contextlib.suppress(OSError):
                    conn.shutdown(socket.SHUT_RDWR)
                return
            for line in messages:
                text = line.decode("latin-1").rstrip("\r")
                kinds = faults.take(text)
                if "drop" in kinds:
                    with contextlib.suppress(OSError):
                        conn.shutdown(socket.SHUT_RDWR)
                    return
                slot.busy += 1
                try:
                    response = session.execute(text)
                finally:
                    slot.busy -= 1
                slot.handled()  # before the reply: a client that has it finds it counted
                if response is not None and "no_reply" not in kinds:
                    if "garble" in kinds:
                        response = garble(response)
                    if not _send(conn, response, limits):
                        return
            if not slot.pending(framer.pending, limits):
                return


# --------------------------------------------------------------------------------------------
# GPIB device behind a Prologix adapter


class SimulatedAnalyserServer:
    """A virtual 35670A on a simulated rig, served on loopback.

    Parameters
    ----------
    rig
        A ``rigsim.rigfile.Rig``, a rig file path, a preset name, or ``None`` for the preset
        ``"table"`` (ignored when ``simulator`` or ``analyser`` is given).
    port
        Port of the raw SCPI socket (0: the OS picks a free one).
    prologix
        Also serve a Prologix GPIB-Ethernet endpoint (on ``prologix_port``), and make
        :attr:`resource` the GPIB resource behind it.
    pty
        Also serve a Prologix GPIB-USB adapter on a pseudo-terminal (POSIX only).
    pace
        Simulated seconds per wall second; ``None`` runs as fast as possible.
    seed
        Seed of the simulator's noise.
    host
        Address to bind (loopback unless told otherwise).
    gpib_address
        The analyser's GPIB address behind the Prologix adapters (factory setting 11).
    options
        Installed options reported by ``*OPT?``.
    simulator, analyser
        Use this rig simulator or this analyser instead of building one.
    limits
        Bounds of the service (message length, connections, time-outs).
    read_timeout_floor_s
        Shortest wait of the Prologix adapter's ``++read`` (0: exactly ``++read_tmo_ms``).

    Attributes
    ----------
    analyser : VirtualAnalyser
        The instrument (in-process: ``mount``, ``force_overload``, ``push_error``).
    faults : FaultInjector
        Faults to inject into the next messages.
    socket_resource : str
        ``TCPIP::127.0.0.1::<port>::SOCKET``.
    prologix_resource : str or None
        ``PRLGX-TCPIP::127.0.0.1::<port>::INTFC``.
    pty_resource : str or None
        ``PRLGX-ASRL::/dev/pts/N::INTFC``.
    gpib_resource : str
        ``GPIB0::11::INSTR``: open it after a Prologix interface resource.
    resource : str
        What a client opens to talk to the analyser: the GPIB resource when ``prologix`` is set
        (after :attr:`interface_resource`), the raw socket otherwise.
    resources : tuple of str
        The resources to open, in order (``(socket,)`` or ``(prologix interface, GPIB)``).
    """

    def __init__(
        self,
        rig: Any = None,
        *,
        port: int = 0,
        prologix: bool = False,
        prologix_port: int = 0,
        pty: bool = False,
        pace: float | None = None,
        seed: int | None = None,
        host: str = "127.0.0.1",
        gpib_address: int = 11,
        options: tuple[str, ...] = DEFAULT_OPTIONS,
        idn: str = DEFAULT_IDN,
        simulator: Simulator | None = None,
        analyser: VirtualAnalyser | None = None,
        limits: ServiceLimits | None = None,
        read_timeout_floor_s: float = READ_TIMEOUT_FLOOR_S,
    ) -> None:
        if analyser is None:
            if simulator is None:
                simulator = build_simulator("table" if rig is None else rig, seed=seed)
            analyser = VirtualAnalyser(simulator, pace=pace, options=options, idn=idn)
        self.analyser = analyser
        self.faults = FaultInjector(analyser)
        self.limits = limits or ServiceLimits()
        self.read_timeout_floor_s = read_timeout_floor_s
        self.refused = 0
        #: Connections dropped to give their slot to a new client.
        self.evicted = 0
        self._adapter_log: deque[str] = deque(maxlen=1000)
        self.host = host
        self.gpib_address = gpib_address
        self._port = port
        self._prologix = prologix
        self._prologix_port = prologix_port
        self._pty = pty
        self._stop = threading.Event()
        self._threads: list[threading.Thread] = []
        self._listeners: list[socket.socket] = []
        self._connections: dict[socket.socket, _Slot] = {}
        self._adapters: list[PrologixAdapter] = []
        self._lock = threading.Lock()
        self._pty_fds: tuple[int, ...] | None = None
        self._wake = os.pipe()
        self.socket_resource = ""
        self.prologix_resource: str | None = None
        self.pty_resource: str | None = None
        self.gpib_resource = f"GPIB0::{gpib_address}::INSTR"
        self.started = False

    # ---------------------------------------------------------------- lifecycle

    def start(self) -> SimulatedAnalyserServer:
        """Bind and start serving (idempotent)."""
        if self.started:
            return self
        self.started = True
        raw = self._listen(self._port)
        self.socket_resource = f"TCPIP::{self.host}::{raw.getsockname()[1]}::SOCKET"
        self._spawn(self._accept_loop, raw, self._serve_raw_connection)
        if self._prologix:
            listener = self._listen(self._prologix_port)
            self.prologix_resource = f"PRLGX-TCPIP::{self.host}::{listener.getsockname()[1]}::INTFC"
            self._spawn(self._accept_loop, listener, self._serve_prologix_connection)
        if self._pty:
            self._start_pty()
        return self

    def close(self) -> None:
        """Stop serving, close every connection, stop any sweep."""
        if self._stop.is_set():
            return
        self._stop.set()
        os.write(self._wake[1], b"x")
        for listener in self._listeners:
            with contextlib.suppress(OSError):
                listener.close()
        with self._lock:
            connections = list(self._connections)
            adapters = list(self._adapters)
        for conn in connections:
            with contextlib.suppress(OSError):
                conn.shutdown(socket.SHUT_RDWR)
        for adapter in adapters:
            adapter.close()
        self.analyser.close()
        for thread in self._threads:
            thread.join(timeout=2.0)
        if self._pty_fds is not None:
            for fd in self._pty_fds:
                with contextlib.suppress(OSError):
                    os.close(fd)
        for fd in self._wake:
            with contextlib.suppress(OSError):
                os.close(fd)

    def serve_forever(self) -> None:
        """Serve until :meth:`close` (or Ctrl-C in the calling thread)."""
        self.start()
        while not self._stop.wait(0.5):
            pass

    def __enter__(self) -> SimulatedAnalyserServer:
        return self.start()

    def __exit__(self, *exc: object) -> None:
        self.close()

    # ---------------------------------------------------------------- resources

    @property
    def adapter_log(self) -> list[str]:
        """Prologix adapter commands received (``++`` removed), closed connections first."""
        with self._lock:
            return [*self._adapter_log, *(line for a in self._adapters for line in a.log)]

    @property
    def interface_resource(self) -> str | None:
        """The Prologix interface to open before :attr:`gpib_resource` (TCP, else pty)."""
        return self.prologix_resource or self.pty_resource

    @property
    def resource(self) -> str:
        return self.gpib_resource if self._prologix else self.socket_resource

    @property
    def resources(self) -> tuple[str, ...]:
        if self._prologix and self.prologix_resource:
            return (self.prologix_resource, self.gpib_resource)
        return (self.socket_resource,)

    # ---------------------------------------------------------------- plumbing

    def _spawn(self, target: Callable[..., None], *args: Any) -> None:
        thread = threading.Thread(target=target, args=args, daemon=True, name="35670A-server")
        thread.start()
        self._threads.append(thread)

    def _listen(self, port: int) -> socket.socket:
        listener = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
        listener.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        listener.bind((self.host, port))
        listener.listen(LISTEN_BACKLOG)
        self._listeners.append(listener)
        return listener

    def _accept_loop(self, listener: socket.socket,
                     serve: Callable[[socket.socket], None]) -> None:
        while not self._stop.is_set():
            try:
                readable, _, _ = select.select([listener, self._wake[0]], [], [])
            except OSError:  # close() came between the loop test and select: listener closed
                return
            if self._stop.is_set():
                return
            if listener not in readable:
                continue
            try:
                conn, _ = listener.accept()
            except OSError:
                return
            _configure(conn)
            slot = _Slot(conn, time.monotonic())
            waited_until = time.monotonic() + SLOT_WAIT_S
            while True:
                with self._lock:
                    full = len(self._connections) >= self.limits.max_connections
                    victim = self._victim() if full else None
                    admitted = not full or victim is not None
                    if victim is not None:
                        del self._connections[victim.conn]
                    if admitted:
                        self._connections[conn] = slot
                if admitted or time.monotonic() > waited_until or self._stop.is_set():
                    break
                time.sleep(0.005)
            if victim is not None:
                self.evicted += 1
                with contextlib.suppress(OSError):  # its thread ends: recv or send fails
                    victim.conn.shutdown(socket.SHUT_RDWR)
            if not admitted:
                self.refused += 1
                with contextlib.suppress(OSError):
                    conn.close()
                continue
            thread = threading.Thread(target=self._serve_connection, args=(serve, slot),
                                      daemon=True, name="35670A-connection")
            thread.start()

    def _victim(self) -> _Slot | None:
        """The connection to drop for a new one (lock held): of those not executing a message,
        the one longest without a message handled; ``None`` when every one is executing."""
        idle = [slot for slot in self._connections.values() if not slot.busy]
        return min(idle, key=lambda slot: slot.progress_at, default=None)

    def _serve_connection(self, serve: Callable[[_Slot], None], slot: _Slot) -> None:
        try:
            serve(slot)
        finally:
            with self._lock:
                if self._connections.get(slot.conn) is slot:
                    del self._connections[slot.conn]
            with contextlib.suppress(OSError):
                slot.conn.close()

    def _serve_raw_connection(self, slot: _Slot) -> None:
        _serve_raw(slot, self.analyser, self.faults, self.limits)

    def _serve_prologix_connection(self, slot: _Slot) -> None:
        conn = slot.conn
        dropped = threading.Event()

        def drop() -> None:
            dropped.set()
            with contextlib.suppress(OSError):
                conn.shutdown(socket.SHUT_RDWR)

        def send(data: bytes) -> None:
            if not _send(conn, data, self.limits):
                drop()

        adapter = PrologixAdapter(self.analyser, self.faults, self.gpib_address, send,
                                   "Prologix GPIB-ETHERNET Controller version 01.06.06.00", drop,
                                   self.limits, self.read_timeout_floor_s)
        with self._lock:
            self._adapters.append(adapter)
        conn.settimeout(self.limits.idle_timeout_s)
        try:
            for data in _received(conn, quickack=True):
                slot.busy += 1
                try:
                    adapter.feed(data)
                except MessageTooLong:
                    _too_long(self.analyser, self.limits)
                    break
                finally:
                    slot.busy -= 1
                if dropped.is_set():
                    break
                partial = bool(adapter.buffer)
                if not partial:
                    slot.handled()
                if not slot.pending(partial, self.limits):
                    break
        finally:
            adapter.close()
            with self._lock:
                self._adapters.remove(adapter)
                self._adapter_log.extend(adapter.log)

    # ---------------------------------------------------------------- pseudo-terminal

    def _start_pty(self) -> None:
        if sys.platform == "win32":
            raise OSError("pseudo-terminals need a POSIX system")
        import termios
        import tty

        master, slave = os.openpty()
        tty.setraw(slave, termios.TCSANOW)  # no echo, no line editing: a USB serial port
        self._pty_fds = (master, slave)  # keep the slave open so the client may reconnect
        self.pty_resource = f"PRLGX-ASRL::{os.ttyname(slave)}::INTFC"

        def send(data: bytes) -> None:
            view = memoryview(data)
            while view:
                written = os.write(master, view)
                view = view[written:]

        dropped = threading.Event()
        unplug = os.pipe()

        def drop() -> None:
            dropped.set()
            os.write(unplug[1], b"x")

        adapter = PrologixAdapter(self.analyser, self.faults, self.gpib_address, send,
                                   "Prologix GPIB-USB Controller version 6.107", drop,
                                   self.limits, self.read_timeout_floor_s)
        self._adapters.append(adapter)

        def loop() -> None:
            while not self._stop.is_set() and not dropped.is_set():
                readable, _, _ = select.select([master, self._wake[0], unplug[0]], [], [])
                if master not in readable:
                    continue
                try:
                    data = os.read(master, 65536)
                except OSError:
                    return
                if data:
                    try:
                        adapter.feed(data)
                    except MessageTooLong:
                        _too_long(self.analyser, self.limits)
            for fd in unplug:
                os.close(fd)
            if dropped.is_set():  # the adapter was "unplugged": the port goes away
                self._pty_fds = (slave,)
                with contextlib.suppress(OSError):
                    os.close(master)

        self._spawn(loop)
