"""Scan for local modes: a matched filter over frequency and width, with its look-elsewhere
threshold.

A small local mode (mass ``m`` on a spring-damper tuned to ``f_n`` with damping ratio ``ζ``,
attached to the disc) adds ``m · u(ω)`` to the disc's dynamic stiffness ``D_v``, with
``u = −ω² ω_n² (1 + 2iζω/ω_n) / (ω_n² − ω² + 2iζωω_n)``. To first order in ``m`` it changes the
residual of every FRF by ``m · (1 + r) · g(ω) · u(ω)``, where ``g = ∂ log H/∂D_v`` is read off the
current model itself (its prediction with ``D_v`` nudged), so the template holds whatever the
model holds (a load cell, sensor terms). Whitened like the residual and with the directions the
current model's own parameters can follow projected out, each template ``t`` gives the
least-squares mass and the drop of ``χ²`` a mode there would bring: ``Δχ² = ⟨t, e⟩²/⟨t, t⟩``
(only for ``m > 0``), ``e`` the whitened residual. Peaks are placed on ``e`` itself (a strong
mode is many standard deviations high); their strength is then read on ``e`` clipped at the
Huber scale, so that an outlier point, which is one point high, is no mode.

The grid: ``ζ`` in :data:`DAMPING_RATIOS` (at least one frequency step within the half-power
band), ``f_n`` inside the band with its half-power band (a mode whose peak lies outside the data
is a smooth trend to them, not a local mode), in steps of ``ζ/2`` in log frequency, so
neighbouring templates overlap by about 90 %. The threshold is
:func:`viscorig.diagnosis.significance.scan_threshold` of the scan's length ``L``, the summed arc
length of the normalised templates along frequency for each width.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from viscorig.diagnosis.data import DiagnosisData
from viscorig.diagnosis.significance import alpha_of, scan_threshold
from viscorig.diagnosis.weighted import Likelihood, winsorized
from viscorig.models import Model, Term

#: Damping ratios of the local modes scanned for.
DAMPING_RATIOS = (0.005, 0.008, 0.0125, 0.02, 0.032, 0.05, 0.08)
#: Peaks closer than this (Hz), or than two half-power bandwidths of the stronger, are one mode.
SEPARATION_HZ = 2.0


class _DiscProbe(Term):
    """Adds a constant real stiffness to ``D_v`` (not a physical effect: a probe)."""

    keyword = "probe"

    def __init__(self, size: float) -> None:
        self.argument = None
        self.size = size

    def disc_stiffness(self, ctx, p):
        return np.full(ctx.omega.shape, self.size, dtype=complex)


@dataclass(frozen=True)
class Peak:
    """A local maximum of the scan: where, how wide, how strong."""

    frequency_hz: float
    damping_ratio: float
    mass_kg: float
    delta_chi2: float
    """Drop of ``χ²`` on the residual clipped at the Huber scale (what decides)."""


@dataclass(frozen=True)
class ScanResult:
    """The scan's peaks (strongest first), its length and its threshold."""

    peaks: tuple[Peak, ...]
    length: float
    threshold: float
    templates: int


def log_sensitivity(
    model: Model, values: dict[str, float], data: DiagnosisData
) -> dict[str, NDArray[np.complex128]]:
    """``∂ log H/∂D_v`` per FRF at every point (1/(N/m)), from the model's own prediction."""
    ctx = data.data.context()
    base = model.predict(ctx, values)
    scale = float(np.median(np.abs(model.disc_dynamic_stiffness(ctx, values))))
    size = 1e-7 * max(scale, 1.0)
    probed = Model((*model.terms, _DiscProbe(size))).predict(ctx, values)
    return {frf: (probed[frf] / base[frf] - 1.0) / size for frf in data.frfs}


