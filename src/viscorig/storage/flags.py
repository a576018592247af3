"""Quality flags of a measured point: the ``flags`` bit mask of the campaign file.

A point is never silently accepted when the controller missed its target: the acquisition
layer sets these bits, and readers count or mask them.
"""

from __future__ import annotations

import enum

import numpy as np
from numpy.typing import ArrayLike


class PointFlag(enum.IntFlag):
    """Bits of the uint16 ``flags`` dataset (shared/docs/data-format.md)."""

    LEVEL_NOT_REACHED = 1
    """The reference acceleration is outside the tolerance around the requested level."""
    INPUT_OVERLOAD = 2
    """An analyser input exceeded its range during the point."""
    SOURCE_AT_LIMIT = 4
    """The source output sat at its voltage limit."""
    FORCE_ABOVE_SHAKER_LIMIT = 8
    """The measured shaker force exceeded the station's shaker force limit."""
    OUTSIDE_SOAK_BAND = 16
    """The specimen temperature was outside the soak band of the last temperature step (an
    extension of the layout, docs/temperature.md)."""


LEVEL_NOT_REACHED = PointFlag.LEVEL_NOT_REACHED
INPUT_OVERLOAD = PointFlag.INPUT_OVERLOAD
SOURCE_AT_LIMIT = PointFlag.SOURCE_AT_LIMIT
FORCE_ABOVE_SHAKER_LIMIT = PointFlag.FORCE_ABOVE_SHAKER_LIMIT
OUTSIDE_SOAK_BAND = PointFlag.OUTSIDE_SOAK_BAND

#: Short names used in listings, in bit order.
FLAG_NAMES: dict[PointFlag, str] = {
    PointFlag.LEVEL_NOT_REACHED: "level not reached",
    PointFlag.INPUT_OVERLOAD: "input overload",
    PointFlag.SOURCE_AT_LIMIT: "source at limit",
    PointFlag.FORCE_ABOVE_SHAKER_LIMIT: "force above shaker limit",
    PointFlag.OUTSIDE_SOAK_BAND: "outside the soak band",
}


def count_flags(flags: ArrayLike) -> dict[PointFlag, int]:
    """Number of points carrying each flag (a point with two bits counts under both).

    Parameters
    ----------
    flags
        The ``flags`` values of a run.

    Returns
    -------
    dict
        Every :class:`PointFlag` mapped to its number of points, zero included.
    """
    values = np.asarray(flags, dtype=np.int64)
    return {flag: int(np.count_nonzero(values & int(flag))) for flag in PointFlag}
