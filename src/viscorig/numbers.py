"""A number with its standard uncertainty: how the package holds one and how it writes one.

Every estimated value with a standard error and a unit is an :class:`Estimate`, whoever
estimated it (a fit of the core, a fit stored in a campaign file, a quantity derived from a fit
such as Table 2's, the Payne fit, a shift function). ``summary``, ``report``, ``identify``,
``show``, ``diagnose`` and ``compare`` all write a value and its standard error through
:func:`with_uncertainty`, so one number reads the same in each.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

__all__ = ["Estimate", "significant", "with_uncertainty"]


class Estimate(NamedTuple):
    """One estimated value: value, standard error and unit (SI).

    ``stderr`` is 0 for a value held fixed exactly and NaN where it is unknown (a campaign file
    that stores none). As a tuple it unpacks as ``value, stderr, unit``.
    """

    value: float
    stderr: float
    unit: str = ""

    def text(self, *, signed: bool = False) -> str:
        """``"152.6 ± 0.6 kN/m"`` (:func:`with_uncertainty`)."""
        return with_uncertainty(self.value, self.stderr, self.unit, signed=signed)

    def to_json(self) -> dict[str, float | str]:
        """``{"value", "stderr", "unit"}``, the shape of a parameter in the JSON output."""
        return {"value": float(self.value), "stderr": float(self.stderr), "unit": self.unit}


#: SI prefixes for newtons, metres and seconds, largest first.
_PREFIXES = ((1e9, "G"), (1e6, "M"), (1e3, "k"), (1.0, ""), (1e-3, "m"), (1e-6, "µ"))

#: Decimals never go past this, however small the error.
_MAX_DECIMALS = 9


def with_uncertainty(value: float, stderr: float, unit: str = "", *, signed: bool = False) -> str:
    """Write ``value ± stderr`` to the error's first significant digit (two when it is a 1 or 2).

    Parameters
    ----------
    value
        The estimate, in ``unit``.
    stderr
        Its standard uncertainty, in ``unit``; NaN, infinite or zero for none.
    unit
        Written after the numbers; a unit starting with N, m or s gets an SI prefix that keeps
        the value between 1 and 1000 (``"152.6 ± 0.6 kN/m"``).
    signed
        Write the value's sign even when positive (``"+9.3 ± 0.6 %"``), for changes.

    Returns
    -------
    str
        ``"152.6 ± 0.6 kN/m"``; without a usable error the value to 4 significant digits;
        ``"–"`` for a value that is not finite.

    Examples
    --------
    >>> with_uncertainty(152_612.0, 613.0, "N/m")
    '152.6 ± 0.6 kN/m'
    >>> with_uncertainty(0.0931, 0.0041, "%", signed=True)
    '+0.093 ± 0.004 %'
    >>> with_uncertainty(3.41, float("nan"), "kg")
    '3.41 kg'
    """
    if not math.isfinite(value):
        return "–"
    sign = "+" if signed else ""
    scale, prefix = 1.0, ""
    if unit and unit[0] in "Nms" and value != 0:
        scale, prefix = next(((s, p) for s, p in _PREFIXES if abs(value) >= s), _PREFIXES[-1])
    v = value / scale
    shown_unit = f" {prefix}{unit}" if unit else ""
    if not (math.isfinite(stderr) and stderr > 0):
        return f"{v:{sign}.4g}{shown_unit}"
    e = stderr / scale
    exponent = math.floor(math.log10(e))
    decimals = (1 if e / 10**exponent < 3 else 0) - exponent
    if decimals <= 0:
        return f"{round(v, decimals):{sign}.0f} ± {round(e, decimals):.0f}{shown_unit}"
    decimals = min(decimals, _MAX_DECIMALS)
    return f"{v:{sign}.{decimals}f} ± {e:.{decimals}f}{shown_unit}"


def significant(value: float, digits: int = 2) -> str:
    """``value`` to ``digits`` significant digits, written out without a power of ten: a size in
    words (``0.0041``, ``1.2``, ``150``), where a fixed number of decimals writes a small one as
    ``0.0``.

    Examples
    --------
    >>> significant(0.004123), significant(12.34), significant(-0.5)
    ('0.0041', '12', '-0.5')
    """
    if not math.isfinite(value):
        return "–"
    return str(np.format_float_positional(value, precision=digits, unique=False,
                                          fractional=False, trim="-"))
