"""Unit labels met in exchange files, and their factors to the SI units viscorig stores.

Instruments and other programs spell units freely (``M/S2``, ``m/s^2``, ``g``, ``N``, ``lbf``).
A label is compared without spaces and case-insensitively; a label that is not in these tables
is refused rather than guessed, because a wrong unit would make every value silently wrong.
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
FORCE_UNITS = {"n": 1.0, "kn": 1e3, "lbf": POUND_FORCE_N, "lb": POUND_FORCE_N}
#: voltage label -> factor to V (an analyser channel with no engineering unit set)
VOLTAGE_UNITS = {"v": 1.0, "mv": 1e-3}
#: frequency label -> factor to Hz
FREQUENCY_UNITS = {"hz": 1.0, "khz": 1e3, "1/s": 1.0}


def normalised(label: str) -> str:
    """A label without spaces, in lower case (``"M/S2 "`` -> ``"m/s2"``)."""
    return "".join(str(label).split()).lower()


def factor(label: str, table: dict[str, float], quantity: str, where: str) -> float:
    """The factor that turns a value in ``label`` into SI.

    Raises
    ------
    InputError
        The label is not a unit of ``quantity`` that viscorig knows.
    """
    key = normalised(label)
    for known, value in table.items():
        if normalised(known) == key:
            return value
    known = ", ".join(sorted({k for k in table}))
    raise InputError(f"unit {label!r} is not a unit of {quantity} (known: {known})", where)

#: modulus (stress) label -> factor to Pa
MODULUS_UNITS = {
    "pa": 1.0, "kpa": 1e3, "mpa": 1e6, "gpa": 1e9, "n/m^2": 1.0, "n/m2": 1.0, "n/mm^2": 1e6,
    "n/mm2": 1e6, "n/mm²": 1e6, "psi": 6894.757293168, "ksi": 6894757.293168,
}
#: temperature label -> offset to °C (value + offset); kelvin is the only offset scale known
TEMPERATURE_OFFSETS = {"c": 0.0, "°c": 0.0, "degc": 0.0, "deg.c": 0.0, "celsius": 0.0,
                       "k": -273.15, "kelvin": -273.15}
#: angular frequency label -> factor to Hz
ANGULAR_FREQUENCY_UNITS = {"rad/s": 0.15915494309189535}
