"""The simulated analyser's servers: Prologix GPIB-Ethernet and GPIB-USB (pty) paths through
pyvisa-py, the adapter protocol byte for byte, query latency, and ``viscorig sim serve``."""

from __future__ import annotations

import os
import re
import signal
import socket
import subprocess
import sys
import time

import numpy as np
import pytest
import pyvisa
from rigsim.server import SimulatedAnalyserServer

MARKER = -3.40282346639e38  # the analyser's no-data value
SWEEP = ("*RST;*CLS;:INST:SEL SINE;:INP3 ON;:INP4 ON;:REF PAIR;:FREQ:STAR 20;STOP 120;"
         ":FREQ:RES:AUTO OFF;"
         ":FREQ:RES 11 PNT/SWP;:SWE:STIM 10 CYCLE;DWEL 10 CYCLE;:SOUR:VOLT 0.3 VPK;"
         ":CALC1:FEED 'XFR:POW:RAT 4,3';:CALC1:FORM NYQ")


@pytest.fixture(scope="module")
def server():
    with SimulatedAnalyserServer("soft-0", prologix=True, seed=2) as srv:
        yield srv


@pytest.fixture
def rm():
    manager = pyvisa.ResourceManager("@py")
    yield manager
    manager.close()


def open_gpib(rm, interface: str, timeout_ms: int = 5000):
    adapter = rm.open_resource(interface, timeout=timeout_ms)
    instrument = rm.open_resource("GPIB0::11::INSTR", timeout=timeout_ms)
    return adapter, instrument


def query(instrument, message: str) -> str:
    """GPIB sessions behind a Prologix adapter keep the line feed (no TERMCHAR attribute)."""
    return instrument.query(message).rstrip("\n")


def real64(instrument, message: str) -> np.ndarray:
    return instrument.query_binary_values(message, datatype="d", is_big_endian=True,
                                          container=np.array)


def test_resource_strings(server) -> None:
    assert re.fullmatch(r"TCPIP::127\.0\.0\.1::\d+::SOCKET", server.socket_resource)
    assert re.fullmatch(r"PRLGX-TCPIP::127\.0\.0\.1::\d+::INTFC", server.prologix_resource)
    assert server.resource == "GPIB0::11::INSTR"
    assert server.resources == (server.prologix_resource, "GPIB0::11::INSTR")


def test_prologix_tcp_path_reads_the_same_data_as_the_socket(rm, server) -> None:
    adapter, gpib = open_gpib(rm, server.prologix_resource)
    try:
        assert "35670A" in query(gpib, "*IDN?")
        gpib.write(SWEEP)
        gpib.write("FORM REAL,64;:ABOR;:INIT")
        assert query(gpib, "*OPC?") == "+1"
        gpib.write("TRAC:DATA D1,TRAC1")
        through_gpib = real64(gpib, "TRAC:DATA? D1")
        x = real64(gpib, "TRAC:X? D1")
        gpib.write("FREQ:STAR +20.5 HZ")  # '+' travels ESC-escaped through the adapter
        assert float(query(gpib, "FREQ:STAR?")) == 20.5
        assert query(gpib, "SYST:ERR?") == '+0,"No error"'
    finally:
        gpib.close()
        adapter.close()
    socket_session = rm.open_resource(server.socket_resource, read_termination="\n",
                                      write_termination="\n", timeout=5000)
    socket_session.write("FORM ASC,12")
    through_socket = np.array(socket_session.query("TRAC:DATA? D1").split(","), float)
    socket_session.close()
    # 11 measured points in a trace of 401: the rest holds the no-data marker (X included)
    assert x.size == 401 and through_gpib.size == 802
    np.testing.assert_allclose(x[:11], np.linspace(20, 120, 11))
    assert np.all(x[11:] == MARKER) and np.all(through_gpib[22:] == MARKER)
    np.testing.assert_allclose(through_socket, through_gpib, rtol=1e-10)


def test_prologix_binary_block_with_line_feeds_inside(rm, server) -> None:
    """Block bytes equal to LF must not end the read early on the Prologix path."""
    adapter, gpib = open_gpib(rm, server.prologix_resource)
    try:
        gpib.write(SWEEP + ";:FORM REAL,32;:FREQ:RES 401 PNT/SWP;:ABOR;:INIT")
        assert query(gpib, "*OPC?") == "+1"
        values = gpib.query_binary_values("CALC1:X:DATA?", datatype="f", is_big_endian=True,
                                          container=np.array)
        # 401 points on the 15.625 mHz grid: 0.25 Hz apart
        np.testing.assert_allclose(values, np.linspace(20, 120, 401), rtol=1e-7)
    finally:
        gpib.close()
        adapter.close()


