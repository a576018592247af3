"""The sequence runner: the steps of a sequence, one after the other, safely.

In the manner of Bluesky's plans: each step kind is a small function (prompt, wait, sweep,
identify the table) and a sequence is their composition. Each sweep run goes through an
explicit lifecycle, ``idle → configuring → measuring → complete | aborted | failed``, and every
step leaves a :class:`StepRecord` (what, when, outcome). A run interrupted by Ctrl-C or an
instrument fault keeps every committed segment, is marked "aborted" in the file, and
:meth:`Runner.run` continues it from its first missing point when started on the same file.

Safety: the source limit (from the station's shaker limit and gain) is part of configuring
and precedes the source; before each sweep the force it needs is predicted, and a sweep over the
shaker limit is refused or run at a reduced level (the sweep's ``over_limit``, or
``RunnerOptions.over_limit`` when given). The prediction comes from:

- a low-level probe (:mod:`viscorig.acquisition.probe`) whenever the mounting may have changed
  since the last run measured (after a prompt, or at the start of a session): the measured
  dynamic stiffness at the band's edges plus the known table;
- the previous run's specimen when no prompt came between (same mounting);
- the table alone for a bare-table run whose table is known (station, identified run, /rig).

The probe precedes the run's start: it is not in the run's datasets or ``time_s``, and is
recorded in the run's attributes (``probe_*``).
"""

from __future__ import annotations

import contextlib
import enum
import math
import signal
import threading
import time
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field, replace

from viscorig.acquisition.console import Console, single_line
from viscorig.acquisition.limits import (
    DEAD_REFERENCE_DB,
    PROBE_LEVEL_FRACTION,
    UNDRIVEN_FORCE_FRACTION,
    ForceEstimate,
    ProbeReading,
    RigEstimate,
    estimate_force,
    estimate_force_from_probe,
    motion_ratio,
    source_limit_v,
    specimen_from_accelerance,
)
from viscorig.acquisition.probe import measure_probe, probe_frequencies_hz, probe_test_time_s
from viscorig.acquisition.protocol import Analyser
from viscorig.acquisition.sweep import (
    SegmentDone,
    SweepHooks,
    SweepInterrupted,
    SweepMeasurement,
    SweepSettings,
    Wiring,
    configure,
)
from viscorig.errors import InstrumentError
from viscorig.sequences import (
    OVER_LIMIT_CHOICES,
    IdentifyTableStep,
    PromptStep,
    Sequence,
    Station,
    Step,
    SweepStep,
    WaitStep,
)
from viscorig.storage import Campaign, RunSettings

#: The table cannot move this many times more than the disc linked to it through a load cell
#: (about 1.1 times for the paper's hard rubber under preload); a probe that says so misread.
MAX_MOTION_RATIO = 10.0
#: Advice to run at a level this many times below the one asked for is never given: a reading
#: that leads there is a sign of wrong wiring or mounting, and says so instead.
ABSURD_REDUCTION = 1000.0


class RunRefused(Exception):  # noqa: N818 (an outcome, not a fault)
    """A sweep is not measured; the message says why and what to do."""


class RunState(enum.Enum):
    """Lifecycle of one sweep run."""

    IDLE = "idle"
    CONFIGURING = "configuring"
    MEASURING = "measuring"
    COMPLETE = "complete"
    ABORTED = "aborted"
    FAILED = "failed"


_TRANSITIONS = {
    RunState.IDLE: {RunState.CONFIGURING, RunState.COMPLETE, RunState.FAILED,
                    RunState.ABORTED},
    RunState.CONFIGURING: {RunState.MEASURING, RunState.ABORTED, RunState.FAILED},
    RunState.MEASURING: {RunState.COMPLETE, RunState.ABORTED, RunState.FAILED},
    RunState.COMPLETE: set(),
    RunState.ABORTED: set(),
    RunState.FAILED: set(),
}