def mode_stiffness(
    omega: NDArray[np.float64], f_n: NDArray[np.float64], zeta: float | NDArray[np.float64]
) -> NDArray[np.complex128]:
    """``u(ω)`` of a mode of unit mass, for every point (rows) and ``f_n`` (columns);
    ``zeta``: one damping ratio, or one per ``f_n``."""
    # u = −ω² − ω⁴/(p + iq), p = ω_n² − ω², q = 2ζω_nω: in real arithmetic, which takes about
    # half the time of the complex division on the scan's million values
    w_n = 2 * np.pi * np.asarray(f_n, dtype=float)
    w2 = omega**2
    p = w_n[None, :] ** 2 - w2[:, None]
    q = (2 * np.asarray(zeta, dtype=float) * w_n)[None, :] * omega[:, None]
    g = p * p
    g += q * q
    np.divide((w2 * w2)[:, None], g, out=g)
    u = np.empty(p.shape, dtype=complex)
    np.multiply(g, q, out=u.imag)
    g *= p
    g += w2[:, None]
    np.negative(g, out=u.real)
    return u


def _orthonormal(jacobian: NDArray[np.float64]) -> NDArray[np.float64]:
    if jacobian.shape[1] == 0:
        return jacobian
    u, s, _ = np.linalg.svd(jacobian, full_matrices=False)
    return u[:, s > s.max() * 1e-10] if s.size and s.max() > 0 else u[:, :0]


#: A template the projection leaves less than this share of (in norm) is removed whole: what is
#: left of it is rounding.
REMOVED = 1e-10


@dataclass(frozen=True)
class Family:
    """A family of templates (:meth:`Residual.family`), one value per template."""

    norm: NDArray[np.float64]
    """``|t|``, the whitened, projected template's norm (0 where removed)."""
    ok: NDArray[np.bool_]
    """The template is not removed whole by the projection."""
    length: float
    """Summed distance between neighbouring unit templates (removed ones skipped)."""
    along_e: NDArray[np.float64]
    """``⟨t, e⟩``, ``e`` the projected whitened residual."""
    along_clipped: NDArray[np.float64]
    """``⟨t, ψ(e)⟩``, the same for the residual clipped at the Huber scale."""


