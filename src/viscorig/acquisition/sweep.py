"""Measure one sweep run segment by segment, committing each segment as soon as it is read.

A run is split by :func:`viscorig.sequences.plan_segments` (by default at most about a minute
of test time per segment, at most 801 points). Each segment is one analyser sweep; what the
analyser returns becomes one :class:`viscorig.storage.Segment` with its flags, appended to the
campaign file in one atomic commit. A run that already holds points continues from its first
missing point, so a crash or an abort loses at most the segment in flight.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from datetime import datetime

import numpy as np
from numpy.typing import NDArray

from viscorig.acquisition.limits import AT_FORCE_LIMIT_DB, point_flags
from viscorig.acquisition.protocol import Analyser, MeasuredSegment, SweepProgressReport
from viscorig.errors import InstrumentError
from viscorig.sequences import (
    Station,
    SweepStep,
    plan_segments,
    point_durations_s,
    resume_index,
    time_left_s,
)
from viscorig.storage import SOURCE_AT_LIMIT, Campaign, Segment

#: ``time_s`` clocks: "wall" is seconds of real time since the run started (a real rig);
#: "test" is accumulated settle and integration time (a simulated rig running faster than
#: real time, whose physics advances by test time).
TIME_BASES = ("wall", "test")
#: Source level the auto-level controller starts a run from, V peak (at most the limit).
START_LEVEL_V = 0.1
#: The analyser sets frequencies in steps of 15.625 mHz; half a step tells points apart.
FREQUENCY_MATCH_HZ = 0.0078125


class SweepInterrupted(Exception):  # noqa: N818 (an outcome, not a fault)
    """The operator stopped the sweep; every committed segment is kept."""


@dataclass(frozen=True)
class Wiring:
    """Which analyser input carries which transducer (from the station file).

    The analyser pairs inputs (1 → 2, 3 → 4): the pair of the excitation force gives the table
    accelerance, the other pair the support accelerance.
    """

    excitation_force: int
    table_acceleration: int
    device_force: int
    device_acceleration: int
    sensitivities_v_per_eu: Mapping[int, float]

    @classmethod
    def from_station(cls, station: Station) -> Wiring:
        """The wiring a station file describes."""
        channels, sensitivity = station.channels, station.sensitivity
        return cls(
            excitation_force=channels.excitation_force,
            table_acceleration=channels.table_acceleration,
            device_force=channels.device_force,
            device_acceleration=channels.device_acceleration,
            sensitivities_v_per_eu={
                channels.excitation_force: sensitivity.excitation_force_v_per_n,
                channels.table_acceleration: sensitivity.table_acceleration_v_per_m_s2,
                channels.device_force: sensitivity.device_force_v_per_n,
                channels.device_acceleration: sensitivity.device_acceleration_v_per_m_s2,
            },
        )

    @property
    def force_limit_acts_on_excitation(self) -> bool:
        """The analyser's input limit (``SOUR:VOLT:LIM:INP``) holds every input but the
        auto-level reference, each in its own unit (programming guide, chapter 19); the
        reference is an accelerometer, so the excitation force input is always held."""
        return self.excitation_force not in (self.table_acceleration, self.device_acceleration)


@dataclass(frozen=True)
class SweepSettings:
    """How one run is measured: the step, the level held and the limits in force."""

    step: SweepStep
    level_m_per_s2: float
    force_limit_n: float
    source_limit_v: float
    time_base: str = "wall"
    poll_interval_s: float = 0.2
    start_level_v: float = START_LEVEL_V
    """Source level the auto-level controller starts from, V peak (capped at the limit)."""

    def __post_init__(self) -> None:
        if self.time_base not in TIME_BASES:
            raise ValueError(f"time_base must be one of {TIME_BASES}, not {self.time_base!r}")


@dataclass(frozen=True)
class SegmentDone:
    """One committed segment, for progress displays and logs."""

    run: str
    number: int
    """1-based segment number within this session's plan of the run."""
    count: int
    """Segments planned this session."""
    points_done: int
    points_total: int
    frequency_hz: NDArray[np.float64]
    reference_amplitude: NDArray[np.float64]
    force_amplitude: NDArray[np.float64]
    flags: NDArray[np.uint16]
    remeasured: bool
    """The segment was measured again after an input overload."""
    seconds_left: float
    """Test time left in the run, s."""


