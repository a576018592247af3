"""The simulated analyser as a network service: bounded messages, connections, time-outs,
memory under floods and slow clients; loopback only by default."""

from __future__ import annotations

import contextlib
import os
import socket
import threading
import time

import pytest
from rigsim.server import SLOT_WAIT_S, ServiceLimits, SimulatedAnalyserServer
from simserve import rss_kib, sim_serve


def connect(host: str, port: int, timeout: float = 5.0) -> socket.socket:
    sock = socket.create_connection((host, port), timeout=timeout)
    sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
    return sock


def ask(sock: socket.socket, message: bytes) -> bytes:
    sock.sendall(message + b"\n")
    reply = b""
    while not reply.endswith(b"\n"):
        chunk = sock.recv(4096)
        if not chunk:
            raise ConnectionError("closed")
        reply += chunk
    return reply.rstrip(b"\n")


def closed_by_peer(sock: socket.socket, within_s: float) -> bool:
    sock.settimeout(within_s)
    try:
        return sock.recv(1) == b""
    except TimeoutError:
        return False
    except OSError:
        return True


@pytest.mark.slow
def test_a_40_mb_line_is_refused_and_memory_stays_bounded() -> None:
    """A peer that sends 40 MB without a line feed: the server answers with -100 after 64 KiB,
    closes that connection, and its resident memory barely moves."""
    with sim_serve("--preset", "table") as (process, host, _, port):
        probe = connect(host, port)
        assert b"35670A" in ask(probe, b"*IDN?")
        before = rss_kib(process.pid)
        flood = connect(host, port)
        chunk = b"A" * (1 << 20)
        sent = 0
        try:
            for _ in range(40):
                flood.sendall(chunk)
                sent += len(chunk)
        except OSError:
            pass  # the server closed the connection part-way: that is the point
        assert closed_by_peer(flood, 5.0)
        flood.close()
        time.sleep(0.2)
        after = rss_kib(process.pid)
        error = ask(probe, b"SYST:ERR?")
        still_serving = ask(probe, b"*IDN?")
        probe.close()
    print(f"\nserver RSS {before} KiB before, {after} KiB after a 40 MB line "
          f"({sent >> 20} MiB accepted before the close)")
    assert after - before < 8 * 1024, (before, after)
    assert error.startswith(b"-100,") and b"longer than 65536 bytes" in error
    assert b"35670A" in still_serving


def test_a_long_block_with_line_feeds_inside_is_one_message() -> None:
    """A definite block may hold line-feed bytes: they do not end the message."""
    payload = (b"\n" * 8 + b"\x00" * 8) * 2  # two complex values with LF bytes, REAL,64
    with SimulatedAnalyserServer("table") as server:
        host, port = server.socket_resource.split("::")[1:3]
        sock = connect(host, int(port))
        ask(sock, b"ABOR;:INIT:IMM;*OPC?")
        sock.sendall(b"FORM REAL,64;:CALC1:FEED 'XFR:POW:LIN 1';:TRAC:DATA D1,TRAC1\n")
        sock.sendall(b"TRAC:DATA D1,#" + str(len(str(len(payload)))).encode()
                     + str(len(payload)).encode() + payload + b"\n")
        assert ask(sock, b"SYST:ERR?").startswith(b"-161,")  # wrong count for the register
        assert ask(sock, b"SYST:ERR?") == b'+0,"No error"'  # and nothing else: one message
        sock.close()


def test_a_line_feed_ends_a_message_whose_quote_is_not_closed() -> None:
    """A client that lost a closing quote: its next query waited for the string's end until
    the client's time-out. The line feed now ends the message, which is refused as -151."""
    with SimulatedAnalyserServer("table") as server:
        host, port = server.socket_resource.split("::")[1:3]
        sock = connect(host, int(port), timeout=2.0)
        sock.sendall(b"CALC1:FEED 'XFR:POW:LIN 1\n")
        start = time.perf_counter()
        assert b"35670A" in ask(sock, b"*IDN?")
        assert time.perf_counter() - start < 1.0
        error = ask(sock, b"SYST:ERR?")
        assert error.startswith(b"-151,") and b"unterminated" in error
        assert ask(sock, b"SYST:ERR?") == b'+0,"No error"'
        assert ask(sock, b"CALC1:FEED?") == b'"XFR:POW 1"'  # the feed was not changed
        sock.close()


