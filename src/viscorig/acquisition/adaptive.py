"""The adaptive sweep: a sequence step whose points an adaptive plan chooses (``plan =
"adaptive"``), measured and stored like any sweep.

The planning core (:class:`viscorig.planning.AdaptivePlan`) looks at the band, fits, and asks
for the frequencies, settle and integration that teach the targets most per second of rig time
until every target uncertainty is met (or the dwell limit). This plan step carries its requests
to the analyser and its results to the file:

- each request is split into analyser sweeps (:func:`viscorig.planning.sweep_segments`): short
  linear sub-sweeps with their own resolution, settle and integration, and points in manual
  sweep mode (``measure_points``), each group with one settle and one integration;
- every point measured is stored, in measurement order, the first look and repeats of one
  frequency included, with its ``settle_cycles`` and ``integrate_cycles``; ``time_s`` is the
  running sum of each point's rig time and ``test_time_s`` their total; segments are committed
  at least every ``segment_s`` of rig time;
- the plan's progress is said as it goes, and its outcome kept in the run's attributes
  (``plan_reason``, ``plan_relative_stderr``, ``plan_history``);
- a run stopped mid-plan (Ctrl-C, a fault, a crash) continues from the file: the points it
  holds are handed to a new plan in the same requests, which then asks for the rest.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass, field, replace

import numpy as np
from numpy.typing import ArrayLike

from viscorig.acquisition import stubs
from viscorig.acquisition.console import format_duration
from viscorig.acquisition.engine import MeasureRequest, Msg, Plan, RunRefused
from viscorig.acquisition.gain import (
    DISAGREE_STDERRS,
    GAIN_SOURCE_V,
    disagreement,
    estimate_gain,
)
from viscorig.acquisition.probe import (
    FREQUENCY_STEP_HZ,
    probe_cycles,
    probe_frequencies_hz,
    probe_settings,
)
from viscorig.acquisition.session import RunState, Session, StepRecord
from viscorig.acquisition.sweep import (
    SegmentDone,
    SweepSettings,
    check_axis,
    check_piece,
    point_times_s,
    segment_of,
)
from viscorig.fitting.data import NORMALIZED_VARIANCE_RANGE
from viscorig.planning import (
    ANALYSER,
    AdaptivePlan,
    AdaptiveSettings,
    MeasuredPoints,
    PlannedPoint,
    PointTiming,
    SweepSegment,
    model_amplitudes,
    sweep_segments,
)
from viscorig.sequences import SweepStep, point_durations_s
from viscorig.storage import CampaignFile, RunRecord, RunSettings, Segment

__all__ = ["DEFAULT_RESOLUTION_HZ", "adaptive_run_settings", "adaptive_settings",
           "adaptive_sweep", "check_adaptive", "shaker_gain", "stored_points"]

#: Spacing of the frequencies an adaptive plan may choose when the step gives none, Hz.
DEFAULT_RESOLUTION_HZ = 0.25
#: The run attribute ``plan_history`` keeps at most this many characters.
HISTORY_CHARACTERS = 16_000


def adaptive_settings(step: SweepStep, level: float, fixed: dict[str, float] | None,
                      force_limit_n: float | None) -> AdaptiveSettings:
    """What the planning core is asked, from the sequence step."""
    return AdaptiveSettings(
        spec=str(step.model), targets=step.targets, band_hz=step.band_hz,
        level_m_per_s2=level, fixed=dict(fixed or {}), dwell_limit_s=step.dwell_limit_s,
        resolution_hz=step.resolution_hz or DEFAULT_RESOLUTION_HZ,
        max_settle_cycles=step.settle_cycles, max_integrate_cycles=step.integrate_cycles,
        force_limit_n=force_limit_n, timing=PointTiming(tolerance_db=step.tolerance_db),
    )  # fmt: skip


def adaptive_run_settings(settings: RunSettings, step: SweepStep) -> RunSettings:
    """An adaptive run's attributes: its settle, integration and resolution are the bounds the
    step allowed (its points carry their own)."""
    return replace(
        settings,
        settle_cycles=step.settle_cycles if step.settle_cycles is not None
        else ANALYSER.max_settle_cycles,
        integrate_cycles=step.integrate_cycles if step.integrate_cycles is not None
        else ANALYSER.max_integrate_cycles,
        resolution_hz=step.resolution_hz or DEFAULT_RESOLUTION_HZ,
    )


def _fixed(session: Session, step: SweepStep) -> dict[str, float] | None:
    if step.bare_table or session.table is None:
        return None
    table = session.table
    return {"M_s": table.table_mass_kg, "K_s": table.table_stiffness_n_per_m,
            "C_s": table.table_damping_ns_per_m}


def check_adaptive(session: Session, step: SweepStep) -> Plan:
    """Before an adaptive run opens: the analyser measures chosen points, and a specimen plan
    knows the table.

    Raises
    ------
    RunRefused
        With what is missing and how to provide it.
    """
    if not (yield Msg("supports", ("measure_points",), step="adaptive")):
        raise RunRefused(f"run '{step.run}': plan = \"adaptive\" needs an analyser that "
                         "measures chosen frequencies (manual sweep mode); this driver has no "
                         "measure_points. Nothing was measured")
    if session.station.shaker_gain_n_per_v is None and not (
            yield Msg("supports", ("measure_at_source",), step="adaptive")):
        raise RunRefused(f"run '{step.run}': an adaptive plan starts each point's auto-level "
                         "controller at the source level the point needs (the force it needs "
                         "over the shaker's gain), so that the rig is steady when it comes back "
                         "to a frequency; this driver cannot measure the gain (no "
                         "measure_at_source): give [shaker] gain_n_per_v in the station file. "
                         "Nothing was measured")
    if not step.bare_table and session.table is None:
        raise RunRefused(f"run '{step.run}': an adaptive plan fits the specimen with the table's "
                         "M_s, K_s, C_s fixed, and they are unknown: add an identify_table step "
                         "after a bare-table sweep, or a [table] in the station file. Nothing "
                         "was measured")


def _targets_text(step: SweepStep) -> str:
    return " ".join(f"{name}={value:g}" for name, value in step.targets.items())


def adaptive_sweep(session: Session, step: SweepStep, record: StepRecord, level: float) -> Plan:
    """Measure (or continue) an adaptive run (module text): announce the plan, measure the
    shaker's gain, set the analyser up, then measure each request the plan makes and hand it
    the points, until it asks for none; then keep its outcome with the run."""
    settings = adaptive_settings(step, level, _fixed(session, step),
                                 session.station.shaker_force_limit_n)
    plan = AdaptivePlan(settings)
    sweep = session.sweep_settings(step, level)
    course = _Course(session, step, plan, settings, sweep)
    yield from course.open(level)
    record.move(RunState.CONFIGURING)
    yield from shaker_gain(session, step, sweep)
    yield from stubs.configure(sweep, "adaptive", band_hz=step.band_hz,
                               resolution_hz=settings.resolution_hz,
                               settle_cycles=step.settle_cycles or 0,
                               integrate_cycles=step.integrate_cycles or 1)
    record.move(RunState.MEASURING)
    while plan.request is not None:
        yield from course.say_notes()
        delivered = yield from course.measure_request()
        plan.deliver(delivered)
    yield from course.say_notes()
    yield from course.close()


@dataclass
class _Batch:
    """What one request has measured so far: the plan's points (an earlier run's part of it
    first), the segments not yet committed and their rig time, and the time the request's
    prediction leaves."""

    left_s: float
    measured: list[MeasuredPoints]
    pending: list[Segment] = field(default_factory=list)
    pending_s: float = 0.0


@dataclass
class _Course:
    """One adaptive run as it goes: the plan and what the run has done (rig time, points
    stored, commits, plan notes said, and the points of a request an earlier run stopped
    in), with one method per part of :func:`adaptive_sweep`."""

    session: Session
    step: SweepStep
    plan: AdaptivePlan
    settings: AdaptiveSettings
    sweep: SweepSettings
    test_time_s: float = 0.0
    points_done: int = 0
    commits: int = 0
    said: int = 0
    partial: MeasuredPoints | None = None

    def open(self, level: float) -> Plan:
        """Read the run; hand a stopped run's points to the plan again (or mark a new run with
        the plan's model and targets); start the progress display and say what the plan is
        for."""
        step, plan, settings = self.step, self.plan, self.settings
        run = yield from stubs.read_run(step.run, "adaptive")
        attributes = yield Msg("compute", (_attributes, step.run), step="adaptive")
        self.test_time_s = float(attributes.get("test_time_s", 0.0))
        self.points_done = run.points
        if run.points:
            self.partial, _ = _replay(plan, stored_points(run))
            self.said = len(plan.history)
            yield from stubs.say(
                f"continuing run '{step.run}': its {run.points} points handed to the plan "
                "again, which asks for the rest", "adaptive")
        else:
            yield from stubs.annotate(step.run, {"plan_model": str(step.model),
                                                 "plan_targets": _targets_text(step)},
                                      step="adaptive")
        yield Msg("progress", ("start_run", step.run, run.points,
                               run.points + _pending(plan, self.partial),
                               int((run.flags != 0).sum())), step="adaptive")
        yield from stubs.say(
            f"run '{step.run}': adaptive plan for {settings.spec}, targets "
            + ", ".join(f"{name} {100 * value:g} %" for name, value in settings.targets.items())
            + f", {step.band_hz[0]:g}-{step.band_hz[1]:g} Hz, level {level:.4g} m/s^2"
            + (f", dwell limit {step.dwell_limit_s:g} s" if step.dwell_limit_s else ""),
            "adaptive")

    def say_notes(self) -> Plan:
        """Say the plan's notes not said yet."""
        for entry in self.plan.history[self.said:]:
            yield from stubs.say(f"  {entry.state.value}: {entry.note}", "adaptive")
        self.said = len(self.plan.history)

    def measure_request(self) -> Plan:
        """Measure what is left of the plan's request, analyser group by group, committing at
        least every ``segment_s`` of rig time, at the request's end, and where a pause takes
        hold; return the request's points, for the plan."""
        request = self.plan.request
        assert request is not None
        skip = 0 if self.partial is None else len(self.partial)
        batch = _Batch(float(request.predicted_s), [] if self.partial is None else [self.partial])
        self.partial = None
        groups = analyser_groups(request.points[skip:])
        while groups:
            group = groups.pop(0)
            count, remeasured = yield from self.measure_group(group, batch)
            ended = count < len(group.points)  # fewer when paused
            if ended:  # the rest of the group after the pause
                groups[:0] = analyser_groups(group.points[count:])
            pause = bool(batch.pending) and not ended and bool(groups) and (
                yield from stubs.pausing("adaptive"))  # between one-point groups
            if batch.pending and (batch.pending_s >= self.step.segment_s or ended or not groups
                                  or pause):
                remaining = sum(len(later.points) for later in groups)
                yield from self.commit(batch, remaining, remeasured)
            elif ended:  # a pause ended the sweep before its first point: pause here
                yield from stubs.checkpoint("adaptive")
        delivered = _joined(batch.measured)
        assert delivered is not None
        return delivered

    def measure_group(self, group: SweepSegment, batch: _Batch) -> Plan:
        """Measure one analyser group, each point started at the source level it needs; add
        what was measured to ``batch`` (the plan's points, a segment to commit, on the run's
        clock). Returns the points measured (fewer than the group's when a pause ended it) and
        whether the analyser measured the group again (an overload, a point without data)."""
        session, sweep = self.session, self.sweep
        f = np.array([p.frequency_hz for p in group.points])
        settle = np.array([p.settle_cycles for p in group.points], dtype=np.int64)
        integrate = np.array([p.integrate_cycles for p in group.points], dtype=np.int64)
        base_s = (settle + integrate) / f
        plan = self.plan
        so_far = _joined([*([] if plan.points is None else [plan.points]), *batch.measured])
        levels = start_levels(f, plan, so_far, self.settings, session)
        call = MeasureRequest(self.step.run, session.resource, f, base_s,
                              max(batch.left_s - float(base_s.sum()), 0.0), _call(group, levels),
                              ends_at_a_point=True)
        measured, remeasured = yield from stubs.measure_segment(
            call, functools.partial(check_piece, frequencies=f, resource=session.resource),
            "adaptive")
        count = np.asarray(measured.frequency_hz).size
        if count:
            rows = slice(0, count)
            batch.left_s = max(batch.left_s - float(base_s[rows].sum()), 0.0)
            rig_s = point_times_s(measured, base_s[rows], sweep.time_base)
            time_s = self.test_time_s + np.cumsum(rig_s)
            self.test_time_s = float(time_s[-1])
            segment = segment_of(measured, session.wiring, sweep, time_s,
                                 (settle[rows], integrate[rows]))
            batch.measured.append(_points(segment, rig_s, self.step.bare_table))
            batch.pending.append(segment)
            batch.pending_s += float(rig_s.sum())
        return count, remeasured

    def commit(self, batch: _Batch, remaining: int, remeasured: bool) -> Plan:
        """Store the segments of ``batch`` not yet committed as one, with the run's rig time
        and the plan's state, and show them (``remaining``: points of the request still to
        measure). A pause takes hold at the checkpoint after the commit."""
        joined = join_segments(batch.pending)
        total = yield from stubs.commit(self.step.run, joined, {
            "test_time_s": self.test_time_s, "plan_state": self.plan.state.value,
        }, "adaptive")
        self.commits += 1
        self.points_done = total
        yield Msg("progress", ("segment", SegmentDone(
            run=self.step.run, number=self.commits, count=self.commits, points_done=total,
            points_total=total + remaining, frequency_hz=np.asarray(joined.frequency_hz),
            reference_amplitude=np.asarray(joined.reference_amplitude),
            force_amplitude=np.asarray(joined.force_amplitude),
            flags=np.asarray(joined.flags, dtype=np.uint16), remeasured=remeasured,
            seconds_left=batch.left_s)), step="adaptive")
        batch.pending, batch.pending_s = [], 0.0

    def close(self) -> Plan:
        """Keep the plan's outcome in the run's attributes (reason, relative standard errors,
        history, rig time) and say it."""
        step, outcome = self.step, self.plan.outcome
        assert outcome is not None
        stderr_text = " ".join(f"{name}={value:.4g}" for name, value in
                               outcome.relative_stderr.items())
        history = "; ".join(f"{entry.state.value}: {entry.note}" for entry in outcome.history)
        yield from stubs.annotate(step.run, {
            "plan_reason": outcome.reason, "plan_state": "done",
            "plan_relative_stderr": stderr_text, "test_time_s": self.test_time_s,
            "plan_history": history[-HISTORY_CHARACTERS:],
        }, step="adaptive")
        frequencies = np.unique(outcome.points.frequency_hz).size
        yield from stubs.say(
            f"run '{step.run}' complete (adaptive plan: {outcome.reason}): {self.points_done} "
            f"points at {frequencies} frequencies, {relative_text(outcome.relative_stderr)}; "
            f"rig time {_clock(self.test_time_s)}", "adaptive")