class Outcome(enum.Enum):
    """How a sequence ended; ``exit_status`` is what the command line returns."""

    COMPLETE = 0
    REFUSED = 2
    FAULT = 3
    INTERRUPTED = 130

    @property
    def exit_status(self) -> int:
        return self.value


@dataclass
class StepRecord:
    """Metadata of one executed (or skipped) step."""

    index: int
    kind: str
    name: str
    state: str = "idle"
    started: float = 0.0
    finished: float = 0.0
    detail: str = ""
    history: list[tuple[str, float]] = field(default_factory=list)

    def move(self, state: RunState | str, detail: str = "") -> None:
        """Change state; a sweep's lifecycle only moves along its allowed transitions."""
        new = state.value if isinstance(state, RunState) else state
        states = {item.value for item in RunState}
        lifecycle = self.kind == "sweep" and self.state in states and new in states
        if lifecycle and RunState(new) not in _TRANSITIONS[RunState(self.state)]:
            raise RuntimeError(f"run {self.name}: {self.state} -> {new} is not allowed")
        self.state = new
        self.history.append((new, time.time()))
        if detail:
            self.detail = detail
        if new in ("complete", "aborted", "failed", "skipped", "done"):
            self.finished = time.time()


@dataclass(frozen=True)
class RunResult:
    """What :meth:`Runner.run` reports."""

    outcome: Outcome
    message: str
    records: list[StepRecord]


class _Stop:
    """Ctrl-C (SIGINT) and SIGTERM while a sequence runs.

    While the analyser measures, the first signal only asks the sweep to stop: the next poll
    aborts the analyser and the segment in flight is dropped, so no partial segment is ever
    written. Elsewhere (a prompt, a wait) it interrupts at once. A second Ctrl-C always does.
    """

    def __init__(self, console: Console) -> None:
        self.console = console
        self.requested = threading.Event()
        self.measuring = [False]

    def __call__(self, signum: int, frame: object) -> None:
        if self.requested.is_set() or not self.measuring[0]:
            self.requested.set()
            raise KeyboardInterrupt
        self.requested.set()
        self.console.say("Stopping: aborting the analyser; committed segments are kept ...")

    @contextlib.contextmanager
    def installed(self) -> Iterator[None]:
        if threading.current_thread() is not threading.main_thread():
            yield
            return
        previous = {sig: signal.signal(sig, self) for sig in (signal.SIGINT, signal.SIGTERM)}
        try:
            yield
        finally:
            for sig, handler in previous.items():
                signal.signal(sig, handler)


@dataclass
class RunnerOptions:
    """How a sequence is run."""

    simulated: bool = False
    """The analyser measures a simulated rig (recorded in every run)."""
    time_base: str = "wall"
    """``time_s`` clock: "wall" on a real rig, "test" on a simulated rig faster than real time."""
    real_time_waits: bool = True
    """Wait steps really wait (off for a simulated rig, whose clock is test time)."""
    over_limit: str | None = None
    """A sweep whose predicted force exceeds the shaker limit: "refuse" it or "reduce" its
    level, for every sweep; ``None``: as each sweep step says (its ``over_limit``)."""
    poll_interval_s: float = 0.2
    mount: Callable[[str], None] | None = None
    """Stand-in for the technician on a simulated rig: mounts a rig preset at a prompt."""
    instrument_errors: tuple[type[BaseException], ...] = ()
    """The driver's exception types that mean an instrument fault."""


