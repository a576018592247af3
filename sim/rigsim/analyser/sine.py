"""The swept-sine measurement (option 1D2): plan, points on the rig simulator, pacing.

``INIT`` plans the sweep from the settings (start, stop, spacing, resolution, direction, manual
mode, settle and integration times, ranges, auto level) and the worker thread asks the rig
simulator for the points (volts at the analyser inputs, :mod:`rigsim.measurement`), passes them
through the wiring (:class:`rigsim.faults.FrontEnd`) and reveals them one by one.

Time per point, as the instrument takes it: settle plus integration plus
:data:`~rigsim.analyser.limits.POINT_OVERHEAD_S` (frequency change, ranging, computing). With a
pace, each phase waits its simulated time on the wall clock, scaled, and ``STAT:OPER`` shows it:
bit 2 ranging and bit 1 settling during the overhead and settle, bit 4 measuring and bit 8
averaging while the sweep runs, bit 0 during an auto-calibration.

Automatic resolution (``FREQ:RES:AUTO ON``): the step starts at the minimum resolution
(``FREQ:RES:AUTO:MIN``), halves (not below the minimum) when the frequency response (input 2
over input 1) changed by more than ``FREQ:RES:AUTO:MCH`` since the last point, and doubles (not
above ``FREQ:RES``) when it changed by less than half of it **(inferred: the manual names the
inputs of the rule, not the rule)**.
"""

from __future__ import annotations

import math
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np

from rigsim.analyser.frequency import point_count, sweep_frequencies
from rigsim.analyser.inputs import CHANNELS
from rigsim.analyser.limits import MAX_POINTS, MIN_DWELL_S, POINT_OVERHEAD_S, display_points
from rigsim.analyser.ramp import SourceOutput, ramp_requests
from rigsim.analyser.run import Measurement, Simulator
from rigsim.analyser.status import (
    OPER_AVERAGING,
    OPER_MEASURING,
    OPER_RANGING,
    OPER_SETTLING,
)
from rigsim.engine import AUTORANGE_HEADROOM
from rigsim.measurement import (
    INPUT_RANGES_VPK,
    SourceControl,
    SweepRecord,
    SweepRequest,
)
from rigsim.scpi import ScpiError

__all__ = ["ZERO_SOURCE_MESSAGE", "MeasuredPoints", "Simulator", "SweptSine", "voltage_bits"]

ZERO_SOURCE_MESSAGE = "SOURCE LEVEL is 0 Volts, measurement paused."
_RANGES_ASCENDING = np.sort(INPUT_RANGES_VPK)


def voltage_bits(overload: np.ndarray, half_range: np.ndarray) -> int:
    """``STAT:QUES:VOLT`` bits: channel n's overload at bit n-1, its half range at bit n+7."""
    bits = 0
    for i in range(CHANNELS):
        bits |= (1 << i) if overload[i] else 0
        bits |= (1 << (8 + i)) if half_range[i] else 0
    return bits


@dataclass
class MeasuredPoints:
    """The points of the current or last sweep, in measurement order, and its plan.

    ``planned_hz`` holds the frequencies the sweep will visit (grows as an automatic-resolution
    sweep decides them); ``slots`` is the number of points its traces hold (401 or 801).
    """

    planned_hz: np.ndarray = field(default_factory=lambda: np.zeros(0))
    slots: int = 401
    frequency_hz: list[float] = field(default_factory=list)
    channel_v: list[np.ndarray] = field(default_factory=list)
    variance: list[np.ndarray] = field(default_factory=list)
    range_vpk: list[np.ndarray] = field(default_factory=list)
    overload: list[np.ndarray] = field(default_factory=list)
    source_vpk: list[float] = field(default_factory=list)
    scale: np.ndarray = field(default_factory=lambda: np.ones(CHANNELS))

    @property
    def count(self) -> int:
        """Points measured so far."""
        return len(self.frequency_hz)

    def channels(self) -> np.ndarray:
        """(points, 4) complex amplitudes in the inputs' display units."""
        if not self.channel_v:
            return np.zeros((0, CHANNELS), complex)
        return np.array(self.channel_v) / self.scale

    def variances(self) -> np.ndarray:
        """(points, 4) normalized variances."""
        return np.array(self.variance) if self.variance else np.zeros((0, CHANNELS))


