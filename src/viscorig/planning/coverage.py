"""Where a plan must look whatever the targets: the first look and the band's coverage.

An adaptive plan spends its time where the target parameters are learnt, which may be two or
three frequencies. Diagnosis needs more: a frequency-dependent modulus shows as a smooth trend
over the band, a non-rigid link as Eq. (4) and Eq. (5) disagreeing over the band, a fixture mode
as a narrow peak. A mode of damping ratio ``ζ`` at ``f`` is ``2ζf`` wide at half power, so a
grid whose neighbours are ``(1 + 2ζ_min/n)`` apart (logarithmic spacing) puts ``n`` points in
the half-power band of every mode at least ``ζ_min`` damped, anywhere in the band: with
``ζ_min = 0.02`` and ``n = 1`` that is 47 points for 20-120 Hz (the paper's sweep has 401), and
every smooth trend is sampled 47 times.
"""

from __future__ import annotations

import math
from itertools import pairwise

import numpy as np
from numpy.typing import ArrayLike, NDArray

from viscorig.planning.instrument import ANALYSER, AnalyserLimits

__all__ = ["coverage_grid", "coverage_ratio", "log_grid"]


def log_grid(
    band_hz: tuple[float, float], count: int, limits: AnalyserLimits = ANALYSER
) -> NDArray[np.float64]:
    """``count`` frequencies spaced logarithmically over the band, both edges included, on the
    analyser's grid (duplicates after rounding removed)."""
    lo, hi = band_hz
    grid = limits.grid(band_hz)
    wanted = np.geomspace(lo, hi, max(count, 2))
    index = np.clip(np.searchsorted(grid, wanted), 0, grid.size - 1)
    below = np.clip(index - 1, 0, grid.size - 1)
    nearest = np.where(np.abs(grid[below] - wanted) < np.abs(grid[index] - wanted), below, index)
    return np.unique(grid[nearest])


def coverage_ratio(narrowest_damping_ratio: float = 0.02, points_per_bandwidth: float = 1.0):
    """Largest ratio of neighbouring frequencies: ``1 + 2 ζ_min / n`` (module docstring)."""
    return 1.0 + 2.0 * narrowest_damping_ratio / points_per_bandwidth


def coverage_grid(
    band_hz: tuple[float, float],
    measured_hz: ArrayLike = (),
    *,
    narrowest_damping_ratio: float = 0.02,
    points_per_bandwidth: float = 1.0,
    limits: AnalyserLimits = ANALYSER,
) -> NDArray[np.float64]:
    """Frequencies to add to ``measured_hz`` so that, with the band's edges, no two
    neighbours are more than :func:`coverage_ratio` apart (log-spaced in every gap, on the
    analyser's grid)."""
    lo, hi = band_hz
    ratio = coverage_ratio(narrowest_damping_ratio, points_per_bandwidth)
    grid = limits.grid(band_hz)
    measured = np.asarray(measured_hz, dtype=float)
    known = np.unique(np.concatenate([measured[(measured >= lo) & (measured <= hi)],
                                      grid[[0, -1]]]))  # fmt: skip
    added: list[float] = []
    for a, b in pairwise(known):
        # 2 % of a step of slack: the analyser's grid moves points by up to 15.625 mHz
        count = math.ceil(math.log(b / a) / math.log(ratio) - 0.02) - 1
        if count <= 0:
            continue
        wanted = np.geomspace(a, b, count + 2)[1:-1]
        index = np.clip(np.searchsorted(grid, wanted), 0, grid.size - 1)
        added += [float(grid[i]) for i in index]
    return np.setdiff1d(np.unique(added), known)
