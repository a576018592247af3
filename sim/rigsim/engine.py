"""The simulated rig as the analyser sees it: physics plus measuring front end.

:class:`RigSimulator` measures a :class:`~rigsim.measurement.SweepRequest` point by point, as the
35670A's swept sine does: at each frequency the source sine drives the shaker, the response runs
through the settle window, and each channel's complex amplitude is extracted over the integration
window by a single-frequency correlation. The state of the rig (positions, velocities, the
rubber's internal arm forces) carries from one point to the next, so a settle too short for a
lightly damped mode shows as a bias, as on a real rig.

The rig is linear and time-invariant within a point, so the time response is solved exactly
(no time step): steady-state phasor plus the homogeneous transient ``e^{At}(z0 - z_ss(0))`` in
modal coordinates, and the correlation integral of the transient in closed form
(:mod:`rigsim.dynamics`). All per-frequency quantities are computed at once for the sweep; the
sequential part (controller, carried state) is a cheap elementwise recurrence.

Clock semantics: :attr:`RigSimulator.clock_s` counts seconds of test time since the rig was
mounted (construction or :meth:`RigSimulator.mount`). Each controller iteration of a point costs
one settle plus one integration window; :meth:`RigSimulator.idle` lets time pass with the source
off. State and clock carry over from one :meth:`RigSimulator.sweep` call to the next, as if the
next sweep started right after the last one ended.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from rigsim.dynamics import ModalSystem, build_state_space
from rigsim.measurement import CHANNEL_COUNT, INPUT_RANGES_VPK, SweepRecord, SweepRequest
from rigsim.rigfile import Rig

__all__ = ["AUTORANGE_HEADROOM", "RigSimulator"]

#: Autorange picks the smallest range at least this many times the expected signal peak.
AUTORANGE_HEADROOM = 1.25
_RANGES_ASCENDING = np.sort(INPUT_RANGES_VPK)
#: Relative resolution at which modulus factors (drift, amplitude) share one modal solution.
_SCALE_RESOLUTION = 1e-9


@dataclass
class _Kernels:
    """Per-point closed-form factors of the measurement (leading axis: points)."""

    modal: ModalSystem
    steady: np.ndarray  # (P, 4)   channel phasor in volts per newton
    leakage: np.ndarray  # (P, 4)  image term of the correlation (non-integer cycles)
    delay_phase: np.ndarray  # (P, 4)  e^{-iωτ_d}
    transient: np.ndarray  # (P, 4, N) correlation of each mode's transient, volts
    bound: np.ndarray  # (P, 4, N) transient envelope at the start of integration, volts
    p_plus: np.ndarray  # (P, N)
    p_minus: np.ndarray  # (P, N)
    decay: np.ndarray  # (P, N) e^{λ t_end}
    rotation: np.ndarray  # (P,) e^{iω t_end}
    relative: np.ndarray  # (P,) displacement phasor across the specimens per newton


def _window_integral(mu: np.ndarray, start: np.ndarray, length: np.ndarray) -> np.ndarray:
    """∫_start^{start+length} e^{μσ} dσ, safe for μ → 0 and strongly decaying μ."""
    mu_t = mu * length
    small = np.abs(mu_t) < 1e-12
    safe_mu = np.where(small, 1.0, mu)
    with np.errstate(over="ignore", under="ignore", invalid="ignore"):
        value = np.exp(mu * start) * np.where(small, length, np.expm1(mu_t) / safe_mu)
    return np.where(np.isfinite(value), value, 0.0)


def _kernels(
    modal: ModalSystem,
    omega: np.ndarray,
    settle_s: np.ndarray,
    integrate_s: np.ndarray,
    delays_s: np.ndarray,
    sensitivity: np.ndarray,
) -> _Kernels:
    lam = modal.eigenvalues
    iw = 1j * omega[:, None]
    p_plus = modal.b_modal / (iw - lam)
    p_minus = modal.b_modal / (-iw - lam)
    steady = (p_plus @ modal.c_modal.T + modal.space.d) * sensitivity
    length = integrate_s[:, None]
    start = settle_s[:, None] - delays_s[None, :]  # (P, 4): window in the sensor's own time
    leakage = _window_integral(-2.0 * iw, start, length) / length
    delay_phase = np.exp(-iw * delays_s[None, :])
    # The transient is integrated from the point's start at the earliest: a delay longer than
    # the settle window would reach back into the previous point, which is not modelled.
    t_start = np.maximum(start, 0.0)[:, :, None]
    t_len = (start + length)[:, :, None] - t_start
    mu = (lam[None, :] - iw)[:, None, :]
    modal_integral = _window_integral(mu, t_start, t_len)
    c_volts = modal.c_modal * sensitivity[:, None]
    transient = (2.0 / length)[:, :, None] * delay_phase[:, :, None] * c_volts * modal_integral
    with np.errstate(under="ignore"):
        bound = np.abs(c_volts)[None] * np.exp(lam.real[None, None, :] * t_start)
    t_end = (settle_s + integrate_s)[:, None]
    with np.errstate(under="ignore"):
        decay = np.exp(lam[None, :] * t_end)
    return _Kernels(
        modal=modal,
        steady=steady,
        leakage=leakage,
        delay_phase=delay_phase,
        transient=transient,
        bound=bound,
        p_plus=p_plus,
        p_minus=p_minus,
        decay=decay,
        rotation=np.exp(iw[:, 0] * t_end[:, 0]),
        relative=p_plus @ modal.relative_modal,
    )


def _clipped_fundamental(ratio: np.ndarray) -> np.ndarray:
    """Fundamental of a sine clipped at ``ratio`` of its peak, relative to the sine (ratio<=1)."""
    a = np.clip(ratio, 0.0, 1.0)
    return (2.0 / np.pi) * (np.arcsin(a) + a * np.sqrt(1.0 - a * a))



class _Points:
    """What a sweep measured, point by point, until it becomes a :class:`SweepRecord`."""

    def __init__(self, points: int) -> None:
        self.channel_v = np.zeros((points, CHANNEL_COUNT), dtype=complex)
        self.variance = np.zeros((points, CHANNEL_COUNT))
        self.range_vpk = np.zeros((points, CHANNEL_COUNT))
        self.overload = np.zeros((points, CHANNEL_COUNT), dtype=bool)
        self.half_range = np.zeros((points, CHANNEL_COUNT), dtype=bool)
        self.source_vpk = np.zeros(points)
        self.level_reached = np.ones(points, dtype=bool)
        self.source_limited = np.zeros(points, dtype=bool)
        self.input_limited = np.zeros(points, dtype=bool)
        self.end_time = np.zeros(points)
        self.iterations = np.zeros(points, dtype=int)
        self.force_limited = np.zeros(points, dtype=bool)
        self.force_n = np.zeros(points)
        self.modulus_scale = np.ones(points)
        self.displacement = np.zeros(points)
        self.temperature = np.full(points, math.nan)

    def record(self, frequency_hz: np.ndarray) -> SweepRecord:
        return SweepRecord(
            frequency_hz=frequency_hz,
            channel_v=self.channel_v,
            variance=self.variance,
            range_vpk=self.range_vpk,
            overload=self.overload,
            half_range=self.half_range,
            source_vpk=self.source_vpk,
            level_reached=self.level_reached,
            source_limited=self.source_limited,
            input_limited=self.input_limited,
            end_time_s=self.end_time,
            extras={
                "iterations": self.iterations,
                "force_limited": self.force_limited,
                "excitation_force_n": self.force_n,
                "modulus_scale": self.modulus_scale,
                "specimen_displacement_m": self.displacement,
                "specimen_temperature_c": self.temperature,
            },
        )

class RigSimulator:
    """Time-domain simulation of the rig and the analyser's measuring front end.

    Parameters
    ----------
    rig
        The rig to simulate (:func:`rigsim.rigfile.load_rig`, :func:`rigsim.rigfile.load_preset`).
    seed
        Seed of the noise generator; ``None`` uses the rig's ``[noise] seed`` (if any, else a
        fresh random seed).
    """

    def __init__(self, rig: Rig, *, seed: int | None = None) -> None:
        if seed is None and rig.noise is not None:
            seed = rig.noise.seed
        self._rng = np.random.default_rng(seed)
        self._chamber = None
        self._chamber_advances = False
        self.mount(rig)

    # ------------------------------------------------------------------ state and clock

    @property
    def rig(self) -> Rig:
        """The rig currently mounted."""
        return self._rig

    @property
    def clock_s(self) -> float:
        """Seconds of test time since the rig was mounted."""
        return self._clock_s

    def mount(self, rig: Rig) -> None:
        """Mount a (new) rig: the structure is at rest and the clock restarts at 0 s.

        The noise generator continues (it is not reseeded).
        """
        self._rig = rig
        self._clock_s = 0.0
        self._phase = 0.0
        self._source_vpk = 0.0
        self._modal_cache: dict[float, ModalSystem] = {}
        base = build_state_space(rig, 1.0)
        self._a_base = base.a
        self._a_per_scale = build_state_space(rig, 2.0).a - base.a
        self._state = np.zeros(base.a.shape[0])
        self._scale = 1.0
        self._point: tuple[float, float, float, float] = (1.0, 1.0, 0.0, 0.0)
        self._displacement = 0.0
        # The true sensitivity of each channel: the nominal one times its gain error.
        self._sensitivity = np.array(
            [rig.sensors.force_v_per_n, rig.sensors.acceleration_v_per_m_s2] * 2
        ) * np.array(rig.sensors.gains())
        self._delays = np.array(rig.delays.as_tuple())
        noise = rig.noise
        self._gain_drift = np.zeros(CHANNEL_COUNT)
        self._gain_drift_time = 0.0
        self._gain_drift_started = False
        if noise is None:
            self._sensor_density = np.zeros(CHANNEL_COUNT)
            self._adc_density_re_range = 0.0
        else:
            asd = np.array(
                [
                    noise.excitation_force_n_per_sqrt_hz,
                    noise.table_acceleration_m_per_s2_per_sqrt_hz,
                    noise.device_force_n_per_sqrt_hz,
                    noise.disc_acceleration_m_per_s2_per_sqrt_hz,
                ]
            )
            self._sensor_density = (asd * self._sensitivity) ** 2  # V²/Hz, one-sided
            self._adc_density_re_range = 10.0 ** (noise.adc_noise_db_re_range_per_sqrt_hz / 10)

    def idle(self, duration_s: float) -> None:
        """Let ``duration_s`` seconds pass with the source off (free decay, clock advances)."""
        if not duration_s >= 0.0:
            raise ValueError(f"duration_s must be >= 0, not {duration_s}")
        self._state = self._modal(*self._point).free_decay(self._state, duration_s)
        self._clock_s += duration_s
        self._time_passes(duration_s)

    # ------------------------------------------------------------------ the chamber

    def attach_chamber(self, chamber: Any, *, advance: bool = True) -> None:
        """Put the specimens in a chamber (:class:`rigsim.chamber.Chamber`): the rubber's
        modulus follows its specimen temperature (the rig's ``[temperature]``).

        ``advance``: the test time this simulator spends (measuring, idling) passes in the
        chamber too (False: something else, a wall clock, moves the chamber's time).
        """
        self._chamber = chamber
        self._chamber_advances = advance

    @property
    def chamber(self) -> Any:
        """The chamber the specimens are in, or None."""
        return self._chamber

    def specimen_temperature_c(self) -> float:
        """The specimens' temperature (the chamber's, else the rig's reference, else NaN)."""
        if self._chamber is not None:
            return float(self._chamber.specimen_c)
        shift = self._rig.temperature
        return math.nan if shift is None else shift.reference_temperature_c

    def _time_shift(self) -> float:
        shift = self._rig.temperature
        if shift is None or self._chamber is None:
            return 1.0
        return 10.0 ** shift.log10_shift(float(self._chamber.specimen_c))

    def _time_passes(self, duration_s: float) -> None:
        if self._chamber is not None and self._chamber_advances and duration_s > 0.0:
            self._chamber.advance(duration_s)

    def state(self) -> np.ndarray:
        """Copy of the rig's state vector (positions, velocities, arm forces)."""
        return self._state.copy()

    def _modal(self, scale: float, shift: float = 1.0, stiffness: float = 0.0,
               damping: float = 0.0) -> ModalSystem:
        key = tuple(round(value / _SCALE_RESOLUTION) * _SCALE_RESOLUTION
                    for value in (scale, shift, stiffness, damping))
        modal = self._modal_cache.get(key)
        if modal is None:
            if len(self._modal_cache) > 256:
                self._modal_cache.clear()
            modal = ModalSystem(build_state_space(self._rig, *key))
            self._modal_cache[key] = modal
        return modal

    def _point_physics(self, omega: float, force_n: float, drift: float,
                       shift: float) -> tuple[float, float, float, float]:
        """(modulus factor, time shift, added stiffness, added damping) at which the specimens'
        own amplitude is consistent with the Payne effect and amplitude dependence (fixed
        point on the displacement across the specimens)."""
        amplitude, payne = self._rig.amplitude, self._rig.payne
        if payne is None:
            if amplitude is None:
                return drift, shift, 0.0, 0.0
            if shift == 1.0:
                return self._amplitude_scale(omega, force_n, drift), 1.0, 0.0, 0.0
        x = self._displacement
        point = (drift, shift, 0.0, 0.0)
        for _ in range(80):
            scale = drift * (1.0 if amplitude is None else amplitude.scale(x))
            storage, loss = (0.0, 0.0) if payne is None else payne.stiffness(x)
            point = (scale, shift, storage, loss / omega)
            space = build_state_space(self._rig, *point)
            size = space.a.shape[0]
            response = np.linalg.solve(1j * omega * np.eye(size) - space.a, space.b)
            new_x = abs(space.relative_displacement @ response) * force_n
            if abs(new_x - x) <= 1e-9 * max(new_x, 1e-15):
                x = new_x
                break
            x = 0.5 * (x + new_x)
        self._displacement = x
        return point

    def _amplitude_scale(self, omega: float, force_n: float, drift: float) -> float:
        """Modulus factor at which the specimens' own amplitude is consistent (fixed point)."""
        amplitude = self._rig.amplitude
        if amplitude is None:
            return drift
        space = build_state_space(self._rig, 1.0)
        relative = space.relative_displacement
        size = self._a_base.shape[0]
        scale = self._scale
        for _ in range(60):
            a = self._a_base + (scale - 1.0) * self._a_per_scale
            response = np.linalg.solve(1j * omega * np.eye(size) - a, space.b)
            displacement = abs(relative @ response) * force_n
            new_scale = drift * amplitude.scale(displacement)
            if abs(new_scale - scale) < 1e-10:
                return new_scale
            scale = 0.5 * (scale + new_scale)
        return scale

    # ------------------------------------------------------------------ measurement

    def sweep(self, request: SweepRequest) -> SweepRecord:
        """Measure every point of ``request`` in order; the clock and state advance.

        Returns
        -------
        SweepRecord
            ``channel_v`` holds each channel's complex amplitude (peak volts) referred to the
            source's phase. ``extras`` adds, per point: ``iterations`` (controller passes),
            ``force_limited`` (the shaker force saturated at ``[shaker] force_limit_n``),
            ``excitation_force_n`` (true force amplitude), ``modulus_scale`` (factor on K* from
            drift and amplitude dependence), ``specimen_displacement_m`` (steady displacement
            amplitude across the specimens).
        """
        frequency = np.asarray(request.frequency_hz, dtype=float).ravel()
        points = frequency.size
        settle = np.broadcast_to(np.asarray(request.settle_s, dtype=float), (points,)).copy()
        integrate = np.broadcast_to(np.asarray(request.integrate_s, dtype=float), (points,)).copy()
        self._check_request(frequency, settle, integrate, request)
        control = request.control
        omega = 2.0 * np.pi * frequency
        fixed_range = np.array(
            [np.nan if r is None else float(r) for r in request.input_range_vpk], dtype=float
        )

        varying = (self._rig.drift is not None or self._rig.amplitude is not None
                   or self._rig.payne is not None
                   or (self._rig.temperature is not None and self._chamber is not None))
        kernels = None
        if not varying:
            kernels = _kernels(
                self._modal(1.0), omega, settle, integrate, self._delays, self._sensitivity
            )

        out = _Points(points)
        gain = self._rig.shaker.force_n_per_v
        force_limit = self._rig.shaker.force_limit_n
        level = min(control.source_vpk, control.source_limit_vpk) if control.auto_level else (
            control.source_vpk
        )
        for n in range(points):
            drift = self._drift_now()
            out.temperature[n] = self.specimen_temperature_c()
            shift = self._time_shift()
            count = 0
            reached = not control.auto_level
            cap = None
            while True:
                count += 1
                force = min(gain * level, force_limit)
                scale, k, index = self._kernel_at(kernels, n, omega, settle, integrate, force,
                                                  drift, shift)
                measured, ranges, over, half = self._measure_point(
                    k, index, force, omega[n], integrate[n], fixed_range,
                    self._clock_s + settle[n] + 0.5 * integrate[n],
                )
                self._clock_s += settle[n] + integrate[n]
                self._time_passes(settle[n] + integrate[n])
                if not control.auto_level:
                    break
                reached, new_level, cap = self._next_level(level, measured, control)
                if reached or count >= control.max_iterations or (
                        abs(new_level - level) <= 1e-12 * level):
                    break
                level = new_level

            out.channel_v[n] = measured
            out.variance[n] = self._variance(measured, ranges, integrate[n])
            out.range_vpk[n] = ranges
            out.overload[n] = over
            out.half_range[n] = half
            out.source_vpk[n] = level
            out.level_reached[n] = reached
            out.source_limited[n] = not reached and cap == "source"
            out.input_limited[n] = not reached and cap == "input"
            out.end_time[n] = self._clock_s
            out.iterations[n] = count
            out.force_limited[n] = gain * level > force_limit
            out.force_n[n] = min(gain * level, force_limit)
            out.modulus_scale[n] = scale
            out.displacement[n] = abs(k.relative[index]) * out.force_n[n]
        self._source_vpk = level
        return out.record(frequency)

    def _drift_now(self) -> float:
        """The thermal drift's factor on the modulus now (refused once it is absurd)."""
        drift = 1.0 if self._rig.drift is None else self._rig.drift.scale(self._clock_s)
        if drift <= 0.05:
            raise ValueError(
                f"thermal drift has brought the modulus to {drift:.3g} of its value at "
                f"{self._clock_s:.0f} s: the rig file's drift rate is too large for this run"
            )
        return drift

    def _kernel_at(self, kernels, n: int, omega: np.ndarray, settle: np.ndarray,
                   integrate: np.ndarray, force: float, drift: float, shift: float):
        """``(modulus scale, kernels, index)`` of point ``n`` at this force: the sweep's
        kernels when nothing varies, else this point's, from its own physics."""
        if kernels is not None:
            return 1.0, kernels, n
        point = self._point_physics(omega[n], force, drift, shift)
        self._point = point
        self._scale = point[0]
        k = _kernels(
            self._modal(*point),
            omega[n : n + 1],
            settle[n : n + 1],
            integrate[n : n + 1],
            self._delays,
            self._sensitivity,
        )
        return point[0], k, 0

    def _next_level(self, level: float, measured: np.ndarray, control
                    ) -> tuple[bool, float, str | None]:
        """Auto level: ``(reached, next source level, what capped it)`` after one pass."""
        reference = abs(measured[control.reference_channel - 1])
        if reference > 0.0 and control.reference_vpk > 0.0:
            error_db = 20.0 * np.log10(control.reference_vpk / reference)
            if abs(error_db) <= control.tolerance_db:
                return True, level, None
            wanted = level * control.reference_vpk / reference
        else:
            wanted = np.inf
        new_level, cap = self._limit(wanted, level, measured, control)
        return False, new_level, cap

    def _variance(self, measured: np.ndarray, ranges: np.ndarray, integrate_s: float
                  ) -> np.ndarray:
        """Normalised variance of each channel's amplitude (0 without noise, inf at zero)."""
        noise_power = self._noise_power(ranges) * 2.0 / integrate_s
        magnitude2 = np.abs(measured) ** 2
        return np.where(
            noise_power == 0.0,
            0.0,
            noise_power / np.where(magnitude2 > 0.0, magnitude2, np.inf) * (magnitude2 > 0)
            + np.where(magnitude2 > 0.0, 0.0, np.inf),
        )

    @staticmethod
    def _check_request(
        frequency: np.ndarray, settle: np.ndarray, integrate: np.ndarray, request: SweepRequest
    ) -> None:
        if not np.all(np.isfinite(frequency)) or np.any(frequency <= 0.0):
            raise ValueError("frequency_hz must be finite and > 0")
        if not np.all(np.isfinite(settle)) or np.any(settle < 0.0):
            raise ValueError("settle_s must be finite and >= 0")
        if not np.all(np.isfinite(integrate)) or np.any(integrate <= 0.0):
            raise ValueError("integrate_s must be finite and > 0")
        if len(request.input_range_vpk) != CHANNEL_COUNT:
            raise ValueError(f"input_range_vpk needs {CHANNEL_COUNT} entries")
        control = request.control
        if not control.source_vpk >= 0.0 or not control.source_limit_vpk > 0.0:
            raise ValueError("source_vpk must be >= 0 and source_limit_vpk > 0")
        if control.auto_level and not 1 <= control.reference_channel <= CHANNEL_COUNT:
            raise ValueError("reference_channel must be 1..4")
        if control.input_limit_channel is not None and not (
            1 <= control.input_limit_channel <= CHANNEL_COUNT
        ):
            raise ValueError("input_limit_channel must be 1..4")

    @staticmethod
    def _limit(
        wanted: float, level: float, measured: np.ndarray, control
    ) -> tuple[float, str | None]:
        """Apply the source limit and the input limit to the level the controller wants."""
        new_level, cap = wanted, None
        if new_level > control.source_limit_vpk:
            new_level, cap = control.source_limit_vpk, "source"
        limits = list(control.input_limits_vpk or ())
        if control.input_limit_channel is not None and control.input_limit_vpk is not None:
            limits += [None] * (control.input_limit_channel - len(limits))
            limits[control.input_limit_channel - 1] = control.input_limit_vpk
        for channel, limit_vpk in enumerate(limits):
            watched = abs(measured[channel])
            if limit_vpk is not None and watched > 0.0 and level > 0.0:
                allowed = level * limit_vpk / watched
                if new_level > allowed:
                    new_level, cap = allowed, "input"
        return float(new_level), cap

    def _noise_power(self, ranges: np.ndarray) -> np.ndarray:
        """One-sided noise density per channel (V²/Hz) on the given ranges."""
        return self._sensor_density + self._adc_density_re_range * ranges**2

    def _burst(self) -> float:
        """Noise factor of this pass: ``burst_factor`` with ``burst_probability``, else 1."""
        noise = self._rig.noise
        if noise is None or noise.burst_probability <= 0.0:
            return 1.0
        return noise.burst_factor if self._rng.random() < noise.burst_probability else 1.0

    def _drift_at(self, time_s: float) -> np.ndarray:
        """Relative sensitivity error of each channel at ``time_s`` (s since mounting).

        Each is a stationary Gauss-Markov process (rms ``sensitivity_drift_rms``, correlation
        time ``sensitivity_drift_time_s``), stepped exactly from its last sample:
        ``δ ← a δ + √(1−a²) σ n`` with ``a = e^{−Δt/τ}``; the first sample is drawn from the
        stationary distribution. A clock that does not advance repeats the sample.
        """
        noise = self._rig.noise
        if noise is None or noise.sensitivity_drift_rms <= 0.0:
            return np.zeros(CHANNEL_COUNT)
        sigma, tau = noise.sensitivity_drift_rms, noise.sensitivity_drift_time_s
        if not self._gain_drift_started:
            self._gain_drift = sigma * self._rng.standard_normal(CHANNEL_COUNT)
            self._gain_drift_started = True
        elif time_s > self._gain_drift_time:
            a = float(np.exp(-(time_s - self._gain_drift_time) / tau))
            innovation = sigma * np.sqrt(1.0 - a * a) * self._rng.standard_normal(CHANNEL_COUNT)
            self._gain_drift = a * self._gain_drift + innovation
        self._gain_drift_time = max(time_s, self._gain_drift_time)
        return self._gain_drift

    def _measure_point(
        self,
        k: _Kernels,
        n: int,
        force_n: float,
        omega: float,
        integrate_s: float,
        fixed_range: np.ndarray,
        time_s: float = 0.0,
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """One settle + integrate pass at one level; advances state and source phase.

        ``time_s``: the clock at the middle of the integration window, where the transducers'
        drifting sensitivities are taken."""
        modal = k.modal
        phasor = force_n * np.exp(1j * self._phase)
        q0 = modal.inverse @ self._state
        p_plus, p_minus = k.p_plus[n], k.p_minus[n]
        q_ss0 = 0.5 * (p_plus * phasor + p_minus * np.conj(phasor))
        offset = q0 - q_ss0
        steady = k.steady[n] * phasor
        value = (steady + np.conj(steady) * k.leakage[n]) * k.delay_phase[n]
        value = value + k.transient[n] @ offset
        peak = np.abs(steady) + k.bound[n] @ np.abs(offset)
        ranges = np.where(
            np.isnan(fixed_range),
            _RANGES_ASCENDING[
                np.minimum(
                    np.searchsorted(_RANGES_ASCENDING, AUTORANGE_HEADROOM * peak),
                    _RANGES_ASCENDING.size - 1,
                )
            ],
            fixed_range,
        )
        over = peak > ranges
        half = peak > 0.5 * ranges
        if np.any(over):
            value = np.where(over, value * _clipped_fundamental(ranges / np.maximum(peak, 1e-300)),
                             value)
        density = self._noise_power(ranges)
        if np.any(density > 0.0):
            sigma = np.sqrt(density / integrate_s) * self._burst()
            value = value + sigma * (
                self._rng.standard_normal(CHANNEL_COUNT)
                + 1j * self._rng.standard_normal(CHANNEL_COUNT)
            )
        value = value * (1.0 + self._drift_at(time_s))
        measured = value * np.exp(-1j * self._phase)
        rotation = k.rotation[n]
        q_end = 0.5 * (p_plus * phasor * rotation + p_minus * np.conj(phasor * rotation))
        q_end = q_end + k.decay[n] * offset
        self._state = modal.to_state(q_end)
        self._phase = float(np.angle(np.exp(1j * (self._phase + np.angle(rotation)))))
        return measured, ranges, over, half
