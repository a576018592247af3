"""Plans: a sequence as a composition of small steps (in the manner of Bluesky's ``plans``).

::

    sequence ─┬─ prompt            say, prompt, mount (simulated rig)
              ├─ wait              sleep
              ├─ identify_table    fit the bare-table run, store the fit
              └─ sweep ──── prediction (probe) ── open or resume the run ─┬─ full sweep
                                                                          └─ adaptive sweep
    full sweep:     configure ─ (measure segment ─ commit ─ checkpoint)* ─ close
                    (a pause ends a segment at a point: the rest is planned again after it)
    adaptive sweep: see :mod:`viscorig.acquisition.adaptive`

Each plan yields :class:`~viscorig.acquisition.engine.Msg` objects through the small steps of
:mod:`~viscorig.acquisition.stubs` and leaves a :class:`~viscorig.acquisition.session.StepRecord`
(what, when, how it ended); a sweep's record moves through ``idle → configuring → measuring →
complete | aborted | failed``. Continuing a stopped sequence is running it again on the same
file: a complete run is skipped, an interrupted one continues from what the file holds.
"""

from __future__ import annotations

import functools
import io
import time
from collections.abc import Callable

import numpy as np

from viscorig.acquisition import stubs
from viscorig.acquisition.chamber import temperature_step
from viscorig.acquisition.console import Console
from viscorig.acquisition.engine import MeasureRequest, Msg, Plan, Rig, RunEngine, RunRefused
from viscorig.acquisition.limits import ForceEstimate
from viscorig.acquisition.prediction import learn_from_run, level_for
from viscorig.acquisition.session import RunState, Session, StepRecord
from viscorig.acquisition.sweep import (
    SegmentDone,
    SweepHooks,
    SweepSettings,
    Wiring,
    check_piece,
    iso_to_epoch,
    point_times_s,
    segment_of,
)
from viscorig.sequences import (
    IdentifyTableStep,
    PromptStep,
    Step,
    SweepStep,
    TemperatureStep,
    WaitStep,
    plan_segments,
    point_durations_s,
    resume_index,
    time_left_s,
)
from viscorig.storage import CampaignFile

__all__ = ["SweepMeasurement", "full_sweep", "sequence_plan", "step_kind", "step_name"]


def step_kind(step: Step) -> str:
    """``prompt``, ``wait``, ``sweep`` or ``identify_table``."""
    return {PromptStep: "prompt", WaitStep: "wait", SweepStep: "sweep",
            IdentifyTableStep: "identify_table", TemperatureStep: "temperature"}[type(step)]


def step_name(step: Step) -> str:
    """What a record calls the step: its run, or the start of its message."""
    if isinstance(step, SweepStep | IdentifyTableStep):
        return step.run
    if isinstance(step, PromptStep):
        return step.message[:40]
    if isinstance(step, TemperatureStep):
        return f"{step.set_point_c:g} °C"
    return f"{step.seconds:g} s"


# -- the whole sequence ------------------------------------------------------------------------

def sequence_plan(session: Session, forecast: Callable[[int], float] | None = None) -> Plan:
    """Every step not yet done, in order; steps already done are skipped (and learnt from).

    ``forecast(index)`` gives the test time of the steps after ``index`` (for the progress
    line's time left).

    Raises
    ------
    RunRefused
        A sweep refused to measure (its record says why).
    """
    start = yield from _first_step_to_run(session)
    for index, step in enumerate(session.sequence.steps):
        record = StepRecord(index, step_kind(step), step_name(step))
        session.records.append(record)
        if index < start or (yield from _already_done(step)):
            yield from _skipped(session, step, record)
            continue
        record.started = time.time()
        if forecast is not None:
            yield Msg("progress", ("campaign_left", forecast(index)), step="sequence")
        if isinstance(step, PromptStep):
            yield from prompt_step(session, step, record)
        elif isinstance(step, WaitStep):
            yield from wait_step(step, record)
        elif isinstance(step, IdentifyTableStep):
            yield from identify_table_step(session, step, record)
        elif isinstance(step, TemperatureStep):
            yield from temperature_step(session, step, record)
        else:
            yield from sweep_step(session, step, record)
        yield from stubs.checkpoint("sequence")