class Residual:
    """The whitened residual of a fit, with the directions its own parameters can follow
    projected out: what an added effect must explain, and a linear estimate of any effect."""

    def __init__(self, current: Likelihood, data: DiagnosisData) -> None:
        self.current = current
        self.data = data
        self.basis = _orthonormal(current.jacobian)
        self.e = self.project(current.augmented)
        self.clipped = self.project(np.concatenate([winsorized(current.whitened),
                                                    current.prior]))

    def project(self, t: NDArray[np.float64]) -> NDArray[np.float64]:
        """``t`` less its part the current model's parameters can follow; a data-only ``t`` is
        first given zero rows for the table's prior (an effect does not move the prior), so that
        the table's nuisance parameters follow it only as far as their prior lets them."""
        missing = self.basis.shape[0] - t.shape[0]
        if missing > 0:
            t = np.concatenate([t, np.zeros((missing, *t.shape[1:]))])
        return t - self.basis @ (self.basis.T @ t)

    def _whitened(self, change: Mapping[str, NDArray[np.inexact]],
                  shared: NDArray[np.complex128] | None = None) -> NDArray[np.float64]:
        """The whitened change of the residual (the data's rows) for ``δ log H`` per FRF; with
        ``shared`` (points, columns), the change of FRF ``frf`` is ``change[frf][:, None] *
        shared``, formed part by part in the whitening's layout without a complex copy."""
        if shared is not None:
            return self.data.whiten_stacked(self._stacked(change, shared), overwrite=True)
        shape = np.shape(next(iter(change.values())))
        columns = {}
        for frf in self.data.frfs:
            c = np.asarray(change.get(frf, np.zeros(shape)), dtype=complex)
            factor = 1.0 + self.current.residuals[frf]
            columns[frf] = factor[:, None] * c if c.ndim > 1 else factor * c
        return self.data.whiten(columns)

    def _stacked(self, change: Mapping[str, NDArray[np.inexact]],
                 shared: NDArray[np.complex128]) -> NDArray[np.float64]:
        """``(1 + r) · change[frf] · shared`` of every FRF, real parts then imaginary parts
        (:meth:`DiagnosisData.whiten_stacked`'s layout)."""
        frfs = self.data.frfs
        n, columns = shared.shape
        out = np.empty((2 * len(frfs) * n, columns))
        half = len(frfs) * n
        scratch = np.empty((n, columns))
        for k, frf in enumerate(frfs):
            along = np.asarray(change.get(frf, np.zeros(n)), dtype=complex)
            along = along * (1.0 + self.current.residuals[frf])
            a, b = along.real[:, None], along.imag[:, None]
            re, im = out[k * n:(k + 1) * n], out[half + k * n:half + (k + 1) * n]
            np.multiply(a, shared.real, out=re)
            re -= np.multiply(b, shared.imag, out=scratch)
            np.multiply(a, shared.imag, out=im)
            im += np.multiply(b, shared.real, out=scratch)
        return out

    def template(self, change: Mapping[str, NDArray[np.inexact]]) -> NDArray[np.float64]:
        """Whitened, projected change of the residual for a change ``δ log H`` per FRF (an FRF
        left out is unchanged); arrays of one column per effect are allowed."""
        return self.project(self._whitened(change))

    def family(self, change: Mapping[str, NDArray[np.inexact]]) -> Family:
        """A family of templates (one column of ``change`` each, :meth:`template`) through
        their norms, inner products and arc length, without forming the projected templates:
        with ``w`` a whitened template and ``B`` the orthonormal basis of the model's own
        directions, ``⟨Pw, Pv⟩ = ⟨w, v⟩ − ⟨Bᵀw, Bᵀv⟩``, and ``e`` and its clipped copy are
        projected already (``⟨Pw, e⟩ = ⟨w, e⟩``). A template the projection leaves less than
        :data:`REMOVED` of is removed whole (``ok`` false)."""
        columns = np.shape(next(iter(change.values())))[1]
        return self.families(change, [columns])[0]

    def families(
        self, change: Mapping[str, NDArray[np.inexact]], sizes: Sequence[int],
        shared: NDArray[np.complex128] | None = None,
    ) -> list[Family]:
        """Several families side by side in ``change`` (``sizes``: their numbers of columns, in
        order), each measured as :meth:`family` does; whitened together, as one matrix.
        ``shared``: the columns, when every FRF's change is one vector ``change[frf]`` times
        them (the scan's templates)."""
        w = self._whitened(change, shared)
        rows = w.shape[0]  # the data's rows; a template's rows of the prior are zero
        c = self.basis[:rows].T @ w
        whole = np.einsum("ij,ij->j", w, w)
        squared = whole - np.einsum("ij,ij->j", c, c)
        ok = (whole > 0) & (squared > REMOVED**2 * whole)
        norm = np.sqrt(np.where(ok, squared, 0.0))
        along_e, along_clipped = self.e[:rows] @ w, self.clipped[:rows] @ w
        out, start = [], 0
        for size in sizes:
            part = slice(start, start + size)
            at = start + np.flatnonzero(ok[part])
            left: slice | NDArray[np.intp]
            right: slice | NDArray[np.intp]
            if at.size > 1 and at.size == size:  # neighbours along the family, as slices
                left, right = slice(start, start + size - 1), slice(start + 1, start + size)
            else:
                left, right = at[:-1], at[1:]
            if at.size > 1:
                inner = (np.einsum("ij,ij->j", w[:, left], w[:, right])
                         - np.einsum("ij,ij->j", c[:, left], c[:, right]))
                cosine = inner / (norm[left] * norm[right])
                length = float(np.sum(np.sqrt(np.maximum(2.0 - 2.0 * cosine, 0.0))))
            else:
                length = 0.0
            out.append(Family(norm[part], ok[part], length, along_e[part], along_clipped[part]))
            start += size
        return out

    def estimate(self, change: Mapping[str, NDArray[np.inexact]]) -> tuple[float, float, float]:
        """Least-squares size of one effect whose unit changes ``log H`` by ``change``: its
        value, standard error and the drop of ``χ²`` it brings, to first order."""
        t = self.template(change)
        norm2 = float(t @ t)
        if not norm2 > 0:
            return 0.0, float("inf"), 0.0
        inner = float(self.e @ t)
        return -inner / norm2, 1.0 / np.sqrt(norm2), inner**2 / norm2