def _clock(seconds: float) -> str:
    return format_duration(seconds)


def _pending(plan: AdaptivePlan, partial: MeasuredPoints | None) -> int:
    """Points of the plan's current request still to measure."""
    if plan.request is None:
        return 0
    return len(plan.request.points) - (0 if partial is None else len(partial))


def _replay(plan: AdaptivePlan, stored: MeasuredPoints) -> tuple[MeasuredPoints | None, int]:
    """Hand the stored points to the plan, request by request; return what is left of a request
    the run stopped in (``None``: none), and the points handed over whole."""
    offset = 0
    while plan.request is not None and offset < len(stored):
        want = len(plan.request.points)
        if offset + want > len(stored):
            return _slice(stored, offset, len(stored)), offset
        plan.deliver(_slice(stored, offset, offset + want))
        offset += want
    return None, offset


def _slice(points: MeasuredPoints, start: int, stop: int) -> MeasuredPoints:
    """Points ``start:stop``."""
    pick = slice(start, stop)

    def cut(values):
        return None if values is None else values[pick]

    return MeasuredPoints(
        frequency_hz=points.frequency_hz[pick],
        accelerance_table=points.accelerance_table[pick],
        accelerance_support=cut(points.accelerance_support),
        reference_amplitude=points.reference_amplitude[pick],
        force_amplitude=points.force_amplitude[pick],
        settle_cycles=points.settle_cycles[pick],
        integrate_cycles=points.integrate_cycles[pick],
        duration_s=points.duration_s[pick],
        variance_table=cut(points.variance_table),
        variance_support=cut(points.variance_support),
        flags=cut(points.flags),
    )


