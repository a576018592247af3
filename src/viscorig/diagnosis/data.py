"""What a diagnosis looks at: one run, or one run with its companions, and their noise.

A *companion* is another run of the same specimen (same specimen text, hardness and preload)
in the same campaign, at another level or in the other sweep direction. Only such runs can
separate amplitude dependence (the level changes, the frequency does not) and thermal drift
(time runs the other way along the band) from a frequency-dependent modulus; diagnosis fits
them jointly with shared parameters. Their ``time_s`` is put on the main run's clock through
the runs' ``started`` stamps.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field, replace
from datetime import datetime

import numpy as np
from numpy.typing import NDArray

from viscorig.errors import InputError
from viscorig.fitting import FrfData, Known, NoiseModel, estimate_noise
from viscorig.fitting.noise import MarkovWhitening
from viscorig.identify import (
    is_bare_table,
    recorded_temperature_c,
    run_data,
    table_parameters,
)
from viscorig.storage import CampaignFile, RunMetadata, RunRecord


@dataclass(frozen=True)
class RunSlice:
    """One run inside the diagnosed data: its name, points, level and sweep direction."""

    run: str
    index: slice
    level_m_per_s2: float
    direction: str


@dataclass(frozen=True)
class DiagnosisData:
    """The runs diagnosed together, as one :class:`FrfData`, with their noise model.

    Attributes
    ----------
    data
        Every point of every run (the main run first), within the band.
    segments
        Where each run's points are in ``data``.
    frfs
        FRFs diagnosed (``"table"`` needs ``table``).
    table
        The table's ``M_s, K_s, C_s`` (their values), or ``None`` (support FRF only).
    noise
        The shared noise model of the core (:class:`viscorig.fitting.NoiseModel`: white power
        along the band, a drift correlated in test time, outlier points), estimated run by run
        from the data alone and joined in the order of the segments. The error floor, the
        whitening of every comparison and so every threshold of diagnosis rest on it.
    table_prior
        The table's values with the covariance they were found with (the bare-table fit's, or
        standard uncertainties given with ``/rig``), or ``None``: the values are exact. The
        parameters it has a covariance for are *nuisance parameters* of every likelihood fit
        (:mod:`viscorig.diagnosis.weighted`): free, with that covariance as a Gaussian prior,
        so that no test mistakes the error of an inherited value for an effect.
    """

    data: FrfData
    segments: tuple[RunSlice, ...]
    frfs: tuple[str, ...]
    table: dict[str, float] | None
    noise: NoiseModel
    temperature_range_c: dict[str, tuple[float, float]] = field(default_factory=dict)
    """Lowest and highest specimen temperature recorded during each run (its per-point
    ``temperature_c`` dataset, a run measured in a chamber), by run name."""
    table_prior: Known | None = None
    prior_scale: float = 1.0
    """``φ`` the prior's ``χ²`` is weighed by: the misfit of the model a diagnosis step starts
    from (:meth:`with_prior_scale`)."""

    def with_prior_scale(self, phi: float) -> DiagnosisData:
        """These data with the table's prior weighed by ``φ``, the dispersion of the model a
        step diagnoses (quasi-likelihood: where the data's ``χ²`` is ``φ`` times what noise
        gives, the prior counts ``φ`` times as much, so that a grossly wrong model does not
        move the table to soak up its misfit; at the noise ``φ = 1``)."""
        if not self.nuisance or phi == self.prior_scale:
            return self
        other = replace(self, prior_scale=float(phi))
        for key in ("_whitening", "_joined_whitening", "_kept", "_left_out_rows", "_prior_w"):
            if key in self.__dict__:
                object.__setattr__(other, key, self.__dict__[key])
        return other

    @property
    def nuisance(self) -> tuple[str, ...]:
        """The table's parameters fitted under their prior (those with a covariance)."""
        if self.table_prior is None or self.table is None:
            return ()
        return tuple(name for name in self.table_prior.names if name in self.table)

    @property
    def exact_table(self) -> dict[str, float]:
        """The table's values held fixed as exact (those without a covariance)."""
        nuisance = set(self.nuisance)
        return {k: v for k, v in (self.table or {}).items() if k not in nuisance}

    def prior_residual(self, values: dict[str, float]) -> NDArray[np.float64]:
        """``W (p − p₀)`` of the nuisance parameters, ``W`` the whitening of their covariance
        (``WᵀW = Σ⁻¹``): what their prior adds to ``χ²`` is its squared norm."""
        names = self.nuisance
        if not names:
            return np.zeros(0)
        p = np.array([values[n] for n in names], dtype=float)
        table = self.table
        assert table is not None  # the nuisance names are the table's
        p0 = np.array([table[n] for n in names], dtype=float)
        return np.sqrt(self.prior_scale) * (self._prior_whitening() @ (p - p0))

    def prior_jacobian(self, values: dict[str, float], log: NDArray[np.bool_]) -> NDArray:
        """``∂ prior_residual/∂x`` for the nuisance parameters' fit coordinates ``x``
        (logarithms where ``log``)."""
        names = self.nuisance
        p = np.array([values[n] for n in names], dtype=float)
        return np.sqrt(self.prior_scale) * self._prior_whitening() * np.where(log, p, 1.0)[None, :]

    def _prior_whitening(self) -> NDArray[np.float64]:
        cached = self.__dict__.get("_prior_w")
        if cached is None:
            known = self.table_prior
            index = [known.names.index(n) for n in self.nuisance]  # type: ignore[union-attr]
            covariance = np.asarray(known.covariance, dtype=float)[np.ix_(index, index)]  # type: ignore[union-attr]
            scale = np.sqrt(np.abs(np.diag(covariance)))
            scale = np.where(scale > 0, scale, 1.0)
            eigen, vectors = np.linalg.eigh(covariance / np.outer(scale, scale))
            floor = 1e-12 * max(float(eigen.max(initial=0.0)), 1e-300)
            cached = (vectors / np.sqrt(np.maximum(eigen, floor))).T / scale[None, :]
            object.__setattr__(self, "_prior_w", cached)
        return cached

    @property
    def run(self) -> str:
        """Name of the main run."""
        return self.segments[0].run

    @property
    def runs(self) -> tuple[str, ...]:
        """Names of every run, the main one first."""
        return tuple(segment.run for segment in self.segments)

    @property
    def levels(self) -> tuple[float, ...]:
        """Distinct levels (m/s²), to 5 %."""
        distinct: list[float] = []
        for segment in self.segments:
            if all(abs(segment.level_m_per_s2 / level - 1) > 0.05 for level in distinct):
                distinct.append(segment.level_m_per_s2)
        return tuple(distinct)

    @property
    def directions(self) -> tuple[str, ...]:
        """Distinct sweep directions."""
        return tuple(dict.fromkeys(segment.direction for segment in self.segments))

    @property
    def noise_floor(self) -> float:
        """``sqrt(mean σ_i²)`` over every point of every FRF: the rms a perfect model reaches."""
        return self.noise.floor_of(self.frfs)

    @property
    def noise_power(self) -> dict[str, NDArray[np.float64]]:
        """FRF name -> ``σ_i² = E|ε_i|²`` at every point (white plus correlated)."""
        return {frf: self.noise.power(frf) for frf in self.frfs}

    @property
    def outliers(self) -> dict[str, NDArray[np.bool_]]:
        """FRF name -> points the noise model found far outside the noise (heavy tails)."""
        return {frf: self.noise.outliers(frf) for frf in self.frfs}

    @property
    def residual_count(self) -> int:
        """Real residuals that count (real and imaginary part of every point not an outlier)."""
        return 2 * sum(int(np.count_nonzero(~mask)) for mask in self.outliers.values())

    @property
    def effective_points(self) -> float:
        """Independent real observations the data are worth (fewer than 2N with a drift)."""
        return max(self.noise.effective_points(self.frfs), 2.0)

    def whiten(self, residuals: dict[str, NDArray[np.complex128]]) -> NDArray[np.float64]:
        """The residuals (``H_model/H_measured − 1`` per FRF, a point per row, one column per
        vector) whitened by the noise model: real numbers of unit variance, independent, when
        they are noise, in the noise model's layout (real parts of every FRF, then imaginary
        parts). Outlier points are left out (their residual counts as zero).

        The same operation as :meth:`NoiseModel.whiten`, with each block's whitening formed
        once (a diagonal for white noise, the O(n) Kalman whitening of a drift,
        :class:`~viscorig.fitting.noise.MarkovWhitening`, or ``L⁻¹`` of its Cholesky factor
        ``L`` where the points are not in time order) so that the many evaluations of a fit
        cost little each."""
        stacked = [np.asarray(residuals[frf], dtype=complex) for frf in self.frfs]
        return self.whiten_stacked(
            np.concatenate([r.real for r in stacked] + [r.imag for r in stacked]),
            overwrite=True)

    def whiten_stacked(self, values: NDArray[np.float64], *,
                       overwrite: bool = False) -> NDArray[np.float64]:
        """:meth:`whiten` of residuals already stacked in its layout: the real parts of every
        FRF in :attr:`frfs` order, then the imaginary parts, a point per row (outlier points
        are set to zero). ``overwrite``: ``values`` may be whitened in place (no copy of a wide
        matrix)."""
        left_out = self._left_out()
        if left_out is not None:
            values = values.copy() if not overwrite else values
            values[left_out] = 0.0
        joined = self._joined()
        if joined is not None and np.isfinite(values).all():
            # (a NaN would leak past its block in the joined solve)
            return joined.apply(values, overwrite=overwrite)
        operators = self._operators()
        sizes = [self.noise.points(frf) for frf in self.frfs]
        half = sum(sizes)
        parts: dict[str, list[NDArray[np.float64]]] = {"re": [], "im": []}
        start = 0
        for frf, size in zip(self.frfs, sizes, strict=True):
            for rows, by_part in operators[frf]:
                at = slice(start + rows.start, start + rows.stop)
                for part, offset in (("re", 0), ("im", half)):
                    block = values[at.start + offset:at.stop + offset]
                    operator = by_part[part]
                    if isinstance(operator, MarkovWhitening):
                        parts[part].append(operator.apply(block))
                    elif operator.ndim == 1:
                        scale = operator if block.ndim == 1 else operator[:, None]
                        parts[part].append(block * scale)
                    else:
                        parts[part].append(operator @ block)
            start += size
        return np.concatenate(parts["re"] + parts["im"])

    def _joined(self) -> MarkovWhitening | None:
        """Every block's whitening as one (:meth:`MarkovWhitening.joined`), in :meth:`whiten`'s
        layout; ``None`` where a block needs a dense ``L⁻¹`` (points not in time order)."""
        if "_joined_whitening" not in self.__dict__:
            operators = self._operators()
            pieces = [by_part[part] for part in ("re", "im") for frf in self.frfs
                      for _, by_part in operators[frf]]
            dense = any(not isinstance(piece, MarkovWhitening) and np.ndim(piece) != 1
                        for piece in pieces)
            object.__setattr__(self, "_joined_whitening",
                               None if dense else MarkovWhitening.joined(pieces))
        return self.__dict__["_joined_whitening"]

    def _operators(self):
        """Per FRF: ``(rows, {part: whitening matrix or diagonal})`` of each noise block."""
        cached = self.__dict__.get("_whitening")
        if cached is None:
            cached = {}
            for frf in self.frfs:
                blocks, start = [], 0
                for block in self.noise.blocks[frf]:
                    rows = slice(start, start + block.size)
                    by_part = {}
                    for part in ("re", "im"):
                        white, correlated = block.part_variance(part)
                        if correlated > 0:
                            operator = block.whitening(part)
                            by_part[part] = (operator if operator is not None
                                             else block.whiten_part(part, np.eye(block.size)))
                        else:
                            by_part[part] = 1.0 / np.sqrt(white)
                    blocks.append((rows, by_part))
                    start += block.size
                cached[frf] = blocks
            object.__setattr__(self, "_whitening", cached)
        return cached

    def whitened_power(self, residuals: dict[str, NDArray[np.complex128]]) -> dict[str, NDArray]:
        """Whitened residual power per point and FRF (mean 1 when the residual is noise): the
        squares of :meth:`whiten`'s real and imaginary components of each point, halved."""
        e = self.whiten(residuals)
        sizes = [self.noise.points(frf) for frf in self.frfs]
        half = e.size // 2
        out, start = {}, 0
        for frf, size in zip(self.frfs, sizes, strict=True):
            re, im = e[start : start + size], e[half + start : half + start + size]
            out[frf] = (re**2 + im**2) / 2.0
            start += size
        return out

    def _left_out(self) -> NDArray[np.bool_] | None:
        """The outlier points' rows in :meth:`whiten_stacked`'s layout; ``None`` if none."""
        if "_left_out_rows" not in self.__dict__:
            rows = np.concatenate([~kept for kept in self._masks().values()] * 2)
            object.__setattr__(self, "_left_out_rows", rows if rows.any() else None)
        return self.__dict__["_left_out_rows"]

    def _masks(self) -> dict[str, NDArray[np.bool_]]:
        cached = self.__dict__.get("_kept")
        if cached is None:
            cached = {frf: ~mask for frf, mask in self.outliers.items()}
            object.__setattr__(self, "_kept", cached)
        return cached