Grid = list[tuple[float, NDArray[np.float64]]]
"""The scan's grid: ``(ζ, its f_n)`` per damping ratio."""
#: The last frequencies scanned, with their grid and mode templates: they depend on the
#: frequencies alone, and a ladder scans the same data at every rung. (Rebound whole, never
#: changed in place: a reader in another thread sees an old entry or a new one.)
_last_grid: tuple[bytes, Grid, NDArray[np.complex128]] | None = None


def _grid(frequency_hz: NDArray[np.float64]) -> tuple[Grid, NDArray[np.complex128]]:
    """The grid of modes scanned for over these frequencies, and their ``u(ω)`` (points ×
    templates, the grid's families side by side; read-only)."""
    global _last_grid
    key = np.asarray(frequency_hz, dtype=float).tobytes()
    last = _last_grid
    if last is not None and last[0] == key:
        return last[1], last[2]
    f_lo, f_hi = float(frequency_hz.min()), float(frequency_hz.max())
    steps = np.diff(np.unique(frequency_hz))
    step = float(np.median(steps)) if steps.size else 1.0
    grid: Grid = []
    for zeta in DAMPING_RATIOS:
        # half-power band at least one step wide, and inside the data
        f_min = max(f_lo * (1 + 2 * zeta), step / (2 * zeta))
        f_max = f_hi * (1 - 2 * zeta)
        if f_min < f_max:
            grid.append((zeta, np.exp(np.arange(np.log(f_min), np.log(f_max), zeta / 2))))
    u = np.zeros((frequency_hz.size, 0), dtype=complex)
    if grid:
        u = mode_stiffness(2 * np.pi * frequency_hz, np.concatenate([f_n for _, f_n in grid]),
                           np.concatenate([np.full(f_n.size, zeta) for zeta, f_n in grid]))
    u.flags.writeable = False
    _last_grid = (key, grid, u)
    return grid, u


def scan(
    current: Likelihood, data: DiagnosisData, existing_hz: tuple[float, ...] = ()
) -> ScanResult:
    """Scan the residual of ``current`` for local modes; peaks near ``existing_hz`` are left
    out (modes the model already has). Its threshold is at the ``α`` of one test of the
    diagnosis step's family (:func:`~viscorig.diagnosis.significance.alpha_of`)."""
    sensitivity = log_sensitivity(current.model, current.values, data)
    residual = Residual(current, data)
    grid, u = _grid(data.data.frequency_hz)
    length, count = 0.0, 0
    best: list[tuple[float, float, float, float, float]] = []  # (Δχ², f_n, ζ, m, robust Δχ²)
    measured: list[Family] = []
    if grid:  # every family's templates whitened as one matrix (points, templates)
        measured = residual.families(sensitivity, [f_n.size for _, f_n in grid], shared=u)
    for (zeta, f_n), family in zip(grid, measured, strict=True):
        ok, norm = family.ok, np.where(family.ok, family.norm, 1.0)
        length += family.length
        count += int(np.count_nonzero(ok))
        projection = np.where(ok, family.along_e / norm, 0.0)  # = ⟨t, e⟩/|t|
        mass = np.where(ok, -projection / norm, 0.0)
        gain = np.where(mass > 0, projection**2, 0.0)
        robust = np.where(mass > 0, np.maximum(-family.along_clipped / norm, 0.0) ** 2, 0.0)
        for i in range(f_n.size):
            best.append((float(gain[i]), float(f_n[i]), zeta, float(mass[i]), float(robust[i])))
    best.sort(reverse=True)
    peaks: list[Peak] = []
    for peak_gain, peak_hz, peak_zeta, peak_mass, peak_robust in best:
        if peak_gain <= 0:
            break
        if any(abs(p.frequency_hz - peak_hz) < max(SEPARATION_HZ, 4 * p.damping_ratio *
                                                     p.frequency_hz) for p in peaks):
            continue
        if any(abs(f - peak_hz) < 1.0 for f in existing_hz):
            continue
        peaks.append(Peak(peak_hz, peak_zeta, peak_mass, peak_robust))
        if len(peaks) >= 8:
            break
    return ScanResult(tuple(peaks), length,
                      scan_threshold(length, alpha_of(current.model, data)), count)