def _usable(values: ArrayLike | None) -> np.ndarray | None:
    """A variance the plan can use (every value within
    :data:`~viscorig.fitting.data.NORMALIZED_VARIANCE_RANGE`, as the fits take it), else
    ``None``."""
    if values is None:
        return None
    values = np.asarray(values, dtype=float)
    low, high = NORMALIZED_VARIANCE_RANGE
    return values if np.all((values >= low) & (values <= high)) else None


def _as_points(source: Segment | RunRecord, settle, integrate, durations_s, bare: bool
               ) -> MeasuredPoints:
    """A stored segment or run as the plan's measured points."""
    return MeasuredPoints(
        frequency_hz=np.asarray(source.frequency_hz, dtype=float),
        accelerance_table=np.asarray(source.accelerance_table, dtype=complex),
        accelerance_support=None if bare else np.asarray(source.accelerance_support, complex),
        reference_amplitude=np.asarray(source.reference_amplitude, dtype=float),
        force_amplitude=np.asarray(source.force_amplitude, dtype=float),
        settle_cycles=np.asarray(settle, dtype=np.int64),
        integrate_cycles=np.asarray(integrate, dtype=np.int64),
        duration_s=np.asarray(durations_s, dtype=float),
        variance_table=_usable(source.variance_table),
        variance_support=None if bare else _usable(source.variance_support),
        flags=np.asarray(source.flags, dtype=np.uint16),
    )


