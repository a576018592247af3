"""The controller: typed reads and writes of the parameters a chamber needs, with limits.

Every value crosses the wire as one 16-bit holding register (function 3 to read, 6 to write),
a two's-complement integer scaled by the decimal places the instrument is configured for
(``decimals``, 1 by default). A set point is only ever written within the limits the driver was
opened with (``limits_c``): the station's, not the controller's much wider range.
"""

from __future__ import annotations

import logging
import math
from dataclasses import dataclass
from typing import Any

from eurotherm3200.errors import (
    BadReplyError,
    ChamberError,
    NoReplyError,
    SensorBreakError,
    SetPointRefusedError,
)
from eurotherm3200.registers import PARAMETERS, SENSOR_BREAK_BIT

__all__ = ["Eurotherm3200", "Link", "parse_address"]

_EXCEPTIONS = {1: "illegal function", 2: "illegal data address", 3: "illegal data value",
               4: "device failure", 6: "device busy"}


@dataclass(frozen=True)
class Link:
    """Where a controller is: ``kind`` "tcp" (``host``, ``port``) or "rtu" (serial ``port``)."""

    kind: str
    host: str = ""
    port: int | str = 502

    def __str__(self) -> str:
        return f"tcp://{self.host}:{self.port}" if self.kind == "tcp" else str(self.port)


def parse_address(address: str) -> Link:
    """A controller's address: ``tcp://HOST:PORT`` (Modbus TCP, port 502 if left out) or a
    serial port (``/dev/ttyUSB0``, ``COM3``: Modbus RTU).

    Raises
    ------
    ValueError
        Not an address of either kind.
    """
    if not isinstance(address, str) or not address.strip():
        raise ValueError(f"expected tcp://HOST:PORT or a serial port, got {address!r}")
    if address.startswith("tcp://"):
        rest = address[len("tcp://"):]
        host, _, port = rest.rpartition(":") if ":" in rest else (rest, "", "502")
        if not host or not port.isdigit() or not 0 < int(port) < 65536:
            raise ValueError(f"{address!r} is not tcp://HOST:PORT")
        return Link("tcp", host, int(port))
    if "://" in address:
        raise ValueError(f"{address!r}: only tcp:// or a serial port")
    return Link("rtu", port=address)


