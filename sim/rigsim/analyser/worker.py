"""The swept-sine measurement: plan, background worker, pacing, pause and abort.

``INIT`` plans the sweep from the settings and starts a worker thread that asks the rig
simulator for segments of points (volts at the analyser inputs, through
:mod:`rigsim.measurement`) and reveals them one by one. With a ``pace``, each point is revealed
when its simulated settle and integration time has passed on the wall clock, scaled, so a client
sees the measuring bit, can pause (``INIT:CONT OFF``) or abort (``ABOR``) mid-sweep, and a long
sweep really outlasts a VISA timeout.

Every start, abort or reset bumps a generation number; a worker whose generation is no longer
current stops at its next look at the state, so an aborted sweep never reveals another point.
"""

from __future__ import annotations

import math
import threading
import time
from collections.abc import Callable
from typing import Any, Protocol

import numpy as np

from rigsim.analyser.limits import MIN_DWELL_S
from rigsim.analyser.state import InstrumentState, MeasuredPoints
from rigsim.analyser.status import OPER_MEASURING, OPER_RANGING, OPER_SETTLING
from rigsim.measurement import CHANNEL_COUNT, SourceControl, SweepRecord, SweepRequest
from rigsim.scpi import ScpiError

__all__ = ["ZERO_SOURCE_MESSAGE", "Simulator", "SweepWorker", "voltage_bits"]

ZERO_SOURCE_MESSAGE = "Settings conflict; SOURCE LEVEL is 0 Volts, measurement paused"


class Simulator(Protocol):
    """What the analyser needs of the rig simulator (``rigsim.engine.RigSimulator``)."""

    clock_s: float

    def sweep(self, request: SweepRequest) -> SweepRecord:
        """Measure the request's points, volts at the analyser inputs."""

    def mount(self, rig: Any) -> None:
        """Replace the rig (new specimens); the clock restarts."""


def voltage_bits(overload: np.ndarray, half_range: np.ndarray) -> int:
    """``STAT:QUES:VOLT`` bits: channel n's overload at bit n-1, its half range at bit n+7."""
    bits = 0
    for i in range(CHANNEL_COUNT):
        bits |= (1 << i) if overload[i] else 0
        bits |= (1 << (8 + i)) if half_range[i] else 0
    return bits