class RawAdapter:
    """A bare TCP client of the Prologix endpoint, to check the protocol byte for byte."""

    def __init__(self, server: SimulatedAnalyserServer) -> None:
        host, port = server.prologix_resource.split("::")[1:3]
        self.sock = socket.create_connection((host, int(port)), timeout=3)
        self.sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
        self.buffer = b""

    def send(self, data: bytes) -> None:
        self.sock.sendall(data)

    def line(self) -> bytes:
        while b"\n" not in self.buffer:
            chunk = self.sock.recv(4096)
            if not chunk:
                raise ConnectionError("closed")
            self.buffer += chunk
        line, _, self.buffer = self.buffer.partition(b"\n")
        return line.rstrip(b"\r")

    def nothing_within(self, seconds: float) -> bool:
        self.sock.settimeout(seconds)
        try:
            return not self.buffer and not self.sock.recv(4096)
        except TimeoutError:
            return True
        finally:
            self.sock.settimeout(3)

    def query(self, message: bytes) -> bytes:
        self.send(message + b"\n++read eoi\n")
        return self.line()

    def close(self) -> None:
        self.sock.close()


def test_adapter_commands_as_pyvisa_py_sends_them(server) -> None:
    raw = RawAdapter(server)
    try:
        raw.send(b"++mode 1\n++auto 0\n++read_tmo_ms 50\n++eos 3\n++eoi 1\n++eot_enable 0\n")
        raw.send(b"++addr 11\n")
        raw.send(b"++addr\n")
        assert raw.line() == b"11"
        raw.send(b"++ver\n")
        assert b"Prologix" in raw.line()
        assert b"35670A" in raw.query(b"*IDN?")
        # ESC-escaped bytes are data: a literal '+' and ';' inside one message
        assert raw.query(b"*CLS;:SOUR:VOLT \x1b+0.25;:SOUR:VOLT?") == b"+2.50000000000E-001"
        # a response nobody reads, then a new message: IEEE 488.2 query interrupted
        raw.send(b"*IDN?\n*ESR?\n")
        assert raw.query(b"SYST:ERR?") == b'-410,"Query INTERRUPTED"'  # *IDN? lost to *ESR?
        assert raw.query(b"SYST:ERR?") == b'-410,"Query INTERRUPTED"'  # *ESR? lost to SYST:ERR?
        assert raw.query(b"SYST:ERR?") == b'+0,"No error"'
        # ++read with nothing to say: query unterminated, and no bytes
        raw.send(b"++read eoi\n")
        assert raw.nothing_within(1.5)
        assert raw.query(b"SYST:ERR?") == b'-420,"Query UNTERMINATED"'
        # serial poll: message available once a response waits
        raw.send(b"*IDN?\n++spoll\n")
        assert int(raw.line()) & 16
        raw.send(b"++read eoi\n")
        assert b"35670A" in raw.line()
        # another address: nobody listens
        raw.send(b"++addr 5\n*IDN?\n++read eoi\n")
        assert raw.nothing_within(0.3)
        raw.send(b"++addr 11\n")
        # ++auto 1 reads after every write
        raw.send(b"++auto 1\n*IDN?\n")
        assert b"35670A" in raw.line()
        raw.send(b"++auto 0\n")
    finally:
        raw.close()


def test_device_clear_ends_a_waiting_opc_query(rm) -> None:
    with SimulatedAnalyserServer("soft-0", prologix=True, pace=20.0) as paced:
        raw = RawAdapter(paced)
        try:
            raw.send(b"++addr 11\n")
            long_sweep = SWEEP + ";:SWE:STIM 200 CYCLE;DWEL 200 CYCLE"  # about 3.5 s at pace 20
            raw.send(long_sweep.encode().replace(b"+", b"\x1b+") + b";:ABOR;:INIT\n")
            raw.send(b"*OPC?\n++read eoi\n")
            assert raw.nothing_within(1.2)  # the device is still measuring
            raw.send(b"++clr\n")
            raw.send(b"++read eoi\n")
            assert raw.nothing_within(1.2)  # the *OPC? answer is gone with the clear
            assert int(raw.query(b"STAT:OPER:COND?")) & 16  # the sweep itself goes on
            raw.send(b"ABOR\n")
        finally:
            raw.close()