def _points(segment: Segment, rig_s: np.ndarray, bare: bool) -> MeasuredPoints:
    """A segment just measured as the plan's measured points."""
    return _as_points(segment, segment.settle_cycles, segment.integrate_cycles, rig_s, bare)


def stored_points(run: RunRecord) -> MeasuredPoints:
    """An adaptive run's points as stored, in measurement order, as the plan was given them
    (each point's rig time from the running sum ``time_s``)."""
    bare = str(run.metadata.specimen).strip().lower() in ("none", "")
    durations = np.diff(np.concatenate([[0.0], np.asarray(run.time_s, dtype=float)]))
    return _as_points(run, *run.cycles, durations, bare)


def analyser_groups(points: tuple[PlannedPoint, ...] | list[PlannedPoint]) -> list[SweepSegment]:
    """The analyser sweeps of a request: its rising linear sub-sweeps, and its manual points in
    runs of one settle and one integration (one ``measure_points`` call each)."""
    groups: list[SweepSegment] = []
    for segment in sweep_segments(list(points)):
        rising = segment.kind == "linear" and segment.stop_hz > segment.start_hz
        if rising:
            groups.append(segment)
            continue
        run: list[PlannedPoint] = []
        for point in segment.points:
            if run and (point.settle_cycles, point.integrate_cycles) != (
                    run[0].settle_cycles, run[0].integrate_cycles):
                groups.append(SweepSegment("manual", tuple(run)))
                run = []
            run.append(point)
        if run:
            groups.append(SweepSegment("manual", tuple(run)))
    return groups