def _first_step_to_run(session: Session) -> Plan:
    """Index of the first step to execute: after the last complete sweep that precedes the
    first incomplete one (so the prompts that set the rig up for it are shown again)."""
    last_complete = -1
    for index, step in enumerate(session.sequence.steps):
        if isinstance(step, SweepStep):
            if (yield from stubs.status(step.run, "resume")) != "complete":
                return last_complete + 1
            last_complete = index
    return last_complete + 1


def _already_done(step: Step) -> Plan:
    if isinstance(step, SweepStep):
        return (yield from stubs.status(step.run, "resume")) == "complete"
    if isinstance(step, IdentifyTableStep):
        if (yield from stubs.status(step.run, "resume")) != "complete":
            return False
        fits = yield Msg("fits", (step.run,), step="resume")
        return any(fit.model == "table" for fit in fits)
    return False


def _skipped(session: Session, step: Step, record: StepRecord) -> Plan:
    record.move("skipped", "already done")
    if isinstance(step, PromptStep) and step.simulated_rig:
        session.preset_wanted = step.simulated_rig
    if isinstance(step, SweepStep):
        yield from learn_from_run(session, step)
    if isinstance(step, IdentifyTableStep):
        fits = [fit for fit in (yield Msg("fits", (step.run,), step="resume"))
                if fit.model == "table"]
        if fits:
            values = {name: p.value for name, p in fits[-1].parameters.items()}
            session.set_table(values, f"the stored fit of run '{step.run}'")


# -- prompt, wait, identify the table ----------------------------------------------------------

def prompt_step(session: Session, step: PromptStep, record: StepRecord) -> Plan:
    """Ask the operator; on a simulated rig, mount the preset the prompt names."""
    record.move("waiting for the operator")
    session.mounting_known = False  # the operator may change the rig at any prompt
    yield from stubs.prompt(step.message, "prompt")
    if step.simulated_rig:
        session.preset_wanted = step.simulated_rig
        yield from mount_wanted(session)
    record.move("done")


def mount_wanted(session: Session) -> Plan:
    """Mount the preset the sequence wants, if it is not mounted (simulated rig only)."""
    wanted = session.preset_wanted
    if session.options.mount is None or wanted is None or wanted == session.preset_mounted:
        return
    yield from stubs.mount(wanted, "mount")
    session.preset_mounted = wanted


def wait_step(step: WaitStep, record: StepRecord) -> Plan:
    """Wait (really on a real rig; a simulated rig's clock is test time)."""
    record.move("waiting")
    waited = yield from stubs.wait(step.seconds, step.message, "wait")
    record.move("done", "" if waited else "not waited (simulated)")


def identify_table_step(session: Session, step: IdentifyTableStep, record: StepRecord) -> Plan:
    """Fit M_s, K_s, C_s to the bare-table run and store the fit in the file."""
    record.move("fitting")
    result = yield from stubs.compute(_table_fit, step.run, step.band_hz, step="identify_table")
    fit_id = yield Msg("store_fit", (step.run, result), step="identify_table")
    values = dict(result.values)
    session.set_table(values, f"the fit of run '{step.run}'")
    yield from stubs.say(
        f"table identified from run '{step.run}' (fit {fit_id}): "
        f"M_s {values['M_s']:.4g} kg, K_s {values['K_s']:.6g} N/m, "
        f"C_s {values['C_s']:.4g} N s/m; rms error {result.rms_error:.2e}", "identify_table")
    record.move("done", f"fit {fit_id}")


def _table_fit(campaign: CampaignFile, run: str, band_hz: tuple[float, float] | None):
    # keeps the command's start fast: scipy loads only when needed
    from viscorig.identify import identify_run

    result, _ = identify_run(campaign, run, "table", band_hz=band_hz)
    return result


# -- a sweep --------------------------------------------------------------------------------------

