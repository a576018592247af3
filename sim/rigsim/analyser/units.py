"""Amplitude units of the 35670A and their conversions (programming guide, chapters 18, 19).

Levels (source level and limit, auto-level reference and input limit, input range) accept
``DBVRMS``, ``VPK``, ``DBVPK``, ``V``, ``DBV``, ``VRMS`` and, where an input is in engineering
units, ``EU`` and ``DBEU``. Inside the simulator every level is volts peak; the unit a level was
last set in is kept so that its query answers in that unit and ``? UNIT`` names it.

``V`` is read as volts peak and ``DBV`` as dB re 1 V peak: the manual lists them beside
``VPK``/``DBVPK`` without defining them, and the source limit's upper bound (13.9794 dB) is 5 Vpk
in dB re 1 V peak **(inferred)**. ``EU`` is engineering units peak on the channel concerned.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from rigsim.scpi import ScpiError

__all__ = ["LEVEL_UNITS", "VOLT_UNITS", "Level", "from_vpk", "to_vpk"]

#: Level units without engineering units, and with them.
VOLT_UNITS = ("DBVRMS", "VPK", "DBVPK", "V", "DBV", "VRMS")
LEVEL_UNITS = (*VOLT_UNITS, "EU", "DBEU")
_SQRT2 = math.sqrt(2.0)


def to_vpk(value: float, unit: str, v_per_eu: float | None = None) -> float:
    """Volts peak of ``value`` in ``unit`` (``v_per_eu``: the channel's sensitivity for EU)."""
    if unit in ("VPK", "V"):
        return value
    if unit == "VRMS":
        return value * _SQRT2
    if unit == "DBVRMS":
        return _SQRT2 * 10.0 ** (value / 20.0)
    if unit in ("DBVPK", "DBV"):
        return 10.0 ** (value / 20.0)
    if unit in ("EU", "DBEU"):
        if v_per_eu is None:
            raise ScpiError(-221, "EU units need an input in engineering units")
        eu = value if unit == "EU" else 10.0 ** (value / 20.0)
        return eu * v_per_eu
    raise ScpiError(-131, unit)


def from_vpk(vpk: float, unit: str, v_per_eu: float | None = None) -> float:
    """``vpk`` volts peak expressed in ``unit`` (dB units of 0 V give -9.9E37)."""
    if unit in ("VPK", "V"):
        return vpk
    if unit == "VRMS":
        return vpk / _SQRT2
    if unit in ("EU", "DBEU"):
        if v_per_eu is None or v_per_eu == 0:
            raise ScpiError(-221, "EU units need an input in engineering units")
        eu = vpk / v_per_eu
        if unit == "EU":
            return eu
        return 20.0 * math.log10(abs(eu)) if eu else -9.9e37
    if vpk <= 0.0:
        return -9.9e37
    if unit == "DBVRMS":
        return 20.0 * math.log10(vpk / _SQRT2)
    if unit in ("DBVPK", "DBV"):
        return 20.0 * math.log10(vpk)
    raise ScpiError(-131, unit)


@dataclass(frozen=True)
class Level:
    """A level as set: volts peak (``vpk``) and the unit it was given in (``unit``).

    For ``EU``/``DBEU`` levels the value in engineering units is kept too (``eu``), since the
    channel's sensitivity may change after the level is set.
    """

    vpk: float
    unit: str
    eu: float | None = None

    def value(self, v_per_eu: float | None = None) -> float:
        """The level in its own unit."""
        if self.unit == "EU" and self.eu is not None:
            return self.eu
        if self.unit == "DBEU" and self.eu is not None:
            return 20.0 * math.log10(self.eu) if self.eu > 0 else -9.9e37
        return from_vpk(self.vpk, self.unit, v_per_eu)

    def volts_peak(self, v_per_eu: float | None = None) -> float:
        """Volts peak now (EU levels follow the channel's sensitivity)."""
        if self.unit in ("EU", "DBEU") and self.eu is not None and v_per_eu is not None:
            return self.eu * v_per_eu
        return self.vpk
