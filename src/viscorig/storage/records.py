"""What a campaign file holds, as plain Python objects: run metadata, segments, runs, fits."""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field, fields, replace
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from viscorig import frf
from viscorig.numbers import Estimate


@dataclass(frozen=True, kw_only=True)
class RunSettings:
    """What the runner knows when it starts a run: specimen, sweep settings and instrument.

    Every field is an attribute of ``/runs/<name>`` (data-format.md), in SI units.
    """

    specimen: str
    """Free text; ``"none"`` for the bare table."""
    level_m_per_s2: float
    """Reference acceleration amplitude (peak) held by the controller, m/s²."""
    direction: str
    """``"up"`` or ``"down"``."""
    settle_cycles: int
    integrate_cycles: int
    resolution_hz: float
    hardness_shore_a: float = math.nan
    preload_strain: float = 0.0
    """Static normal strain of the specimens: 0 without preload, 0.104 for the paper's 10 %."""
    temperature_c: float = math.nan
    instrument: str = ""
    """The analyser's ``*IDN?`` answer."""
    resource: str = ""
    """The VISA resource string."""
    simulated: bool = False
    """True when a simulated rig produced the data."""


@dataclass(frozen=True, kw_only=True)
class RunMetadata(RunSettings):
    """Every attribute of a stored run: its settings plus its lifecycle state."""

    status: str = "running"
    """``"running"``, ``"complete"`` or ``"aborted"``."""
    started: str = ""
    """ISO 8601 UTC."""
    finished: str = ""
    """ISO 8601 UTC, ``""`` while running."""

    @property
    def settings(self) -> RunSettings:
        """The settings part, e.g. to start a run like this one."""
        names = [item.name for item in fields(RunSettings)]
        return RunSettings(**{name: getattr(self, name) for name in names})


def _column(values: ArrayLike | None, dtype: type, name: str) -> NDArray | None:
    if values is None:
        return None
    array: NDArray = np.atleast_1d(np.asarray(values, dtype=dtype))
    if array.ndim != 1:
        raise ValueError(f"segment {name} must be 1-D, got shape {array.shape}")
    return array


@dataclass(frozen=True)
class Segment:
    """Points measured in one go, appended to a run in one commit.

    All arrays have one value per point, in SI units (see data-format.md). ``variance_table``,
    ``variance_support``, ``settle_cycles``, ``integrate_cycles`` (per point, where they vary
    from point to point) and ``extra`` (name -> (values, units)) are optional; a run keeps the
    set of datasets its first segment had.

    Raises
    ------
    ValueError
        Arrays of different lengths, not 1-D, no point, or a frequency that is not finite or
        lies outside :data:`~viscorig.frf.FREQUENCY_RANGE_HZ`.
    """

    frequency_hz: ArrayLike
    time_s: ArrayLike
    accelerance_table: ArrayLike
    accelerance_support: ArrayLike
    reference_amplitude: ArrayLike
    source_amplitude: ArrayLike
    force_amplitude: ArrayLike
    flags: ArrayLike
    variance_table: ArrayLike | None = None
    variance_support: ArrayLike | None = None
    settle_cycles: ArrayLike | None = None
    integrate_cycles: ArrayLike | None = None
    extra: Mapping[str, tuple[ArrayLike, str]] = field(default_factory=dict)

    def columns(self) -> dict[str, tuple[NDArray, str | None]]:
        """Dataset name -> (values as stored, units or None for the layout's own units)."""
        kinds = {
            "frequency_hz": np.float64,
            "time_s": np.float64,
            "accelerance_table": np.complex128,
            "accelerance_support": np.complex128,
            "reference_amplitude": np.float64,
            "source_amplitude": np.float64,
            "force_amplitude": np.float64,
            "flags": np.int64,
            "variance_table": np.float64,
            "variance_support": np.float64,
            "settle_cycles": np.int64,
            "integrate_cycles": np.int64,
        }
        result: dict[str, tuple[NDArray, str | None]] = {}
        for name, dtype in kinds.items():
            array = _column(getattr(self, name), dtype, name)
            if array is not None:
                result[name] = (array, None)
        flags = result["flags"][0]
        if np.any((flags < 0) | (flags > 0xFFFF)):
            raise ValueError("segment flags must fit in 16 bits")
        result["flags"] = (flags.astype(np.uint16), None)
        for name, (values, units) in self.extra.items():
            if name in result or not name or "/" in name:
                raise ValueError(f"segment extra dataset name {name!r} is not allowed")
            array = _column(values, np.float64 if not np.iscomplexobj(values) else complex, name)
            if array is None:
                raise ValueError(f"segment extra dataset {name!r} has no values")
            result[name] = (array, str(units))
        lengths = {name: len(values) for name, (values, _) in result.items()}
        if len(set(lengths.values())) != 1:
            raise ValueError(f"segment arrays differ in length: {lengths}")
        if lengths["frequency_hz"] == 0:
            raise ValueError("a segment holds at least one point")
        problem = frf.frequency_problem(result["frequency_hz"][0])
        if problem is not None:
            raise ValueError(f"segment: {problem}")
        return result


