"""Points a plan asks the rig for, and what the rig gives back: the whole interface to a rig.

A plan never talks to an instrument. It hands a list of :class:`PlannedPoint` (frequency,
settle and integration cycles, in measurement order) to a *measure* callable and receives
:class:`MeasuredPoints`: the same arrays a campaign file stores per point (data-format.md),
plus the rig time each point took. The embedded simulator, the real driver and the tests each
provide such a callable.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass, field, fields
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from viscorig.analyser import ANALYSER_MAX_POINTS
from viscorig.fitting import FrfData

__all__ = ["MeasureFunction", "MeasuredPoints", "PlannedPoint", "sweep_segments"]


@dataclass(frozen=True)
class PlannedPoint:
    """One point to measure.

    Attributes
    ----------
    frequency_hz
        On the analyser's frequency grid.
    settle_cycles
        ``SWE:STIM`` for this point (after the change from the previous point).
    integrate_cycles
        ``SWE:DWEL`` for this point.
    purpose
        Why it is measured: ``"look"`` (first look), ``"cover"`` (coverage of the band for
        diagnosis), ``"refine"`` (chosen for the targets).
    """

    frequency_hz: float
    settle_cycles: int
    integrate_cycles: int
    purpose: str = "refine"


def _array(values: ArrayLike | None, dtype: type) -> NDArray | None:
    return None if values is None else np.atleast_1d(np.asarray(values, dtype=dtype))


@dataclass(frozen=True)
class MeasuredPoints:
    """Points measured on the rig, in measurement order.

    Attributes
    ----------
    frequency_hz
        The analyser's own frequency of each point.
    accelerance_table, accelerance_support
        ``ẍ_s/F_e`` and ``ẍ_v/F_v`` (m/s²/N); ``accelerance_support`` is ``None`` on a bare
        table.
    reference_amplitude
        Achieved amplitude of the reference accelerometer (m/s², peak).
    force_amplitude
        ``|F_e|`` (N).
    settle_cycles, integrate_cycles
        As measured.
    duration_s
        Rig time each point took (controller passes and instrument overhead included).
    variance_table, variance_support
        The analyser's normalized variance of each FRF, or ``None``.
    flags
        Campaign-file flag bits (``viscorig.storage``), or ``None``.
    """

    frequency_hz: NDArray[np.float64]
    accelerance_table: NDArray[np.complex128]
    accelerance_support: NDArray[np.complex128] | None
    reference_amplitude: NDArray[np.float64]
    force_amplitude: NDArray[np.float64]
    settle_cycles: NDArray[np.int64]
    integrate_cycles: NDArray[np.int64]
    duration_s: NDArray[np.float64]
    variance_table: NDArray[np.float64] | None = None
    variance_support: NDArray[np.float64] | None = None
    flags: NDArray[np.uint16] | None = None
    extras: dict[str, NDArray] = field(default_factory=dict, compare=False)

    def __post_init__(self) -> None:
        kinds = {
            "frequency_hz": float, "accelerance_table": complex, "accelerance_support": complex,
            "reference_amplitude": float, "force_amplitude": float, "settle_cycles": np.int64,
            "integrate_cycles": np.int64, "duration_s": float, "variance_table": float,
            "variance_support": float, "flags": np.uint16,
        }  # fmt: skip
        size = np.atleast_1d(self.frequency_hz).size
        for name, kind in kinds.items():
            value = _array(getattr(self, name), kind)
            if value is not None and value.shape != (size,):
                raise ValueError(f"{name} has {value.size} values for {size} points")
            object.__setattr__(self, name, value)

    def __len__(self) -> int:
        return int(self.frequency_hz.size)

    @property
    def test_time_s(self) -> float:
        """Rig time of all the points."""
        return float(np.sum(self.duration_s))

    @property
    def integrate_s(self) -> NDArray[np.float64]:
        """Integration time of each point, s."""
        return self.integrate_cycles / self.frequency_hz

    def concatenate(self, other: MeasuredPoints) -> MeasuredPoints:
        """These points followed by ``other``'s."""
        values: dict[str, Any] = {}
        for item in fields(self):
            if item.name == "extras":
                continue
            mine, theirs = getattr(self, item.name), getattr(other, item.name)
            if mine is None or theirs is None:
                if (mine is None) != (theirs is None) and item.name == "accelerance_support":
                    raise ValueError("cannot join bare-table points with specimen points")
                values[item.name] = None
            else:
                values[item.name] = np.concatenate([mine, theirs])
        return MeasuredPoints(**values)

    def merged(self) -> MeasuredPoints:
        """One point per frequency, in frequency order: repeats at a frequency joined as one
        point integrated over their summed cycles (each FRF the inverse-variance weighted mean,
        its variance ``1/Σ(1/v)``; without variances, weighted by integration time). For tools
        that expect distinct frequencies."""
        f = self.frequency_hz
        unique, inverse = np.unique(f, return_inverse=True)
        count = unique.size

        def total(values: NDArray) -> NDArray:
            return np.bincount(inverse, weights=values, minlength=count)

        def weights_of(variance: NDArray | None) -> NDArray:
            return self.integrate_s if variance is None else 1.0 / variance

        def mean(values: NDArray, variance: NDArray | None) -> NDArray:
            w = weights_of(variance)
            if np.iscomplexobj(values):
                return (total(values.real * w) + 1j * total(values.imag * w)) / total(w)
            return total(values * w) / total(w)

        def joined_variance(variance: NDArray | None) -> NDArray | None:
            return None if variance is None else 1.0 / total(1.0 / variance)

        first = np.zeros(count, dtype=int)
        first[inverse[::-1]] = np.arange(f.size)[::-1]
        support = self.accelerance_support
        return MeasuredPoints(
            frequency_hz=unique,
            accelerance_table=mean(self.accelerance_table, self.variance_table),
            accelerance_support=None if support is None else mean(support, self.variance_support),
            reference_amplitude=mean(self.reference_amplitude, None),
            force_amplitude=mean(self.force_amplitude, None),
            settle_cycles=self.settle_cycles[first],
            integrate_cycles=total(self.integrate_cycles.astype(float)).astype(np.int64),
            duration_s=total(self.duration_s),
            variance_table=joined_variance(self.variance_table),
            variance_support=joined_variance(self.variance_support),
            flags=None if self.flags is None else np.bitwise_or.reduceat(
                self.flags[np.argsort(inverse, kind="stable")],
                np.r_[0, np.cumsum(np.bincount(inverse))[:-1]],
            ).astype(np.uint16),
        )  # fmt: skip

    def frf_data(self, name: str = "plan") -> FrfData:
        """The points as :class:`~viscorig.fitting.FrfData`, sorted by frequency (stable), with
        the test time at the end of each point and the analyser's variance where there is one."""
        order = np.argsort(self.frequency_hz, kind="stable")

        def pick(values: NDArray | None) -> NDArray | None:
            return None if values is None else values[order]

        return FrfData(
            self.frequency_hz[order],
            self.accelerance_table[order],
            pick(self.accelerance_support),
            np.cumsum(self.duration_s)[order],
            self.reference_amplitude[order],
            variance_table=pick(self.variance_table),
            variance_support=pick(self.variance_support),
            name=name,
        )


