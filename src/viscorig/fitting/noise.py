"""The noise model of a measured FRF, shared by the whole core.

What it describes. A measured accelerance is ``H_i = H_true,i (1 + ε_i)``; ``ε_i`` is the
relative error of point ``i`` (complex: ``Re ε`` the relative magnitude error, ``Im ε`` the
phase error in radians). A perfect model leaves the residual ``H_model/H_measured − 1 ≈ −ε``,
so the model of ``ε`` is what the error measure, the standard errors and the significance tests
all need. Per FRF, ``ε`` is modelled as the sum of two independent Gaussian parts:

- *white*: independent from point to point, circular (real and imaginary parts each carry half),
  with a power ``w_i = E|ε_w,i|²`` that changes along the band (under constant-acceleration
  control the forces, and so their relative noise, change by orders of magnitude);
- *correlated*: a stationary Gauss-Markov (Ornstein-Uhlenbeck) process in the test time ``t``,
  with variance ``σ_re²`` on the real and ``σ_im²`` on the imaginary part and correlation
  ``exp(−|t_i − t_j|/τ)``: the slow drift of a transducer's sensitivity or of a conditioning
  phase during the sweep. Its variance does not depend on the signal level (a relative gain).

Where the data carry no test time, the point index stands for it (``axis_unit`` "point").
The covariance of the stacked real residual ``[Re ε; Im ε]`` is block diagonal:
``Σ_re = diag(w/2) + σ_re² R``, ``Σ_im = diag(w/2) + σ_im² R``, ``R_ij = exp(−|t_i − t_j|/τ)``.

What it offers (:class:`NoiseModel`, one or more FRFs): the total power per point
(:meth:`NoiseModel.power`, the local ``σ_i²``), the noise floor (:attr:`NoiseModel.floor`), the
whitening of residual vectors and Jacobians (:meth:`NoiseModel.whiten`, Cholesky factors of the
blocks, so that ``‖whiten(r)‖² = rᵀ Σ⁻¹ r``), the Gaussian log-likelihood, χ² and BIC of a
residual, the effective number of independent points, and the sandwich covariance of a
least-squares estimate under this noise (:meth:`NoiseModel.sandwich`).

The estimation from the data alone is in :mod:`viscorig.fitting.noise_estimation`.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray
from scipy.linalg import cho_factor, solve_triangular
from scipy.linalg.lapack import dtbtrs

#: Parts of the relative error, in the order of the fitter's stacked real residual.
PARTS = ("re", "im")


def exponential_kernel_apply(
    axis: NDArray[np.float64], tau: float, values: NDArray[np.float64]
) -> NDArray[np.float64]:
    """``R @ values`` with ``R_ij = exp(−|t_i − t_j|/τ)``, in O(n) per column.

    ``R`` is the covariance of a Gauss-Markov process: it splits into a causal and an
    anti-causal exponential filter, ``y_i = Σ_{j≤i} e^{−(t_i−t_j)/τ} x_j + Σ_{j≥i} … − x_i``,
    each a cumulative sum after scaling by ``e^{±t/τ}`` (in blocks short enough not to
    overflow).

    Parameters
    ----------
    axis
        ``t_i`` in any order (``values`` rows follow it).
    tau
        Correlation length, in the unit of ``axis``.
    values
        ``(n,)`` or ``(n, k)`` real array.
    """
    x = np.asarray(values, dtype=float)
    flat = x.ndim == 1
    if flat:
        x = x[:, None]
    order = np.argsort(axis, kind="stable")
    s = np.asarray(axis, dtype=float)[order] / tau
    xs = x[order]
    forward = _causal_exponential(s, xs)
    backward = _causal_exponential(-s[::-1], xs[::-1])[::-1]
    result = np.empty_like(xs)
    result[order] = forward + backward - xs
    return result[:, 0] if flat else result


#: Largest span of ``t/τ`` handled in one cumulative sum (``e^300`` is far from overflow).
_BLOCK_SPAN = 300.0


def _causal_exponential(s: NDArray[np.float64], x: NDArray[np.float64]) -> NDArray[np.float64]:
    """``y_i = Σ_{j≤i} e^{−(s_i − s_j)} x_j`` for non-decreasing ``s``."""
    n = s.size
    y = np.empty_like(x)
    start, carry, s_carry = 0, None, 0.0
    while start < n:
        stop = int(np.searchsorted(s, s[start] + _BLOCK_SPAN, side="right"))
        stop = max(stop, start + 1)
        offset = s[start:stop] - s[start]
        scale = np.exp(offset)[:, None]
        block = np.cumsum(x[start:stop] * scale, axis=0) / scale
        if carry is not None:
            block += carry[None, :] * np.exp(-(s[start:stop] - s_carry))[:, None]
        y[start:stop] = block
        carry, s_carry = block[-1], s[stop - 1]
        start = stop
    return y


#: From this many columns on, :meth:`MarkovWhitening.apply` filters row by row across the
#: columns instead of solving column by column (on 1,604 rows: 2.2× faster at the scan's 2,500
#: columns, 1.5× at the frame's 640; the two cross between 200 and 250).
WIDE_COLUMNS = 256


def monotone(axis: NDArray[np.float64]) -> bool:
    """The points are in the order of ``axis`` (either way): a drift along it is then whitened
    in O(n) (:class:`MarkovWhitening`), else through a dense Cholesky factor."""
    gaps = np.diff(np.asarray(axis, dtype=float))
    return bool(np.all(gaps >= 0) or np.all(gaps <= 0))


@dataclass(frozen=True)
class MarkovWhitening:
    """``L⁻¹`` of ``Σ = diag(d) + σ² R`` (``R_ij = exp(−|t_i − t_j|/τ)``, ``Σ = L Lᵀ``) for
    points in monotone time order, applied in O(n) per column.

    Along a monotone axis the correlated part is a Markov process observed with white noise,
    so ``(L⁻¹ y)_i`` is the normalised innovation of its Kalman filter,
    ``(y_i − a_i m_{i−1}) / √S_i``, with ``a_i = exp(−|t_i − t_{i−1}|/τ)`` and the filtered
    mean ``m_i = a_i (1 − K_i) m_{i−1} + K_i y_i``. The gains ``K_i`` and innovation variances
    ``S_i`` depend on the covariance alone (computed once); the mean is one bidiagonal
    triangular solve. The same numbers as the dense Cholesky factor's triangular solve, without
    its ``n²`` cost per column.
    """

    step: NDArray[np.float64]
    """``a_i`` (the first ``0``): the process's decay from the previous point."""
    decay: NDArray[np.float64]
    """``a_i (1 − K_i)``: the filtered mean's decay."""
    gain: NDArray[np.float64]
    """``K_i``."""
    scale: NDArray[np.float64]
    """``1/√S_i``."""
    band: NDArray[np.float64] = field(repr=False)
    """``I − B`` of the filtered mean's recursion in LAPACK's lower band storage."""

    @classmethod
    def of(
        cls, white: NDArray[np.float64], sigma2: float, axis: NDArray[np.float64], tau: float
    ) -> MarkovWhitening | None:
        """The whitening of ``diag(white) + sigma2 R``; ``None`` when ``axis`` is not monotone
        (the points are then not in the process's order)."""
        axis = np.asarray(axis, dtype=float)
        if axis.size == 0 or not monotone(axis):
            return None
        gaps = np.diff(axis)
        step = np.concatenate([[0.0], np.exp(-np.abs(gaps) / tau)])
        n = axis.size
        gain, variance = np.empty(n), np.empty(n)
        filtered = 0.0
        for i in range(n):  # the Riccati recursion: once per block, O(n)
            a = step[i]
            predicted = a * a * filtered + sigma2 * (1.0 - a * a)
            variance[i] = predicted + white[i]
            gain[i] = predicted / variance[i]
            filtered = (1.0 - gain[i]) * predicted
        decay = step * (1.0 - gain)
        band = np.zeros((2, n))
        band[0] = 1.0
        band[1, :-1] = -decay[1:]
        return cls(step, decay, gain, 1.0 / np.sqrt(variance), band)

    @classmethod
    def joined(cls, pieces: Sequence[MarkovWhitening | NDArray[np.float64]]) -> MarkovWhitening:
        """One whitening of independent pieces stacked end to end: each a
        :class:`MarkovWhitening` or the ``1/σ_i`` of white noise. No piece's process reaches
        into the next (its first ``a_i`` is 0), so one banded solve whitens them all."""
        arrays: dict[str, list[NDArray[np.float64]]] = {
            "step": [], "decay": [], "gain": [], "scale": []}
        for piece in pieces:
            if isinstance(piece, MarkovWhitening):
                own = {"step": piece.step, "decay": piece.decay, "gain": piece.gain,
                       "scale": piece.scale}
            else:
                scale = np.asarray(piece, dtype=float)
                zero = np.zeros_like(scale)
                own = {"step": zero, "decay": zero, "gain": zero, "scale": scale}
            for key, value in own.items():
                arrays[key].append(value)
        step, decay, gain, scale = (np.concatenate(arrays[key])
                                    for key in ("step", "decay", "gain", "scale"))
        band = np.zeros((2, step.size))
        band[0] = 1.0
        band[1, :-1] = -decay[1:]
        return cls(step, decay, gain, scale, band)

    def apply(self, values: NDArray[np.float64], *, overwrite: bool = False
              ) -> NDArray[np.float64]:
        """``L⁻¹ values`` (rows: points; a vector or a matrix); ``overwrite``: a float array
        ``values`` may hold the result (no copy of a wide matrix)."""
        y = np.asarray(values, dtype=float)
        flat = y.ndim == 1
        matrix = y[:, None] if flat else y.reshape(y.shape[0], -1)
        in_place = overwrite and y is values and np.shares_memory(matrix, y)
        if matrix.shape[1] >= WIDE_COLUMNS:
            mean = self._filtered_by_rows(matrix)
        else:
            # column-major for LAPACK, solved in place
            mean, info = dtbtrs(self.band, np.multiply(self.gain[:, None], matrix, order="F"),
                                uplo="L", diag="U", overwrite_b=True)
            if info != 0:
                raise np.linalg.LinAlgError(f"banded solve failed (info {info})")
        mean[:-1] *= (self.step[1:] * self.scale[1:])[:, None]
        if in_place:
            matrix *= self.scale[:, None]
            out = matrix
        else:
            out = matrix * self.scale[:, None]
        out[1:] -= mean[:-1]
        return out[:, 0] if flat else out.reshape(y.shape)

    def _filtered_by_rows(self, matrix: NDArray[np.float64]) -> NDArray[np.float64]:
        """The filtered means ``m_i = decay_i m_{i−1} + K_i y_i`` of every column, a row at a
        time: each step is one vector operation across the columns, where the banded solve
        makes a column at a time a chain of dependent scalar steps."""
        mean = np.multiply(self.gain[:, None], matrix, order="C")
        carried = np.empty(mean.shape[1])
        for i in np.flatnonzero(self.decay).tolist():  # a piece's first point carries nothing
            if i > 0:
                np.multiply(mean[i - 1], self.decay[i], out=carried)
                mean[i] += carried
        return mean