def test_connections_are_bounded_and_a_new_one_takes_the_idlest_slot() -> None:
    limits = ServiceLimits(max_connections=3)
    with SimulatedAnalyserServer("table", limits=limits) as server:
        host, port = server.socket_resource.split("::")[1:3]
        kept = [connect(host, int(port)) for _ in range(3)]
        for sock in kept:
            assert b"35670A" in ask(sock, b"*IDN?")
        assert b"35670A" in ask(kept[0], b"*IDN?")  # kept[1] is now the idlest
        extra = connect(host, int(port))
        assert b"35670A" in ask(extra, b"*IDN?")
        assert closed_by_peer(kept[1], 2.0)
        assert (server.evicted, server.refused) == (1, 0)
        assert len(server._connections) == 3
        for sock in (kept[0], kept[2]):
            assert b"35670A" in ask(sock, b"*IDN?")
        for sock in (*kept, extra):
            sock.close()


def test_a_new_client_waits_for_a_slot_that_ends_its_message_before_it_is_refused() -> None:
    """Every slot executing a message when a client arrives (clients flooding short queries
    are each inside one most of the time): the newcomer was refused at once, a connection reset
    on a loaded machine. It now takes the first slot that ends its message within SLOT_WAIT_S,
    and is refused only when none does."""
    limits = ServiceLimits(max_connections=2)
    with SimulatedAnalyserServer("table", limits=limits) as server:
        host, port = server.socket_resource.split("::")[1:3]
        held = [connect(host, int(port)) for _ in range(2)]
        for sock in held:
            assert b"35670A" in ask(sock, b"*IDN?")
        slots = list(server._connections.values())
        for slot in slots:
            slot.busy += 1  # each one inside a message
        ending = threading.Timer(0.2 * SLOT_WAIT_S, lambda: setattr(slots[0], "busy", 0))
        ending.start()
        newcomer = connect(host, int(port))
        assert b"35670A" in ask(newcomer, b"*IDN?")
        ending.join()
        assert (server.evicted, server.refused) == (1, 0)
        for slot in server._connections.values():  # the other held slot and the newcomer's
            slot.busy += 1
        late = connect(host, int(port))
        assert closed_by_peer(late, 2.0 + SLOT_WAIT_S)
        assert server.refused == 1
        for sock in (*held, newcomer, late):
            sock.close()


@pytest.mark.slow
def test_an_idle_connection_is_closed_and_a_busy_one_is_not() -> None:
    with sim_serve("--preset", "table", "--idle-timeout", "0.5") as (_, host, _, port):
        idle = connect(host, port)
        busy = connect(host, port)
        start = time.monotonic()
        while time.monotonic() - start < 1.2:
            assert b"35670A" in ask(busy, b"*IDN?")
            time.sleep(0.1)
        assert closed_by_peer(idle, 1.0)
        assert b"35670A" in ask(busy, b"*IDN?")
        idle.close()
        busy.close()


def test_a_client_that_never_reads_is_dropped() -> None:
    """Queries whose replies are never read fill the socket buffers; the server gives up after
    its send time-out instead of holding a thread and memory for ever."""
    limits = ServiceLimits(send_timeout_s=0.5)
    with SimulatedAnalyserServer("table", limits=limits) as server:
        host, port = server.socket_resource.split("::")[1:3]
        slow = connect(host, int(port))
        slow.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 4096)
        ask(slow, b"ABOR;:INIT:IMM;*OPC?")
        slow.settimeout(0.2)
        query = b"FORM ASC,12;:TRAC:X? TRAC1\n" * 50
        deadline = time.monotonic() + 10
        dropped = False
        while time.monotonic() < deadline and not dropped:
            try:
                slow.sendall(query)
            except TimeoutError:
                time.sleep(0.1)
            except OSError:
                dropped = True
            if not dropped and not server._connections:
                dropped = True
        assert dropped or not server._connections
        other = connect(host, int(port))
        assert b"35670A" in ask(other, b"*IDN?")
        slow.close()
        other.close()