@dataclass
class SweepHooks:
    """Callbacks of a sweep: stop request, progress while measuring, segment committed."""

    should_stop: Callable[[], bool] = lambda: False
    on_poll: Callable[[float, float], None] | None = None
    """Called with (estimated current frequency Hz, test time left in the run s)."""
    on_segment: Callable[[SegmentDone], None] | None = None
    measuring: list[bool] = field(default_factory=lambda: [False])
    """``measuring[0]`` is true while the analyser is measuring (for signal handlers)."""


def configure(analyser: Analyser, wiring: Wiring, settings: SweepSettings) -> None:
    """Set the analyser up for a run; the source limit is part of it and precedes the source.

    The analyser's input limit (shaker force) is used only when it watches the excitation
    force (input 1); otherwise the source limit alone bounds the drive.
    """
    step = settings.step
    grid = np.sort(step.frequencies_hz())
    first_stop = grid[min(grid.size - 1, 800)]
    reference = wiring.table_acceleration if step.bare_table else wiring.device_acceleration
    analyser.configure_swept_sine(
        sensitivities_v_per_eu=dict(wiring.sensitivities_v_per_eu),
        level_m_per_s2=settings.level_m_per_s2,
        source_limit_vpk=settings.source_limit_v,
        force_limit_n=settings.force_limit_n if wiring.force_limit_acts_on_excitation else None,
        reference_channel=reference,
        four_channels=True,
        resolution_hz=step.resolution_hz,
        start_hz=float(grid[0]),
        stop_hz=float(first_stop),
        settle_cycles=step.settle_cycles,
        integrate_cycles=step.integrate_cycles,
        direction=step.direction.upper(),
        tolerance_db=step.tolerance_db,
        start_level_vpk=min(settings.start_level_v, settings.source_limit_v),
    )


def _no_data(measured: MeasuredSegment) -> NDArray[np.bool_]:
    """Points where the driver flagged no data (the analyser's marker), if it says."""
    flags = getattr(measured, "no_data", None)
    count = np.asarray(measured.frequency_hz).size
    if flags is None:
        return np.zeros(count, dtype=bool)
    return np.asarray(flags, dtype=bool)


def _iso_to_epoch(text: str) -> float | None:
    try:
        return datetime.fromisoformat(text.replace("Z", "+00:00")).timestamp()
    except ValueError:
        return None