@dataclass
class FrfNoise:
    """The noise of one FRF of one run (see the module text for the model).

    Attributes
    ----------
    frf
        Name of the FRF (``"table"``, ``"support"``).
    white_power
        ``w_i = E|ε_w,i|²`` at each point (both parts together), in the data's point order.
    correlated_power
        ``(σ_re², σ_im²)``: variance of the correlated part on the real (magnitude) and the
        imaginary (phase) part of ``ε``.
    correlation_length
        ``τ``, in the unit of ``axis`` (seconds of test time, or points).
    axis
        ``t_i`` of each point (test time ``time_s``, or the point index).
    axis_unit
        ``"s"`` or ``"point"``.
    resolution
        Longest correlation length the data could resolve (same unit); a drift slower than
        this is indistinguishable from the FRF's own shape (see the estimation module).
    source
        How the white part was obtained (``"differences"`` or ``"analyser variance"``).
    outliers
        Points that stand alone far outside the noise (heavy-tailed noise), left out of the
        estimate; ``None`` when none were looked for. Their white power is the local one: a
        consumer that wants to ignore them must do so itself (a whitened residual there is
        large by construction).
    interference
        ``(Hz, ratio)`` of each multiple of the mains frequency where the white noise peaks,
        ``ratio`` times its median elsewhere (see
        :func:`~viscorig.fitting.noise_estimation.mains_interference`).
    """

    frf: str
    white_power: NDArray[np.float64] = field(repr=False)
    correlated_power: tuple[float, float] = (0.0, 0.0)
    correlation_length: float = 1.0
    axis: NDArray[np.float64] | None = field(default=None, repr=False)
    axis_unit: str = "point"
    resolution: float = math.inf
    source: str = "differences"
    outliers: NDArray[np.bool_] | None = field(default=None, repr=False)
    interference: tuple[tuple[float, float], ...] = ()
    _factors: dict[str, tuple[NDArray[np.float64], bool]] = field(
        default_factory=dict, repr=False, compare=False
    )
    _effective: float | None = field(default=None, repr=False, compare=False)
    _whitenings: dict[str, MarkovWhitening | NDArray[np.float64] | None] = field(
        default_factory=dict, repr=False, compare=False
    )

    def __post_init__(self) -> None:
        self.white_power = np.maximum(np.asarray(self.white_power, dtype=float), 1e-300)
        if self.axis is None:
            self.axis = np.arange(self.white_power.size, dtype=float)
        self.axis = np.asarray(self.axis, dtype=float)
        re, im = (max(float(v), 0.0) for v in self.correlated_power)
        self.correlated_power = (re, im)

    @property
    def size(self) -> int:
        """Number of points."""
        return int(self.white_power.size)

    @property
    def correlated(self) -> bool:
        """The model has a correlated part."""
        return max(self.correlated_power) > 0.0

    def power(self) -> NDArray[np.float64]:
        """``E|ε_i|²`` at each point: white plus correlated (both parts)."""
        return self.white_power + sum(self.correlated_power)

    def part_variance(self, part: str) -> tuple[NDArray[np.float64], float]:
        """Diagonal (white) variance and correlated variance of one part (``"re"``/``"im"``)."""
        return self.white_power / 2.0, self.correlated_power[PARTS.index(part)]

    @property
    def _positions(self) -> NDArray[np.float64]:
        """``axis``, which ``__post_init__`` always fills."""
        assert self.axis is not None
        return self.axis

    @property
    def dense(self) -> bool:
        """Its drift is whitened through dense Cholesky factors (the points out of the order of
        their axis), not in O(n)."""
        return self.correlated and not monotone(self._positions)

    def covariance(self, part: str) -> NDArray[np.float64]:
        """Dense covariance matrix of one part of ``ε`` (``n × n``)."""
        white, sigma2 = self.part_variance(part)
        matrix = np.diag(white)
        if sigma2 > 0.0:
            lag = np.abs(self._positions[:, None] - self._positions[None, :])
            matrix = matrix + sigma2 * np.exp(-lag / self.correlation_length)
        return matrix

    def apply_covariance(self, part: str, values: NDArray[np.float64]) -> NDArray[np.float64]:
        """``Σ_part @ values`` (rows: points) without forming ``Σ``."""
        white, sigma2 = self.part_variance(part)
        values = np.asarray(values, dtype=float)
        out = white.reshape((-1,) + (1,) * (values.ndim - 1)) * values
        if sigma2 > 0.0:
            out = out + sigma2 * exponential_kernel_apply(
                self._positions, self.correlation_length, values
            )
        return out

    def _factor(self, part: str) -> tuple[NDArray[np.float64], bool]:
        """Lower Cholesky factor of ``Σ_part`` (or the diagonal's square root), cached."""
        if part not in self._factors:
            white, sigma2 = self.part_variance(part)
            if sigma2 > 0.0:
                lower, _ = cho_factor(self.covariance(part), lower=True, check_finite=False)
                self._factors[part] = (np.tril(lower), True)
            else:
                self._factors[part] = (np.sqrt(white), False)
        return self._factors[part]

    def whitening(self, part: str) -> MarkovWhitening | NDArray[np.float64] | None:
        """What :meth:`whiten_part` applies, cached: ``1/σ`` of each point (a white part), the
        O(n) whitening of the drift along a monotone axis (:class:`MarkovWhitening`), or
        ``None`` (an axis out of order: the dense Cholesky factor is used)."""
        if part not in self._whitenings:
            white, sigma2 = self.part_variance(part)
            self._whitenings[part] = (
                MarkovWhitening.of(white, sigma2, self._positions, self.correlation_length)
                if sigma2 > 0.0 else 1.0 / np.sqrt(white)
            )
        return self._whitenings[part]

    def whiten_part(self, part: str, values: NDArray[np.float64]) -> NDArray[np.float64]:
        """``L⁻¹ values`` with ``Σ_part = L Lᵀ`` (rows: points; a vector or a matrix)."""
        values = np.asarray(values, dtype=float)
        operator = self.whitening(part)
        if isinstance(operator, MarkovWhitening):
            return operator.apply(values)
        if operator is not None:
            return values * operator.reshape((-1,) + (1,) * (values.ndim - 1))
        factor, _ = self._factor(part)
        return solve_triangular(factor, values, lower=True, check_finite=False)

    def logdet(self) -> float:
        """``log det Σ`` of both parts."""
        total = 0.0
        for part in PARTS:
            factor, dense = self._factor(part)
            diagonal = np.diag(factor) if dense else factor
            total += 2.0 * float(np.sum(np.log(diagonal)))
        return total

    def effective_points(self) -> float:
        """Independent real observations the FRF is worth: ``Σ_parts n² / ‖C_part‖_F²``.

        ``C`` is the correlation matrix of the part (covariance scaled to a unit diagonal),
        so white noise gives ``2n`` and a part dominated by a drift of correlation length ``ℓ``
        points gives about ``n/ℓ`` (the participation ratio of its eigenvalues).
        """
        if self._effective is not None:
            return self._effective
        n = self.size
        total = 0.0
        for part in PARTS:
            white, sigma2 = self.part_variance(part)
            if sigma2 <= 0.0:
                total += n
                continue
            diagonal = white + sigma2
            lag = np.abs(self._positions[:, None] - self._positions[None, :])
            off = sigma2 * np.exp(-lag / self.correlation_length)
            np.fill_diagonal(off, 0.0)
            scaled = off / np.sqrt(np.outer(diagonal, diagonal))
            total += n * n / (n + float(np.sum(scaled**2)))
        self._effective = total
        return total

    def select(self, index: NDArray) -> FrfNoise:
        """The same noise at a subset of the points."""
        return FrfNoise(
            self.frf,
            self.white_power[index],
            self.correlated_power,
            self.correlation_length,
            self._positions[index],
            self.axis_unit,
            self.resolution,
            self.source,
            None if self.outliers is None else self.outliers[index],
            self.interference,
        )

    def describe(self) -> str:
        """One line for humans: white level, drift level and correlation length."""
        text = f"{self.frf}: white rms {math.sqrt(float(np.mean(self.white_power))):.2g}"
        if self.correlated:
            re, im = (math.sqrt(v) for v in self.correlated_power)
            text += (
                f", correlated rms {re:.2g} (magnitude) / {im:.2g} (phase) over "
                f"{self.correlation_length:.3g} {self.axis_unit}"
            )
        count = 0 if self.outliers is None else int(np.count_nonzero(self.outliers))
        if count:
            text += f", {count} outlier point{'s' if count > 1 else ''}"
        for frequency, ratio in self.interference:
            text += (f"; it peaks at {frequency:g} Hz, {ratio:.3g} times its median: mains "
                     "interference (a ground loop, or pickup in a cable of this FRF's inputs)")
        return text + f" ({self.source})"