def _direction(frequency_hz: NDArray[np.float64]) -> str:
    return "down" if frequency_hz.size > 1 and frequency_hz[-1] < frequency_hz[0] else "up"


def _level(data: FrfData) -> float:
    if data.reference_amplitude is None:
        return math.nan
    return float(np.median(data.reference_amplitude))


def combine(
    runs: Sequence[tuple[str, FrfData]],
    *,
    table: dict[str, float] | Known | None,
    band_hz: tuple[float, float] | None = None,
    frfs: Sequence[str] | None = None,
) -> DiagnosisData:
    """Diagnosis data from runs as plain arrays (the main run first).

    ``time_s`` of every run must already be on one clock (seconds since the main run started)
    for the ``drift`` term to use it across runs. ``table``: the table's values, as exact, or
    with the covariance they were found with (a :class:`~viscorig.fitting.Known`, as
    ``TableSource.known`` gives it), which the tests then allow for.
    """
    prior: Known | None = None
    exact: dict[str, float] | None
    if isinstance(table, Known):
        prior = table
        exact = dict(table.values) if table.values else None
    else:
        exact = table
    if not runs:
        raise InputError("no run to diagnose", "diagnosis")
    pieces = [(name, data.in_band(band_hz)) for name, data in runs]
    main = pieces[0][1]
    whole = runs[0][1].frequency_hz
    if band_hz is not None and main.frequency_hz.size == 0 and whole.size:
        raise InputError(f"the band {band_hz[0]:g}:{band_hz[1]:g} Hz holds none of its points "
                         f"(it spans {whole.min():g}-{whole.max():g} Hz)", main.name)
    if frfs is None:
        frfs = tuple(name for name in ("table", "support") if name in main.available)
        if exact is None:
            frfs = tuple(name for name in frfs if name != "table")
    frfs = tuple(frfs)
    if not frfs:
        raise InputError("has no FRF to diagnose", main.name)
    if "table" in frfs and exact is None:
        raise InputError(
            "the table FRF needs the table's M_s, K_s, C_s (a bare-table run or /rig)", main.name
        )
    segments, noises = [], []
    start = 0
    for name, data in pieces:
        data.checked(frfs, band_hz)
        n = data.frequency_hz.size
        segments.append(RunSlice(name, slice(start, start + n), _level(data), _direction(
            data.frequency_hz)))
        noises.append(estimate_noise(data, frfs))
        start += n

    def joined(field: str) -> NDArray | None:
        values = [getattr(data, field) for _, data in pieces]
        if any(value is None for value in values):
            return None
        return np.concatenate(values)

    combined = FrfData(
        np.concatenate([data.frequency_hz for _, data in pieces]),
        joined("table"),
        joined("support"),
        joined("time_s"),
        joined("reference_amplitude"),
        name=main.name,
        temperature_c=joined("temperature_c"),
    )
    return DiagnosisData(
        combined,
        tuple(segments),
        frfs,
        None if exact is None else dict(exact),
        NoiseModel.join(noises),
        table_prior=prior if prior is not None and prior.names else None,
    )