@pytest.mark.slow
def test_a_flood_behind_the_prologix_adapter_waits_like_gpib() -> None:
    """While the analyser works through a long wait, messages queue up to a bound; the adapter
    then stops reading the socket (as GPIB's handshake holds a talker)."""
    limits = ServiceLimits(queued_messages=16)
    with SimulatedAnalyserServer("table", prologix=True, pace=20.0, limits=limits) as server:
        host, port = server.prologix_resource.split("::")[1:3]
        sock = connect(host, int(port))
        sock.sendall(b"++addr 11\n*RST;:INST:SEL SINE;:FREQ:RES:AUTO OFF;:SOUR:VOLT 0.1 VPK;"
                     b":SWE:STIM 50 CYCLE;:DWEL 50 CYCLE;:ABOR;:INIT\n*WAI\n")
        sent = {"bytes": 0}
        chunk = b"*CLS\n" * 100000  # 500 kB of messages, 40 times: 20 MB offered

        def flood() -> None:
            sock.settimeout(3.0)
            try:
                for _ in range(40):
                    sock.sendall(chunk)
                    sent["bytes"] += len(chunk)
            except OSError:
                pass

        thread = threading.Thread(target=flood, daemon=True)
        thread.start()
        time.sleep(1.5)
        adapter = server._adapters[0]
        queued = adapter.device.inbox.qsize()
        assert queued <= 16
        assert sent["bytes"] < 40 * len(chunk)  # the socket stopped taking data
        server.analyser.abort()
        sock.close()
        thread.join(5)


def test_loopback_by_default() -> None:
    with SimulatedAnalyserServer("table") as server:
        assert server.socket_resource.startswith("TCPIP::127.0.0.1::")


@pytest.mark.parametrize("limit", [64, 1024])
def test_the_message_bound_is_the_one_asked_for(limit: int) -> None:
    with SimulatedAnalyserServer("table", limits=ServiceLimits(max_message_bytes=limit)) as srv:
        host, port = srv.socket_resource.split("::")[1:3]
        fits = connect(host, int(port))
        assert ask(fits, b"*IDN?" + b" " * 0).startswith(b"Agilent")
        too_long = connect(host, int(port))
        too_long.sendall(b"DISP:ERR '" + b"x" * limit + b"'\n")
        assert closed_by_peer(too_long, 2.0)
        assert ask(fits, b"SYST:ERR?").startswith(b"-100,")
        fits.close()
        too_long.close()


# -- crowds: a new client is answered whatever holds the slots ------------------------------

def _crowd_of_non_readers(host: str, port: int, count: int) -> list[socket.socket]:
    """Clients that send queries and never read a reply (their receive buffers fill)."""
    crowd = []
    for _ in range(count):
        sock = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
        sock.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 4096)
        sock.settimeout(2.0)
        sock.connect((host, port))
        sock.settimeout(0.05)
        with contextlib.suppress(OSError):  # full buffers, or dropped: it never reads anyway
            sock.sendall(b"*IDN?;*IDN?;*IDN?;*IDN?\n" * 200)  # 150 kB of replies
        crowd.append(sock)
    return crowd


