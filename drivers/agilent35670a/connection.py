"""The connection to the analyser: any pyvisa resource string, timeouts, one safe retry.

Three ways in, all through pyvisa:

- ``GPIB0::11::INSTR`` with a GPIB backend (NI-VISA / Keysight VISA);
- a Prologix GPIB-USB or GPIB-Ethernet adapter through pyvisa-py: the adapter's interface
  resource (``PRLGX-ASRL::/dev/ttyUSB0::INTFC`` or ``PRLGX-TCPIP::host::1234::INTFC``) is opened
  first, then ``GPIB<board>::<address>::INSTR``;
- ``TCPIP::host::port::SOCKET`` (the simulated analyser), read and write termination ``"\\n"``.

Timeouts and lost connections become :class:`InstrumentTimeout` and :class:`ConnectionLost` with
the resource, the command and the timeout in the message. Only queries in
:data:`IDEMPOTENT_QUERIES` are retried, once, after restoring the connection; a command that
changes state is never sent twice.
"""

from __future__ import annotations

import contextlib
import re
import socket
import threading
from typing import cast

import pyvisa
from pyvisa import constants
from pyvisa.errors import VisaIOError

from .blocks import split_definite_block
from .errors import ConnectionLost, InstrumentTimeout, MalformedReply

#: Queries that change nothing in the analyser, so asking twice is harmless. Compared with the
#: query's header (upper case, up to the first space). Deliberately absent: ``SYST:ERR?``,
#: ``*ESR?`` and ``STAT:QUES:VOLT:EVEN?`` (reading them clears them), ``*OPC?`` (it waits on the
#: measurement).
IDEMPOTENT_QUERIES = frozenset(
    {
        "*IDN?",
        "*OPT?",
        "*STB?",
        "STAT:OPER:COND?",
        "STAT:QUES:VOLT:COND?",
        "TRAC:DATA?",
        "TRAC:X?",
        "CALC1:DATA?",
        "CALC2:DATA?",
        "CALC1:DATA:HEAD:POIN?",
        "INST:SEL?",
        "FREQ:STAR?",
        "FREQ:STOP?",
        "FREQ:SPAN?",
        "FREQ:MAN?",
        "FREQ:RES?",
        "FREQ:RES:AUTO?",
        "SWE:SPAC?",
        "SWE:DIR?",
        "SWE:MODE?",
        "SWE:STIM?",
        "SWE:DWEL?",
        "REF?",
        "OUTP?",
        "SOUR:FUNC?",
        "SOUR:FREQ?",
        "SOUR:VOLT?",
        "SOUR:VOLT:LIM?",
        "SOUR:VOLT:AUTO?",
        "SOUR:VOLT:REF?",
        "SOUR:VOLT:REF:CHAN?",
        "SOUR:VOLT:REF:TOL?",
        "SOUR:VOLT:LIM:INP?",
        "SOUR:VOLT:SLEW?",
        "WIND?",
        "AVER?",
        "AVER:COUN?",
        "AVER:TYPE?",
        "FORM?",
        *(f"INP{ch}?" for ch in range(1, 5)),
        *(f"INP{ch}:COUP?" for ch in range(1, 5)),
        *(f"INP{ch}:LOW?" for ch in range(1, 5)),
        *(f"INP{ch}:BIAS?" for ch in range(1, 5)),
        *(f"VOLT{ch}:RANG?" for ch in range(1, 5)),
        *(f"VOLT{ch}:RANG:AUTO?" for ch in range(1, 5)),
        *(f"VOLT{ch}:RANG:UNIT:USER?" for ch in range(1, 5)),
        *(f"VOLT{ch}:RANG:UNIT:USER:SFAC?" for ch in range(1, 5)),
        *(f"VOLT{ch}:RANG:UNIT:XDCR:LAB?" for ch in range(1, 5)),
    }
)

#: Prologix adapter read timeout (ms) between characters of a reply. pyvisa-py sets 50 ms on open;
#: the analyser can take longer to compose a trace, so it is raised here (inferred, harmless on a
#: fast instrument; the adapter accepts 1..3000).
PROLOGIX_READ_TIMEOUT_MS = 500

_PROLOGIX_INTFC = re.compile(r"^PRLGX-(TCPIP|ASRL)(\d*)::.+::INTFC$", re.IGNORECASE)