def sweep_step(session: Session, step: SweepStep, record: StepRecord) -> Plan:
    """Measure (or continue) one run: predict its force and level (a new run), open or resume
    it, measure it (a full or an adaptive plan), close it.

    Raises
    ------
    RunRefused
        The run is not measured (the record moves to "failed").
    """
    yield from mount_wanted(session)
    if not session.instrument:
        session.instrument = yield Msg("identify", step="sweep")
    existing = yield from stubs.status(step.run, "sweep")
    if existing is None:
        try:
            level, estimate = yield from level_for(session, step)
            if step.adaptive:
                # keeps the command's start fast: scipy loads only when needed
                from viscorig.acquisition.adaptive import check_adaptive

                yield from check_adaptive(session, step)
        except RunRefused as refused:
            record.move(RunState.FAILED, str(refused))
            raise
        yield from _open(session, step, level, estimate)
        done = 0
    else:
        run = yield from stubs.read_run(step.run, "sweep")
        level = run.metadata.level_m_per_s2
        done = yield from stubs.resume_run(step.run, "sweep")
        if not step.adaptive:
            grid = step.frequencies_hz()
            yield from stubs.say(
                f"continuing run '{step.run}' from point {done + 1} of {step.points}"
                + (f" ({grid[done]:g} Hz)" if done < step.points else ""), "sweep")
    try:
        if step.adaptive:
            # keeps the command's start fast: scipy loads only when needed
            from viscorig.acquisition.adaptive import adaptive_sweep

            yield from adaptive_sweep(session, step, record, level)
        else:
            yield from full_sweep(session, step, record, level, done)
    except GeneratorExit:
        raise
    except BaseException as error:
        interrupted = isinstance(error, KeyboardInterrupt) or type(error).__name__ == (
            "SweepInterrupted")
        record.move(RunState.ABORTED, "interrupted" if interrupted else str(error))
        yield from stubs.close_run(step.run, "aborted", "sweep")
        raise
    yield from stubs.close_run(step.run, "complete", "sweep")
    session.mounting_known = True
    record.move(RunState.COMPLETE)
    run = yield from stubs.read_run(step.run, "sweep")
    flagged = int((run.flags != 0).sum())
    if not step.adaptive:
        yield from stubs.say(f"run '{step.run}' complete: {run.points} points, {flagged} "
                             "flagged", "sweep")
    yield from learn_from_run(session, step)


def _open(session: Session, step: SweepStep, level: float,
          estimate: ForceEstimate | None) -> Plan:
    """Create the run with its settings and the conditions it runs under."""
    settings = session.run_settings(step, level)
    if step.adaptive:
        # keeps the command's start fast: scipy loads only when needed
        from viscorig.acquisition.adaptive import adaptive_run_settings

        settings = adaptive_run_settings(settings, step)
    yield from stubs.open_run(step.run, settings, "sweep")
    mode, source = session.over_limit_mode(step)
    attributes: dict[str, str | float | bool] = {
        "requested_level_m_per_s2": step.level_m_per_s2,
        "requested_level": step.level,
        "tolerance_db": step.tolerance_db,
        "shaker_force_limit_n": session.station.shaker_force_limit_n,
        "source_limit_v": session.source_limit_v(),
        "estimated_peak_force_n": np.nan if estimate is None else estimate.peak_n,
        "estimated_peak_frequency_hz": (np.nan if estimate is None
                                        else estimate.peak_frequency_hz),
        "estimated_peak_force_at_run_level_n": (
            np.nan if estimate is None else estimate.peak_n * level / step.level_m_per_s2),
        "force_estimate_basis": "" if estimate is None else estimate.basis,
        "over_limit": mode,
        "over_limit_from": source,
        "segment_s": step.segment_s,
        "test_time_s": 0.0,
        "plan": step.plan,
    }
    if estimate is not None and estimate.probes:
        attributes.update(probe_attributes(estimate))
    yield from stubs.annotate(step.run, attributes, step="sweep")
    yield from stubs.annotate(step.run, {
        "note": "the 35670A does not report its source level per point in swept sine; NaN",
    }, "source_amplitude", step="sweep")
    if step.adaptive:
        clock = ("running sum of each point's rig time: settle and integration on the "
                 "simulated rig's test clock" if session.options.time_base == "test" else
                 "running sum of each point's rig time: its segment's wall-clock time shared "
                 "out in proportion to settle and integration")
    else:
        clock = ("accumulated settle and integration time (simulated rig, faster than real "
                 "time)" if session.options.time_base == "test"
                 else "wall-clock time since the run started")
    yield from stubs.annotate(step.run, {"time_base": session.options.time_base,
                                         "note": clock}, "time_s", step="sweep")