@pytest.mark.slow
def test_200_connections_half_not_reading_do_not_lock_out_a_new_client() -> None:
    """200 clients held open at once, 100 of them flooding queries without reading a reply: a
    new connection's ``*IDN?`` is answered at once; connections, threads and memory stay
    bounded."""
    with SimulatedAnalyserServer("table") as server:
        host, port = server.socket_resource.split("::")[1:3]
        probe = connect(host, int(port))
        assert b"35670A" in ask(probe, b"*IDN?")
        probe.close()
        before = rss_kib(os.getpid())
        start = time.monotonic()
        crowd = []
        for _ in range(50):  # idle and non-reading clients interleaved
            crowd += _crowd_of_non_readers(host, int(port), 2)
            crowd += [connect(host, int(port)) for _ in range(2)]
        built_s = time.monotonic() - start
        newcomer = connect(host, int(port))
        asked = time.monotonic()
        answer = ask(newcomer, b"*IDN?")
        answered_s = time.monotonic() - asked
        served, threads = len(server._connections), threading.active_count()
        after = rss_kib(os.getpid())
        for sock in (*crowd, newcomer):
            sock.close()
    print(f"\n200 connections in {built_s:.2f} s ({server.evicted} dropped for a newer one); "
          f"*IDN? answered in {1000 * answered_s:.1f} ms; {threads} threads; "
          f"RSS {before} -> {after} KiB")
    assert b"35670A" in answer
    assert answered_s < 5.0  # about 0.03 s alone, up to 1 s on a loaded 2-core machine
    assert served <= server.limits.max_connections
    assert threads < 8 + 2 * server.limits.max_connections
    assert after - before < 16 * 1024, (before, after)


def test_50_slowloris_connections_do_not_lock_out_a_new_client() -> None:
    """50 clients each dripping a message one byte at a time: a new ``*IDN?`` is answered."""
    with SimulatedAnalyserServer("table") as server:
        host, port = server.socket_resource.split("::")[1:3]
        drips = [connect(host, int(port)) for _ in range(50)]
        for _ in range(3):  # bounded: three drips each, 50 ms apart
            for sock in drips:
                with contextlib.suppress(OSError):
                    sock.sendall(b"*")
            time.sleep(0.05)
        newcomer = connect(host, int(port))
        asked = time.monotonic()
        answer = ask(newcomer, b"*IDN?")
        answered_s = time.monotonic() - asked
        threads = threading.active_count()
        served = len(server._connections)
        for sock in (*drips, newcomer):
            sock.close()
    assert b"35670A" in answer and answered_s < 2.0
    assert served <= server.limits.max_connections
    assert threads < 8 + 2 * server.limits.max_connections


def test_a_message_begun_and_never_ended_closes_its_connection() -> None:
    """A client dripping bytes of one message is closed once the message is older than
    ``message_timeout_s``, though it is never silent for the idle time-out."""
    limits = ServiceLimits(message_timeout_s=0.5, idle_timeout_s=5.0)
    with SimulatedAnalyserServer("table", limits=limits) as server:
        host, port = server.socket_resource.split("::")[1:3]
        drip = connect(host, int(port))
        start = time.monotonic()
        closed = False
        for _ in range(40):  # at most 4 s
            try:
                drip.sendall(b"*")
            except OSError:
                closed = True
                break
            if closed_by_peer(drip, 0.1):
                closed = True
                break
        elapsed = time.monotonic() - start
        drip.close()
        other = connect(host, int(port))
        assert b"35670A" in ask(other, b"*IDN?")
        other.close()
    assert closed and 0.4 < elapsed < 2.0, elapsed


def test_a_crowd_behind_the_prologix_adapter_does_not_lock_out_a_new_client() -> None:
    """The Prologix endpoint shares the slots: 12 adapters each left with half a message, and a
    new one's ``*IDN?`` is answered."""
    with SimulatedAnalyserServer("table", prologix=True) as server:
        host, port = server.prologix_resource.split("::")[1:3]
        crowd = [connect(host, int(port)) for _ in range(12)]
        for sock in crowd:
            sock.sendall(b"++addr 11\n*ID")
        time.sleep(0.1)
        newcomer = connect(host, int(port))
        answer = ask(newcomer, b"++addr 11\n*IDN?\n++read eoi")
        served = len(server._connections)
        for sock in (*crowd, newcomer):
            sock.close()
    assert b"35670A" in answer
    assert served <= server.limits.max_connections
