"""The Eurotherm 3200 driver over real Modbus transports: loopback TCP and RTU on
pseudo-terminals, against the simulated chamber and against frames written by hand here.

The register addresses are the 3200 Series Engineering Handbook's (HA028651, "Parameter Modbus
Addresses"): PV.IN 1, TG.SP 2, WRK.OP 4, WKG.SP 5, RNG.LO 11, RNG.HI 12, SP.RAT 35, StAt 75
(bit 5 sensor break). They are pinned here as literals, for the driver and the simulator alike.
"""

from __future__ import annotations

import os
import select
import threading
import time
import tty

import pytest
from eurotherm3200 import (
    PARAMETERS,
    SENSOR_BREAK_BIT,
    BadReplyError,
    Eurotherm3200,
    NoReplyError,
    SensorBreakError,
    SetPointRefusedError,
    parse_address,
)
from rigsim import chamber_server
from rigsim.chamber import Chamber, ChamberParameters
from rigsim.chamber_server import ChamberServer

MANUAL = {"PV.IN": 1, "TG.SP": 2, "WRK.OP": 4, "WKG.SP": 5, "RNG.LO": 11, "RNG.HI": 12,
          "SP.RAT": 35, "StAt": 75}
FAST = {"timeout_s": 0.3, "retries": 0}


def test_register_map_is_the_handbooks() -> None:
    assert {name: p.address for name, p in PARAMETERS.items()} == MANUAL
    assert SENSOR_BREAK_BIT == 5
    assert {name for name, p in PARAMETERS.items() if p.writable} == {"TG.SP", "SP.RAT"}
    simulated = {"PV.IN": chamber_server.PV, "TG.SP": chamber_server.TARGET,
                 "WRK.OP": chamber_server.OUTPUT, "WKG.SP": chamber_server.WORKING,
                 "RNG.LO": chamber_server.RANGE_LO, "RNG.HI": chamber_server.RANGE_HI,
                 "SP.RAT": chamber_server.RATE, "StAt": chamber_server.STATUS}
    assert simulated == MANUAL
    assert chamber_server.SENSOR_BREAK == 1 << 5


@pytest.mark.parametrize(("text", "kind", "where"), [
    ("tcp://127.0.0.1:5020", "tcp", "tcp://127.0.0.1:5020"),
    ("tcp://chamber.lab", "tcp", "tcp://chamber.lab:502"),
    ("/dev/ttyUSB0", "rtu", "/dev/ttyUSB0"),
])
def test_addresses(text: str, kind: str, where: str) -> None:
    link = parse_address(text)
    assert (link.kind, str(link)) == (kind, where)


@pytest.mark.parametrize("text", ["", "tcp://:502", "tcp://host:0", "udp://host:502"])
def test_bad_addresses(text: str) -> None:
    with pytest.raises(ValueError, match="tcp://"):
        parse_address(text)


# -- frames written by hand: the exact bytes on an RTU line ---------------------------------------

def _crc16(frame: bytes) -> bytes:
    """Modbus RTU CRC (polynomial 0xA001 reflected, initial 0xFFFF), low byte first."""
    crc = 0xFFFF
    for byte in frame:
        crc ^= byte
        for _ in range(8):
            crc = (crc >> 1) ^ 0xA001 if crc & 1 else crc >> 1
    return bytes([crc & 0xFF, crc >> 8])


class _HandController:
    """A controller on a pseudo-terminal that answers from a table of request -> reply frames
    (without CRC) and records the requests."""

    def __init__(self, replies: dict[bytes, bytes]) -> None:
        self.replies = replies
        self.requests: list[bytes] = []
        self.master, slave = os.openpty()
        tty.setraw(slave)
        self.path = os.ttyname(slave)
        self._slave = slave
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._serve, daemon=True)
        self._thread.start()

    def _serve(self) -> None:
        buffer = b""
        deadline = time.monotonic() + 20.0
        while not self._stop.is_set() and time.monotonic() < deadline:
            ready, _, _ = select.select([self.master], [], [], 0.05)
            if ready:
                buffer += os.read(self.master, 256)
            while len(buffer) >= 8:  # function 3 and 6 requests are 8 bytes long
                frame, buffer = buffer[:8], buffer[8:]
                assert frame[6:] == _crc16(frame[:6]), frame.hex()
                self.requests.append(frame[:6])
                reply = self.replies.get(frame[:6])
                if reply is not None:
                    os.write(self.master, reply + _crc16(reply))

    def close(self) -> None:
        self._stop.set()
        self._thread.join(2.0)
        for fd in (self.master, self._slave):
            os.close(fd)