def test_prologix_faults(rm, server) -> None:
    adapter, gpib = open_gpib(rm, server.prologix_resource, timeout_ms=500)
    try:
        server.faults.no_reply("*IDN?")
        with pytest.raises(pyvisa.errors.VisaIOError):
            gpib.query("*IDN?")
        server.faults.garble_reply()
        assert "35670A" not in gpib.query("*IDN?")
        assert "35670A" in gpib.query("*IDN?")
        server.faults.drop_connection()
        with pytest.raises(pyvisa.errors.VisaIOError):
            gpib.query("*IDN?")
    finally:
        gpib.close()
        adapter.close()


def test_pty_path_through_pyserial(rm) -> None:
    if not hasattr(os, "openpty"):
        pytest.skip("no pseudo-terminals on this system")
    try:
        srv = SimulatedAnalyserServer("soft-0", pty=True, seed=1).start()
    except OSError as error:
        pytest.skip(f"pseudo-terminal not available: {error}")
    try:
        assert srv.pty_resource.startswith("PRLGX-ASRL::/dev/")
        adapter, gpib = open_gpib(rm, srv.pty_resource)
        try:
            assert "35670A" in query(gpib, "*IDN?")
            gpib.write(SWEEP + ";:FORM REAL,64;:ABOR;:INIT")
            assert query(gpib, "*OPC?") == "+1"
            values = real64(gpib, "CALC1:DATA?")
            assert values.size == 802 and np.all(np.abs(values[:22]) < 1e30)
            assert np.all(values[22:] == MARKER)
            assert query(gpib, "SYST:ERR?") == '+0,"No error"'
        finally:
            gpib.close()
            adapter.close()
    finally:
        srv.close()


def median_latency_ms(session, message: str, count: int = 200) -> float:
    times = []
    for _ in range(count):
        start = time.perf_counter()
        session.query(message)
        times.append(time.perf_counter() - start)
    return 1000 * float(np.median(times))


def test_query_latency_stays_low(rm, server) -> None:
    """Thousands of queries of a campaign must take seconds: no delayed ACKs, no sleeps."""
    sock = rm.open_resource(server.socket_resource, read_termination="\n",
                            write_termination="\n", timeout=5000)
    socket_ms = median_latency_ms(sock, "STAT:OPER:COND?")
    sock.close()
    adapter, gpib = open_gpib(rm, server.prologix_resource)
    prologix_ms = median_latency_ms(gpib, "STAT:OPER:COND?")
    gpib.close()
    adapter.close()
    assert socket_ms < 5.0, socket_ms
    assert prologix_ms < 10.0, prologix_ms


# --------------------------------------------------------------------------------------------
# command line


def viscorig(*args: str, **kwargs) -> subprocess.Popen:
    code = "import sys; from viscorig.cli import main; sys.exit(main(sys.argv[1:]))"
    return subprocess.Popen([sys.executable, "-c", code, *args], stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True, **kwargs)


def test_cli_serves_until_interrupted(rm) -> None:
    process = viscorig("sim", "serve", "--preset", "table", "--prologix",
                       "--fault", "error=-310,System error; injected")
    try:
        lines = [process.stdout.readline() for _ in range(3)]
        socket_resource = re.search(r"TCPIP::\S+::SOCKET", lines[1]).group(0)
        interface = re.search(r"PRLGX-TCPIP::\S+::INTFC", lines[2]).group(0)
        inst = rm.open_resource(socket_resource, read_termination="\n",
                                write_termination="\n", timeout=5000)
        assert inst.query("SYST:ERR?") == '-310,"System error; injected"'
        inst.close()
        adapter, gpib = open_gpib(rm, interface)
        assert "35670A" in query(gpib, "*IDN?")
        gpib.close()
        adapter.close()
    finally:
        process.send_signal(signal.SIGINT)
        assert process.wait(10) == 0


@pytest.mark.slow
@pytest.mark.parametrize(("args", "message"), [
    (("--rig", "/no/such/rig.toml"), "cannot read rig file"),
    (("--preset", "nonesuch"), "no rig preset"),
    (("--fault", "sparks"), "unknown fault"),
    (("--pace", "-1"), "must be positive"),
])
def test_cli_bad_input_is_one_line_and_exit_2(args, message) -> None:
    process = viscorig("sim", "serve", *args)
    _, err = process.communicate(timeout=30)
    assert process.returncode == 2
    assert message in err and len(err.strip().splitlines()) == 1 and "Traceback" not in err