def _joined(pieces: list[MeasuredPoints]) -> MeasuredPoints | None:
    """Points measured one after the other, as one (``None`` for none)."""
    if not pieces:
        return None
    joined = pieces[0]
    for more in pieces[1:]:
        joined = joined.concatenate(more)
    return joined


#: Lowest start level an adaptive plan sets, V peak (a start of 0 V would pause the sweep).
MIN_START_LEVEL_V = 1e-3


def start_levels(frequency_hz: np.ndarray, plan: AdaptivePlan, measured: MeasuredPoints | None,
                 settings: AdaptiveSettings, session: Session) -> np.ndarray | None:
    """The source level each point's auto-level controller starts from: the force the point
    needs over the shaker's gain, within the source limit.

    The analyser starts every measurement at its source level; started where the controller
    will land, a point finds the rig steady when the one before it was at the same frequency
    and level (what the plan's lead-in points and repeats count on). The force needed is the
    fitted model's under the controller's level (:func:`viscorig.planning.model_amplitudes`),
    or, before the first fit, the nearest point measured, scaled to the level. ``None``: nothing
    known yet (the analyser's own start).
    """
    gain = session.shaker_gain_n_per_v or session.station.shaker_gain_n_per_v
    if gain is None:
        return None
    level = settings.level_m_per_s2
    result = plan.result
    if result is not None:
        force = model_amplitudes(result.model, result.values, frequency_hz, level,
                                 force_limit_n=settings.force_limit_n).excitation_force
    elif measured is not None and len(measured):
        reached = np.asarray(measured.reference_amplitude, dtype=float)
        usable = np.isfinite(reached) & (reached > 0) & np.isfinite(measured.force_amplitude)
        if not np.any(usable):
            return None
        known = measured.frequency_hz[usable]
        scaled = measured.force_amplitude[usable] * level / reached[usable]
        nearest = np.argmin(np.abs(np.log(frequency_hz[:, None] / known[None, :])), axis=1)
        force = scaled[nearest]
    else:
        return None
    return np.clip(np.asarray(force, dtype=float) / gain, MIN_START_LEVEL_V,
                   session.source_limit_v())