def test_rtu_frames_by_hand() -> None:
    """Reading PV.IN of unit 1 is 01 03 0001 0001; 25.0 °C comes back as 250 (0x00FA); -20.0 °C
    as a target set point is written as 0xFF38 with function 6 and echoed."""
    replies = {
        bytes.fromhex("010300010001"): bytes.fromhex("010302 00FA".replace(" ", "")),
        bytes.fromhex("01030002 0001".replace(" ", "")): bytes.fromhex("010302FF38"),
        bytes.fromhex("01060002FF38"): bytes.fromhex("01060002FF38"),
        bytes.fromhex("0103004B0001"): bytes.fromhex("0103020020"),  # StAt: bit 5 set
    }
    hand = _HandController(replies)
    try:
        controller = Eurotherm3200.open(hand.path, unit=1, limits_c=(-40.0, 90.0), **FAST)
        assert hand.requests[0] == bytes.fromhex("010300010001")
        controller.set_target(-20.0)
        assert hand.requests[-1] == bytes.fromhex("01060002FF38")
        assert controller.target_c() == -20.0
        assert controller.read("PV.IN") == 25.0
        with pytest.raises(SensorBreakError, match="sensor break on the chamber thermocouple"):
            controller.air_c()
        controller.close()
    finally:
        hand.close()


# -- against the simulated chamber ------------------------------------------------------------

@pytest.fixture(params=["tcp", "rtu"])
def served(request):
    chamber = Chamber(ChamberParameters(start_temperature_c=23.0))
    with ChamberServer(chamber, transport=request.param) as server:
        yield chamber, server


def test_reads_and_writes(served) -> None:
    chamber, server = served
    with Eurotherm3200.open(server.address, unit=1, specimen_unit=2, limits_c=(-30.0, 90.0),
                            **FAST) as controller:
        assert controller.air_c() == 23.0 and controller.specimen_c() == 23.0
        assert controller.range_c() == (-70.0, 180.0)
        controller.set_rate_limit(2.0)
        controller.set_target(-20.0)
        assert chamber.target_c == -20.0 and chamber.rate_k_per_min == 2.0
        chamber.advance(900.0)
        # the working set point ramps at 2 °C/min: 23 - 30 = -7 °C after 15 min
        assert controller.working_set_point_c() == pytest.approx(-7.0, abs=0.05)
        air, specimen = controller.air_c(), controller.specimen_c()
        assert air < specimen < 23.0  # the specimens lag the air
        assert controller.output_percent() < 0.0  # cooling


def test_set_point_outside_limits_writes_nothing(served) -> None:
    chamber, server = served
    with Eurotherm3200.open(server.address, limits_c=(-30.0, 90.0), **FAST) as controller:
        requests = server.requests
        with pytest.raises(SetPointRefusedError, match=r"outside the limits \[-30, 90\]"):
            controller.set_target(95.0)
        assert server.requests == requests and chamber.target_c == 23.0
        wide = Eurotherm3200(controller._client, controller.link, unit=1, specimen_unit=None,
                             limits_c=(-500.0, 500.0), decimals=1)
        with pytest.raises(SetPointRefusedError, match="illegal data value"):
            wide.set_target(250.0)  # beyond the controller's own range: exception 3
        assert chamber.target_c == 23.0


def test_bad_reply_is_one_line(served) -> None:
    _, server = served
    with Eurotherm3200.open(server.address, **FAST) as controller:
        server.inject("garble")
        # TCP has no checksum: the corrupted function code is a bad reply; on RTU the CRC fails
        # and the frame is dropped, so it is no valid reply
        with pytest.raises((BadReplyError, NoReplyError)) as caught:
            controller.air_c()
        message = str(caught.value)
        assert "\n" not in message and "unit 1, StAt (address 75)" in message
        server.inject("none")
        assert controller.air_c() == 23.0  # the link recovers


def test_controller_that_stops_answering(served) -> None:
    _, server = served
    with Eurotherm3200.open(server.address, **FAST) as controller:
        server.inject("silent")
        started = time.monotonic()
        with pytest.raises(NoReplyError, match="no valid reply") as caught:
            controller.specimen_c()
        assert time.monotonic() - started < 2.0
        assert "\n" not in str(caught.value)


def test_no_controller_at_all() -> None:
    with pytest.raises(NoReplyError, match="cannot connect"):
        Eurotherm3200.open("tcp://127.0.0.1:1", **FAST)


def test_broken_specimen_thermocouple(served) -> None:
    chamber, server = served
    with Eurotherm3200.open(server.address, specimen_unit=2, **FAST) as controller:
        chamber.break_thermocouple("specimen")
        assert controller.air_c() == 23.0
        with pytest.raises(SensorBreakError, match="unit 2: sensor break on the specimen"):
            controller.specimen_c()