#: ``measure(points) -> MeasuredPoints``: measure the points in the order given.
MeasureFunction = Callable[[Sequence[PlannedPoint]], MeasuredPoints]


@dataclass(frozen=True)
class SweepSegment:
    """A run of points the analyser measures in one go.

    ``kind`` is ``"linear"`` (a short linear sweep ``start_hz .. stop_hz`` at ``resolution_hz``,
    one settle and integration setting) or ``"manual"`` (``SWE:MODE MAN``, one ``FREQ:MAN`` per
    point).
    """

    kind: str
    points: tuple[PlannedPoint, ...]
    resolution_hz: float = 0.0

    @property
    def start_hz(self) -> float:
        return self.points[0].frequency_hz

    @property
    def stop_hz(self) -> float:
        return self.points[-1].frequency_hz


def sweep_segments(
    points: Sequence[PlannedPoint], *, min_linear_points: int = 3,
    max_points: int = ANALYSER_MAX_POINTS
) -> list[SweepSegment]:
    """Group points, in order, into short linear sweeps and manual points.

    A linear sweep is a run of at least ``min_linear_points`` consecutive points, equally
    spaced in one direction, with one settle and one integration setting; every other point
    is measured in manual sweep mode.
    """
    segments: list[SweepSegment] = []
    manual: list[PlannedPoint] = []
    i, n = 0, len(points)
    while i < n:
        j = i + 1
        if j < n:
            step = points[j].frequency_hz - points[i].frequency_hz
            same = (points[i].settle_cycles, points[i].integrate_cycles)
            while (
                j < n
                and j - i < max_points
                and step != 0.0
                and abs(points[j].frequency_hz - points[j - 1].frequency_hz - step) < 1e-9
                and (points[j].settle_cycles, points[j].integrate_cycles) == same
            ):
                j += 1
        if j - i >= min_linear_points:
            if manual:
                segments.append(SweepSegment("manual", tuple(manual)))
                manual = []
            run = tuple(points[i:j])
            segments.append(
                SweepSegment("linear", run, abs(run[1].frequency_hz - run[0].frequency_hz))
            )
            i = j
        else:
            manual.append(points[i])
            i += 1
    if manual:
        segments.append(SweepSegment("manual", tuple(manual)))
    return segments
