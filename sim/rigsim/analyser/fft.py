"""The FFT measurement: the rig simulated in the time domain, windows, averaging, spectra.

The rig's linear model (:func:`rigsim.dynamics.build_state_space`) is run sample by sample in
its modal coordinates (exact for a source held constant over each sample), driven by the source
(``SOUR:FUNC`` sine, random, burst random, periodic chirp, burst chirp, pink noise) through the
shaker (gain, force limit). Each input adds its transducer's noise and the analyser's own noise
relative to its range (the rig file's ``[noise]``), passes the wiring
(:class:`rigsim.faults.FrontEnd`), is ranged (autorange at the start of the measurement, as the
manual says the analyser does not autorange during an averaged measurement) and clipped at its
range when it overloads.

Each time record (``2.56 × lines`` samples at ``2.56 × span`` per second in baseband) is
windowed and transformed; the averages kept are the spectra the traces need: linear spectra
(complex, peak), auto and cross spectra (rms²), the last time records. ``XFR:POW:RAT b,a`` is the
H1 estimate ``G_ab / G_aa``, ``XFR:POW:COH a,b`` the coherence.

Not simulated (documented in ``docs/virtual-analyser.md``): triggers other than free run (the
measurement runs as if ``TRIG:SOUR IMM``), sensor delays, drift and amplitude dependence (the
rig's nominal linear model is used), the anti-alias filter's roll-off.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from scipy import signal

from rigsim.analyser.inputs import CHANNELS, snap_range_dbvrms
from rigsim.analyser.limits import FFT_LINES
from rigsim.analyser.run import Measurement
from rigsim.analyser.sine import voltage_bits
from rigsim.analyser.status import OPER_AVERAGING, OPER_MEASURING
from rigsim.dynamics import ModalSystem, build_state_space
from rigsim.engine import AUTORANGE_HEADROOM
from rigsim.measurement import INPUT_RANGES_VPK
from rigsim.scpi import ScpiError

__all__ = ["FftMeasurement", "FftResult", "window"]

_RANGES_ASCENDING = np.sort(INPUT_RANGES_VPK)
#: Longest record the simulation computes (samples at the simulation's rate); narrower zooms
#: are refused.
MAX_RECORD_SAMPLES = 1 << 23
#: Records per second the analyser processes at most (service guide: at least 33 averages/s).
RECORDS_PER_S = 33.0
#: Time simulated before the first record with the source on, at most (the rig settles).
MAX_PREROLL_S = 20.0
#: The rig is simulated at this many times the analyser's sample rate.
OVERSAMPLING = 16


def window(kind: str, samples: int, fs_hz: float, force_s: float,
           exponential_s: float) -> np.ndarray:
    """A window of the 35670A (``WIND`` HANN, FLAT, UNIF, FORC, EXP)."""
    t = np.arange(samples) / fs_hz
    if kind == "HANN":
        return signal.windows.hann(samples, sym=False)
    if kind == "FLAT":
        return signal.windows.flattop(samples, sym=False)
    if kind == "FORC":
        return np.where(t <= force_s, 1.0, 0.0) * np.exp(-t / exponential_s)
    if kind == "EXP":
        return np.exp(-t / exponential_s)
    return np.ones(samples)


@dataclass
class FftResult:
    """Averaged spectra and last records of an FFT measurement (channels 1..4 at index 0..3).

    Attributes
    ----------
    frequency_hz
        Frequencies of the stored lines (``lines × 1.28 + 1`` in baseband, alias lines
        included; the displayed lines are the first ``lines + 1``).
    lines
        The resolution (displayed lines - 1).
    linear
        (4, F) complex linear spectra, peak (vector average with time averaging, else the last
        record's).
    power
        (4, F) auto spectra, rms².
    cross
        (4, 4, F) cross spectra ``conj(X_a) X_b / 2``.
    time, windowed
        (4, N) last time records before and after the window, and their times ``time_s``.
    averages
        Records averaged so far.
    peak_hold
        Averaging was MAX (cross spectra, frequency responses and coherence are invalid).
    """

    frequency_hz: np.ndarray
    lines: int
    linear: np.ndarray
    power: np.ndarray
    cross: np.ndarray
    time: np.ndarray
    windowed: np.ndarray
    time_s: np.ndarray
    scale: np.ndarray = field(default_factory=lambda: np.ones(CHANNELS))
    averages: int = 0
    peak_hold: bool = False
    vector: bool = False
    sum_linear: Any = None


@dataclass
class _Plan:
    fs: float
    samples: int
    hop: int
    bins: np.ndarray
    frequencies: np.ndarray
    lines: int
    windows: np.ndarray  # (4, N)
    averages: int
    kind: str  # OFF, RMS, TIME, MAX
    exponential: bool
    reject: bool
    source: dict[str, Any]
    scale: np.ndarray


class _RigStream:
    """The rig model run sample by sample from the shaker force, its state kept.

    Each mode of the rig's modal decomposition is a first-order recursion, exact for a force
    varying linearly between samples (first-order hold), run at :data:`OVERSAMPLING` times the
    analyser's sample rate so that the force, band-limited to the span, is followed closely;
    the response is then taken at the analyser's sample rate.
    """

    def __init__(self, rig: Any, fs: float, rng: np.random.Generator) -> None:
        self.rig = rig
        self.fs = fs
        self.rng = rng
        #: Samples taken so far (the hum's clock).
        self.taken = 0
        modal = ModalSystem(build_state_space(rig, 1.0))
        self.modal = modal
        lam = modal.eigenvalues
        step = 1.0 / (fs * OVERSAMPLING)
        self.decay = np.exp(lam * step)
        small = np.abs(lam * step) < 1e-8
        safe = np.where(small, 1.0, lam)
        whole = np.where(small, step, (self.decay - 1.0) / safe)
        ramp = np.where(small, step / 2.0, (self.decay - 1.0 - lam * step) / (safe * safe * step))
        # q[k] = E q[k-1] + b ((I0 - I1) u[k-1] + I1 u[k])
        self.taps = np.stack([ramp * modal.b_modal, (whole - ramp) * modal.b_modal])
        self.zi = np.zeros(lam.size, complex)
        sensors = rig.sensors
        self.sensitivity = np.array([sensors.force_v_per_n, sensors.acceleration_v_per_m_s2] * 2)
        noise = rig.noise
        if noise is None:
            self.sensor_sigma = np.zeros(CHANNELS)
            self.adc_re_range = 0.0
        else:
            asd = np.array([noise.excitation_force_n_per_sqrt_hz,
                            noise.table_acceleration_m_per_s2_per_sqrt_hz,
                            noise.device_force_n_per_sqrt_hz,
                            noise.disc_acceleration_m_per_s2_per_sqrt_hz])
            self.sensor_sigma = asd * self.sensitivity * math.sqrt(fs / 2.0)
            self.adc_re_range = 10.0 ** (noise.adc_noise_db_re_range_per_sqrt_hz / 20) * math.sqrt(
                fs / 2.0)
        slowest = np.min(np.abs(lam.real)) if lam.size else 1.0
        self.settle_s = min(MAX_PREROLL_S, 5.0 / max(slowest, 1e-3))
        # the analyser's anti-alias filter (INP:FILT, on by default): flat to the span's edge
        # (0.39 of the sample rate), 90 dB down before anything can fold into the span
        self.anti_alias = signal.ellip(8, 0.01, 90.0, 0.4 * fs, fs=fs * OVERSAMPLING,
                                       output="sos")
        self.filter_state = np.zeros((CHANNELS, self.anti_alias.shape[0], 2))

    def _response(self, z: np.ndarray) -> np.ndarray:
        """(modes, len(z)) discrete response of each mode's recursion to ``z**k`` inputs."""
        inverse = 1.0 / z[None, :]
        c1, c0 = self.taps[0][:, None], self.taps[1][:, None]
        return (c1 + c0 * inverse) / (1.0 - self.decay[:, None] * inverse)

    def settle_periodic(self, force_period: np.ndarray, start: int) -> None:
        """Put the rig in its periodic steady state for a force repeating ``force_period``
        (fine samples); ``start``: the index in the period of the next sample to be run."""
        count = force_period.size
        spectrum = np.fft.fft(force_period)
        z = np.exp(2j * np.pi * np.arange(count) / count)
        modal = np.fft.ifft(self._response(z) * spectrum[None, :], axis=1)
        self.zi = modal[:, start] - self.taps[0] * force_period[start]

    def settle_sine(self, amplitude: float, omega: float, phase: float, offset: float) -> None:
        """Steady state for ``offset + amplitude sin(omega k + phase)`` (k: the fine sample
        index of the next sample run, omega in radians per fine sample)."""
        z = np.exp(1j * np.array([omega, -omega, 0.0]))
        response = self._response(z)
        state = (amplitude / 2j) * (response[:, 0] * np.exp(1j * phase)
                                    - response[:, 1] * np.exp(-1j * phase))
        state = state + offset * response[:, 2]
        force = offset + amplitude * math.sin(phase)
        self.zi = state - self.taps[0] * force

    def run(self, force_n: np.ndarray, filtered: np.ndarray | None = None) -> np.ndarray:
        """Transducer volts (4, N) at the analyser's rate for a force given at
        :data:`OVERSAMPLING` times that rate (N × OVERSAMPLING samples); the state carries.
        ``filtered``: inputs whose anti-alias filter is on (all by default)."""
        q_out = np.empty((self.zi.size, force_n.size), complex)
        for m in range(self.zi.size):
            q_out[m], zf = signal.lfilter(self.taps[:, m], [1.0, -self.decay[m]], force_n,
                                          zi=self.zi[m:m + 1])
            self.zi[m] = zf[0]
        space = self.modal.space
        fine = (self.modal.c_modal @ q_out).real + space.d[:, None] * force_n[None, :]
        for channel in range(CHANNELS):
            if filtered is None or filtered[channel]:
                fine[channel], self.filter_state[channel] = signal.sosfilt(
                    self.anti_alias, fine[channel], zi=self.filter_state[channel])
        volts = fine[:, OVERSAMPLING - 1::OVERSAMPLING] * self.sensitivity[:, None]
        volts += self.sensor_sigma[:, None] * self.rng.standard_normal(volts.shape)
        return volts


class FftMeasurement(Measurement):
    """FFT measurements on a rig simulator.

    Parameters: those of :class:`~rigsim.analyser.run.Measurement`.
    """

    def __init__(self, *parts: Any) -> None:
        super().__init__(*parts)
        self.result: FftResult | None = None
        self.rng = np.random.default_rng()
        self._stream: _RigStream | None = None
        self._source_state: dict[str, Any] = {}

    # ---------------------------------------------------------------- planning (lock held)

    def plan(self) -> _Plan:
        """The records, windows, averaging and source of the next measurement."""
        get = self.store.get
        lines = int(get("freq.res"))
        if lines not in FFT_LINES:
            lines = 400
        start, stop = float(get("freq.start")), float(get("freq.stop"))
        span = stop - start
        record_s = lines / span
        fs = 2.56 * span if start <= 0.0 else 2.56 * stop
        samples = round(fs * record_s)
        if samples * OVERSAMPLING > MAX_RECORD_SAMPLES:
            raise ScpiError(-221, "Invalid program state change requested.")
        if start <= 0.0:
            stored = round(lines * 1.28) + 1
            bins = np.arange(stored)
        else:
            first = round(start * record_s)
            bins = first + np.arange(lines + 1)
        frequencies = bins / record_s
        force_s, exp_s = float(get("wind.forc")), float(get("wind.exp"))
        windows = np.array([window(str(get("wind.type", (n,))), samples, fs, force_s, exp_s)
                            for n in range(1, CHANNELS + 1)])
        overlap = int(get("swe.over")) if start <= 0 else 0
        hop = max(1, round(samples * (1 - overlap / 100.0)))
        averaging = bool(get("aver.state"))
        kind = str(get("aver.type")) if averaging else "OFF"
        return _Plan(
            fs=fs, samples=samples, hop=hop, bins=bins, frequencies=frequencies, lines=lines,
            windows=windows, averages=int(get("aver.count")) if averaging else 1,
            kind="TIME" if kind == "VECT" else kind,
            exponential=get("aver.tcon") == "EXP", reject=bool(get("rej.state")),
            source=self._source_settings(start, stop, samples, fs), scale=self.inputs.scale())

    def _source_settings(self, start: float, stop: float, samples: int, fs: float) -> dict:
        get = self.store.get
        on = bool(get("outp.state"))
        level = float(get("sour.volt").vpk) if on else 0.0
        return {"on": on and level > 0, "function": str(get("sour.func")), "level": level,
                "offset": float(get("sour.offs")) if on else 0.0,
                "frequency": float(get("sour.freq")), "burst": float(get("sour.burs")) / 100.0,
                "band": (max(start, 0.0), stop), "samples": samples, "fs": fs}

    def start(self, plan: _Plan, *, more: bool = False) -> None:
        """Start a new measurement, or (``more``) add averages to the finished one."""
        if not more or self.result is None:
            self.result = None
        self.run.start(lambda generation: self._measure(generation, plan, more))

    # ---------------------------------------------------------------- the worker thread

    def _source(self, plan: _Plan, samples: int) -> np.ndarray:
        """The next ``samples`` of source voltage (continuous across calls)."""
        src = plan.source
        state = self._source_state
        if not src["on"]:
            return np.full(samples, 0.0)
        fs, level, function = plan.fs * OVERSAMPLING, src["level"], src["function"]
        position = state.get("position", 0)
        t = (position + np.arange(samples)) / fs
        state["position"] = position + samples
        record = src["samples"] * OVERSAMPLING
        in_record = (position + np.arange(samples)) % record
        lo, hi = src["band"]
        hi = min(hi, 0.45 * plan.fs)
        if function == "SIN":
            wave = level * np.sin(2.0 * np.pi * src["frequency"] * t)
        elif function in ("RAND", "BRAN", "PINK"):
            sos = state.get("sos")
            if sos is None or state.get("sos_key") != (lo, hi, fs, function):
                sos = (signal.butter(6, [lo, hi], btype="bandpass", fs=fs, output="sos")
                       if lo > 0 else signal.butter(6, hi, fs=fs, output="sos"))
                state["sos"], state["sos_key"] = sos, (lo, hi, fs, function)
                state["zi"] = np.zeros((sos.shape[0], 2))
            white = self.rng.standard_normal(samples)
            if function == "PINK":
                white = self._pink(white, state)
            wave, state["zi"] = signal.sosfilt(sos, white, zi=state["zi"])
            gain = state.setdefault("rms_gain", self._rms_gain(sos, fs, function))
            wave = wave * gain * level / math.sqrt(2.0)
            if function == "BRAN":
                wave = np.where(in_record < src["burst"] * record, wave, 0.0)
        else:  # PCH, BCH (USER and CAPT need option 1D4)
            wave = level * self._chirp(record, fs, lo, hi, src["burst"] if function == "BCH"
                                       else 1.0)[in_record]
        return wave + src["offset"]

    def _rms_gain(self, sos: np.ndarray, fs: float, function: str) -> float:
        probe = self.rng.standard_normal(1 << 15)
        if function == "PINK":
            probe = self._pink(probe, {})
        filtered = signal.sosfilt(sos, probe)
        rms = float(np.sqrt(np.mean(filtered[len(filtered) // 4:] ** 2)))
        return 1.0 / rms if rms > 0 else 0.0

    @staticmethod
    def _pink(white: np.ndarray, state: dict) -> np.ndarray:
        # a three-pole approximation of a 1/f spectrum
        b = [0.049922035, -0.095993537, 0.050612699, -0.004408786]
        a = [1.0, -2.494956002, 2.017265875, -0.522189400]
        zi = state.get("pink_zi", np.zeros(3))
        out, state["pink_zi"] = signal.lfilter(b, a, white, zi=zi)
        return out

    @staticmethod
    def _chirp(record: int, fs: float, lo: float, hi: float, burst: float) -> np.ndarray:
        """One record of a periodic (or burst) chirp from ``lo`` to ``hi``, peak 1."""
        active = max(2, int(burst * record))
        t = np.arange(active) / fs
        duration = active / fs
        phase = 2 * np.pi * (lo * t + 0.5 * (hi - lo) * t * t / duration)
        wave = np.zeros(record)
        wave[:active] = np.sin(phase)
        return wave

    def _measure(self, generation: int, plan: _Plan, more: bool) -> None:
        rig = self.simulator.rig
        with self.run.changed:
            if self._stream is None or self._stream.rig is not rig or self._stream.fs != plan.fs:
                self._stream = _RigStream(rig, plan.fs, self.rng)
            stream = self._stream
        gain, limit = rig.shaker.force_n_per_v, rig.shaker.force_limit_n
        preroll = plan.samples
        if not self._steady(stream, plan, gain, limit) and plan.source["on"]:
            preroll = max(preroll, int(stream.settle_s * plan.fs))
        buffer = self._acquire(stream, plan, preroll, gain, limit)
        ranges = self._autorange(buffer)
        result = self.result if more and self.result is not None else self._empty(plan)
        target = result.averages + plan.averages
        tail = buffer[:, -(plan.samples - plan.hop):] if plan.hop < plan.samples else None
        rejected = 0
        elapsed = preroll / plan.fs
        while result.averages < target:
            self.calibrate(generation)
            new = self._acquire(stream, plan, plan.hop, gain, limit)
            record = new if tail is None else np.concatenate([tail, new], axis=1)[
                :, -plan.samples:]
            tail = record[:, plan.hop:] if plan.hop < plan.samples else None
            record, over, half = self._range(record, ranges)
            hop_s = plan.hop / plan.fs
            elapsed += hop_s
            self.run.wait(generation, max(hop_s, 1.0 / RECORDS_PER_S),
                          OPER_MEASURING | OPER_AVERAGING)
            with self.run.changed:
                self.run.check(generation)
                active = np.array([self.inputs.enabled(n) for n in range(1, CHANNELS + 1)])
                self.status.volt.set_condition(voltage_bits(over & active, half & active))
                if plan.reject and np.any(over & active) and rejected < 10 * plan.averages:
                    rejected += 1
                    continue
                self._accumulate(result, record, plan)
                self.result = result
        with self.run.changed:
            self.status.volt.set_condition(0)
        self.simulator.idle(elapsed)

    def _steady(self, stream: _RigStream, plan: _Plan, gain: float, limit: float) -> bool:
        """A periodic source (sine, chirps) has been driving the rig: start it in its steady
        state. Random sources have none: the rig runs a while first (the caller's pre-roll)."""
        src = plan.source
        if not src["on"] or src["function"] not in ("SIN", "PCH", "BCH"):
            return False
        fine = plan.fs * OVERSAMPLING
        position = self._source_state.get("position", 0)
        if src["function"] == "SIN" and src["level"] * gain <= limit:
            omega = 2 * np.pi * src["frequency"] / fine
            stream.settle_sine(gain * src["level"], omega, omega * position,
                               gain * src["offset"])
            return True
        record = src["samples"] * OVERSAMPLING
        lo, hi = src["band"]
        hi = min(hi, 0.45 * plan.fs)
        if src["function"] == "SIN":
            wave = src["level"] * np.sin(2 * np.pi * src["frequency"] * np.arange(record) / fine)
        else:
            burst = src["burst"] if src["function"] == "BCH" else 1.0
            wave = src["level"] * self._chirp(record, fine, lo, hi, burst)
        force = np.clip(gain * (wave + src["offset"]), -limit, limit)
        stream.settle_periodic(force, position % record)
        return src["function"] != "SIN"

    def _acquire(self, stream: _RigStream, plan: _Plan, samples: int, gain: float,
                 limit: float) -> np.ndarray:
        force = np.clip(gain * self._source(plan, samples * OVERSAMPLING), -limit, limit)
        filtered = np.array([bool(self.store.get("inp.filt", (n,)))
                             for n in range(1, CHANNELS + 1)])
        volts = self.front_end.apply(stream.run(force, filtered).T).T
        if self.front_end.hum:
            times = (stream.taken + np.arange(samples)) / plan.fs
            volts = volts + self.front_end.hum_samples(times)
        stream.taken += samples
        return volts

    def _autorange(self, record: np.ndarray) -> np.ndarray:
        """Ranges (volts peak) per input: chosen from the signal where autorange is on."""
        ranges = np.zeros(CHANNELS)
        for n in range(1, CHANNELS + 1):
            pinned = self.front_end.pinned_range_dbvrms.get(n)
            if pinned is not None:
                ranges[n - 1] = math.sqrt(2.0) * 10 ** (pinned / 20.0)
                continue
            if self.inputs.autorange(n):
                peak = float(np.max(np.abs(record[n - 1])))
                index = min(int(np.searchsorted(_RANGES_ASCENDING, AUTORANGE_HEADROOM * peak)),
                            _RANGES_ASCENDING.size - 1)
                vpk = float(_RANGES_ASCENDING[index])
                with self.run.changed:
                    self.inputs.set_range_dbvrms(n, snap_range_dbvrms(
                        20 * math.log10(vpk / math.sqrt(2.0))))
                ranges[n - 1] = vpk
            else:
                ranges[n - 1] = float(self.store.get("volt.range", (n,)).vpk)
        return ranges

    def _range(self, record: np.ndarray, ranges: np.ndarray) -> tuple[np.ndarray, ...]:
        """Add the analyser's own noise, detect overloads and clip at the ranges."""
        stream = self._stream
        assert stream is not None
        noisy = record + (stream.adc_re_range * ranges)[:, None] * self.rng.standard_normal(
            record.shape)
        peak = np.max(np.abs(noisy), axis=1)
        over = peak > ranges
        half = peak > 0.5 * ranges
        clipped = np.clip(noisy, -ranges[:, None], ranges[:, None])
        return clipped, over, half

    def _empty(self, plan: _Plan) -> FftResult:
        f = plan.frequencies.size
        return FftResult(
            frequency_hz=plan.frequencies, lines=plan.lines,
            linear=np.zeros((CHANNELS, f), complex), power=np.zeros((CHANNELS, f)),
            cross=np.zeros((CHANNELS, CHANNELS, f), complex),
            time=np.zeros((CHANNELS, plan.samples)), windowed=np.zeros((CHANNELS, plan.samples)),
            time_s=np.arange(plan.samples) / plan.fs, scale=plan.scale,
            peak_hold=plan.kind == "MAX", vector=plan.kind == "TIME")

    def _accumulate(self, result: FftResult, record: np.ndarray, plan: _Plan) -> None:
        windowed = record * plan.windows
        coherent = np.sum(plan.windows, axis=1)
        spectrum = np.fft.fft(windowed, axis=1)[:, plan.bins] / coherent[:, None]
        if plan.bins[0] == 0:
            spectrum[:, 1:] *= 2.0
        else:
            spectrum *= 2.0
        n = result.averages + 1
        weight = 1.0 / n
        if plan.exponential and n > plan.averages:
            weight = 1.0 / plan.averages
        if plan.kind == "TIME":
            summed = spectrum if result.sum_linear is None else (
                (1 - weight) * result.sum_linear + weight * spectrum)
            result.sum_linear = summed
            result.linear = summed
            result.power = np.abs(summed) ** 2 / 2.0
            result.cross = np.conj(summed)[:, None, :] * summed[None, :, :] / 2.0
        else:
            power = np.abs(spectrum) ** 2 / 2.0
            cross = np.conj(spectrum)[:, None, :] * spectrum[None, :, :] / 2.0
            if plan.kind == "MAX":
                result.power = np.maximum(result.power, power)
            else:
                result.power = (1 - weight) * result.power + weight * power
                result.cross = (1 - weight) * result.cross + weight * cross
            result.linear = spectrum
        result.time = record
        result.windowed = windowed
        result.averages = n