def _disable_nagle(resource: pyvisa.resources.Resource) -> None:
    """Send each message at once over a pyvisa-py TCP socket (TCP_NODELAY).

    A command that gets no reply followed by ``SYST:ERR?`` otherwise waits for the peer's
    delayed acknowledgement (about 40 ms on Linux) before the query leaves. pyvisa-py 0.8.1 wires
    ``VI_ATTR_TCPIP_NODELAY`` to a setter that raises, so the option is set on its socket. Other
    backends keep their own behaviour.
    """
    session = getattr(resource.visalib, "sessions", {}).get(resource.session)
    interface = getattr(session, "interface", None)
    if isinstance(interface, socket.socket):
        interface.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)


def is_idempotent(query: str) -> bool:
    """Whether ``query`` may be sent again after a failure (see :data:`IDEMPOTENT_QUERIES`)."""
    return query.strip().split(" ")[0].upper() in IDEMPOTENT_QUERIES


class Connection:
    """A message-based connection to one analyser.

    Parameters
    ----------
    resource
        A pyvisa resource string: ``GPIB0::11::INSTR``, ``TCPIP::host::port::SOCKET``, or a
        Prologix interface ``PRLGX-...::INTFC`` alone, which means the analyser at
        ``gpib_address`` behind it.
    adapter
        Prologix interface resource to open before a ``GPIB<board>::<address>::INSTR`` resource.
    gpib_address
        GPIB address used when ``resource`` is a Prologix interface (factory address 11).
    timeout_s
        VISA timeout for each read, in seconds.
    backend
        pyvisa backend (``"@py"``, ``"@ivi"``); by default ``"@py"`` for sockets and Prologix
        adapters and pyvisa's default otherwise.
    """

    def __init__(
        self,
        resource: str,
        *,
        adapter: str | None = None,
        gpib_address: int = 11,
        timeout_s: float = 5.0,
        backend: str | None = None,
    ) -> None:
        match = _PROLOGIX_INTFC.match(resource)
        if match and adapter is None:
            adapter = resource
            resource = f"GPIB{match.group(2) or 0}::{gpib_address}::INSTR"
        self.resource_name = resource
        self.adapter_name = adapter
        self.is_socket = resource.upper().endswith("::SOCKET")
        if backend is None and (adapter or self.is_socket):
            backend = "@py"
        self.backend = backend
        self._timeout_s = timeout_s
        self._manager: pyvisa.ResourceManager | None = None
        self._adapter: pyvisa.resources.MessageBasedResource | None = None
        self._instrument: pyvisa.resources.MessageBasedResource | None = None
        self.lock = threading.RLock()
        self.bytes_read = 0
        self.open()

    @property
    def description(self) -> str:
        """The resource, with its adapter when there is one (used in messages)."""
        if self.adapter_name:
            return f"{self.resource_name} via {self.adapter_name}"
        return self.resource_name

    # -- lifecycle ---------------------------------------------------------------------------
    def open(self) -> None:
        """Open the adapter (if any) and the instrument resource."""
        try:
            if self._manager is None:
                backend = (self.backend,) if self.backend else ()
                self._manager = pyvisa.ResourceManager(*backend)
            if self.adapter_name:
                # both sessions are message based: the names are INTFC and INSTR resources
                adapter = cast(pyvisa.resources.MessageBasedResource,
                               self._manager.open_resource(self.adapter_name))
                self._adapter = adapter
                # pyvisa-py reads through the adapter's session: its timeout is the one that acts
                adapter.timeout = self._timeout_s * 1000.0
                _disable_nagle(adapter)
                adapter.write_raw(f"++read_tmo_ms {PROLOGIX_READ_TIMEOUT_MS}\n".encode())
            instrument = cast(pyvisa.resources.MessageBasedResource,
                              self._manager.open_resource(self.resource_name))
            self._instrument = instrument
        except (VisaIOError, OSError, ValueError) as error:
            self._close_quietly()
            raise ConnectionLost(f"cannot open: {error}", self.description) from error
        except Exception as error:  # pyvisa-py raises a bare Exception when a socket cannot connect
            self._close_quietly()
            raise ConnectionLost(f"cannot open: {error}", self.description) from error
        instrument.timeout = self._timeout_s * 1000.0
        if self.is_socket:
            _disable_nagle(instrument)
        instrument.write_termination = "\n"
        try:
            instrument.read_termination = "\n"
        except VisaIOError:
            # A Prologix GPIB session has no termination attribute; the adapter session already
            # ends reads at a line feed, which is stripped from replies below.
            instrument._read_termination = None

    def close(self) -> None:
        """Close the instrument and adapter resources."""
        with self.lock:
            self._close_quietly()
            if self._manager is not None:
                self._manager.close()
                self._manager = None

    def _close_quietly(self) -> None:
        for resource in (self._instrument, self._adapter):
            if resource is not None:
                # closing a broken session must not hide the original fault
                with contextlib.suppress(Exception):
                    resource.close()
        self._instrument = None
        self._adapter = None

    def reconnect(self) -> None:
        """Close and reopen the resources (the analyser keeps its state)."""
        with self.lock:
            self._close_quietly()
            self.open()

    @property
    def timeout_s(self) -> float:
        """VISA timeout of each read, in seconds."""
        return self._timeout_s

    @timeout_s.setter
    def timeout_s(self, value: float) -> None:
        self._timeout_s = float(value)
        for resource in (self._instrument, self._adapter):
            if resource is not None:
                resource.timeout = self._timeout_s * 1000.0

    # -- I/O ---------------------------------------------------------------------------------
    def write(self, command: str) -> None:
        """Send one message. Never retried: it may change the analyser's state."""
        with self.lock:
            self._guard(command, lambda: self._require().write(command))

    def query(self, command: str) -> str:
        """Send a query and return its reply without the line feed.

        An idempotent query (:func:`is_idempotent`) is retried once after restoring the
        connection; any other failure raises at once.
        """
        return self._with_retry(command, lambda: self._ask(command))

    def query_block(self, command: str) -> bytes:
        """Send a query answered by a definite-length block; return the whole validated message."""
        return self._with_retry(command, lambda: self._ask_block(command))

    def _ask(self, command: str) -> str:
        instrument = self._require()
        instrument.write(command)
        raw = instrument.read_raw()
        self.bytes_read += len(raw)
        return raw.decode("ascii", errors="replace").rstrip("\r\n")

    def _ask_block(self, command: str) -> bytes:
        instrument = self._require()
        instrument.write(command)
        head = instrument.read_bytes(2)
        if head[:1] != b"#" or not head[1:2].isdigit() or head == b"#0":
            rest = b"" if head.endswith(b"\n") else instrument.read_raw()
            raise MalformedReply(
                f"{command!r}: expected a definite-length block, got {(head + rest)[:40]!r}"
            )
        digits = int(head[1:2])
        length_field = instrument.read_bytes(digits)
        if not length_field.isdigit():
            raise MalformedReply(f"{command!r}: block length field {length_field!r} is not digits")
        body = instrument.read_bytes(int(length_field) + 1)  # payload and the final line feed
        message = head + length_field + body
        self.bytes_read += len(message)
        try:
            split_definite_block(message)
        except MalformedReply as error:
            raise MalformedReply(f"{command!r}: {error.detail}", self.description) from None
        return message

    def _with_retry(self, command: str, ask):
        with self.lock:
            try:
                return self._guard(command, ask)
            except (InstrumentTimeout, ConnectionLost):
                if not is_idempotent(command):
                    raise
            self._restore()
            return self._guard(command, ask)

    def _restore(self) -> None:
        """Discard any late reply: reopen a socket; device-clear (or reopen) a GPIB session."""
        if not self.is_socket and self._instrument is not None:
            try:
                self._instrument.clear()
                return
            except Exception:  # a dead session cannot be cleared: reopen it
                pass
        self.reconnect()

    def _guard(self, command: str, action):
        try:
            return action()
        except VisaIOError as error:
            if error.error_code == constants.StatusCode.error_timeout:
                raise InstrumentTimeout(
                    f"no reply to {command!r} within the VISA timeout of {self._timeout_s:g} s",
                    self.description,
                ) from None
            raise ConnectionLost(f"{command!r} failed: {error}", self.description) from None
        except (OSError, pyvisa.errors.InvalidSession) as error:
            raise ConnectionLost(f"{command!r} failed: {error}", self.description) from None

    def _require(self) -> pyvisa.resources.MessageBasedResource:
        if self._instrument is None:
            raise ConnectionLost("the connection is closed", self.description)
        return self._instrument