class SweepWorker(InstrumentState):
    """Runs swept-sine measurements in a background thread (a base of the analyser).

    ``state`` is ``"IDLE"``, ``"RUNNING"`` or ``"PAUSED"``; a paused sweep counts as running
    for ``*OPC`` and ``*WAI``.
    """

    simulator: Simulator
    pace: float | None
    #: Points asked of the simulator at once when unpaced.
    segment_points: int
    #: Called with the number of points measured after each point (in-process hook).
    on_point: Callable[[int], None] | None

    def _init_sweep(self, simulator: Simulator, pace: float | None) -> None:
        self.simulator = simulator
        self.pace = pace
        self.state = "IDLE"  # IDLE | RUNNING | PAUSED
        self._generation = 0
        self._worker: threading.Thread | None = None
        self._measured = MeasuredPoints(0)
        self._point_window: tuple[float, float, float] | None = None  # wall: start, settled, end
        self._last_flags = np.zeros((2, CHANNEL_COUNT), bool)
        self._forced_overload: dict[int, int | None] = {}
        self.segment_points = 64
        self.on_point = None

    # ---------------------------------------------------------------- conditions

    def oper_condition(self) -> int:
        """``STAT:OPER:COND?``: settling 2, ranging 4, measuring 16."""
        with self.lock:
            if self.state != "RUNNING":
                return 0
            bits = OPER_MEASURING
            window = self._point_window
            if window is not None:
                now = time.monotonic()
                start, settled, _ = window
                if start <= now < settled:
                    bits |= OPER_SETTLING
                    # autorange ranges at the start of each point (inferred: first 20 % of settle)
                    autorange = any(c.enabled and c.autorange for c in self.channels)
                    if autorange and now < start + 0.2 * (settled - start):
                        bits |= OPER_RANGING
            return bits

    def _volt_condition(self) -> int:
        """``STAT:QUES:VOLT:COND?``: the flags of the last point while a sweep runs."""
        if self.state != "RUNNING":
            return 0
        over, half = self._last_flags
        return voltage_bits(over, half)

    # ---------------------------------------------------------------- plan

    def _point_list(self) -> np.ndarray:
        s = self.settings
        if s.sweep_mode == "MAN":
            return np.array([s.manual_hz])
        lo, hi = sorted((s.start_hz, s.stop_hz))
        if s.spacing == "LOG":
            if lo <= 0:
                raise ScpiError(-221, "logarithmic sweep needs a start frequency above 0 Hz")
            points = np.geomspace(lo, hi, s.points)
        else:
            points = np.linspace(lo, hi, s.points)
        return points[::-1].copy() if s.direction == "DOWN" else points

    @staticmethod
    def _seconds(setting: tuple[float, str], frequency_hz: np.ndarray) -> np.ndarray:
        value, unit = setting
        if unit == "CYCLE":
            return value / frequency_hz
        return np.full(frequency_hz.shape, value)

    def _control(self, start_vpk: float) -> SourceControl:
        src = self.source
        ref_channel = self.channels[src.reference_channel - 1]
        ref_value, ref_unit = src.reference
        reference_vpk = ref_value * ref_channel.v_per_eu() if ref_unit == "EU" else ref_value
        limit_channel = limit_vpk = None
        if src.input_limit_on:
            limit_channel = src.input_limit_channel
            value, unit = src.input_limit
            scale = self.channels[limit_channel - 1].v_per_eu() if unit == "EU" else 1.0
            limit_vpk = value * scale
        return SourceControl(
            source_vpk=start_vpk,
            auto_level=src.auto_level,
            reference_channel=src.reference_channel,
            reference_vpk=reference_vpk,
            tolerance_db=src.tolerance_db,
            source_limit_vpk=src.limit_vpk,
            input_limit_channel=limit_channel,
            input_limit_vpk=limit_vpk,
        )

    def _zero_source(self) -> bool:
        return not self.source.output or self.source.level_vpk <= 0.0

    # ---------------------------------------------------------------- start, abort, pause

    def _initiate(self) -> None:
        if self.mode != "SINE":
            # FFT measurements are not simulated: say so instead of returning nothing (inferred)
            raise ScpiError(-221, "only swept sine (INST:SEL SINE) is simulated")
        if self.state != "IDLE":
            raise ScpiError(-213, "measurement already running; ABOR first")
        if self.source.auto_level and not self.channels[self.source.reference_channel - 1].enabled:
            channel = self.source.reference_channel
            raise ScpiError(-221, f"auto-level reference channel {channel} is off")
        frequencies = self._point_list()
        settle_s = self._seconds(self.settings.settle, frequencies)
        integrate_s = np.maximum(self._seconds(self.settings.dwell, frequencies),
                                 np.maximum(MIN_DWELL_S, 1.0 / frequencies))
        ranges = tuple(
            None if c.autorange else float(math.sqrt(2.0) * 10 ** (c.range_dbvrms / 20))
            for c in self.channels
        )
        self._plan = (frequencies, settle_s, integrate_s, ranges)
        self._measured = MeasuredPoints(frequencies.size)
        self._measured.v_per_eu = np.array([c.v_per_eu() for c in self.channels])
        self._source_level = self.source.level_vpk
        self._generation += 1
        self._point_window = None
        if self._zero_source():
            self.state = "PAUSED"
            self.status.push_error(-221, ZERO_SOURCE_MESSAGE)
        else:
            self.state = "RUNNING"
        self._worker = threading.Thread(
            target=self._run, args=(self._generation,), name="35670A-sweep", daemon=True
        )
        self._worker.start()

    def _abort(self) -> None:
        if self.state != "IDLE":
            self.state = "IDLE"
            self._generation += 1
            self._point_window = None
            self.status.complete_operation()

    def _pause(self) -> None:
        if self.state == "RUNNING":
            self.state = "PAUSED"
            self._point_window = None
            self.changed.notify_all()

    def _resume(self) -> None:
        if self.state == "PAUSED":
            if self._zero_source():
                self.status.push_error(-221, ZERO_SOURCE_MESSAGE)
                return
            self.state = "RUNNING"
            self.changed.notify_all()

    # ---------------------------------------------------------------- the worker thread

    def _next_segment(self, start: int) -> int:
        frequencies, settle_s, integrate_s, _ = self._plan
        stop = min(frequencies.size, start + self.segment_points)
        if self.pace is not None:
            # compute ahead about half a wall second of paced test time
            durations = np.cumsum(settle_s[start:stop] + integrate_s[start:stop]) / self.pace
            stop = start + max(1, int(np.searchsorted(durations, 0.5)))
        return stop

    def _run(self, generation: int) -> None:
        """Worker: measure segment by segment, reveal points as simulated time passes."""
        try:
            self._run_points(generation)
        except Exception as exc:  # the simulator failed: a device error, never a silent stop
            with self.lock:
                if generation == self._generation:
                    self.status.push_error(-310, f"System error; simulator: {exc}"[:200])
                    self.state = "IDLE"
                    self.status.complete_operation()

    def _run_points(self, generation: int) -> None:
        frequencies, settle_s, integrate_s, ranges = self._plan
        computed = 0
        while True:
            with self.changed:
                while self.state == "PAUSED" and generation == self._generation:
                    self.changed.wait()
                if generation != self._generation:
                    return
                start = computed
                if start >= frequencies.size:
                    self.state = "IDLE"
                    self._point_window = None
                    # an overload forced "for the next sweep" ends with it
                    for channel, remaining in list(self._forced_overload.items()):
                        if remaining is None:
                            del self._forced_overload[channel]
                    self.status.complete_operation()
                    return
                stop = self._next_segment(start)
                request = SweepRequest(
                    frequency_hz=frequencies[start:stop],
                    settle_s=settle_s[start:stop],
                    integrate_s=integrate_s[start:stop],
                    control=self._control(self._source_level),
                    input_range_vpk=ranges,
                )
                clock_before = float(self.simulator.clock_s)
            record = self.simulator.sweep(request)
            computed = stop
            ends = np.asarray(record.end_time_s, float)
            previous_end = clock_before
            for k in range(len(record)):
                if self.pace is not None:
                    duration = max(0.0, (ends[k] - previous_end) / self.pace)
                    point_s = settle_s[start + k] + integrate_s[start + k]
                    settle_share = settle_s[start + k] / max(point_s, 1e-12)
                    if not self._wait_point(generation, duration, settle_share):
                        return
                previous_end = ends[k]
                with self.lock:
                    if generation != self._generation:
                        return
                    self._reveal(record, k, integrate_s[start + k])

    def _wait_point(self, generation: int, duration_s: float, settle_share: float) -> bool:
        """Wait a paced point's wall time, honouring pause and abort. False when aborted."""
        with self.changed:
            while True:
                while self.state == "PAUSED" and generation == self._generation:
                    self.changed.wait()
                if generation != self._generation:
                    return False
                start = time.monotonic()
                end = start + duration_s
                self._point_window = (start, start + settle_share * duration_s, end)
                while self.state == "RUNNING" and generation == self._generation:
                    remaining = end - time.monotonic()
                    if remaining <= 0:
                        return True
                    self.changed.wait(remaining)
                if generation != self._generation:
                    return False
                # paused mid-point: the point starts again on resume

    def _reveal(self, record: SweepRecord, k: int, integrate_s: float) -> None:
        """Point ``k`` of ``record`` is measured: store it, set the status bits, tell the hook."""
        self._source_level = float(record.source_vpk[k]) or self._source_level
        overload = np.array(record.overload[k], bool)
        for channel, remaining in list(self._forced_overload.items()):
            overload[channel - 1] = True
            if remaining is not None:
                if remaining <= 1:
                    del self._forced_overload[channel]
                else:
                    self._forced_overload[channel] = remaining - 1
        record.overload[k] = overload
        self._measured.append(record, slice(k, k + 1), np.array([integrate_s]))
        half = np.array(record.half_range[k], bool)
        self._last_flags = np.array([overload, half])
        enabled = np.array([c.enabled for c in self.channels])
        bits = voltage_bits(overload & enabled, half & enabled)
        status = self.status
        status.volt_event |= bits
        if bits & status.volt_enable:
            status.ques_event |= 1  # QUES bit 0: voltage summary (inferred)
        status.oper_event |= OPER_MEASURING
        if self.on_point is not None:
            self.on_point(self._measured.count)