def shaker_gain(session: Session, step: SweepStep, sweep: SweepSettings) -> Plan:
    """Measure the amplifier-and-shaker gain before an adaptive run (module
    :mod:`viscorig.acquisition.gain`), store it with the run and use it; the station's value,
    when given, is a check. Returns the gain used, N/V.

    Raises
    ------
    RunRefused
        No force was measured and the station gives no gain.
    """
    station = session.station.shaker_gain_n_per_v
    session.shaker_gain_n_per_v = None
    if not (yield Msg("supports", ("measure_at_source",), step="gain")):
        yield from stubs.annotate(step.run, {"shaker_gain_n_per_v": station,
                                             "shaker_gain_stderr_n_per_v": math.nan,
                                             "shaker_gain_basis": "the station file"}, step="gain")
        return station
    frequencies = np.array(probe_frequencies_hz(step))
    settle, integrate = probe_cycles(step)
    source = min(GAIN_SOURCE_V, sweep.source_limit_v)
    low = probe_settings(sweep, session.wiring.lowest_reference_level(step.bare_table))
    span = max(frequencies[-1] - frequencies[0], FREQUENCY_STEP_HZ)
    yield from stubs.configure(low, "gain", band_hz=(frequencies[0], frequencies[0] + span),
                               resolution_hz=span, settle_cycles=settle,
                               integrate_cycles=integrate)
    durations = point_durations_s(frequencies, settle, integrate)

    def call(analyser, progress, poll_interval_s):
        return analyser.measure_at_source(frequencies.tolist(), source,
                                          progress=progress, poll_interval_s=poll_interval_s)

    request = MeasureRequest(step.run, session.resource, frequencies, durations, 0.0, call)
    measured, _ = yield from stubs.measure_segment(
        request, lambda m: check_axis(m, frequencies, session.resource), "gain")
    force_channel = session.wiring.excitation_force
    estimate = estimate_gain(measured.frequency_hz,
                             measured.amplitude_eu.get(force_channel, [math.nan]), source,
                             measured.variance.get(force_channel))
    if estimate is None:
        where = (f"{source:.3g} Vpk at " + " and ".join(f"{f:g}" for f in frequencies)
                 + f" Hz gave no force on input {force_channel}")
        if station is None:
            raise RunRefused(f"run '{step.run}': measuring the shaker's gain, {where}: check "
                             "the amplifier (on, gain) and the excitation force transducer, or "
                             "give [shaker] gain_n_per_v in the station file. Nothing was "
                             "measured")
        yield from stubs.warn(f"run '{step.run}': measuring the shaker's gain, {where}; the "
                              f"station's {station:g} N/V is used", "gain")
        yield from stubs.annotate(step.run, {"shaker_gain_n_per_v": station,
                                             "shaker_gain_stderr_n_per_v": math.nan,
                                             "shaker_gain_basis": "the station file"}, step="gain")
        return station
    yield from stubs.say(f"run '{step.run}': shaker gain {estimate.text()} ({estimate.basis}; "
                         f"{float(durations.sum()):.0f} s of test time, not part of the run)",
                         "gain")
    distance = disagreement(estimate, station)
    if distance is not None and distance > DISAGREE_STDERRS:
        yield from stubs.warn(
            f"run '{step.run}': the station file's [shaker] gain_n_per_v = {station:g} N/V "
            f"disagrees with the {estimate.text()} measured ({distance:.3g} standard errors "
            "apart); the measured gain is used. Check the amplifier's gain setting, or correct "
            "the station file", "gain")
    yield from stubs.annotate(step.run, estimate.attributes(), step="gain")
    session.shaker_gain_n_per_v = estimate.value_n_per_v
    return estimate.value_n_per_v