def _started(run: RunRecord) -> datetime | None:
    try:
        return datetime.fromisoformat(str(run.metadata.started).replace("Z", "+00:00"))
    except ValueError:
        return None


def same_specimen(ma: RunMetadata, mb: RunMetadata) -> bool:
    """Two runs (their metadata) measure the same specimen in the same state (text, hardness,
    preload)."""
    hard_a, hard_b = float(ma.hardness_shore_a), float(mb.hardness_shore_a)
    same_hardness = (math.isnan(hard_a) and math.isnan(hard_b)) or hard_a == hard_b
    return (
        str(ma.specimen).strip().lower() == str(mb.specimen).strip().lower()
        and same_hardness
        and abs(float(ma.preload_strain) - float(mb.preload_strain)) < 0.005
    )


#: Runs whose temperatures differ by more than this are not diagnosed together, K.
SAME_TEMPERATURE_K = 1.0


def _same_temperature(a: RunRecord, b: RunRecord) -> bool:
    ta, tb = a.metadata.temperature_c, b.metadata.temperature_c
    if math.isnan(ta) or math.isnan(tb):
        return math.isnan(ta) and math.isnan(tb)
    return abs(ta - tb) <= SAME_TEMPERATURE_K


def recorded_temperature_range(run: RunRecord) -> tuple[float, float] | None:
    """Lowest and highest per-point ``temperature_c`` of a run, or None where not recorded."""
    values = recorded_temperature_c(run, every_point=False)
    if values is None:
        return None
    values = values[np.isfinite(values)]
    return (float(values.min()), float(values.max())) if values.size else None


