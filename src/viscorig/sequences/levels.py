"""Acceleration levels written with their unit: ``"1.4 m/s^2"``, ``"15 mm/s2"``, ``"0.15 g"``.

The paper's level is ambiguous by three orders of magnitude (physics.md, open points), so a
level is never a bare number: the unit is part of the value. Levels are peak amplitudes unless
``rms`` follows the unit.

A unit may be spelt as technicians write it: ``m/s^2``, ``m/s2``, ``m/s²``, ``m/s**2``,
``m s^-2``, ``m·s⁻²``, ``m/s/s`` (and the same with ``cm`` or ``mm``), ``g`` or ``mg``
(standard gravity, 9.80665 m/s²).
"""

from __future__ import annotations

import difflib
import math
import re

from viscorig.sequences.problems import quoted

STANDARD_GRAVITY_M_PER_S2 = 9.80665

#: canonical unit -> metres per second squared
ACCELERATION_UNITS: dict[str, float] = {
    "m/s^2": 1.0,
    "cm/s^2": 1e-2,
    "mm/s^2": 1e-3,
    "g": STANDARD_GRAVITY_M_PER_S2,
    "mg": 1e-3 * STANDARD_GRAVITY_M_PER_S2,
}

#: What the examples and the reference show for each canonical unit.
UNIT_SPELLINGS = ("m/s^2", "m/s2", "m/s²", "m/s**2", "m s^-2", "m/s/s", "cm/s^2", "mm/s^2", "g",
                  "mg")

_LEVEL = re.compile(
    r"^\s*(?P<number>[-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?)\s*(?P<unit>.*?)"
    r"(?:\s+(?P<kind>peak|pk|rms))?\s*$",
    re.IGNORECASE,
)
_LENGTH = {"m": "m", "cm": "cm", "mm": "mm"}


def canonical_unit(unit: str) -> str | None:
    """The canonical spelling of an acceleration unit (``"m/s^2"``, ``"g"``...), or None.

    Examples
    --------
    >>> canonical_unit("mm/s²"), canonical_unit("m s^-2"), canonical_unit("G")
    ('mm/s^2', 'm/s^2', None)
    """
    compact = (unit.replace(" ", "").replace("·", "").replace("*", "")
               .replace("²", "2").replace("⁻", "-").replace("^", ""))
    if compact in ("g", "mg"):
        return compact
    match = re.fullmatch(r"(?P<length>c?m|mm)(?:/s2|/s/s|s-2)", compact)
    if match is None:
        return None
    return f"{_LENGTH[match['length']]}/s^2"


def parse_level(text: str) -> float:
    """Peak acceleration in m/s² from a level written with its unit.

    Parameters
    ----------
    text
        A number, a unit (see the module's docstring) and optionally ``peak`` (the default)
        or ``rms``.

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
    >>> parse_level("1.4 m/s2")
    1.4
    """
    if not isinstance(text, str):
        number = isinstance(text, int | float) and not isinstance(text, bool)
        shown = f"\"{text:g} m/s^2\"" if number and 0 < text < math.inf else "\"1.4 m/s^2\""
        raise ValueError(f"a level is text with its unit, e.g. {shown}, not {quoted(text)}")
    match = _LEVEL.match(text)
    if match is None:
        raise ValueError(f"{quoted(text)} is not a number followed by a unit, e.g. \"1.4 m/s^2\"")
    written = match["unit"].strip()
    if not written:
        raise ValueError(
            f"{quoted(text)} has no unit; write it out, e.g. \"{match['number']} m/s^2\" (peak) or "
            f"\"{match['number']} g\""
        )
    unit = canonical_unit(written)
    if unit is None:
        close = difflib.get_close_matches(
            written, [unit for unit in UNIT_SPELLINGS if unit.isascii()], n=1, cutoff=0.5)
        if canonical_unit(written.lower()) is not None:
            close = [written.lower()]
        hint = f"; did you mean \"{match['number']} {close[0]}\"?" if close else ""
        raise ValueError(
            f"unit {quoted(written)} of {quoted(text)} is not one of "
            f"{', '.join(UNIT_SPELLINGS)}{hint}"
        )
    value = float(match["number"]) * ACCELERATION_UNITS[unit]
    if (match["kind"] or "").lower() == "rms":
        value *= math.sqrt(2.0)
    if not (math.isfinite(value) and value > 0.0):
        raise ValueError(f"level {quoted(text)} must be positive and finite")
    return value