def probe_attributes(estimate: ForceEstimate) -> dict[str, str | float | int]:
    """The probe points of an estimate as run attributes (``probe_<i>_...``, i from 0)."""
    probes = estimate.probes
    attributes: dict[str, str | float | int] = {
        "probe_points": len(probes),
        "probe_level_m_per_s2": probes[0].level_m_per_s2,
        "probe_test_time_s": sum(p.test_time_s for p in probes),
        "probe_note": "measured before the run started, in manual sweep mode at a tenth of its "
                      "level, to predict the shaker force; not part of the run's datasets or "
                      "of time_s",
    }
    for i, probe in enumerate(probes):
        stiffness = complex(probe.dynamic_stiffness_n_per_m)
        attributes.update({
            f"probe_{i}_frequency_hz": probe.frequency_hz,
            f"probe_{i}_dynamic_stiffness_real_n_per_m": stiffness.real,
            f"probe_{i}_dynamic_stiffness_imag_n_per_m": stiffness.imag,
            f"probe_{i}_force_n": probe.force_n,
            f"probe_{i}_reference_m_per_s2": probe.reference_m_per_s2,
            f"probe_{i}_flags": probe.flags,
        })
    return attributes


# -- the full sweep -----------------------------------------------------------------------------

def full_sweep(session: Session, step: SweepStep, record: StepRecord, level: float,
               done: int) -> Plan:
    """Configure the analyser and measure every missing point of a full plan."""
    settings = session.sweep_settings(step, level)
    flags = 0
    if done:
        run = yield from stubs.read_run(step.run, "sweep")
        flags = int((run.flags != 0).sum())
    yield Msg("progress", ("start_run", step.run, done, step.points, flags), step="sweep")
    yield from stubs.say(
        f"run '{step.run}': {step.points} points {step.band_hz[0]:g}-{step.band_hz[1]:g} Hz, "
        f"level {level:.4g} m/s^2, source limit {settings.source_limit_v:.3g} V, "
        f"shaker limit {session.station.shaker_force_limit_n:g} N", "sweep")
    if done >= step.points:
        return
    record.move(RunState.CONFIGURING)
    yield from stubs.configure(settings, "sweep")
    record.move(RunState.MEASURING)
    yield from measure_run(session.wiring, settings, session.resource)


def measure_run(wiring: Wiring, settings: SweepSettings, resource: str) -> Plan:
    """Measure every missing point of a full plan's run, segment by segment (at most about a
    minute of test time and 801 points each, :func:`viscorig.sequences.plan_segments`), each
    committed as soon as it is read; the run continues from its first missing point. Returns
    the run's points.

    Raises
    ------
    InstrumentError
        The analyser returned a segment that does not match the plan.
    """
    step = settings.step
    stored = yield from stubs.read_run(step.run, "measure")
    attributes = yield Msg("compute", (_attributes, step.run), step="measure")
    planned = step.frequencies_hz()
    _, settle_cycles, integrate_cycles = step.full_plan()
    durations = point_durations_s(planned, settle_cycles, integrate_cycles)
    done = resume_index(planned, stored.frequency_hz,
                        where=f"{attributes['path']}: /runs/{step.run}")
    last_time_s = float(stored.time_s[-1]) if stored.points else 0.0
    test_time_s = float(attributes.get("test_time_s", last_time_s))
    run_started = iso_to_epoch(stored.metadata.started)
    number = 0
    while done < planned.size:
        pieces = plan_segments(planned[done:], settle_cycles, integrate_cycles,
                               max_segment_s=step.segment_s, max_points=step.segment_points)
        piece, number = pieces[0], number + 1
        rows = slice(done + piece.start, done + piece.stop)
        frequencies = planned[rows]
        request = MeasureRequest(step.run, resource, frequencies, durations[rows],
                                 _left(step, rows.stop), _linear_call(frequencies),
                                 ends_at_a_point=True)
        measured, remeasured = yield from stubs.measure_segment(
            request, functools.partial(check_piece, frequencies=frequencies, resource=resource),
            "measure")
        count = np.asarray(measured.frequency_hz).size  # fewer when paused at a point
        if count:
            rows = slice(rows.start, rows.start + count)
            rig_time = point_times_s(measured, durations[rows], settings.time_base)
            if settings.time_base == "test" or run_started is None:
                time_s = last_time_s + np.cumsum(durations[rows])
            else:
                share = np.cumsum(durations[rows]) / durations[rows].sum()
                wall = measured.started_at_s + share * (measured.finished_at_s
                                                        - measured.started_at_s)
                time_s = np.maximum(wall - run_started, last_time_s)
            segment = segment_of(measured, wiring, settings, time_s)
            test_time_s += float(rig_time.sum())
            total = yield from stubs.commit(step.run, segment, {"test_time_s": test_time_s},
                                            "measure")
            last_time_s = float(time_s[-1])
            done = rows.stop
            yield Msg("progress", ("segment", SegmentDone(
                run=step.run, number=number, count=number + len(pieces) - 1,
                points_done=total, points_total=planned.size,
                frequency_hz=np.asarray(segment.frequency_hz),
                reference_amplitude=np.asarray(segment.reference_amplitude),
                force_amplitude=np.asarray(segment.force_amplitude),
                flags=np.asarray(segment.flags, dtype=np.uint16), remeasured=remeasured,
                seconds_left=_left(step, total))), step="measure")
        else:  # a pause ended the sweep before its first point: pause here, then go on
            yield from stubs.checkpoint("measure")
    return planned.size


