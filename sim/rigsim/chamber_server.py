"""The simulated chamber's controllers as Modbus servers on loopback (TCP, or RTU on a
pseudo-terminal), with the registers of a Eurotherm 3200-class controller.

Two units answer on one line, as on a bench where a second 3200 serves as an indicator for the
specimen's own thermocouple:

- the *controller* (default unit 1): ``PV.IN`` (1) the air temperature, ``TG.SP`` (2) target
  set point (read/write), ``WRK.OP`` (4) output %, ``WKG.SP`` (5) working set point,
  ``RNG.LO``/``RNG.HI`` (11, 12) the range, ``SP.RAT`` (35) set-point rate limit in °C/min
  (read/write), ``StAt`` (75) status bitmap with bit 5 the sensor break;
- the *indicator* (default unit 2): ``PV.IN`` the specimen temperature, ``StAt`` its sensor
  break.

Values are 16-bit two's-complement integers scaled by the decimal places the instrument is
configured for (``decimals``: one, the instrument's default, is tenths). A target outside the
range is refused with exception 3 (illegal data value), a write to a read-only parameter with
exception 2. Every register is refreshed from the :class:`~rigsim.chamber.Chamber` when it is
read.

Faults (:meth:`ChamberServer.inject`): ``"silent"`` (no reply at all, the controller stops
answering), ``"garble"`` (replies with a corrupted byte), ``"none"``.

The register addresses are the simulator's own copy of the manual's table; the driver
(``eurotherm3200``) has its own, and the protocol tests pin both against the manual.
"""

from __future__ import annotations

import asyncio
import contextlib
import logging
import os
import select
import threading
import time
import tty
from functools import partial

from rigsim.chamber import Chamber

__all__ = ["ChamberServer"]

#: Registers served per unit (addresses 0..REGISTER_COUNT-1).
REGISTER_COUNT = 128
PV, TARGET, OUTPUT, WORKING, RANGE_LO, RANGE_HI, RATE, STATUS = 1, 2, 4, 5, 11, 12, 35, 75
WRITABLE = (TARGET, RATE)
SENSOR_BREAK = 1 << 5
FAULTS = ("none", "silent", "garble")


def quiet_library_log() -> None:
    """pymodbus logs every frame it drops; the simulator's own messages are enough."""
    logging.getLogger("pymodbus").setLevel(logging.CRITICAL)


def _word(value_c: float, decimals: int = 1) -> int:
    """A temperature as the instrument's 16-bit word (scaled by its decimal places, two's
    complement)."""
    return round(value_c * 10.0**decimals) & 0xFFFF


def _value(word: int, decimals: int = 1) -> float:
    return (word - 0x10000 if word & 0x8000 else word) / 10.0**decimals


