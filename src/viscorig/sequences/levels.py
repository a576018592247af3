"""Acceleration levels written with their unit: ``"1.4 m/s^2"``, ``"15 mm/s^2"``, ``"0.15 g"``.

The paper's level is ambiguous by three orders of magnitude (physics.md, open points), so a
level is never a bare number: the unit is part of the value. Levels are peak amplitudes unless
``rms`` follows the unit.
"""

from __future__ import annotations

import math
import re

STANDARD_GRAVITY_M_PER_S2 = 9.80665

#: unit (spaces removed, ``²`` and ``**2`` written ``^2``) -> metres per second squared
ACCELERATION_UNITS: dict[str, float] = {
    "m/s^2": 1.0,
    "cm/s^2": 1e-2,
    "mm/s^2": 1e-3,
    "g": STANDARD_GRAVITY_M_PER_S2,
    "mg": 1e-3 * STANDARD_GRAVITY_M_PER_S2,
}

_LEVEL = re.compile(
    r"^\s*(?P<number>[-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?)\s*(?P<unit>.*?)"
    r"(?:\s+(?P<kind>peak|pk|rms))?\s*$"
)


def parse_level(text: str) -> float:
    """Peak acceleration in m/s² from a level written with its unit.

    Parameters
    ----------
    text
        A number, a unit (m/s^2, cm/s^2, mm/s^2, g, mg; ``²`` for ``^2`` is accepted) and
        optionally ``peak`` (the default) or ``rms``.

    Returns
    -------
    float
        Peak acceleration, m/s².

    Raises
    ------
    ValueError
        No unit, an unknown unit, or a value that is not positive and finite; the message says
        what to write instead.

    Examples
    --------
    >>> parse_level("15 mm/s^2")
    0.015
    >>> round(parse_level("0.15 g"), 4)
    1.471
    """
    if not isinstance(text, str):
        raise ValueError(f"a level is text with its unit, e.g. \"1.4 m/s^2\", not {text!r}")
    match = _LEVEL.match(text)
    if match is None:
        raise ValueError(f"{text!r} is not a number followed by a unit, e.g. \"1.4 m/s^2\"")
    unit = match["unit"].replace(" ", "").replace("²", "^2").replace("**", "^")
    if not unit:
        raise ValueError(
            f"{text!r} has no unit; write it out, e.g. \"1.4 m/s^2\" (peak) or \"0.14 g\""
        )
    if unit not in ACCELERATION_UNITS:
        known = ", ".join(ACCELERATION_UNITS)
        raise ValueError(f"unit {match['unit']!r} of {text!r} is not one of {known}")
    value = float(match["number"]) * ACCELERATION_UNITS[unit]
    if match["kind"] == "rms":
        value *= math.sqrt(2.0)
    if not (math.isfinite(value) and value > 0.0):
        raise ValueError(f"level {text!r} must be positive and finite")
    return value
