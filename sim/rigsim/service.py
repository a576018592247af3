"""Bounds of the virtual 35670A as a network service (shared by its servers and adapters)."""

from __future__ import annotations

from dataclasses import dataclass

#: Least time ``++read`` waits for the device, s, whatever ``++read_tmo_ms`` says.
READ_TIMEOUT_FLOOR_S = 1.0
#: Longest wait of a serial poll for a message in progress, s.
POLL_SETTLE_S = 0.1


@dataclass(frozen=True)
class ServiceLimits:
    """Bounds of the simulated analyser as a network service.

    Attributes
    ----------
    max_message_bytes
        Longest program message (terminator excluded); a longer one is refused with -100 and
        the connection closed. 64 KiB holds the largest block the analyser takes (a data
        register of 2049 complex points in REAL,64 is 32.8 kB).
    max_connections
        Clients served at once (raw sockets and Prologix endpoints together).
    idle_timeout_s
        A connection that sends nothing for this long is closed (``None``: never, the default
        in process; ``viscorig sim serve`` sets one hour).
    send_timeout_s
        A reply the client does not take within this time drops the connection.
    queued_messages
        Messages waiting for the GPIB device behind a Prologix adapter.
    message_timeout_s
        A message begun (bytes received, no terminator yet) must end within this time, else the
        connection is closed; a program writes a message at once (64 KiB take milliseconds on
        loopback or a LAN).
    """

    max_message_bytes: int = 65536
    max_connections: int = 8
    idle_timeout_s: float | None = None
    send_timeout_s: float = 30.0
    queued_messages: int = 64
    message_timeout_s: float = 10.0