class Runner:
    """Run (or continue) a sequence on one analyser, recording into one campaign file.

    Parameters
    ----------
    campaign
        The campaign file (mode "a"); it holds the sequence and station texts.
    sequence, station
        The parsed sequence and station (for the embedded simulated rig, the station the
        command line builds for it).
    analyser
        A connected :class:`~viscorig.acquisition.protocol.Analyser`.
    console
        Prompts and progress.
    options
        See :class:`RunnerOptions`.
    """

    def __init__(
        self,
        campaign: Campaign,
        sequence: Sequence,
        station: Station,
        analyser: Analyser,
        console: Console,
        options: RunnerOptions | None = None,
    ) -> None:
        self.campaign = campaign
        self.sequence = sequence
        self.station = station
        self.analyser = analyser
        self.console = console
        self.options = options or RunnerOptions()
        if self.options.over_limit not in (None, *OVER_LIMIT_CHOICES):
            raise ValueError(f"over_limit must be None or one of {OVER_LIMIT_CHOICES}")
        self.wiring = Wiring.from_station(station)
        self.records: list[StepRecord] = []
        self.stop = _Stop(console)
        self._instrument_id: str | None = None
        self._preset_wanted: str | None = None
        self._preset_mounted: str | None = None
        self._table: RigEstimate | None = self._station_table()
        self._specimen: tuple[float, float, float, float, str] | None = None
        self._mounting_known = False
        """A run was measured in this session and no prompt came since (same mounting)."""
        self.console.time_label = "test time left" if self.options.time_base == "test" else "left"

    # -- the whole sequence ------------------------------------------------------------------
    def run(self) -> RunResult:
        """Run every step not yet done; return the outcome (never raises for the operator's
        Ctrl-C or an instrument fault: both are outcomes with a message)."""
        start = self._first_step_to_run()
        current: StepRecord | None = None
        with self.stop.installed():
            try:
                for index, step in enumerate(self.sequence.steps):
                    record = StepRecord(index, _kind(step), _name(step))
                    self.records.append(record)
                    if index < start or self._already_done(step):
                        self._note_skipped(step, record)
                        continue
                    current = record
                    record.started = time.time()
                    self._set_campaign_left(index)
                    refused = self._execute(step, record)
                    if refused is not None:
                        return RunResult(Outcome.REFUSED, refused, self.records)
                    if self.stop.requested.is_set():
                        raise KeyboardInterrupt
            except (KeyboardInterrupt, SweepInterrupted):
                return RunResult(Outcome.INTERRUPTED, self._interrupted(current), self.records)
            except InstrumentError as error:
                return RunResult(Outcome.FAULT, self._fault(current, single_line(str(error))),
                                 self.records)
            except Exception as error:
                if self.options.instrument_errors and isinstance(
                    error, self.options.instrument_errors
                ):
                    message = single_line(str(error))
                    if self.analyser.resource not in message:
                        message = f"{self.analyser.resource}: {message}"
                    return RunResult(Outcome.FAULT, self._fault(current, message), self.records)
                raise
        names = ", ".join(self.sequence.run_names)
        return RunResult(Outcome.COMPLETE, f"sequence complete: {names}", self.records)

    def _execute(self, step: Step, record: StepRecord) -> str | None:
        if isinstance(step, PromptStep):
            self.prompt_step(step, record)
        elif isinstance(step, WaitStep):
            self.wait_step(step, record)
        elif isinstance(step, IdentifyTableStep):
            self.identify_table_step(step, record)
        else:
            return self.sweep_step(step, record)
        return None

    # -- resuming ------------------------------------------------------------------------------
    def _status(self, run: str) -> str | None:
        if run not in self.campaign.run_names:
            return None
        return self.campaign.run(run).metadata.status

    def _first_step_to_run(self) -> int:
        """Index of the first step to execute: after the last complete sweep that precedes the
        first incomplete one (so the prompts that set the rig up for it are shown again)."""
        last_complete = -1
        for index, step in enumerate(self.sequence.steps):
            if isinstance(step, SweepStep):
                if self._status(step.run) != "complete":
                    return last_complete + 1
                last_complete = index
        return last_complete + 1

    def _already_done(self, step: Step) -> bool:
        if isinstance(step, SweepStep):
            return self._status(step.run) == "complete"
        if isinstance(step, IdentifyTableStep):
            return self._status(step.run) == "complete" and any(
                fit.model == "table" for fit in self.campaign.fits(step.run)
            )
        return False

    def _note_skipped(self, step: Step, record: StepRecord) -> None:
        record.move("skipped", "already done")
        if isinstance(step, PromptStep) and step.simulated_rig:
            self._preset_wanted = step.simulated_rig
        if isinstance(step, SweepStep):
            self._learn_from_run(step)
        if isinstance(step, IdentifyTableStep):
            fits = [fit for fit in self.campaign.fits(step.run) if fit.model == "table"]
            if fits:
                values = {name: p.value for name, p in fits[-1].parameters.items()}
                self._set_table(values, f"the stored fit of run '{step.run}'")

    # -- step kinds ----------------------------------------------------------------------------
    def prompt_step(self, step: PromptStep, record: StepRecord) -> None:
        """Ask the operator; on a simulated rig, mount the preset the prompt names."""
        record.move("waiting for the operator")
        self._mounting_known = False  # the operator may change the rig at any prompt
        self.console.prompt(step.message)
        if step.simulated_rig:
            self._preset_wanted = step.simulated_rig
            self._mount_wanted()
        record.move("done")

    def wait_step(self, step: WaitStep, record: StepRecord) -> None:
        """Wait (really on a real rig; a simulated rig's clock is test time)."""
        if not self.options.real_time_waits:
            self.console.say(f"{step.message}: {step.seconds:g} s (simulated rig: not waited)")
            record.move("done", "not waited (simulated)")
            return
        self.console.say(f"{step.message}: {step.seconds:g} s ...")
        record.move("waiting")
        time.sleep(step.seconds)
        record.move("done")

    def identify_table_step(self, step: IdentifyTableStep, record: StepRecord) -> None:
        """Fit M_s, K_s, C_s to the bare-table run and store the fit in the file."""
        from viscorig.identify import identify_run, store_fit  # scipy: only when needed

        record.move("fitting")
        result, _ = identify_run(self.campaign, step.run, "table", band_hz=step.band_hz)
        fit_id = store_fit(self.campaign, step.run, result)
        values = dict(result.values)
        self._set_table(values, f"the fit of run '{step.run}'")
        self.console.say(
            f"table identified from run '{step.run}' (fit {fit_id}): "
            f"M_s {values['M_s']:.4g} kg, K_s {values['K_s']:.6g} N/m, "
            f"C_s {values['C_s']:.4g} N s/m; rms error {result.rms_error:.2e}"
        )
        record.move("done", f"fit {fit_id}")

    def sweep_step(self, step: SweepStep, record: StepRecord) -> str | None:
        """Measure (or continue) one run. Returns a refusal message, or ``None``."""
        self._mount_wanted()
        existing = self._status(step.run)
        limit = self.station.shaker_force_limit_n
        if existing is None:
            level = step.level_m_per_s2
            try:
                estimate = self._predict(step, level)
                if estimate is not None and estimate.peak_n > limit:
                    level = self._over_limit(step, estimate)
            except RunRefused as refused:
                record.move(RunState.FAILED, str(refused))
                return str(refused)
            self.campaign.start_run(step.run, self._settings(step, level))
            self._annotate(step, level, estimate)
            done = 0
        else:
            level = self.campaign.run(step.run).metadata.level_m_per_s2
            done = self.campaign.resume_run(step.run)
            self.console.say(
                f"continuing run '{step.run}' from point {done + 1} of {step.points}"
                + (f" ({step.frequencies_hz()[done]:g} Hz)" if done < step.points else "")
            )
        settings = self._sweep_settings(step, level)
        flags = int((self.campaign.run(step.run).flags != 0).sum()) if done else 0
        self.console.start_run(step.run, done, step.points, flags)
        self.console.say(
            f"run '{step.run}': {step.points} points {step.band_hz[0]:g}-{step.band_hz[1]:g} Hz, "
            f"level {level:.4g} m/s^2, source limit {settings.source_limit_v:.3g} V, "
            f"shaker limit {limit:g} N"
        )
        try:
            if done < step.points:
                record.move(RunState.CONFIGURING)
                configure(self.analyser, self.wiring, settings)
                record.move(RunState.MEASURING)
                hooks = SweepHooks(
                    should_stop=self.stop.requested.is_set,
                    on_poll=self.console.poll,
                    on_segment=self._on_segment,
                    measuring=self.stop.measuring,
                )
                SweepMeasurement(self.campaign, self.analyser, self.wiring, settings,
                                 hooks).run()
        except BaseException as error:
            interrupted = isinstance(error, KeyboardInterrupt | SweepInterrupted)
            record.move(RunState.ABORTED, "interrupted" if interrupted else str(error))
            self.campaign.finish_run(step.run, "aborted")
            raise
        self.campaign.finish_run(step.run, "complete")
        self._mounting_known = True
        record.move(RunState.COMPLETE)
        run = self.campaign.run(step.run)
        flagged = int((run.flags != 0).sum())
        self.console.say(f"run '{step.run}' complete: {run.points} points, {flagged} flagged")
        self._learn_from_run(step)
        return None

    # -- helpers of the sweep step ---------------------------------------------------------
    def _on_segment(self, done: SegmentDone) -> None:
        self.console.segment(done)

    def _sweep_settings(self, step: SweepStep, level: float) -> SweepSettings:
        return SweepSettings(
            step=step, level_m_per_s2=level, force_limit_n=self.station.shaker_force_limit_n,
            source_limit_v=self._source_limit_v(), time_base=self.options.time_base,
            poll_interval_s=self.options.poll_interval_s,
        )

    def _source_limit_v(self) -> float:
        return source_limit_v(self.station.source_limit_v, self.station.shaker_force_limit_n,
                              self.station.shaker_gain_n_per_v)

    def _identity(self) -> str:
        if self._instrument_id is None:
            self._instrument_id = self.analyser.identify()
        return self._instrument_id

    def _settings(self, step: SweepStep, level: float) -> RunSettings:
        return RunSettings(
            specimen=step.specimen, level_m_per_s2=level, direction=step.direction,
            settle_cycles=step.settle_cycles, integrate_cycles=step.integrate_cycles,
            resolution_hz=step.resolution_hz, hardness_shore_a=step.hardness_shore_a,
            preload_strain=step.preload_strain, temperature_c=step.temperature_c,
            instrument=self._identity(), resource=self.analyser.resource,
            simulated=self.options.simulated,
        )

    def _annotate(self, step: SweepStep, level: float, estimate: ForceEstimate | None) -> None:
        attributes: dict[str, str | float | bool] = {
            "requested_level_m_per_s2": step.level_m_per_s2,
            "requested_level": step.level,
            "tolerance_db": step.tolerance_db,
            "shaker_force_limit_n": self.station.shaker_force_limit_n,
            "source_limit_v": self._source_limit_v(),
            "estimated_peak_force_n": math.nan if estimate is None else estimate.peak_n,
            "estimated_peak_frequency_hz": (math.nan if estimate is None
                                            else estimate.peak_frequency_hz),
            "estimated_peak_force_at_run_level_n": (
                math.nan if estimate is None
                else estimate.peak_n * level / step.level_m_per_s2),
            "force_estimate_basis": "" if estimate is None else estimate.basis,
            "over_limit": self._over_limit_mode(step)[0],
            "over_limit_from": self._over_limit_mode(step)[1],
            "segment_s": step.segment_s,
        }
        if estimate is not None and estimate.probes:
            attributes.update(_probe_attributes(estimate))
        self.campaign.annotate(step.run, attributes)
        self.campaign.annotate(step.run, {
            "note": "the 35670A does not report its source level per point in swept sine; NaN",
        }, dataset="source_amplitude")
        clock = ("accumulated settle and integration time (simulated rig, faster than real time)"
                 if self.options.time_base == "test" else "wall-clock time since the run started")
        self.campaign.annotate(step.run, {"time_base": self.options.time_base, "note": clock},
                               dataset="time_s")

    def _over_limit_mode(self, step: SweepStep) -> tuple[str, str]:
        """(refuse | reduce, where the choice comes from): the command line wins."""
        if self.options.over_limit is not None:
            return self.options.over_limit, "command line"
        return step.over_limit, "sequence"

    def _over_limit(self, step: SweepStep, estimate: ForceEstimate) -> float:
        """The level to run at when the estimate exceeds the shaker limit.

        Raises
        ------
        RunRefused
            The sweep refuses (``over_limit``), or the level that would fit is absurdly low.
        """
        limit = self.station.shaker_force_limit_n
        reduced = estimate.level_for(limit, step.level_m_per_s2)
        what = (f"run '{step.run}': estimated force {estimate.peak_n:.3g} N at "
                f"{estimate.peak_frequency_hz:g} Hz exceeds the shaker limit {limit:g} N "
                f"(level {step.level}; estimate from {estimate.basis})")
        self.console.warn(what)
        if reduced * ABSURD_REDUCTION < step.level_m_per_s2:
            raise RunRefused(
                f"{what}; not measured. Holding it under the limit would need "
                f"{reduced:.2g} m/s^2, over {ABSURD_REDUCTION:g} times below the level asked "
                "for: no specimen is that stiff, so the estimate rests on readings that cannot "
                "be right. The wiring or the mounting is wrong: check that the device is "
                "mounted and each transducer is on the input the station file names")
        mode, source = self._over_limit_mode(step)
        chosen = "--over-limit" if source == "command line" else "over_limit in the sequence"
        if mode == "reduce":
            self.console.warn(f"run '{step.run}': level reduced to {reduced:.4g} m/s^2 "
                              f"(requested {step.level}; {chosen} is \"reduce\")")
            return reduced
        raise RunRefused(
            f"{what}; not measured ({chosen} is \"refuse\"). Lower the level, set "
            f"over_limit = \"reduce\" in the sequence, or continue with: viscorig resume "
            f"{self.campaign.path} --over-limit reduce (level {reduced:.3g} m/s^2)"
        )

    # -- what is known of the rig ----------------------------------------------------------
    def _station_table(self) -> RigEstimate | None:
        table = self.station.table
        if table is None:
            rig = self.campaign.rig
            keys = ("table_mass_kg", "table_stiffness_n_per_m", "table_damping_ns_per_m")
            if all(key in rig for key in keys):
                return RigEstimate(*(float(rig[key]) for key in keys), basis="/rig")
            return None
        return RigEstimate(table.mass_kg, table.stiffness_n_per_m, table.damping_ns_per_m,
                           basis="the station's table")

    def _set_table(self, values: dict[str, float], basis: str) -> None:
        self._table = RigEstimate(values["M_s"], values["K_s"], values["C_s"], basis=basis)

    def _learn_from_run(self, step: SweepStep) -> None:
        """Keep a rough specimen stiffness from a finished specimen run."""
        if step.bare_table or self._table is None or self._status(step.run) is None:
            return
        run = self.campaign.run(step.run)
        keep = run.flags == 0
        found = specimen_from_accelerance(run.frequency_hz[keep], run.accelerance_table[keep],
                                          self._table)
        if found is not None:
            ratio = motion_ratio(run.accelerance_table[keep], run.force_amplitude[keep],
                                 run.reference_amplitude[keep])
            self._specimen = (*found, ratio, step.run)

    def _predict(self, step: SweepStep, level: float) -> ForceEstimate | None:
        """The force a new run will need: probed on a newly mounted rig, else from what is
        known (see the module's docstring); printed with where it comes from."""
        known_table = step.bare_table and self._table is not None
        same_mounting = (not step.bare_table and self._mounting_known
                         and self._specimen is not None)
        if known_table or same_mounting:
            return self._estimate(step, level)
        estimate = self._probe(step, level)
        if estimate is None:
            return self._estimate(step, level, "the probe gave no usable reading; ")
        self._say_estimate(step, estimate)
        return estimate

    def _probe(self, step: SweepStep, level: float) -> ForceEstimate | None:
        """Measure the probe points of a newly mounted rig and predict from them."""
        frequencies = " and ".join(f"{f:g}" for f in probe_frequencies_hz(step))
        probe_level = level * PROBE_LEVEL_FRACTION
        self.console.say(
            f"run '{step.run}': newly mounted; probing at {frequencies} Hz at "
            f"{probe_level:.3g} m/s^2 (a tenth of the level; {probe_test_time_s(step):.0f} s "
            "of test time, not part of the run)"
        )
        hooks = SweepHooks(should_stop=self.stop.requested.is_set, measuring=self.stop.measuring)
        readings = measure_probe(self.analyser, self.wiring, self._sweep_settings(step, level),
                                 hooks)
        for reading in readings:
            stiffness = complex(reading.dynamic_stiffness_n_per_m)
            self.console.say(
                f"  probe {reading.frequency_hz:g} Hz: |F_e/X_s| {abs(stiffness):.4g} N/m, "
                f"force {reading.force_n:.3g} N at {reading.reference_m_per_s2:.3g} m/s^2"
                + ("" if reading.usable else "  (not usable)")
            )
        self._check_probe(step, readings)
        if not readings[0].usable:
            return None
        table = ("the table unknown" if self._table is None
                 else f"the table of {self._table.basis}")
        basis = f"a probe of the mounted rig at {frequencies} Hz and {table}"
        return estimate_force_from_probe(step.frequencies_hz(), level, readings, self._table,
                                         basis)

    def _check_probe(self, step: SweepStep, readings: tuple[ProbeReading, ...]) -> None:
        """Refuse a run whose probe shows that the reference does not see the rig it drives:
        a reference :data:`DEAD_REFERENCE_DB` or more below the level asked for, or a table
        moving more than :data:`MAX_MOTION_RATIO` times the disc linked to it.

        Raises
        ------
        RunRefused
            With what was read and what to check.
        """
        def dead(reading: ProbeReading) -> bool:
            ratio = reading.motion_ratio
            return reading.shortfall_db >= DEAD_REFERENCE_DB or (
                not step.bare_table and math.isfinite(ratio) and ratio > MAX_MOTION_RATIO)

        reading = next((r for r in readings if dead(r)), None)
        if reading is None:
            return
        if step.bare_table:
            name, channel = "table", self.wiring.table_acceleration
        else:
            name, channel = "disc", self.wiring.device_acceleration
        sensitivity = self.wiring.sensitivities_v_per_eu[channel]
        read = (f"run '{step.run}': the probe at {reading.frequency_hz:g} Hz asked "
                f"{reading.level_m_per_s2:.3g} m/s^2 of the {name} accelerometer (input "
                f"{channel}) and read {reading.reference_m_per_s2:.2g} m/s^2 "
                f"({reading.shortfall_db:.0f} dB short) while the shaker gave "
                f"{reading.force_n:.3g} N")
        check = (f"the {name} accelerometer is on input {channel} with the sensitivity the "
                 f"station file gives ({sensitivity:g} V/(m/s^2))")
        if not reading.force_n >= UNDRIVEN_FORCE_FRACTION * self.station.shaker_force_limit_n:
            why = ("the shaker is hardly driven. Check the amplifier (on, gain), the cable from "
                   f"the analyser's source, and that {check}")
        elif step.bare_table:
            why = f"the table accelerometer does not see the motion. Check that {check}"
        else:
            why = (f" and the table {reading.table_acceleration_m_per_s2:.3g} m/s^2: the disc "
                   f"cannot move {reading.motion_ratio:.3g} times less than the table it is "
                   "linked to. The wiring or the mounting is wrong: check that the damper device "
                   f"is mounted and linked to the table, and that {check}")
        separator = "" if why.startswith(" ") else ": "
        raise RunRefused(f"{read}{separator}{why}. Nothing was measured")

    def _say_estimate(self, step: SweepStep, estimate: ForceEstimate) -> None:
        self.console.say(
            f"run '{step.run}': estimated force up to {estimate.peak_n:.3g} N at "
            f"{estimate.peak_frequency_hz:g} Hz (shaker limit "
            f"{self.station.shaker_force_limit_n:g} N; from {estimate.basis})"
        )

    def _estimate(self, step: SweepStep, level: float, why: str = "") -> ForceEstimate | None:
        if self._table is None:
            self.console.warn(f"run '{step.run}': {why}table parameters unknown (no [table] in "
                              "the station, no identified table run): no force estimate")
            return None
        rig = self._table
        if not step.bare_table:
            if self._specimen is None:
                rig = replace(rig, basis=f"{why}{rig.basis} only; specimen unknown, a lower "
                              "bound")
            else:
                stiffness, damping, mass, ratio, source = self._specimen
                same = ("" if why else " (same mounting)")
                rig = replace(rig, specimen_stiffness_n_per_m=stiffness,
                              specimen_damping_ns_per_m=damping, specimen_mass_kg=mass,
                              motion_ratio=ratio,
                              basis=f"{why}{rig.basis} and the specimen of run "
                              f"'{source}'{same}")
        else:
            rig = replace(rig, basis=f"{why}{rig.basis}")
        estimate = estimate_force(step.frequencies_hz(), level, rig)
        self._say_estimate(step, estimate)
        return estimate

    def _mount_wanted(self) -> None:
        wanted = self._preset_wanted
        if self.options.mount is None or wanted is None or wanted == self._preset_mounted:
            return
        self.options.mount(wanted)
        self._preset_mounted = wanted
        self.console.say(f"(simulated rig: {wanted} mounted)")

    def _set_campaign_left(self, index: int) -> None:
        """Test time of the later sweeps, their probes and waits."""
        later = range(index + 1, len(self.sequence.steps))
        steps = self.sequence.steps
        self.console.campaign_left_s = sum(
            steps[i].duration_s() if isinstance(steps[i], SweepStep) else steps[i].seconds
            for i in later if isinstance(steps[i], SweepStep | WaitStep)
        ) + sum(probe_test_time_s(steps[i]) for i in later if self._probe_expected(i))

    def _probe_expected(self, index: int) -> bool:
        """Will the sweep at ``index`` be probed (for the time left; decided when it comes)?"""
        step = self.sequence.steps[index]
        if not isinstance(step, SweepStep) or self._status(step.run) is not None:
            return False
        if step.bare_table and (self._table is not None or any(
                isinstance(s, IdentifyTableStep) for s in self.sequence.steps[:index])):
            return False
        for before in reversed(self.sequence.steps[:index]):
            if isinstance(before, PromptStep):
                return True
            if isinstance(before, SweepStep):
                return False
        return True

    # -- endings -------------------------------------------------------------------------------
    def _resume_hint(self) -> str:
        return f"viscorig resume {self.campaign.path}"

    def _where_stopped(self, record: StepRecord | None) -> str:
        if record is None or record.kind != "sweep":
            return ""
        if self._status(record.name) is None:
            return f" before run '{record.name}' started"
        points = self.campaign.run(record.name).points
        return f" in run '{record.name}' after {points} points (kept)"

    def _interrupted(self, record: StepRecord | None) -> str:
        return (f"interrupted{self._where_stopped(record)}; data measured so far is kept in "
                f"{self.campaign.path}. Continue with: {self._resume_hint()}")

    def _fault(self, record: StepRecord | None, message: str) -> str:
        return (f"instrument fault: {message}. Stopped{self._where_stopped(record)}; data "
                f"measured so far is kept in {self.campaign.path}. Check the analyser and its "
                f"connection, then continue with: {self._resume_hint()}")


def _kind(step: Step) -> str:
    return {PromptStep: "prompt", WaitStep: "wait", SweepStep: "sweep",
            IdentifyTableStep: "identify_table"}[type(step)]


def _name(step: Step) -> str:
    if isinstance(step, SweepStep | IdentifyTableStep):
        return step.run
    if isinstance(step, PromptStep):
        return step.message[:40]
    return f"{step.seconds:g} s"


def _probe_attributes(estimate: ForceEstimate) -> dict[str, str | float | int]:
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
