"""How long to settle: the residual transient after a frequency change, from identified damping.

When the source jumps from ``f_prev`` to ``f`` (phase-continuous, as the analyser's source is),
the rig starts from the old steady state; the difference to the new steady state decays as a
free vibration of each mode, ``∝ e^{−ζ ω_n t}``. Under constant-acceleration control the disc's
displacement amplitude is ``a/ω²`` and its phase to the source is ``ψ(f) = arg H(f)``, so the
initial mismatch, relative to the new motion, is the larger of the displacement and velocity
mismatches ::

    δ_step = max(|(ω/ω_p)² e^{i(ψ_p − ψ)} − 1|, |(ω/ω_p) e^{i(ψ_p − ψ)} − 1|)

and when the needed source level changes by more than the auto-level tolerance the controller
measures once more after correcting it, which restarts a transient of relative size
``|V_p/V − 1|``. The correlation over the integration window ``T`` then sees the transient
reduced by ``g = (|∫_0^T e^{(λ−iω)t}dt| + |∫_0^T e^{(λ*−iω)t}dt|)/T`` (``λ = −ζω_n + iω_d``), and
the bias of the point is about ::

    bias = s · δ · g · e^{−ζ ω_n t_settle}

with ``s`` = 2 for the two channels of the ratio. The settle time keeps it below
``bias_fraction`` of the point's noise standard deviation. A local (fixture) mode of mass ``m``
on a disc of mass ``M_v`` takes part with ``(m/M_v) · max|r(ω)|``, ``r`` its dynamic
amplification, so it only matters near its own frequency.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from viscorig.estimates import measured_resonance
from viscorig.models import Context, Model

__all__ = ["Mode", "identified_modes", "settle_s"]

#: The transient shows in both channels of an FRF ratio.
CHANNEL_FACTOR = 2.0


@dataclass(frozen=True)
class Mode:
    """A lightly damped mode: natural frequency, damping ratio, and how much it takes part.

    ``participation`` is 1 for the system's own mode; a local mode's is
    ``mass_ratio · max|r(ω)|`` at the frequencies of the change (:meth:`weight`).
    """

    frequency_hz: float
    damping_ratio: float
    mass_ratio: float = 0.0  # 0: the system's own mode (participation 1)

    @property
    def decay_per_s(self) -> float:
        """``ζ ω_n``."""
        return self.damping_ratio * 2.0 * np.pi * self.frequency_hz

    def eigenvalue(self) -> complex:
        w_n = 2.0 * np.pi * self.frequency_hz
        z = min(self.damping_ratio, 0.999)
        return complex(-z * w_n, w_n * np.sqrt(1.0 - z * z))

    def weight(self, *frequency_hz: float) -> float:
        """Participation in a change between these frequencies."""
        if self.mass_ratio == 0.0:
            return 1.0
        ratio = np.asarray(frequency_hz, dtype=float) / self.frequency_hz
        amplification = 1.0 / np.abs(1.0 - ratio**2 + 2j * self.damping_ratio * ratio)
        return float(min(1.0, self.mass_ratio * amplification.max()))


def identified_modes(
    model: Model,
    values: Mapping[str, float],
    band_hz: tuple[float, float],
    *,
    fallback_damping_ratio: float = 0.02,
) -> list[Mode]:
    """The modes a fitted model shows: the system's resonance read off its predicted table FRF
    (peak and half-power bandwidth on a fine grid over a band widened by an octave each way),
    and every fixture term's own mode.

    When the predicted FRF has no resonance with both half-power points in that range, the
    system's mode is taken at the band's lower edge with ``fallback_damping_ratio``.
    """
    lo, hi = band_hz
    f = np.geomspace(max(lo / 2.0, 0.1), hi * 2.0, 4000)
    ctx = Context(f, np.zeros_like(f), np.ones_like(f))
    table = model.predict(ctx, values)["table"]
    peak = measured_resonance(f, table)
    if np.isfinite(peak.damping_factor) and peak.damping_factor > 0:
        modes = [Mode(peak.peak_hz, peak.damping_factor)]
    else:
        modes = [Mode(lo, fallback_damping_ratio)]
    disc_mass = float(values.get("M_v", np.nan))
    for name in values:
        if name == "f_n" or name.startswith("f_n_"):
            suffix = name[3:]
            mass = float(values.get("m" + suffix, 0.0))
            zeta = float(values.get("zeta" + suffix, fallback_damping_ratio))
            ratio = mass / disc_mass if np.isfinite(disc_mass) and disc_mass > 0 else 1.0
            modes.append(Mode(float(values[name]), zeta, max(ratio, 1e-12)))
    return modes


def _window_gain(mode: Mode, omega: float, integrate_s: float) -> float:
    """``g``: what the correlation over the window leaves of a unit transient of the mode."""
    lam = mode.eigenvalue()
    total = 0.0
    for mu in (lam - 1j * omega, np.conj(lam) - 1j * omega):
        total += abs((1.0 - np.exp(mu * integrate_s)) / mu)
    return min(1.0, total / integrate_s)


def step_mismatch(
    frequency_hz: float,
    previous_hz: float | None,
    response: Callable[[NDArray[np.float64]], NDArray[np.complex128]],
    source_ratio: float = 1.0,
    tolerance_db: float = 1.0,
) -> float:
    """``δ``: the transient's initial size relative to the new steady motion.

    ``response(f)`` is the table accelerance (its phase is the motion's phase to the source);
    ``source_ratio`` is the needed source level at ``frequency_hz`` over that at
    ``previous_hz``. From rest (``previous_hz`` ``None``) ``δ`` is 1.
    """
    if previous_hz is None:
        return 1.0
    h = response(np.array([previous_hz, frequency_hz]))
    rotation = np.exp(1j * (np.angle(h[0]) - np.angle(h[1])))
    ratio = frequency_hz / previous_hz
    delta = max(abs(ratio**2 * rotation - 1.0), abs(ratio * rotation - 1.0))
    if abs(20.0 * np.log10(source_ratio)) > tolerance_db:
        delta = max(delta, abs(1.0 / source_ratio - 1.0))
    return float(delta)


def settle_s(
    frequency_hz: float,
    previous_hz: float | None,
    modes: list[Mode],
    *,
    mismatch: float,
    noise_sd: float,
    integrate_s: float,
    bias_fraction: float = 0.3,
) -> float:
    """Settle time (s) that keeps the transient's bias below ``bias_fraction · noise_sd``.

    Parameters
    ----------
    frequency_hz, previous_hz
        The point and the one before it (``None``: from rest).
    modes
        :func:`identified_modes`.
    mismatch
        :func:`step_mismatch`.
    noise_sd
        Relative noise standard deviation of the point (the larger of its FRFs').
    integrate_s
        The point's integration time.
    bias_fraction
        Bias allowed, as a fraction of ``noise_sd``.
    """
    omega = 2.0 * np.pi * frequency_hz
    allowed = bias_fraction * noise_sd
    longest = 0.0
    for mode in modes:
        frequencies = (frequency_hz,) if previous_hz is None else (previous_hz, frequency_hz)
        size = CHANNEL_FACTOR * mismatch * mode.weight(*frequencies)
        size *= _window_gain(mode, omega, integrate_s)
        if size > allowed and mode.decay_per_s > 0:
            longest = max(longest, float(np.log(size / allowed) / mode.decay_per_s))
    return longest