def companions(campaign: CampaignFile, main: RunRecord) -> list[RunRecord]:
    """Other runs of the same specimen in the campaign that differ in level or direction."""
    found = []
    for name in campaign.run_names:
        if name == main.name or not same_specimen(main.metadata, campaign.run_metadata(name)):
            continue
        other = campaign.run(name)
        if not other.points or is_bare_table(other):
            continue
        level_differs = abs(other.metadata.level_m_per_s2 / main.metadata.level_m_per_s2 - 1) > 0.05
        if not _same_temperature(main, other):
            continue  # another temperature is another material state, not a companion
        if level_differs or other.metadata.direction != main.metadata.direction:
            found.append(other)
    return found


def from_campaign(
    campaign: CampaignFile,
    run_name: str,
    *,
    band_hz: tuple[float, float] | None = None,
    frfs: Sequence[str] | None = None,
    with_companions: bool = True,
) -> DiagnosisData:
    """Diagnosis data of a stored run (and its companions), table parameters from the file."""
    run = campaign.run(run_name)
    if not run.points:
        raise InputError("has no measured point", f"run '{run_name}'")
    if is_bare_table(run):
        raise InputError(
            "is a bare-table run; diagnosis looks at specimen runs (identify it with 'table')",
            f"run '{run_name}'",
        )
    table = table_parameters(campaign)
    runs = [run] + (companions(campaign, run) if with_companions else [])
    started = _started(run)
    pieces = []
    for piece in runs:
        name = piece.name
        data = run_data(piece)
        other = _started(piece)
        if piece is not run and data.time_s is not None and started and other:
            offset = (other - started).total_seconds()
            data = replace(data, time_s=data.time_s + offset)
        pieces.append((name, data))
    combined = combine(pieces, table=None if table is None else table.known, band_hz=band_hz,
                       frfs=frfs)
    ranges = {piece.name: recorded_temperature_range(piece) for piece in runs}
    return replace(combined, temperature_range_c={
        name: span for name, span in ranges.items() if span is not None})
