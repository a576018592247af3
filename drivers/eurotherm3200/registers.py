"""The Eurotherm 3200 series' Modbus parameters that a chamber needs, as its manual gives them.

Source: Eurotherm 3200 Series Engineering Handbook (HA028651), section "Parameter Modbus
Addresses". Every parameter is one 16-bit holding register read with function 3 and written
with function 6. Values are signed integers scaled by the instrument's configured decimal
places (one by default: 25.0 °C is 250); the set-point rate limit is in display units per
minute (the default ramp units) with the same scaling; outputs are in % (heat positive, cool
negative on a heat/cool instrument).
"""

from __future__ import annotations

from dataclasses import dataclass

__all__ = ["PARAMETERS", "SENSOR_BREAK_BIT", "Parameter"]


@dataclass(frozen=True)
class Parameter:
    """One parameter: its mnemonic on the instrument's display, its Modbus address, whether it
    may be written, and whether it is scaled by the decimal places."""

    mnemonic: str
    address: int
    writable: bool
    scaled: bool
    meaning: str


#: The parameters the driver uses, by name.
PARAMETERS: dict[str, Parameter] = {p.mnemonic: p for p in (
    Parameter("PV.IN", 1, False, True, "process value (the controller's thermocouple), °C"),
    Parameter("TG.SP", 2, True, True, "target set point, °C"),
    Parameter("WRK.OP", 4, False, True, "working output, % (heat +, cool -)"),
    Parameter("WKG.SP", 5, False, True, "working set point (ramping towards TG.SP), °C"),
    Parameter("RNG.LO", 11, False, True, "input range low limit, °C"),
    Parameter("RNG.HI", 12, False, True, "input range high limit, °C"),
    Parameter("SP.RAT", 35, True, True, "set-point rate limit, °C/min (0: no limit)"),
    Parameter("StAt", 75, False, False, "instrument status bitmap"),
)}

#: Bit of the instrument status (StAt, address 75) set on a sensor break.
SENSOR_BREAK_BIT = 5
#: Bit of the instrument status set when the PV is over its range by more than 5 % of span.
PV_OVER_RANGE_BIT = 10