@dataclass(frozen=True)
class FitRecord:
    """A fit as the campaign file stores it under ``/runs/<run>/fits/<id>``: what the file
    says, unchecked against the model library (:func:`viscorig.identify.read_fit` makes it the
    fit the package uses)."""

    id: str
    run: str
    model: str
    """Model spec string, e.g. ``"maxwell(3)+load_cell"``."""
    band_hz: tuple[float, float]
    rms_error: float
    noise_floor: float
    created: str
    parameters: dict[str, Estimate]
    """name -> value, standard error (NaN when the file stores none) and unit."""
    correlation: tuple[tuple[str, ...], NDArray[np.float64]] | None = None
    """Names and correlation matrix of the parameters with a standard error, if stored."""
    weighting: str = ""
    """How the fit weighted the points (``"noise"``, ``"uniform"``), if stored."""


@dataclass(frozen=True)
class JointFitRecord:
    """A fit of several runs together as the campaign file stores it under ``/fits/<id>`` (the
    Payne effect's Kraus model from runs at several levels, :mod:`viscorig.strain`): what the
    file says, unchecked against the model."""

    id: str
    model: str
    """What was fitted, e.g. ``"kraus"``."""
    runs: tuple[str, ...]
    """The runs it used, in the fit's order (for ``kraus`` the lowest level first)."""
    band_hz: tuple[float, float]
    reduced_chi_square: float
    points: int
    created: str
    parameters: dict[str, Estimate]
    """name -> value, standard error (NaN when the file stores none) and unit."""
    correlation: tuple[tuple[str, ...], NDArray[np.float64]] | None = None
    """Names and correlation matrix of the parameters, if stored."""
    weighting: str = ""
    extra: dict[str, Any] = field(default_factory=dict)
    """The fit group's other attributes (``displacement_range_m`` of a ``kraus`` fit)."""


