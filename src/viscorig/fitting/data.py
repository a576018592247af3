"""Plain-array container for the FRFs of one run, independent of the campaign storage."""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from viscorig.errors import InputError
from viscorig.frf import FREQUENCY_RANGE_HZ
from viscorig.models import FRF_NAMES, Context

#: Fewest frequency points a fit accepts in its band: a fit estimates its noise model from its
#: own points (:mod:`viscorig.fitting.noise_estimation`), which takes this many.
MIN_POINTS = 10
#: An FRF value this many times above or below the band's median magnitude is no measurement:
#: the analyser's dynamic range is about 90 dB (3e4), a rig's FRF over a band a few decades.
ABSURD_RATIO = 1e8
#: Accelerances (m/s² per N) outside this range are no measurement in SI units: a kilogram
#: moves at 1 m/s² per N, and a rig of a gram to ten tonnes, stiffness-controlled down to
#: 0.01 Hz, stays decades inside it (beyond it, squares of dynamic stiffness overflow).
ACCELERANCE_RANGE = (1e-15, 1e15)
#: Normalized variances (relative power) an analyser reports for a measured point: from a
#: scatter a millionth of the single-precision resolution to a million times the value
#: measured. Outside them a dataset is damaged (its squares overflow or underflow in the
#: whitening), and the noise is estimated from the points' differences.
NORMALIZED_VARIANCE_RANGE = (1e-24, 1e12)
#: Optional real per-point fields.
_REAL_FIELDS = ("time_s", "reference_amplitude", "variance_table", "variance_support",
                "temperature_c")


def _complex_or_none(values: ArrayLike | None) -> NDArray[np.complex128] | None:
    if values is None:
        return None
    array = np.atleast_1d(np.asarray(values, dtype=complex))
    return None if np.all(np.isnan(array)) else array