class ChamberServer:
    """Serve a chamber's controller and indicator (module text) from a thread of its own.

    Parameters
    ----------
    chamber
        The thermal model the registers show and the writes drive.
    controller_unit, specimen_unit
        Modbus unit addresses (``specimen_unit`` None: no second thermocouple).
    transport
        ``"tcp"`` (``host``, ``port``; 0 a free port) or ``"rtu"`` (a pseudo-terminal pair; the
        client opens :attr:`serial_port`).
    pace
        Let the chamber's time follow the wall clock, ``pace`` simulated seconds per second
        (None: something else advances it, the rig simulator's test time).
    """

    def __init__(self, chamber: Chamber, *, controller_unit: int = 1,
                 specimen_unit: int | None = 2, transport: str = "tcp",
                 host: str = "127.0.0.1", port: int = 0, baudrate: int = 19200,
                 pace: float | None = None, decimals: int = 1) -> None:
        if transport not in ("tcp", "rtu"):
            raise ValueError(f"transport must be 'tcp' or 'rtu', not {transport!r}")
        self.chamber = chamber
        self.controller_unit = controller_unit
        self.specimen_unit = specimen_unit
        self.transport = transport
        self.host = host
        self.port = port
        self.baudrate = baudrate
        self.fault = "none"
        self.requests = 0
        self.serial_port: str | None = None
        self._loop: asyncio.AbstractEventLoop | None = None
        self._server = None
        self._thread: threading.Thread | None = None
        self._ready = threading.Event()
        self._error: BaseException | None = None
        self._bridge: _PtyBridge | None = None
        self.pace = pace
        self.decimals = decimals
        self._stop_clock = threading.Event()
        self._clock: threading.Thread | None = None

    # ------------------------------------------------------------------ lifecycle

    @property
    def address(self) -> str:
        """What a station names: ``tcp://HOST:PORT`` or the serial port."""
        if self.transport == "tcp":
            return f"tcp://{self.host}:{self.port}"
        return str(self.serial_port)

    def start(self) -> ChamberServer:
        """Start serving; returns when the server listens."""
        if self.transport == "rtu":
            self._bridge = _PtyBridge(self)
            self.serial_port = self._bridge.client_path
        self._thread = threading.Thread(target=self._run, name="chamber-modbus", daemon=True)
        self._thread.start()
        if not self._ready.wait(10.0):
            raise RuntimeError("the simulated chamber controller did not start")
        if self._error is not None:
            raise RuntimeError(f"the simulated chamber controller cannot serve: {self._error}")
        if self.pace is not None:
            self._clock = threading.Thread(target=self._tick, name="chamber-clock", daemon=True)
            self._clock.start()
        return self

    def _tick(self) -> None:
        """The chamber's time follows the wall clock at ``pace`` (``sim serve``)."""
        last = time.monotonic()
        while not self._stop_clock.wait(0.1):
            now = time.monotonic()
            self.chamber.advance((now - last) * float(self.pace or 0.0))
            last = now

    def close(self) -> None:
        """Stop serving and release the port or pseudo-terminals."""
        self._stop_clock.set()
        if self._clock is not None:
            self._clock.join(2.0)
        loop, server = self._loop, self._server
        if loop is not None and server is not None and loop.is_running():
            with contextlib.suppress(Exception):
                asyncio.run_coroutine_threadsafe(server.shutdown(), loop).result(5.0)
        if self._thread is not None:
            self._thread.join(5.0)
        if self._bridge is not None:
            self._bridge.close()

    def __enter__(self) -> ChamberServer:
        return self.start()

    def __exit__(self, *exc: object) -> None:
        self.close()

    def inject(self, fault: str) -> None:
        """Make the controller misbehave from now on (module text)."""
        if fault not in FAULTS:
            raise ValueError(f"fault must be one of {', '.join(FAULTS)}, not {fault!r}")
        self.fault = fault

    # ------------------------------------------------------------------ serving

    def _run(self) -> None:
        try:
            asyncio.run(self._serve())
        except BaseException as error:  # reported by start()
            self._error = error
            self._ready.set()

    def _devices(self) -> list:
        from pymodbus.simulator import DataType, SimData, SimDevice

        units = [(self.controller_unit, "air")]
        if self.specimen_unit is not None:
            units.append((self.specimen_unit, "specimen"))
        return [SimDevice(id=unit, simdata=[SimData(
            address=0, count=REGISTER_COUNT, values=0, datatype=DataType.REGISTERS)],
            action=partial(self._action, sensor)) for unit, sensor in units]

    async def _serve(self) -> None:
        from pymodbus.server import ModbusSerialServer, ModbusTcpServer

        quiet_library_log()
        self._loop = asyncio.get_running_loop()
        if self.transport == "tcp":
            server = ModbusTcpServer(self._devices(), address=(self.host, self.port),
                                     trace_packet=self._trace)
        else:
            assert self._bridge is not None
            server = ModbusSerialServer(self._devices(), port=self._bridge.server_path,
                                        baudrate=self.baudrate, trace_packet=self._trace)
        self._server = server
        await server.serve_forever(background=True)
        if self.transport == "tcp":
            self.port = server.transport.sockets[0].getsockname()[1]
        self._ready.set()
        with contextlib.suppress(asyncio.CancelledError):
            await server.serving

    def _trace(self, sending: bool, data: bytes) -> bytes:
        if not sending:
            return data
        if self.fault == "silent":
            return b""
        if self.fault == "garble" and data:
            # the function code (byte 7 of a TCP frame, 1 of an RTU frame; its CRC then fails)
            at = 7 if self.transport == "tcp" else 1
            return data[:at] + bytes([data[at] ^ 0x5A]) + data[at + 1:]
        return data

    async def _action(self, sensor: str, function_code: int, start_address: int,
                      address: int, count: int, registers: list[int],
                      values: list[int] | None):
        from pymodbus.constants import ExcCodes

        self.requests += 1
        chamber = self.chamber
        if values is not None and function_code in (6, 16):
            for offset, word in enumerate(values):
                where = address + offset
                if sensor != "air" or where not in WRITABLE:
                    return ExcCodes.ILLEGAL_ADDRESS
                value = _value(word, self.decimals)
                if where == TARGET:
                    p = chamber.parameters
                    if not p.low_limit_c <= value <= p.high_limit_c:
                        return ExcCodes.ILLEGAL_VALUE
                    chamber.set_target(value)
                elif value < 0.0:
                    return ExcCodes.ILLEGAL_VALUE
                else:
                    chamber.set_rate(value)
            return None
        broken = chamber.broken(sensor)
        reading = chamber.air_c if sensor == "air" else chamber.specimen_c
        p = chamber.parameters
        d = self.decimals
        fresh = {
            PV: _word(p.high_limit_c if broken else reading, d),
            RANGE_LO: _word(p.low_limit_c, d), RANGE_HI: _word(p.high_limit_c, d),
            STATUS: SENSOR_BREAK if broken else 0,
        }
        if sensor == "air":
            fresh |= {TARGET: _word(chamber.target_c, d),
                      OUTPUT: _word(chamber.output_percent, d),
                      WORKING: _word(chamber.working_c, d),
                      RATE: _word(chamber.rate_k_per_min, d)}
        for where, word in fresh.items():
            registers[where - start_address] = word
        return None


class _PtyBridge:
    """Two pseudo-terminals joined back to back (a null-modem cable): the server opens one
    end, the client the other; bytes are copied between them by a thread."""

    def __init__(self, owner: ChamberServer) -> None:
        self.owner = owner
        self._server_master, server_slave = os.openpty()
        self._client_master, client_slave = os.openpty()
        for fd in (server_slave, client_slave):
            tty.setraw(fd)
        self.server_path = os.ttyname(server_slave)
        self.client_path = os.ttyname(client_slave)
        self._slaves = (server_slave, client_slave)
        self._stop = os.pipe()
        self._thread = threading.Thread(target=self._copy, name="chamber-pty", daemon=True)
        self._thread.start()

    def _copy(self) -> None:
        pairs = {self._server_master: self._client_master,
                 self._client_master: self._server_master}
        while True:
            ready, _, _ = select.select([*pairs, self._stop[0]], [], [], 1.0)
            if self._stop[0] in ready:
                return
            for fd in ready:
                try:
                    data = os.read(fd, 4096)
                except OSError:
                    continue
                with contextlib.suppress(OSError):
                    os.write(pairs[fd], data)

    def close(self) -> None:
        os.write(self._stop[1], b"x")
        self._thread.join(2.0)
        for fd in (self._server_master, self._client_master, *self._slaves, *self._stop):
            with contextlib.suppress(OSError):
                os.close(fd)
