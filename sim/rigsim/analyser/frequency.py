"""Frequencies of the swept sine and of the FFT: rounding, point lists, allowed spans.

Swept sine (chapter 18, ``FREQuency``, ``SWEep``): start and centre are rounded to the next
lower 15.625 mHz step, stop and span to the next higher; the resolution is given in ``HZ``,
``PCT``, ``PNT/SWP`` (linear or logarithmic), ``PNT/DEC`` or ``PNT/OCT`` (logarithmic). Each
point's frequency is on the 15.625 mHz grid too, rounded down like the start **(inferred)**.

FFT: the span is the widest span divided by a power of two (at most 2^19); a span that is not
one of them is raised to the next one that is **(inferred: as the range rounds up)**.
"""

from __future__ import annotations

import math

import numpy as np

from rigsim.analyser.limits import FREQUENCY_STEP_HZ, MAX_POINTS, MIN_POINTS

__all__ = [
    "RESOLUTION_UNITS",
    "allowed_span",
    "point_count",
    "round_down",
    "round_up",
    "sweep_frequencies",
]

RESOLUTION_UNITS = ("HZ", "PCT", "PNT/SWP", "PNT/DEC", "PNT/OCT")


def round_down(frequency_hz: float) -> float:
    """Next lower 15.625 mHz step (a value on the grid stays)."""
    return math.floor(frequency_hz / FREQUENCY_STEP_HZ + 1e-9) * FREQUENCY_STEP_HZ


def round_up(frequency_hz: float) -> float:
    """Next higher 15.625 mHz step (a value on the grid stays)."""
    return math.ceil(frequency_hz / FREQUENCY_STEP_HZ - 1e-9) * FREQUENCY_STEP_HZ


def point_count(start_hz: float, stop_hz: float, spacing: str, value: float, unit: str) -> float:
    """Points a resolution gives over ``start_hz`` .. ``stop_hz`` (not yet limited to 2..801)."""
    span = abs(stop_hz - start_hz)
    lo, hi = min(start_hz, stop_hz), max(start_hz, stop_hz)
    if unit == "PNT/SWP":
        return value
    if span == 0:
        return 1.0
    if spacing == "LIN":
        if unit == "HZ":
            return math.floor(span / value + 1e-9) + 1
        if unit == "PCT":
            return math.floor(100.0 / value + 1e-9) + 1
        octaves = math.log2(hi / lo) if lo > 0 else 0.0
        per = value * (octaves if unit == "PNT/OCT" else octaves / math.log2(10.0))
        return math.floor(per + 1e-9) + 1
    if lo <= 0:
        return 1.0
    if unit == "PCT":
        return math.floor(math.log(hi / lo) / math.log1p(value / 100.0) + 1e-9) + 1
    if unit == "PNT/DEC":
        return math.floor(value * math.log10(hi / lo) + 1e-9) + 1
    if unit == "PNT/OCT":
        return math.floor(value * math.log2(hi / lo) + 1e-9) + 1
    # HZ on a logarithmic sweep: the span in steps of that width (inferred)
    return math.floor(span / value + 1e-9) + 1


def sweep_frequencies(
    start_hz: float, stop_hz: float, spacing: str, value: float, unit: str, direction: str
) -> np.ndarray:
    """The points of a swept sine in measurement order, on the 15.625 mHz grid.

    Linear sweeps in ``HZ`` step by the resolution from the start (the last point at or below
    the stop); other resolutions spread their points from start to stop.
    """
    lo, hi = min(start_hz, stop_hz), max(start_hz, stop_hz)
    count = int(min(MAX_POINTS, max(MIN_POINTS, point_count(lo, hi, spacing, value, unit))))
    if spacing == "LIN" and unit == "HZ":
        points = lo + value * np.arange(count)
    elif spacing == "LOG" and lo > 0:
        points = np.geomspace(lo, hi, count)
    else:
        points = np.linspace(lo, hi, count)
    points = np.floor(points / FREQUENCY_STEP_HZ + 1e-9) * FREQUENCY_STEP_HZ
    points = np.maximum(points, FREQUENCY_STEP_HZ)
    return points[::-1].copy() if direction == "DOWN" else points


def allowed_span(span_hz: float, max_span_hz: float) -> float:
    """The FFT span at or above ``span_hz``: ``max_span_hz / 2**n``, n = 0..19."""
    spans = max_span_hz / 2.0 ** np.arange(20)
    fitting = spans[spans >= span_hz * (1 - 1e-9)]
    return float(fitting[-1]) if fitting.size else float(spans[0])
