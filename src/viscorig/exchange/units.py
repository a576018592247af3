"""Unit labels met in exchange files, and their factors to the SI units viscorig stores.

Instruments and other programs spell units freely (``M/S2``, ``m/s^2``, ``g``, ``N``, ``lbf``).
A label is compared without spaces, as written; one written in a single case (``MPA``, ``hz``,
as instruments and old programs write them) is also compared case-insensitively. One in mixed
case that is not a known spelling (``mPa``, millipascal, is no ``MPa``) is refused, as is any
label not in these tables, rather than guessed: a wrong unit would make every value silently
wrong.
"""

from __future__ import annotations

from viscorig.errors import InputError

STANDARD_GRAVITY_M_PER_S2 = 9.80665
POUND_FORCE_N = 4.4482216152605

#: acceleration label -> factor to m/s²
ACCELERATION_UNITS = {
    "m/s^2": 1.0, "m/s2": 1.0, "m/s²": 1.0, "m/s/s": 1.0, "ms^-2": 1.0, "m/(s^2)": 1.0,
    "mm/s^2": 1e-3, "mm/s2": 1e-3, "mm/s²": 1e-3,
    "g": STANDARD_GRAVITY_M_PER_S2, "gn": STANDARD_GRAVITY_M_PER_S2,
}
#: velocity label -> factor to m/s
VELOCITY_UNITS = {"m/s": 1.0, "mm/s": 1e-3, "ms^-1": 1.0}
#: displacement label -> factor to m
DISPLACEMENT_UNITS = {"m": 1.0, "mm": 1e-3, "um": 1e-6, "µm": 1e-6}
#: force label -> factor to N
FORCE_UNITS = {"N": 1.0, "kN": 1e3, "lbf": POUND_FORCE_N, "lb": POUND_FORCE_N}
#: voltage label -> factor to V (an analyser channel with no engineering unit set)
VOLTAGE_UNITS = {"V": 1.0, "mV": 1e-3}
#: frequency label -> factor to Hz
FREQUENCY_UNITS = {"Hz": 1.0, "kHz": 1e3, "1/s": 1.0}


def normalised(label: str) -> str:
    """A label without spaces, in lower case (``"M/S2 "`` -> ``"m/s2"``)."""
    return "".join(str(label).split()).lower()


def lookup(label: str, table: dict[str, float]) -> float | None:
    """The factor of ``label`` in ``table`` as the module text compares labels, or ``None``."""
    key = "".join(str(label).split())
    if key in table:
        return table[key]
    if key not in (key.lower(), key.upper()):
        return None
    return next((value for known, value in table.items() if known.lower() == key.lower()),
                None)


def factor(label: str, table: dict[str, float], quantity: str, where: str) -> float:
    """The factor that turns a value in ``label`` into SI.

    Raises
    ------
    InputError
        The label is not a unit of ``quantity`` that viscorig knows.
    """
    value = lookup(label, table)
    if value is not None:
        return value
    known = ", ".join(sorted({k for k in table}))
    raise InputError(f"unit {label!r} is not a unit of {quantity} (known: {known}; case "
                     "counts where it is mixed: mPa is no MPa)", where)

#: modulus (stress) label -> factor to Pa
MODULUS_UNITS = {
    "Pa": 1.0, "kPa": 1e3, "MPa": 1e6, "GPa": 1e9, "N/m^2": 1.0, "N/m2": 1.0, "N/mm^2": 1e6,
    "N/mm2": 1e6, "N/mm²": 1e6, "psi": 6894.757293168, "ksi": 6894757.293168,
}
#: temperature label -> offset to °C (value + offset); kelvin is the only offset scale known
TEMPERATURE_OFFSETS = {"c": 0.0, "°c": 0.0, "degc": 0.0, "deg.c": 0.0, "celsius": 0.0,
                       "k": -273.15, "kelvin": -273.15}
#: angular frequency label -> factor to Hz
ANGULAR_FREQUENCY_UNITS = {"rad/s": 0.15915494309189535}