def _call(group: SweepSegment, levels: np.ndarray | None):
    """The driver call that measures one group (each point started at its level)."""
    first = group.points[0]
    settle, integrate = first.settle_cycles, first.integrate_cycles
    frequencies = [p.frequency_hz for p in group.points]
    starts = None if levels is None else [float(v) for v in levels]

    def call(analyser, progress, poll_interval_s):
        if group.kind == "linear":
            return analyser.measure(group.start_hz, group.stop_hz,
                                    resolution_hz=group.resolution_hz, settle_cycles=settle,
                                    integrate_cycles=integrate,
                                    start_level_vpk=None if starts is None else starts[0],
                                    progress=progress, poll_interval_s=poll_interval_s)
        return analyser.measure_points(frequencies, settle_cycles=settle,
                                       integrate_cycles=integrate, start_levels_vpk=starts,
                                       progress=progress, poll_interval_s=poll_interval_s)

    return call


def join_segments(segments: list[Segment]) -> Segment:
    """Segments measured one after the other, as one (one commit)."""
    if len(segments) == 1:
        return segments[0]

    def joined(name: str):
        values = [getattr(segment, name) for segment in segments]
        if any(value is None for value in values):
            return None
        return np.concatenate([np.asarray(value) for value in values])

    return Segment(**{name: joined(name) for name in (
        "frequency_hz", "time_s", "accelerance_table", "accelerance_support",
        "reference_amplitude", "source_amplitude", "force_amplitude", "flags",
        "variance_table", "variance_support", "settle_cycles", "integrate_cycles")})


def _attributes(campaign: CampaignFile, run: str) -> dict[str, object]:
    return campaign.run_attributes(run)


def relative_text(values: dict[str, float]) -> str:
    """``K_v ± 0.1 %, C_v ± 0.2 %``."""
    return ", ".join(f"{name} ± {100 * value:.3g} %" for name, value in values.items()
                     if math.isfinite(value))