@dataclass
class _Plan:
    frequencies: np.ndarray  # fixed list, or the first point of an adaptive sweep
    adaptive: bool
    settle: tuple[float, str]
    dwell: tuple[float, str]
    ranges: tuple[float | None, ...]  # per physical transducer channel
    control: SourceControl
    start_vpk: float
    min_step: float = 0.0
    max_step: float = 0.0
    log: bool = False
    stop_hz: float = 0.0
    descending: bool = False
    mch: float = 2.0


#: Longest wall time a sweep holds at a point boundary for an in-process end request before it
#: goes on (the controller that asked for the end sends ``ABOR`` at its next poll).
END_HOLD_S = 5.0

class SweptSine(Measurement):
    """Swept-sine measurements on a rig simulator.

    Parameters: those of :class:`~rigsim.analyser.run.Measurement`. ``on_point`` is called
    (lock held) with the number of points measured after each point.
    """

    def __init__(self, *parts: Any) -> None:
        super().__init__(*parts)
        self.points = MeasuredPoints()
        self.on_point: Callable[[int], None] | None = None
        self.forced_overload: dict[int, int | None] = {}
        self.last_flags = (np.zeros(CHANNELS, bool), np.zeros(CHANNELS, bool))
        self.rng = np.random.default_rng()
        self.output = SourceOutput()
        """What the source outputs: the sweep's level, then its ramp down (module ramp)."""
        self.rig_lock = threading.Lock()
        """Held while the rig simulator computes (the worker's points, a ramp down)."""
        self._plan: _Plan | None = None
        self.aborting = False
        """``ABOR`` is stopping the sweep (the rig is driven through the ramp down)."""
        self.end_wanted = False
        """An end asked in process (``VirtualAnalyser.end_after_point``): hold at the next point
        boundary until ``ABOR``."""

    # ---------------------------------------------------------------- planning (lock held)

    def point_list(self) -> np.ndarray:
        """The points an automatic sweep with a fixed resolution visits, in order."""
        get = self.store.get
        start, stop = float(get("freq.start")), float(get("freq.stop"))
        value, unit = get("freq.res")
        return sweep_frequencies(start, stop, str(get("swe.spac")), float(value), str(unit),
                                 str(get("swe.dir")))

    def _step(self, value: float, unit: str, start: float, stop: float, log: bool) -> float:
        """A resolution as a step: Hz (linear) or a frequency ratio (logarithmic)."""
        count = max(2.0, point_count(start, stop, "LOG" if log else "LIN", value, unit))
        if log:
            return (stop / start) ** (1.0 / (count - 1.0)) if start > 0 else 2.0
        if unit == "HZ":
            return value
        return (stop - start) / (count - 1.0)

    def _control(self) -> SourceControl:
        get = self.store.get
        wiring = self.front_end
        reference = int(str(get("sour.ref.chan"))[-1])
        ref_level = get("sour.ref")
        ref_vpk = ref_level.volts_peak(self.inputs.v_per_eu(reference))
        physical = wiring.source[reference]
        if physical is None:  # the controller watches an input that reads nothing
            physical, ref_vpk = reference, 1e9
        else:
            ref_vpk = ref_vpk / abs(wiring.gain[reference])
        limit = get("sour.lim.inp")
        limits: list[float | None] = [None] * CHANNELS
        for channel in self.inputs.active():
            source = wiring.source[channel]
            if channel == reference or source is None:
                continue
            vpk = limit.volts_peak(self.inputs.v_per_eu(channel)) / abs(wiring.gain[channel])
            current = limits[source - 1]
            limits[source - 1] = vpk if current is None else min(current, vpk)
        return SourceControl(
            source_vpk=float(get("sour.volt").vpk),
            auto_level=bool(get("sour.volt.auto")),
            reference_channel=physical,
            reference_vpk=ref_vpk,
            tolerance_db=float(get("sour.ref.tol")),
            source_limit_vpk=max(float(get("sour.lim").vpk), 1e-6),
            input_limits_vpk=tuple(limits),
        )

    def _ranges(self) -> tuple[float | None, ...]:
        """Fixed ranges per transducer channel (``None``: autorange), stuck ranges included."""
        ranges: list[float | None] = []
        for channel in range(1, CHANNELS + 1):
            pinned = self.front_end.pinned_range_dbvrms.get(channel)
            if pinned is not None:
                ranges.append(math.sqrt(2.0) * 10 ** (pinned / 20.0))
            elif self.inputs.autorange(channel):
                ranges.append(None)
            else:
                ranges.append(float(self.store.get("volt.range", (channel,)).vpk))
        return tuple(ranges)

    def plan(self) -> _Plan:
        """Check the settings and plan the sweep (-221 when it cannot run)."""
        get = self.store.get
        control = self._control()
        if control.auto_level and not self.inputs.enabled(int(str(get("sour.ref.chan"))[-1])):
            raise ScpiError(-221, "Invalid program state change requested.")
        manual = get("swe.mode") == "MAN"
        start, stop = float(get("freq.start")), float(get("freq.stop"))
        log = get("swe.spac") == "LOG"
        adaptive = bool(get("freq.res.auto")) and not manual
        descending = get("swe.dir") == "DOWN"
        if manual:
            frequencies = np.array([float(get("freq.man"))])
        elif adaptive:
            frequencies = np.array([stop if descending else start])
        else:
            frequencies = self.point_list()
        plan = _Plan(frequencies=frequencies, adaptive=adaptive, settle=get("swe.stim"),
                     dwell=get("swe.dwel"), ranges=self._ranges(), control=control,
                     start_vpk=control.source_vpk, log=log, stop_hz=start if descending else stop,
                     descending=descending, mch=float(get("freq.res.auto.mch")))
        if adaptive:
            lo, hi = min(start, stop), max(start, stop)
            min_value, min_unit = get("freq.res.auto.min")
            res_value, res_unit = get("freq.res")
            plan.min_step = self._step(float(min_value), str(min_unit), lo, hi, log)
            plan.max_step = max(plan.min_step, self._step(float(res_value), str(res_unit),
                                                          lo, hi, log))
        return plan

    def start(self, plan: _Plan) -> None:
        """Reset the traces for a new sweep and start the worker (lock held)."""
        if plan.adaptive:
            min_value, min_unit = self.store.get("freq.res.auto.min")
            start, stop = float(self.store.get("freq.start")), float(self.store.get("freq.stop"))
            count = point_count(min(start, stop), max(start, stop),
                                str(self.store.get("swe.spac")), float(min_value), str(min_unit))
            slots = display_points(int(min(MAX_POINTS, max(3, count))))
        else:
            slots = display_points(plan.frequencies.size)
        self.points = MeasuredPoints(planned_hz=plan.frequencies.copy(), slots=slots,
                                     scale=self.inputs.scale())
        self._plan = plan
        zero = plan.start_vpk <= 0.0
        if not zero:
            self.output.drive(plan.start_vpk, float(plan.frequencies[0]))
        self.run.start(lambda generation: self._measure(generation, plan), paused=zero)
        if zero:
            self.status.push_error(-221, ScpiError(-221, ZERO_SOURCE_MESSAGE).message)

    def resume(self) -> None:
        """``INIT:CONT ON`` on a paused sweep (a 0 V source keeps it paused)."""
        if self.run.state == "PAUSED" and float(self.store.get("sour.volt").vpk) <= 0.0:
            self.status.push_error(-221, ScpiError(-221, ZERO_SOURCE_MESSAGE).message)
            return
        self.run.resume()

    # ---------------------------------------------------------------- the worker thread

    @staticmethod
    def _seconds(setting: tuple[float, str], frequency_hz: np.ndarray) -> np.ndarray:
        value, unit = setting
        if unit == "CYCLE":
            return value / frequency_hz
        return np.full(frequency_hz.shape, float(value))

    def _timing(self, plan: _Plan, frequencies: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        settle = self._seconds(plan.settle, frequencies)
        value, unit = plan.dwell
        dwell = (np.maximum(value, 1.0) / frequencies if unit == "CYCLE"
                 else np.full(frequencies.shape, float(value)))
        return settle, np.maximum(dwell, MIN_DWELL_S)

    def _measure(self, generation: int, plan: _Plan) -> None:
        level = plan.start_vpk
        index = 0
        frequencies = plan.frequencies
        step = plan.min_step
        while True:
            with self.run.changed:
                self.run.check(generation)
                if index >= frequencies.size:
                    if not plan.adaptive:
                        break
                    frequencies, step, done = self._next_adaptive(plan, frequencies, step)
                    if done:
                        break
                    self.points.planned_hz = frequencies.copy()
                stop = index + 1 if plan.adaptive or self.run.pace is not None else min(
                    frequencies.size, index + 64)
                chunk = frequencies[index:stop]
                settle, integrate = self._timing(plan, chunk)
                control = replace(plan.control, source_vpk=level)
                request = SweepRequest(frequency_hz=chunk, settle_s=settle, integrate_s=integrate,
                                       control=control, input_range_vpk=plan.ranges)
            self.calibrate(generation)
            with self.rig_lock:
                self.run.check_unlocked(generation)  # a ramp down may have run meanwhile
                record = self.simulator.sweep(request)
            self._wire(record, integrate, plan.ranges)
            for k in range(len(record)):
                with self.run.changed:
                    self._hold_at_boundary(generation)
                self._pace_point(generation, float(settle[k]), float(integrate[k]))
                with self.run.changed:
                    self.run.check(generation)
                    self._reveal(record, k)
                level = float(record.source_vpk[k]) or level
            index = stop

    def _hold_at_boundary(self, generation: int) -> None:
        """An end asked in process, once a point is measured: settle at this boundary (``STAT:OPER``
        measuring and settling) until ``ABOR`` ends the sweep, at most :data:`END_HOLD_S` of wall
        time, then go on (lock held)."""
        if not self.end_wanted or self.points.count == 0:
            return
        self.end_wanted = False
        self.run.set_operation(OPER_MEASURING | OPER_AVERAGING | OPER_SETTLING)
        deadline = time.monotonic() + END_HOLD_S
        while generation == self.run.generation:
            remaining = deadline - time.monotonic()
            if remaining <= 0:
                break
            self.run.changed.wait(remaining)
        self.run.check(generation)

    def _next_adaptive(self, plan: _Plan, frequencies: np.ndarray,
                       step: float) -> tuple[np.ndarray, float, bool]:
        """The next point of an automatic-resolution sweep (and the step it used)."""
        last = frequencies[-1]
        if self.points.count >= 2:
            ratios = self.points.channels()[-2:, 1] / np.where(
                self.points.channels()[-2:, 0] == 0, 1.0, self.points.channels()[-2:, 0])
            previous, current = ratios
            change = 100.0 * abs(current - previous) / max(abs(previous), 1e-300)
            if change > plan.mch:
                step = max(plan.min_step, step / 2.0 if not plan.log else math.sqrt(step))
            elif change < plan.mch / 2.0:
                step = min(plan.max_step, step * 2.0 if not plan.log else step * step)
        sign = -1.0 if plan.descending else 1.0
        following = last * step ** sign if plan.log else last + sign * step
        beyond = following > plan.stop_hz * (1 + 1e-12) if not plan.descending else (
            following < plan.stop_hz * (1 - 1e-12))
        at_end = abs(last - plan.stop_hz) < 1e-9
        if at_end or frequencies.size >= MAX_POINTS:
            return frequencies, step, True
        if beyond:
            following = plan.stop_hz
        following = math.floor(following / 0.015625 + 1e-9) * 0.015625
        return np.append(frequencies, following), step, False

    def _pace_point(self, generation: int, settle_s: float, integrate_s: float) -> None:
        base = OPER_MEASURING | OPER_AVERAGING
        ranging = OPER_RANGING if any(r is None for r in self._ranges()) else 0
        self.run.wait(generation, POINT_OVERHEAD_S, base | ranging | OPER_SETTLING)
        self.run.wait(generation, settle_s, base | OPER_SETTLING)
        self.run.wait(generation, integrate_s, base)

    def _wire(self, record: SweepRecord, integrate_s: np.ndarray,
              ranges: tuple[float | None, ...]) -> None:
        """What the inputs read through the wiring (faults): amplitudes, ranges, overloads."""
        wiring = self.front_end
        if wiring.healthy:
            return
        physical = record.channel_v.copy()
        record.channel_v[:] = wiring.apply(physical)
        record.variance[:] = wiring.apply(record.variance.copy(), scaled=False)
        if wiring.hum:
            # the hum is not locked to the source: over its random phase, the estimate varies
            # by the hum's power (normalized by the signal's)
            hum = wiring.hum_phasors(record.frequency_hz, integrate_s, self.rng)
            signal = np.abs(record.channel_v) ** 2
            record.channel_v[:] += hum
            with np.errstate(divide="ignore", invalid="ignore"):
                record.variance[:] += np.where(signal > 0, np.abs(hum) ** 2 / signal, 0.0)
        noise = getattr(self.simulator.rig, "noise", None)
        adc = 0.0 if noise is None else 10.0 ** (noise.adc_noise_db_re_range_per_sqrt_hz / 10)
        for channel in range(1, CHANNELS + 1):
            if not wiring.altered(channel):
                continue
            column = channel - 1
            peak = np.abs(record.channel_v[:, column])
            fixed = ranges[column]
            if fixed is None:
                chosen = _RANGES_ASCENDING[np.minimum(
                    np.searchsorted(_RANGES_ASCENDING, AUTORANGE_HEADROOM * peak),
                    _RANGES_ASCENDING.size - 1)]
            else:
                chosen = np.full(peak.shape, fixed)
            record.range_vpk[:, column] = chosen
            record.overload[:, column] = peak > chosen
            record.half_range[:, column] = peak > 0.5 * chosen
            if wiring.source[channel] is None:
                sigma = np.sqrt(adc * chosen**2 / integrate_s)
                record.channel_v[:, column] = sigma * (
                    self.rng.standard_normal(peak.size) + 1j * self.rng.standard_normal(peak.size))
                record.variance[:, column] = np.inf

    def _reveal(self, record: SweepRecord, k: int) -> None:
        """Point ``k`` of ``record`` is measured: store it, set the status bits (lock held)."""
        overload = np.array(record.overload[k], bool)
        for channel, remaining in list(self.forced_overload.items()):
            overload[channel - 1] = True
            if remaining is not None:
                if remaining <= 1:
                    del self.forced_overload[channel]
                else:
                    self.forced_overload[channel] = remaining - 1
        points = self.points
        points.frequency_hz.append(float(record.frequency_hz[k]))
        points.channel_v.append(np.array(record.channel_v[k]))
        points.variance.append(np.array(record.variance[k]))
        points.range_vpk.append(np.array(record.range_vpk[k]))
        points.overload.append(overload)
        points.source_vpk.append(float(record.source_vpk[k]))
        self.output.drive(float(record.source_vpk[k]), float(record.frequency_hz[k]))
        active = np.array([self.inputs.enabled(n) for n in range(1, CHANNELS + 1)])
        half = np.array(record.half_range[k], bool)
        self.last_flags = (overload & active, half & active)
        self.status.volt.set_condition(voltage_bits(overload & active, half & active))
        for channel in range(1, CHANNELS + 1):
            if self.inputs.autorange(channel):
                vpk = float(record.range_vpk[k][channel - 1])
                self.inputs.set_range_dbvrms(channel, 20 * math.log10(vpk / math.sqrt(2.0)))
        if self.on_point is not None:
            self.on_point(points.count)

    def finished(self) -> None:
        """The sweep ended: a forced overload "for the next sweep" ends with it; the voltage
        condition clears (lock held)."""
        for channel, remaining in list(self.forced_overload.items()):
            if remaining is None:
                del self.forced_overload[channel]
        self.status.volt.set_condition(0)
        self.end_wanted = False
        aborted, self.aborting = self.aborting, False
        self._ramp_down(aborted)

    def _ramp_down(self, aborted: bool) -> None:
        """The source ramps down at the slew rate (module :mod:`rigsim.analyser.ramp`); when
        ``ABOR`` stopped the sweep the rig simulator is driven through the ramp (lock held).

        At a sweep's own end the rig is not: the simulator takes consecutive sweeps as one
        continuous excitation (the next starts where the last left the rig), which the
        segments of a full plan and an adaptive plan's points rely on."""
        frequency, level = self.output.frequency_hz, self.output.driving_vpk
        duration_s = self.output.stop(float(self.store.get("sour.slew")), self.run.pace)
        plan = self._plan
        if plan is None or duration_s <= 0.0 or not aborted:
            return
        with self.rig_lock:
            for request in ramp_requests(frequency, level, duration_s, plan.control,
                                         plan.ranges):
                self.simulator.sweep(request)