@dataclass
class NoiseModel:
    """The noise of every FRF fitted together: one or more blocks per FRF.

    ``blocks[frf]`` holds the :class:`FrfNoise` of consecutive segments of that FRF's points
    (one per run when runs are diagnosed together); the points of an FRF are the concatenation
    of its blocks, in the order the data hold them. Blocks are independent of each other.
    Residual vectors in the fitter's layout stack the real parts of every FRF, then the
    imaginary parts (``[Re r_table, Re r_support, Im r_table, Im r_support]``).
    """

    blocks: dict[str, list[FrfNoise]]

    @classmethod
    def of(cls, *noises: FrfNoise) -> NoiseModel:
        """A model of single-block FRFs."""
        return cls({noise.frf: [noise] for noise in noises})

    @classmethod
    def join(cls, models: Sequence[NoiseModel]) -> NoiseModel:
        """Runs side by side: the blocks of each FRF concatenated in the order given."""
        blocks: dict[str, list[FrfNoise]] = {}
        for model in models:
            for frf, parts in model.blocks.items():
                blocks.setdefault(frf, []).extend(parts)
        return cls(blocks)

    @property
    def frfs(self) -> tuple[str, ...]:
        """The FRFs described."""
        return tuple(self.blocks)

    def points(self, frf: str) -> int:
        """Points of one FRF."""
        return sum(block.size for block in self.blocks[frf])

    def power(self, frf: str) -> NDArray[np.float64]:
        """``E|ε_i|²`` at every point of one FRF (white plus correlated): the local ``σ_i²``."""
        return np.concatenate([block.power() for block in self.blocks[frf]])

    def outliers(self, frf: str) -> NDArray[np.bool_]:
        """The points of one FRF found far outside the noise (glitches)."""
        return np.concatenate([np.zeros(block.size, dtype=bool) if block.outliers is None
                               else np.asarray(block.outliers) for block in self.blocks[frf]])

    def scale(self, frf: str) -> NDArray[np.float64]:
        """``σ_i``: the rms relative error of each point of one FRF."""
        return np.sqrt(self.power(frf))

    def floor_of(self, frfs: Sequence[str] | None = None) -> float:
        """Noise floor of the error measure over the given FRFs (default all)."""
        frfs = self.frfs if frfs is None else tuple(frfs)
        return float(np.sqrt(np.mean(np.concatenate([self.power(frf) for frf in frfs]))))

    @property
    def floor(self) -> float:
        """``sqrt(mean σ_i²)`` over every point of every FRF: the ``rms_error`` a perfect model
        would reach (design.md), the same pooling as ``rms_error``."""
        return self.floor_of()

    @property
    def correlated(self) -> bool:
        """Some block has a correlated part."""
        return any(block.correlated for blocks in self.blocks.values() for block in blocks)

    def effective_points(self, frfs: Sequence[str] | None = None) -> float:
        """Independent real observations (see :meth:`FrfNoise.effective_points`)."""
        frfs = self.frfs if frfs is None else tuple(frfs)
        return float(sum(b.effective_points() for frf in frfs for b in self.blocks[frf]))

    # -- residual vectors ---------------------------------------------------------------------
    def _segments(self, frfs: Sequence[str]) -> list[tuple[str, int, FrfNoise]]:
        """``(part, offset, block)`` of every block in the stacked real layout."""
        out = []
        offset = 0
        for part in PARTS:
            for frf in frfs:
                for block in self.blocks[frf]:
                    out.append((part, offset, block))
                    offset += block.size
        return out

    def stack(self, residuals: Mapping[str, NDArray[np.complex128]], frfs=None) -> NDArray:
        """Complex residuals per FRF in the fitter's stacked real layout."""
        frfs = tuple(residuals) if frfs is None else tuple(frfs)
        joined = np.concatenate([np.asarray(residuals[frf]) for frf in frfs], axis=0)
        return np.concatenate([joined.real, joined.imag], axis=0)

    def _blockwise(self, values: NDArray, frfs: Sequence[str], operation: str) -> NDArray:
        """``FrfNoise.<operation>(part, rows)`` on every block's rows of the stacked layout."""
        values = np.asarray(values, dtype=float)
        out = np.empty_like(values)
        for part, offset, block in self._segments(frfs):
            rows = slice(offset, offset + block.size)
            out[rows] = getattr(block, operation)(part, values[rows])
        return out

    def stacked_variance(self, frfs: Sequence[str]) -> NDArray[np.float64]:
        """``diag Σ`` in the stacked layout of ``frfs``: each real component's own variance
        (white part plus the correlated part's variance)."""
        out = []
        for part, _, block in self._segments(frfs):
            white, sigma2 = block.part_variance(part)
            out.append(white + sigma2)
        return np.concatenate(out)

    def whiten_stacked(self, values: NDArray[np.float64], frfs: Sequence[str]) -> NDArray:
        """``Σ^{-1/2} values`` for a real vector or matrix in the stacked layout of ``frfs``."""
        return self._blockwise(values, frfs, "whiten_part")

    def whiten(self, residuals: Mapping[str, NDArray[np.complex128]]) -> NDArray[np.float64]:
        """Whitened residual: a real vector whose squared norm is ``rᵀ Σ⁻¹ r`` (unit variance,
        independent components when the model is right)."""
        frfs = tuple(residuals)
        return self.whiten_stacked(self.stack(residuals, frfs), frfs)

    def whiten_jacobian(
        self, jacobian: Mapping[str, NDArray[np.complex128]]
    ) -> NDArray[np.float64]:
        """Whitened Jacobian: complex ``∂r/∂p`` per FRF (points × parameters) to the real,
        stacked, whitened ``(2N × k)`` matrix matching :meth:`whiten`."""
        frfs = tuple(jacobian)
        return self.whiten_stacked(self.stack(jacobian, frfs), frfs)

    def apply_covariance(self, values: NDArray[np.float64], frfs: Sequence[str]) -> NDArray:
        """``Σ @ values`` for a real vector or matrix in the stacked layout of ``frfs``."""
        return self._blockwise(values, frfs, "apply_covariance")

    def chi2(self, residuals: Mapping[str, NDArray[np.complex128]]) -> float:
        """``rᵀ Σ⁻¹ r``: chi-square with (real observations − parameters) degrees of freedom
        for a maximum-likelihood fit of a right model."""
        return float(np.sum(self.whiten(residuals) ** 2))

    def logdet(self, frfs: Sequence[str] | None = None) -> float:
        """``log det Σ`` over the given FRFs (default all)."""
        frfs = self.frfs if frfs is None else tuple(frfs)
        return float(sum(block.logdet() for frf in frfs for block in self.blocks[frf]))

    def log_likelihood(self, residuals: Mapping[str, NDArray[np.complex128]]) -> float:
        """Gaussian log-likelihood of the residuals: ``−(χ² + log det Σ + n log 2π)/2``."""
        n = 2 * sum(np.asarray(r).size for r in residuals.values())
        return -0.5 * (self.chi2(residuals) + self.logdet(tuple(residuals)) + n * math.log(
            2 * math.pi))

    def bic(self, residuals: Mapping[str, NDArray[np.complex128]], parameters: int) -> float:
        """``χ² + k ln n_eff``: the Bayesian information criterion with this (known) noise,
        without the constant terms (they cancel between models of the same data). ``n_eff`` is
        :meth:`effective_points`: with correlated noise, fewer independent observations."""
        n_eff = max(self.effective_points(tuple(residuals)), 2.0)
        return self.chi2(residuals) + parameters * math.log(n_eff)

    def sandwich(
        self,
        jacobian: NDArray[np.float64],
        frfs: Sequence[str],
        weights: NDArray[np.float64] | None = None,
    ) -> NDArray[np.float64]:
        """Covariance of a least-squares estimate under this noise.

        For the estimate minimising ``‖V r(p)‖²`` (``V = diag(weights)``, default 1) with the
        stacked real Jacobian ``J = ∂r/∂p``: ``A⁻¹ Jᵀ V Σ V J A⁻¹`` with ``A = Jᵀ V² J``
        (exact to first order whatever ``V``; ``V = Σ^{-1/2}`` would give ``A⁻¹``).
        """
        jac = np.asarray(jacobian, dtype=float)
        vj = jac if weights is None else jac * weights[:, None]
        a = vj.T @ vj
        meat = vj.T @ self.apply_covariance(vj, frfs)
        inverse = np.linalg.pinv(a, rcond=1e-14, hermitian=True)
        return inverse @ meat @ inverse

    def select(self, frf: str, index: NDArray) -> NoiseModel:
        """The model of one single-block FRF at a subset of its points (and the other FRFs)."""
        blocks = dict(self.blocks)
        if len(blocks[frf]) != 1:
            raise ValueError("select works on single-block FRFs")
        blocks[frf] = [blocks[frf][0].select(index)]
        return NoiseModel(blocks)

    def describe(self) -> list[str]:
        """One line per block."""
        return [block.describe() for blocks in self.blocks.values() for block in blocks]