class Eurotherm3200:
    """A connected Eurotherm 3200-class controller (module text).

    Use :meth:`open`. ``unit`` is the controller's Modbus address; ``specimen_unit`` that of a
    second 3200 on the same line whose thermocouple is on the specimens (None: the controller's
    own thermocouple stands for the specimens).
    """

    def __init__(self, client: Any, link: Link, *, unit: int, specimen_unit: int | None,
                 limits_c: tuple[float, float], decimals: int) -> None:
        self._client = client
        self.link = link
        self.unit = unit
        self.specimen_unit = specimen_unit
        self.limits_c = limits_c
        self.decimals = decimals

    @classmethod
    def open(cls, address: str, *, unit: int = 1, specimen_unit: int | None = None,
             limits_c: tuple[float, float] = (-40.0, 150.0), timeout_s: float = 1.0,
             retries: int = 1, baudrate: int = 19200, decimals: int = 1) -> Eurotherm3200:
        """Connect and check that the controller answers (reads its process value).

        Parameters
        ----------
        address
            ``tcp://HOST:PORT`` or a serial port (:func:`parse_address`).
        unit, specimen_unit
            Modbus unit addresses (1-247).
        limits_c
            No set point outside ``[low, high]`` °C is ever written.
        timeout_s, retries
            Per request.
        baudrate
            RTU only (8 data bits, no parity, 1 stop bit: the 3200's default framing).
        decimals
            Decimal places the instrument is configured for.

        Raises
        ------
        ValueError
            A bad address, unit or limits.
        ChamberError
            The controller cannot be reached or does not answer.
        """
        from pymodbus.client import ModbusSerialClient, ModbusTcpClient

        # the errors raised here say what went wrong in one line; the library's log would
        # repeat it with frame dumps on stderr
        logging.getLogger("pymodbus").setLevel(logging.CRITICAL)
        link = parse_address(address)
        for name, value in (("unit", unit), ("specimen_unit", specimen_unit)):
            if value is not None and not (isinstance(value, int) and 1 <= value <= 247):
                raise ValueError(f"{name} must be a Modbus address 1-247, not {value!r}")
        low, high = limits_c
        if not (math.isfinite(low) and math.isfinite(high) and low < high):
            raise ValueError(f"limits_c must be [low, high] with low < high, not {limits_c!r}")
        client: ModbusTcpClient | ModbusSerialClient
        if link.kind == "tcp":
            client = ModbusTcpClient(link.host, port=int(link.port), timeout=timeout_s,
                                     retries=retries, reconnect_delay=0.0)
        else:
            client = ModbusSerialClient(str(link.port), baudrate=baudrate, bytesize=8,
                                        parity="N", stopbits=1, timeout=timeout_s,
                                        retries=retries, reconnect_delay=0.0)
        if not client.connect():
            client.close()
            raise NoReplyError(f"temperature controller {link}: cannot connect")
        controller = cls(client, link, unit=unit, specimen_unit=specimen_unit,
                         limits_c=(float(low), float(high)), decimals=decimals)
        try:
            controller.read("PV.IN")
        except ChamberError:
            controller.close()
            raise
        return controller

    def close(self) -> None:
        """Close the link (the controller keeps its set point)."""
        self._client.close()

    def __enter__(self) -> Eurotherm3200:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    # ------------------------------------------------------------------ registers

    def _where(self, mnemonic: str, unit: int) -> str:
        address = PARAMETERS[mnemonic].address
        return f"temperature controller {self.link} unit {unit}, {mnemonic} (address {address})"

    def read_word(self, mnemonic: str, unit: int | None = None) -> int:
        """The raw 16-bit word of a parameter."""
        from pymodbus.exceptions import ModbusException

        unit = self.unit if unit is None else unit
        parameter = PARAMETERS[mnemonic]
        try:
            reply = self._client.read_holding_registers(parameter.address, count=1,
                                                        device_id=unit)
        except ModbusException as error:
            raise self._link_error(mnemonic, unit, error) from None
        return self._check(reply, mnemonic, unit)[0]

    def _check(self, reply: Any, mnemonic: str, unit: int) -> list[int]:
        where = self._where(mnemonic, unit)
        if reply is None:
            raise NoReplyError(f"{where}: no reply")
        if reply.isError():
            code = getattr(reply, "exception_code", None)
            what = _EXCEPTIONS.get(code, f"exception {code}") if code else str(reply)
            raise BadReplyError(f"{where}: the controller refused the request ({what})")
        registers = list(getattr(reply, "registers", []) or [])
        if len(registers) != 1 or not 0 <= registers[0] <= 0xFFFF:
            raise BadReplyError(f"{where}: expected one 16-bit register, got {registers!r}")
        return registers

    def _link_error(self, mnemonic: str, unit: int, error: Exception) -> ChamberError:
        text = " ".join(str(error).split())
        where = self._where(mnemonic, unit)
        if "No response" in text or "cannot connect" in text.lower() or "Connection" in text:
            return NoReplyError(f"{where}: no valid reply (is the controller on, at this "
                                f"address and baud rate?)")
        return BadReplyError(f"{where}: bad reply ({text})")

    def read(self, mnemonic: str, unit: int | None = None) -> float:
        """A parameter's value in engineering units (scaled ones divided by 10^decimals)."""
        word = self.read_word(mnemonic, unit)
        parameter = PARAMETERS[mnemonic]
        if not parameter.scaled:
            return float(word)
        signed = word - 0x10000 if word & 0x8000 else word
        return signed / 10.0**self.decimals

    def write(self, mnemonic: str, value: float) -> None:
        """Write a writable scaled parameter of the controller (not limit-checked: use
        :meth:`set_target`)."""
        from pymodbus.exceptions import ModbusException

        parameter = PARAMETERS[mnemonic]
        if not parameter.writable:
            raise ValueError(f"{mnemonic} is read-only")
        word = round(value * 10.0**self.decimals)
        if not -0x8000 <= word <= 0x7FFF:
            raise SetPointRefusedError(f"{self._where(mnemonic, self.unit)}: {value:g} does not "
                                  f"fit a 16-bit register at {self.decimals} decimal(s)")
        try:
            reply = self._client.write_register(parameter.address, word & 0xFFFF,
                                                device_id=self.unit)
        except ModbusException as error:
            raise self._link_error(mnemonic, self.unit, error) from None
        where = self._where(mnemonic, self.unit)
        if reply is None:
            raise NoReplyError(f"{where}: no reply")
        if reply.isError():
            code = getattr(reply, "exception_code", None)
            what = _EXCEPTIONS.get(code, f"exception {code}") if isinstance(code, int) \
                else f"exception {code}"
            raise SetPointRefusedError(f"{where}: the controller refused {value:g} ({what})")

    # ------------------------------------------------------------------ the chamber

    def status(self, unit: int | None = None) -> int:
        """The instrument status bitmap (StAt)."""
        return self.read_word("StAt", unit)

    def _temperature(self, unit: int, which: str) -> float:
        if self.status(unit) & (1 << SENSOR_BREAK_BIT):
            raise SensorBreakError(f"temperature controller {self.link} unit {unit}: sensor break "
                              f"on the {which} thermocouple")
        return self.read("PV.IN", unit)

    def air_c(self) -> float:
        """The controller's own thermocouple (the chamber air), °C.

        Raises
        ------
        SensorBreakError
            The thermocouple is broken.
        """
        return self._temperature(self.unit, "chamber")

    def specimen_c(self) -> float:
        """The specimen thermocouple (``specimen_unit``), else the chamber's, °C."""
        if self.specimen_unit is None:
            return self.air_c()
        return self._temperature(self.specimen_unit, "specimen")

    def target_c(self) -> float:
        return self.read("TG.SP")

    def working_set_point_c(self) -> float:
        return self.read("WKG.SP")

    def output_percent(self) -> float:
        return self.read("WRK.OP")

    def rate_limit_c_per_min(self) -> float:
        return self.read("SP.RAT")

    def range_c(self) -> tuple[float, float]:
        """The controller's input range (RNG.LO, RNG.HI)."""
        return self.read("RNG.LO"), self.read("RNG.HI")

    def set_target(self, temperature_c: float) -> None:
        """Write the target set point.

        Raises
        ------
        SetPointRefusedError
            Outside ``limits_c`` (nothing is written) or refused by the controller.
        """
        low, high = self.limits_c
        if not (math.isfinite(temperature_c) and low <= temperature_c <= high):
            raise SetPointRefusedError(f"temperature controller {self.link}: set point "
                                  f"{temperature_c:g} °C is outside the limits "
                                  f"[{low:g}, {high:g}] °C; nothing written")
        self.write("TG.SP", temperature_c)

    def set_rate_limit(self, rate_c_per_min: float) -> None:
        """Write the set-point rate limit, °C/min (0: none)."""
        if not (math.isfinite(rate_c_per_min) and rate_c_per_min >= 0.0):
            raise SetPointRefusedError(f"temperature controller {self.link}: rate limit "
                                  f"{rate_c_per_min:g} °C/min must be >= 0")
        self.write("SP.RAT", rate_c_per_min)