def _attributes(campaign: CampaignFile, run: str) -> dict[str, object]:
    return {**campaign.run_attributes(run), "path": str(campaign.path)}


def _left(step: SweepStep, done: int) -> float:
    return time_left_s(step.frequencies_hz(), done, *step.full_plan()[1:])


def _linear_call(frequencies: np.ndarray):
    """The driver call for a piece of a full plan: one point, or the configured grid."""
    lo, hi = float(frequencies.min()), float(frequencies.max())

    def call(analyser, progress, poll_interval_s):
        if frequencies.size == 1:
            return analyser.measure_point(lo, progress=progress, poll_interval_s=poll_interval_s)
        return analyser.measure(lo, hi, progress=progress, poll_interval_s=poll_interval_s)

    return call


# -- one run's measurement, for callers that hold an analyser ---------------------------------

class SweepMeasurement:
    """Measure (or continue) one full-plan run of a campaign (:func:`measure_run` on an engine
    of its own).

    Parameters
    ----------
    campaign
        The campaign file, open for appending; the run must exist (started or resumed).
    analyser
        Any :class:`~viscorig.acquisition.protocol.Analyser`, already configured for the run
        (:func:`~viscorig.acquisition.sweep.configure`).
    wiring, settings
        Inputs and how the run is measured.
    hooks
        Stop request and progress callbacks.
    """

    def __init__(self, campaign: CampaignFile, analyser, wiring: Wiring, settings: SweepSettings,
                 hooks: SweepHooks | None = None) -> None:
        self.campaign = campaign
        self.analyser = analyser
        self.wiring = wiring
        self.settings = settings
        self.hooks = hooks or SweepHooks()

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
        rig = Rig(self.analyser, self.wiring, poll_interval_s=self.settings.poll_interval_s)
        engine = RunEngine(self.campaign, rig, _HookedConsole(self.hooks))
        engine.stop.asked = self.hooks.should_stop  # type: ignore[method-assign]
        engine.stop.measuring = self.hooks.measuring
        return engine.run(measure_run(self.wiring, self.settings, self.analyser.resource),
                          signals=False)


class _HookedConsole(Console):
    """The progress a plan reports, handed to a sweep's hooks; nothing is printed."""

    def __init__(self, hooks: SweepHooks) -> None:
        super().__init__(yes=True, out=io.StringIO(), interactive=False)
        self.hooks = hooks
        self.campaign_left_s = 0.0

    def say(self, text: str) -> None:
        pass

    warn = say

    def poll(self, frequency_hz: float, run_left_s: float) -> None:
        if self.hooks.on_poll is not None:
            self.hooks.on_poll(frequency_hz, run_left_s)

    def segment(self, done: SegmentDone) -> None:
        if self.hooks.on_segment is not None:
            self.hooks.on_segment(done)

    def start_run(self, run: str, points_done: int, points_total: int, flags: int = 0) -> None:
        pass
