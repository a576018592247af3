"""How noisy a point will be: the relative FRF error as a function of frequency, level and
integration time, from the physics of the measurement, with its constants estimated from data.

Physics. The analyser extracts each channel's complex amplitude by a single-frequency
correlation over the integration window ``T``: ``Y = (2/T) ∫ y(t) e^{-iωt} dt``. White sensor
noise of one-sided density ``S`` (EU²/Hz) adds to each of the real and imaginary parts a
variance ``S/T``, so ``E|δY|² = 2S/T``. An FRF is a ratio of two channels, so its relative error
``ε = δY/Y − δX/X`` has ::

    E|ε|² = (2/T) · ( S_F/|F|² + S_a/|a|² + r )

where ``F`` is the force channel (``F_e`` for ``ẍ_s/F_e``, ``F_v`` for ``ẍ_v/F_v``), ``a`` the
acceleration channel, and ``r`` (1/Hz) the converters' floor, which scales with the input range
and so is a constant *relative* density (the autorange keeps each range a fixed factor above its
signal). Under constant-acceleration control the accelerations hold the level while the forces
follow the dynamic stiffness: ``|F_v| = |ẍ_v|/|H_support|`` falls towards high frequency (the
specimen's stiffness against the disc's inertia), ``|F_e|`` dips at the system's resonance. That
is why the information lies where it does, and why integration time buys least at the top of
the band.

Estimate. ``S_F``, ``S_a`` and ``r`` of each FRF are fitted to the per-point noise powers of
points already measured (a first look at known cycles), as the core's noise model gives them
(:func:`shared_noise`: the analyser's normalized variance where the instrument gives it, else
the core's estimate from the data). The fit is a gamma quasi-likelihood with a linear,
non-negative mean (iteratively reweighted non-negative least squares), because a single point's
noise power scatters like an exponential variable.
The channel amplitudes at frequencies not yet measured come from a fitted model of the rig
(:func:`model_amplitudes`).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.optimize import nnls

from viscorig.fitting import NoiseModel
from viscorig.fitting import estimate_noise as estimate_shared_noise
from viscorig.models import Context, Model
from viscorig.planning.points import MeasuredPoints

__all__ = [
    "ChannelAmplitudes",
    "FrfNoiseForecast",
    "NoiseForecast",
    "fit_noise_forecast",
    "measured_amplitudes",
    "model_amplitudes",
    "point_noise_power",
    "shared_noise",
]


@dataclass(frozen=True)
class ChannelAmplitudes:
    """Peak amplitude of every transducer at each frequency (engineering units).

    ``device_force`` and ``disc_acceleration`` are ``None`` on a bare table.
    """

    frequency_hz: NDArray[np.float64]
    excitation_force: NDArray[np.float64]
    table_acceleration: NDArray[np.float64]
    device_force: NDArray[np.float64] | None = None
    disc_acceleration: NDArray[np.float64] | None = None

    def pair(self, frf: str) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """``(force, acceleration)`` amplitudes of the channels of one FRF."""
        if frf == "table":
            return self.excitation_force, self.table_acceleration
        if self.device_force is None or self.disc_acceleration is None:
            raise ValueError("a bare table has no support FRF")
        return self.device_force, self.disc_acceleration


@dataclass(frozen=True)
class FrfNoiseForecast:
    """Noise densities behind one FRF.

    Attributes
    ----------
    force_psd
        Force transducer noise, one-sided, N²/Hz.
    acceleration_psd
        Accelerometer noise, one-sided, (m/s²)²/Hz.
    relative_psd
        Range-relative floor of both converters together, 1/Hz.
    """

    force_psd: float
    acceleration_psd: float
    relative_psd: float

    def rate(self, force: ArrayLike, acceleration: ArrayLike) -> NDArray[np.float64]:
        """``T · E|ε|²`` (s): relative noise power times integration time."""
        force = np.asarray(force, dtype=float)
        acceleration = np.asarray(acceleration, dtype=float)
        with np.errstate(divide="ignore"):
            return 2.0 * (
                self.force_psd / force**2
                + self.acceleration_psd / acceleration**2
                + self.relative_psd
            )


@dataclass(frozen=True)
class NoiseForecast:
    """Relative noise power of each FRF of a point: ``E|ε|² = rate(f) / T``.

    Attributes
    ----------
    frfs
        ``{"table": FrfNoiseForecast, "support": FrfNoiseForecast}`` (``support`` absent on a
        bare table).
    source
        Where the constants were estimated from (``"analyser variance"``, ``"fit residuals"``).
    """

    frfs: Mapping[str, FrfNoiseForecast]
    source: str = ""
    local: Mapping[str, tuple[NDArray[np.float64], NDArray[np.float64]]] = field(
        default_factory=dict
    )

    def rate(self, frf: str, amplitudes: ChannelAmplitudes) -> NDArray[np.float64]:
        """``T · E|ε|²`` of one FRF at the amplitudes' frequencies, s (with the measured
        correction where a frequency was measured, :meth:`calibrated`)."""
        force, acceleration = amplitudes.pair(frf)
        rate = self.frfs[frf].rate(force, acceleration)
        if frf in self.local:
            frequencies, factors = self.local[frf]
            index = np.clip(np.searchsorted(frequencies, amplitudes.frequency_hz), 0,
                            max(frequencies.size - 1, 0))  # fmt: skip
            hit = np.abs(frequencies[index] - amplitudes.frequency_hz) < 1e-9
            rate = np.where(hit, rate * factors[index], rate)
        return rate

    def calibrated(
        self, points: MeasuredPoints, power: Mapping[str, ArrayLike]
    ) -> NoiseForecast:
        """This model corrected, at every frequency already measured, to what the points
        there measured (the median of ``E|ε|² T`` over the model's rate at that frequency).

        The physics leaves out what only a measurement knows: the converters' floor follows
        the input range, which the autorange sets in 2 dB steps, so at a given frequency the
        floor sits anywhere between 1.25 and 1.6 times the signal's share. A frequency that is
        measured again is predicted from its own past.
        """
        amplitudes = measured_amplitudes(points)
        local = {}
        for frf, values in power.items():
            if frf not in self.frfs:
                continue
            force, acceleration = amplitudes.pair(frf)
            ratio = np.asarray(values, float) * points.integrate_s / self.frfs[frf].rate(
                force, acceleration)  # fmt: skip
            frequencies, inverse = np.unique(points.frequency_hz, return_inverse=True)
            factors = np.array([np.median(ratio[inverse == i]) for i in range(frequencies.size)])
            local[frf] = (frequencies, np.where(np.isfinite(factors), factors, 1.0))
        return NoiseForecast(self.frfs, self.source, local)

    def power(
        self, frf: str, amplitudes: ChannelAmplitudes, integrate_s: ArrayLike
    ) -> NDArray[np.float64]:
        """``E|ε|²`` of one FRF for an integration of ``integrate_s`` seconds."""
        return self.rate(frf, amplitudes) / np.asarray(integrate_s, dtype=float)

    def scaled(self, factor: float) -> NoiseForecast:
        """Every density multiplied by ``factor``."""
        return NoiseForecast(
            {
                name: FrfNoiseForecast(n.force_psd * factor, n.acceleration_psd * factor,
                               n.relative_psd * factor)
                for name, n in self.frfs.items()
            },
            self.source,
            self.local,
        )  # fmt: skip


def measured_amplitudes(points: MeasuredPoints) -> ChannelAmplitudes:
    """Channel amplitudes of measured points, from the stored per-point quantities.

    ``|F_e|`` is stored; the reference accelerometer's amplitude is stored (the disc's on a
    specimen run, the table's on a bare table); the other two follow from the FRFs.
    """
    force_e = np.abs(points.force_amplitude)
    reference = np.abs(points.reference_amplitude)
    if points.accelerance_support is None:
        return ChannelAmplitudes(points.frequency_hz, force_e, reference)
    table_acc = np.abs(points.accelerance_table) * force_e
    device_force = reference / np.abs(points.accelerance_support)
    return ChannelAmplitudes(points.frequency_hz, force_e, table_acc, device_force, reference)


def model_amplitudes(
    model: Model,
    values: Mapping[str, float],
    frequency_hz: ArrayLike,
    level_m_per_s2: float,
    *,
    force_limit_n: float | None = None,
) -> ChannelAmplitudes:
    """Channel amplitudes a model predicts under constant-acceleration control.

    The reference accelerometer (the disc's, or the table's on a bare table) holds
    ``level_m_per_s2``. With a finite link ``K_c``, ``ẍ_s = ẍ_v (1 − ω²/(K_c H_support))``
    (``x_s − x_v = F_v/K_c``); with a rigid one the table moves with the disc. Where the shaker
    would need more than ``force_limit_n`` every amplitude is scaled down to the limit, as the
    controller's source limit does.
    """
    f = np.atleast_1d(np.asarray(frequency_hz, dtype=float))
    ctx = Context(f, np.zeros_like(f), np.full_like(f, level_m_per_s2))
    predicted = model.predict(ctx, values)
    table = predicted["table"]
    if "support" not in predicted:
        force_e = level_m_per_s2 / np.abs(table)
        scale = _force_scale(force_e, force_limit_n)
        return ChannelAmplitudes(f, force_e * scale, np.full_like(f, level_m_per_s2) * scale)
    support = predicted["support"]
    disc = np.full_like(f, level_m_per_s2)
    omega2 = (2 * np.pi * f) ** 2
    k_c = values.get("K_c")
    transmission = 1.0 - omega2 / (k_c * support) if k_c else np.ones_like(f)
    table_acc = disc * np.abs(transmission)
    force_e = table_acc / np.abs(table)
    device_force = disc / np.abs(support)
    scale = _force_scale(force_e, force_limit_n)
    return ChannelAmplitudes(
        f, force_e * scale, table_acc * scale, device_force * scale, disc * scale
    )


def _force_scale(force_e: NDArray[np.float64], limit: float | None) -> NDArray[np.float64]:
    if limit is None:
        return np.ones_like(force_e)
    return np.minimum(1.0, limit / np.maximum(force_e, 1e-300))


def shared_noise(points: MeasuredPoints) -> NoiseModel:
    """The core's noise model (:class:`viscorig.fitting.NoiseModel`) of measured points, in
    the order of :meth:`MeasuredPoints.frf_data` (frequency order), as ``identify`` estimates
    it for a run (:func:`viscorig.fitting.estimate_noise`).

    A plan's points are not a dense, even grid: there the core takes the analyser's normalized
    variance of each point at face value (the differences of neighbouring points would read
    the FRF's shape between sparse points as noise), and a scatter beyond it still shows in a
    fit's χ² (:func:`viscorig.fitting.fit` scales its covariance by the misfit).
    """
    data = points.frf_data()
    return estimate_shared_noise(data, data.available)


def point_noise_power(
    points: MeasuredPoints, noise: NoiseModel | None = None
) -> tuple[dict[str, NDArray[np.float64]], str]:
    """Per-point relative noise power ``E|ε_i|²`` of each FRF, in measurement order, from the
    core's noise model of the points (:func:`shared_noise` unless given), and its source."""
    noise = shared_noise(points) if noise is None else noise
    order = np.argsort(points.frequency_hz, kind="stable")
    back = np.empty_like(order)
    back[order] = np.arange(order.size)
    sources = {block.source for blocks in noise.blocks.values() for block in blocks}
    return {name: noise.power(name)[back] for name in noise.frfs}, ", ".join(sorted(sources))


def fit_noise_forecast(
    points: MeasuredPoints, power: Mapping[str, ArrayLike], source: str = ""
) -> NoiseForecast:
    """Fit the densities of each FRF to per-point noise powers of measured points.

    Parameters
    ----------
    points
        The measured points (their integration times and channel amplitudes).
    power
        ``{frf: |ε_i|²}`` per point (:func:`point_noise_power`).
    source
        Recorded in the result.
    """
    amplitudes = measured_amplitudes(points)
    integrate_s = points.integrate_s
    frfs = {}
    for name, values in power.items():
        force, acceleration = amplitudes.pair(name)
        y = np.asarray(values, dtype=float)
        design = (2.0 / integrate_s)[:, None] * np.column_stack(
            [1.0 / force**2, 1.0 / acceleration**2, np.ones_like(force)]
        )
        good = np.isfinite(y) & (y > 0) & np.all(np.isfinite(design), axis=1)
        frfs[name] = FrfNoiseForecast(*_gamma_nnls(design[good], y[good]))
    return NoiseForecast(frfs, source)


def _gamma_nnls(design: NDArray[np.float64], y: NDArray[np.float64]) -> NDArray[np.float64]:
    """Non-negative ``c`` with ``E[y] = design @ c`` and ``Var y ∝ E[y]²`` (gamma family):
    iteratively reweighted NNLS, each row divided by its current mean."""
    if y.size == 0:
        raise ValueError("no point with a usable noise power")
    scale = np.max(np.abs(design), axis=0)
    scale[scale == 0] = 1.0
    x = design / scale
    mean = np.full_like(y, np.median(y))
    coefficients = np.zeros(x.shape[1])
    for _ in range(30):
        solution, _ = nnls(x / mean[:, None], y / mean)
        new_mean = np.maximum(x @ solution, 1e-12 * np.median(y))
        done = np.allclose(solution, coefficients, rtol=1e-6, atol=0.0)
        coefficients, mean = solution, new_mean
        if done:
            break
    return coefficients / scale