class SweepMeasurement:
    """Measure (or continue) one run of a campaign.

    Parameters
    ----------
    campaign
        The campaign file, open for appending; the run must exist (started or resumed).
    analyser
        Any :class:`~viscorig.acquisition.protocol.Analyser`, already configured for the run
        (:func:`configure`).
    wiring, settings
        Inputs and how the run is measured.
    hooks
        Stop request and progress callbacks.
    """

    def __init__(
        self,
        campaign: Campaign,
        analyser: Analyser,
        wiring: Wiring,
        settings: SweepSettings,
        hooks: SweepHooks | None = None,
    ) -> None:
        self.campaign = campaign
        self.analyser = analyser
        self.wiring = wiring
        self.settings = settings
        self.hooks = hooks or SweepHooks()
        step = settings.step
        self.planned_hz = step.frequencies_hz()
        self.durations_s = point_durations_s(self.planned_hz, step.settle_cycles,
                                             step.integrate_cycles)

    def run(self) -> int:
        """Measure every missing point; return the run's point count (all planned points).

        Raises
        ------
        SweepInterrupted
            ``hooks.should_stop()`` turned true; the segment in flight was dropped.
        InstrumentError
            The analyser returned a segment that does not match the plan.
        Exception
            Whatever the driver raises on an instrument fault (the caller classifies it).
        """
        step = self.settings.step
        stored = self.campaign.run(step.run)
        where = f"{self.campaign.path}: /runs/{step.run}"
        done = resume_index(self.planned_hz, stored.frequency_hz, where=where)
        last_time_s = float(stored.time_s[-1]) if stored.points else 0.0
        run_started = _iso_to_epoch(stored.metadata.started)
        remaining = self.planned_hz[done:]
        plan = plan_segments(remaining, step.settle_cycles, step.integrate_cycles,
                             max_segment_s=step.segment_s, max_points=step.segment_points)
        for number, piece in enumerate(plan, start=1):
            if self.hooks.should_stop():
                raise SweepInterrupted(step.run)
            rows = slice(done + piece.start, done + piece.stop)
            measured, remeasured = self._measure_rows(rows)
            segment = self._to_segment(measured, rows, last_time_s, run_started)
            total = self.campaign.append_segment(step.run, segment)
            last_time_s = float(np.asarray(segment.time_s)[-1])
            if self.hooks.on_segment is not None:
                self.hooks.on_segment(SegmentDone(
                    run=step.run, number=number, count=len(plan), points_done=total,
                    points_total=self.planned_hz.size,
                    frequency_hz=np.asarray(segment.frequency_hz),
                    reference_amplitude=np.asarray(segment.reference_amplitude),
                    force_amplitude=np.asarray(segment.force_amplitude),
                    flags=np.asarray(segment.flags, dtype=np.uint16),
                    remeasured=remeasured,
                    seconds_left=self._seconds_left(total),
                ))
        return self.planned_hz.size

    # -- one segment -------------------------------------------------------------------------
    def _seconds_left(self, done: int) -> float:
        step = self.settings.step
        return time_left_s(self.planned_hz, done, step.settle_cycles, step.integrate_cycles)

    def _measure_rows(self, rows: slice) -> tuple[MeasuredSegment, bool]:
        """Measure the planned rows; once more if an input overloaded (flagged if again) or a
        point came without data (refused if again: never stored as a measurement)."""
        measured = self._measure_once(rows)
        if not measured.overload_channels and not _no_data(measured).any():
            return measured, False
        measured = self._measure_once(rows)
        missing = _no_data(measured)
        if missing.any():
            where = ", ".join(f"{f:g}" for f in np.asarray(measured.frequency_hz)[missing][:5])
            raise InstrumentError(
                f"{self.analyser.resource}: the analyser gave no data at {missing.sum()} "
                f"point(s) ({where} Hz) twice in a row"
            )
        return measured, True

    def _measure_once(self, rows: slice) -> MeasuredSegment:
        frequencies = self.planned_hz[rows]
        cumulative = np.cumsum(self.durations_s[rows])
        left_after = self._seconds_left(rows.stop)

        def progress(report: SweepProgressReport) -> None:
            if self.hooks.should_stop():
                self.analyser.abort()
                return
            if self.hooks.on_poll is not None:
                index = min(int(np.searchsorted(cumulative, report.elapsed_s)), cumulative.size - 1)
                in_flight = max(float(cumulative[-1]) - float(report.elapsed_s), 0.0)
                self.hooks.on_poll(float(frequencies[index]), left_after + in_flight)

        poll = self.settings.poll_interval_s
        self.hooks.measuring[0] = True
        try:
            if frequencies.size == 1:
                measured = self.analyser.measure_point(
                    float(frequencies[0]), progress=progress, poll_interval_s=poll)
            else:
                lo, hi = float(frequencies.min()), float(frequencies.max())
                measured = self.analyser.measure(lo, hi, progress=progress, poll_interval_s=poll)
        except Exception as error:
            if self.hooks.should_stop():
                raise SweepInterrupted(self.settings.step.run) from error
            raise
        finally:
            self.hooks.measuring[0] = False
        if self.hooks.should_stop():  # stopped as the segment ended: drop it all the same
            raise SweepInterrupted(self.settings.step.run)
        self._check_axis(measured, frequencies)
        return measured

    def _check_axis(self, measured: MeasuredSegment, frequencies: NDArray[np.float64]) -> None:
        axis = np.asarray(measured.frequency_hz, dtype=float)
        if axis.shape != frequencies.shape or not np.allclose(
            axis, frequencies, rtol=0.0, atol=FREQUENCY_MATCH_HZ
        ):
            shown = f"{axis.size} points" + (f" from {axis[0]:g} to {axis[-1]:g} Hz"
                                             if axis.size else "")
            raise InstrumentError(
                f"{self.analyser.resource}: the analyser returned {shown}; expected "
                f"{frequencies.size} from {frequencies[0]:g} to {frequencies[-1]:g} Hz"
            )

    def _to_segment(
        self, measured: MeasuredSegment, rows: slice, last_time_s: float,
        run_started: float | None,
    ) -> Segment:
        """The storage segment of a measured one: FRFs by wiring, amplitudes, time, flags."""
        step, wiring, settings = self.settings.step, self.wiring, self.settings
        count = rows.stop - rows.start
        excitation_first = wiring.excitation_force == 1
        frf_43 = measured.frf_43
        if frf_43 is None:
            frf_43 = np.full(count, complex(math.nan, math.nan))
        table, support = (measured.frf_21, frf_43) if excitation_first else (frf_43,
                                                                              measured.frf_21)
        amplitude, variance = measured.amplitude_eu, measured.variance
        nan = np.full(count, math.nan)
        reference_channel = (wiring.table_acceleration if step.bare_table
                             else wiring.device_acceleration)
        reference = np.asarray(amplitude.get(reference_channel, nan), dtype=float)
        force = np.asarray(amplitude.get(wiring.excitation_force, nan), dtype=float)

        def pair_variance(a: int, b: int) -> NDArray[np.float64]:
            if a in variance and b in variance:
                return np.asarray(variance[a], float) + np.asarray(variance[b], float)
            return nan

        variance_table = pair_variance(wiring.excitation_force, wiring.table_acceleration)
        variance_support = pair_variance(wiring.device_force, wiring.device_acceleration)
        if step.bare_table:
            support = np.full(count, complex(math.nan, math.nan))
            variance_support = nan

        durations = self.durations_s[rows]
        if settings.time_base == "test" or run_started is None:
            time_s = last_time_s + np.cumsum(durations)
        else:
            share = np.cumsum(durations) / durations.sum()
            wall = measured.started_at_s + share * (measured.finished_at_s - measured.started_at_s)
            time_s = np.maximum(wall - run_started, last_time_s)

        flags = point_flags(
            reference, force,
            level_m_per_s2=settings.level_m_per_s2,
            tolerance_db=step.tolerance_db,
            force_limit_n=settings.force_limit_n,
            overloaded=bool(measured.overload_channels),
        )
        if wiring.force_limit_acts_on_excitation:
            # the input limit also holds the device force: a level missed while the device
            # force sat at the limit was held by the input limit, not by the source limit
            device = np.asarray(amplitude.get(wiring.device_force, nan), dtype=float)
            held = device >= settings.force_limit_n * 10.0 ** (-AT_FORCE_LIMIT_DB / 20.0)
            flags[held] &= np.uint16(~int(SOURCE_AT_LIMIT) & 0xFFFF)
        return Segment(
            frequency_hz=np.asarray(measured.frequency_hz, dtype=float),
            time_s=time_s,
            accelerance_table=np.asarray(table, dtype=complex),
            accelerance_support=np.asarray(support, dtype=complex),
            reference_amplitude=reference,
            source_amplitude=nan,
            force_amplitude=force,
            flags=flags,
            variance_table=variance_table,
            variance_support=variance_support,
        )
