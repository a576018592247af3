"""Driver for Eurotherm 3200-class temperature controllers (3216, 3208, 3204, 32h8) over Modbus
RTU (a serial line, pyserial) or Modbus TCP (a gateway), with pymodbus.

::

    from eurotherm3200 import Eurotherm3200

    with Eurotherm3200.open("/dev/ttyUSB0", unit=1, specimen_unit=2,
                            limits_c=(-40.0, 90.0)) as chamber:
        chamber.set_rate_limit(2.0)                  # °C/min
        chamber.set_target(-20.0)
        print(chamber.air_c(), chamber.specimen_c())

The register map is :data:`eurotherm3200.registers.PARAMETERS` (from the 3200 Series
Engineering Handbook). The driver knows nothing of viscorig.
"""

from eurotherm3200.controller import Eurotherm3200, parse_address
from eurotherm3200.errors import (
           BadReplyError,
           ChamberError,
           NoReplyError,
           SensorBreakError,
           SetPointRefusedError,
)
from eurotherm3200.registers import PARAMETERS, SENSOR_BREAK_BIT, Parameter

__all__ = ["PARAMETERS", "SENSOR_BREAK_BIT", "BadReplyError", "ChamberError", "Eurotherm3200",
           "NoReplyError", "Parameter", "SensorBreakError", "SetPointRefusedError",
           "parse_address"]