@dataclass(frozen=True, eq=False)
class RunRecord:
    """One sweep run read from a campaign file; arrays are read-only numpy arrays.

    Accelerances are what the analyser measured; receptance and dynamic stiffness are derived
    with :mod:`viscorig.frf`.
    """

    name: str
    metadata: RunMetadata
    # arrays are left out of repr(), which would otherwise print every point
    frequency_hz: NDArray[np.float64] = field(repr=False)
    time_s: NDArray[np.float64] = field(repr=False)
    accelerance_table: NDArray[np.complex128] = field(repr=False)
    """ẍ_s / F_e, m/s²/N."""
    accelerance_support: NDArray[np.complex128] = field(repr=False)
    """ẍ_v / F_v, m/s²/N (NaN on a bare-table run)."""
    reference_amplitude: NDArray[np.float64] = field(repr=False)
    source_amplitude: NDArray[np.float64] = field(repr=False)
    force_amplitude: NDArray[np.float64] = field(repr=False)
    flags: NDArray[np.uint16] = field(repr=False)
    variance_table: NDArray[np.float64] | None = field(default=None, repr=False)
    variance_support: NDArray[np.float64] | None = field(default=None, repr=False)
    settle_cycles: NDArray[np.int64] | None = field(default=None, repr=False)
    """Settle cycles of each point, where they vary (else the run attribute holds)."""
    integrate_cycles: NDArray[np.int64] | None = field(default=None, repr=False)
    """Integration cycles of each point, where they vary (else the run attribute holds)."""
    extra: dict[str, tuple[NDArray, str]] = field(default_factory=dict, repr=False)
    """Other per-point datasets an instrument added: name -> (values, units)."""

    @property
    def points(self) -> int:
        """Number of points measured so far."""
        return int(self.frequency_hz.size)

    @property
    def cycles(self) -> tuple[NDArray[np.int64], NDArray[np.int64]]:
        """Settle and integration cycles of every point (per point, or the run's)."""
        size = self.frequency_hz.size
        settle = (self.settle_cycles if self.settle_cycles is not None
                  else np.full(size, self.metadata.settle_cycles, dtype=np.int64))
        integrate = (self.integrate_cycles if self.integrate_cycles is not None
                     else np.full(size, self.metadata.integrate_cycles, dtype=np.int64))
        return settle, integrate

    def select(self, keep: ArrayLike) -> RunRecord:
        """The run at some of its points (a boolean mask or indices), in the order given."""
        index = np.asarray(keep)
        columns: dict[str, Any] = {
            item.name: None if getattr(self, item.name) is None else getattr(self, item.name)[index]
            for item in fields(self) if item.name not in ("name", "metadata", "extra")
        }
        extra = {key: (values[index], units) for key, (values, units) in self.extra.items()}
        return replace(self, extra=extra, **columns)

    def merged(self) -> RunRecord:
        """The run as analysis reads it: points in frequency order, repeats of one frequency
        merged into one point.

        A run stores every point in measurement order, repeats included (an adaptive plan comes
        back to the frequencies that teach most). Merged, a frequency measured ``k`` times is
        one point integrated over all its cycles: each accelerance the mean weighted by the
        inverse of its normalized variance (by integration time where the run has no variance),
        its variance ``1/Σ(1/v)``; the amplitudes and the time the plain means, the flags
        joined, the settle of the first and the integration summed. A sweep (distinct
        frequencies in order, up or down) is returned as it is.
        """
        f = self.frequency_hz
        steps = np.diff(f)
        if f.size < 2 or np.all(steps > 0) or np.all(steps < 0):
            return self
        unique, inverse = np.unique(f, return_inverse=True)
        count = unique.size
        settle, integrate = self.cycles
        measured = f >= frf.FREQUENCY_RANGE_HZ[0]  # (a damaged 1e-309 Hz would overflow 1/f)
        integrate_s = np.where(measured, integrate / np.where(measured, f, 1.0), 1.0)

        def total(values: NDArray) -> NDArray:
            return np.bincount(inverse, weights=values, minlength=count)

        def mean(values: NDArray, weights: NDArray) -> NDArray:
            if np.iscomplexobj(values):
                return (total(values.real * weights) + 1j * total(values.imag * weights)) / total(
                    weights)
            return total(values * weights) / total(weights)

        def usable(variance: NDArray | None) -> bool:
            return variance is not None and bool(np.all(np.isfinite(variance) & (variance > 0)))

        def joined(values: NDArray, variance: NDArray | None) -> tuple[NDArray, NDArray | None]:
            if usable(variance):
                assert variance is not None
                return mean(values, 1.0 / variance), 1.0 / total(1.0 / variance)
            return (mean(values, integrate_s),
                    None if variance is None else mean(variance, np.ones(f.size)))

        ones = np.ones(f.size)
        table, variance_table = joined(self.accelerance_table, self.variance_table)
        support, variance_support = joined(self.accelerance_support, self.variance_support)
        first = np.zeros(count, dtype=int)
        first[inverse[::-1]] = np.arange(f.size)[::-1]
        flags = np.zeros(count, dtype=np.uint16)
        np.bitwise_or.at(flags, inverse, self.flags)
        varying = self.settle_cycles is not None or self.integrate_cycles is not None
        return replace(
            self,
            frequency_hz=unique,
            time_s=mean(self.time_s, ones),
            accelerance_table=table,
            accelerance_support=support,
            reference_amplitude=mean(self.reference_amplitude, ones),
            source_amplitude=mean(self.source_amplitude, ones),
            force_amplitude=mean(self.force_amplitude, ones),
            flags=flags,
            variance_table=variance_table,
            variance_support=variance_support,
            settle_cycles=settle[first] if varying else None,
            integrate_cycles=total(integrate.astype(float)).astype(np.int64) if varying else None,
            extra={key: (mean(values, ones), units) for key, (values, units) in self.extra.items()
                   if np.issubdtype(np.asarray(values).dtype, np.number)},
        )

    def receptance_table(self) -> NDArray[np.complex128]:
        """X_s / F_e in m/N."""
        return frf.accelerance_to_receptance(self.frequency_hz, self.accelerance_table)

    def receptance_support(self) -> NDArray[np.complex128]:
        """X_v / F_v in m/N."""
        return frf.accelerance_to_receptance(self.frequency_hz, self.accelerance_support)

    def dynamic_stiffness_table(self) -> NDArray[np.complex128]:
        """F_e / X_s in N/m."""
        return frf.accelerance_to_dynamic_stiffness(self.frequency_hz, self.accelerance_table)

    def dynamic_stiffness_support(self) -> NDArray[np.complex128]:
        """F_v / X_v in N/m (Eq. 5: K* = F_v/X_v + ω² M_v)."""
        return frf.accelerance_to_dynamic_stiffness(self.frequency_hz, self.accelerance_support)

    def flagged(self, flag: int | None = None) -> NDArray[np.bool_]:
        """Mask of points carrying ``flag`` (any flag when ``None``)."""
        flags = self.flags.astype(np.int64)
        return flags != 0 if flag is None else (flags & int(flag)) != 0