@dataclass(frozen=True)
class FrfData:
    """The measured FRFs of one run, as plain arrays.

    Attributes
    ----------
    frequency_hz
        Frequency of each point (Hz).
    table
        Accelerance ``ẍ_s/F_e`` (m/s²/N), or ``None``.
    support
        Accelerance ``ẍ_v/F_v`` (m/s²/N), or ``None`` (bare table: all NaN becomes ``None``).
    time_s
        Seconds since the run's start at each point, or ``None``.
    reference_amplitude
        Achieved reference acceleration amplitude at each point (m/s²), or ``None``.
    variance_table, variance_support
        The analyser's normalized variance of each FRF at each point (relative power
        ``E|δH/H|²`` within the point's integration), or ``None``.
    temperature_c
        The specimen's recorded temperature at each point (°C), or ``None``.
    name
        Where the data comes from (run name), used in error messages.
    """

    frequency_hz: NDArray[np.float64]
    table: NDArray[np.complex128] | None = None
    support: NDArray[np.complex128] | None = None
    time_s: NDArray[np.float64] | None = None
    reference_amplitude: NDArray[np.float64] | None = None
    name: str = "data"
    variance_table: NDArray[np.float64] | None = None
    variance_support: NDArray[np.float64] | None = None
    temperature_c: NDArray[np.float64] | None = None

    def __post_init__(self) -> None:
        frequency = np.atleast_1d(np.asarray(self.frequency_hz, dtype=float))
        object.__setattr__(self, "frequency_hz", frequency)
        object.__setattr__(self, "table", _complex_or_none(self.table))
        object.__setattr__(self, "support", _complex_or_none(self.support))
        for field in _REAL_FIELDS:
            value = getattr(self, field)
            if value is not None:
                object.__setattr__(self, field, np.atleast_1d(np.asarray(value, dtype=float)))
        for field in ("table", "support", *_REAL_FIELDS):
            value = getattr(self, field)
            if value is not None and value.shape != frequency.shape:
                raise InputError(
                    f"{field} has {value.size} points but frequency_hz has {frequency.size}",
                    self.name,
                )
        if np.any(~np.isfinite(frequency)) or np.any(frequency <= 0):
            raise InputError("frequency_hz must be finite and positive", self.name)

    def has(self, field: str) -> bool:
        """``field`` (``time_s``, ``reference_amplitude``, ``temperature_c``) is known at every
        point: a term that needs it can be evaluated."""
        return self.lacks(field) is None

    def lacks(self, field: str) -> str | None:
        """Why ``field`` cannot serve a term (:meth:`has`), in words; ``None`` when it can."""
        value = getattr(self, field)
        if value is None:
            return "the run lacks"
        missing = ~np.isfinite(value)
        if not missing.any():
            return None
        return (f"the run lacks at {int(missing.sum())} of its points (the first at "
                f"{self.frequency_hz[np.argmax(missing)]:.6g} Hz)")

    @property
    def available(self) -> tuple[str, ...]:
        """Names of the FRFs present (``"table"``, ``"support"``)."""
        return tuple(name for name in FRF_NAMES if getattr(self, name) is not None)

    def frf(self, name: str) -> NDArray[np.complex128]:
        """One FRF by name; :class:`InputError` if the run does not have it."""
        if name not in FRF_NAMES:
            raise InputError(f"unknown FRF '{name}' (known: {', '.join(FRF_NAMES)})", self.name)
        value = getattr(self, name)
        if value is None:
            raise InputError(f"has no {FRF_NAMES[name]} (bare table run?)", self.name)
        return value

    def variance(self, name: str) -> NDArray[np.float64] | None:
        """The analyser's normalized variance of one FRF, or ``None`` when not every value is
        within :data:`NORMALIZED_VARIANCE_RANGE`."""
        value = getattr(self, f"variance_{name}", None)
        low, high = NORMALIZED_VARIANCE_RANGE
        if value is None or not np.all((value >= low) & (value <= high)):
            return None
        return value

    def context(self) -> Context:
        """The model context at these points."""
        return Context(self.frequency_hz, self.time_s, self.reference_amplitude,
                       self.temperature_c)

    def select(self, index: NDArray[np.intp] | NDArray[np.bool_] | slice) -> FrfData:
        """The data at the selected points."""
        pick: dict[str, Any] = {
            field: None if getattr(self, field) is None else getattr(self, field)[index]
            for field in ("table", "support", *_REAL_FIELDS)
        }
        return replace(self, frequency_hz=self.frequency_hz[index], **pick)

    def in_band(self, band_hz: tuple[float, float] | None) -> FrfData:
        """The points with ``lo ≤ f ≤ hi`` (all points when ``band_hz`` is ``None``)."""
        if band_hz is None:
            return self
        lo, hi = band_hz
        if not (np.isfinite(lo) and np.isfinite(hi) and 0 <= lo < hi):
            raise InputError(f"band {lo}:{hi} Hz must have 0 ≤ LO < HI", self.name)
        return self.select((self.frequency_hz >= lo) & (self.frequency_hz <= hi))

    def checked(self, frfs: tuple[str, ...], band_hz: tuple[float, float] | None) -> FrfData:
        """Data in the band, after checking it can be fitted: enough points, no NaN."""
        data = self.in_band(band_hz)
        where = f"{self.name}, band {band_hz[0]:g}:{band_hz[1]:g} Hz" if band_hz else self.name
        if data.frequency_hz.size < MIN_POINTS:
            raise InputError(
                f"{data.frequency_hz.size} point{'s' if data.frequency_hz.size != 1 else ''}, "
                f"a fit needs at least {MIN_POINTS}", where
            )
        low, high = FREQUENCY_RANGE_HZ
        outside = np.flatnonzero(~((data.frequency_hz >= low) & (data.frequency_hz <= high)))
        if outside.size:
            raise InputError(
                f"{outside.size} frequenc{'y lies' if outside.size == 1 else 'ies lie'} "
                f"outside {low:g} to {high:g} Hz (first: "
                f"{data.frequency_hz[outside[0]]:g} Hz), not a measurement", where)
        for name in frfs:
            values = data.frf(name)
            bad = int(np.count_nonzero(~np.isfinite(values) | (values == 0)))
            if bad:
                raise InputError(f"{FRF_NAMES[name]} has {bad} NaN or zero values", where)
            magnitude = np.abs(values)
            median = float(np.median(magnitude))
            low, high = ACCELERANCE_RANGE
            beyond = np.flatnonzero((magnitude < low) | (magnitude > high))
            if beyond.size:
                first = int(beyond[0])
                raise InputError(
                    f"{FRF_NAMES[name]} has {beyond.size} value(s) outside {low:g} to {high:g} "
                    f"m/s² per N (first: {magnitude[first]:.3g} at {data.frequency_hz[first]:g} "
                    "Hz), not a measurement in SI units", where)
            absurd = np.flatnonzero((magnitude > median * ABSURD_RATIO)
                                    | (magnitude < median / ABSURD_RATIO))
            if absurd.size:
                first = int(absurd[0])
                raise InputError(
                    f"{FRF_NAMES[name]} has {absurd.size} value(s) {ABSURD_RATIO:.0e} times or "
                    f"more off the median |H| = {median:.3g} (first: {magnitude[first]:.3g} at "
                    f"{data.frequency_hz[first]:g} Hz), not a measurement", where)
        return data
