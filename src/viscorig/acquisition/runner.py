"""The sequence runner: a sequence's plan (:mod:`viscorig.acquisition.plans`) executed by the run
engine (:mod:`viscorig.acquisition.engine`) on one analyser, into one campaign file.

:class:`Runner` is what the command line uses: it builds the session (what is known of the rig),
runs the plan and turns how the engine ended into an outcome with its message and exit status.
A run interrupted by Ctrl-C or an instrument fault keeps every committed segment, is marked
"aborted" in the file, and running the sequence again on the same file continues it from what
the file holds (``viscorig resume``).

Safety: the source limit (from the station's shaker limit and gain) is part of configuring and
precedes the source; before each new run the force it needs is predicted and a run over the
shaker limit is refused or run at a reduced level (:mod:`viscorig.acquisition.prediction`).
"""

from __future__ import annotations

import enum
from collections.abc import Mapping
from dataclasses import dataclass

from viscorig.acquisition.chamber import (
    ChamberedAnalyser,
    ChamberEngine,
    ChamberFaultError,
    ChamberNotSafeError,
)
from viscorig.acquisition.console import Console, single_line
from viscorig.acquisition.engine import Rig, RunEngine, RunRefused
from viscorig.acquisition.forecast import Floor, forecast_sequence
from viscorig.acquisition.plans import sequence_plan
from viscorig.acquisition.protocol import Analyser
from viscorig.acquisition.session import RunnerOptions, RunState, Session, StepRecord
from viscorig.acquisition.sweep import SweepInterrupted, Wiring
from viscorig.errors import InstrumentError
from viscorig.sequences import OVER_LIMIT_CHOICES, Sequence, Station
from viscorig.storage import CampaignFile

__all__ = ["OVER_LIMIT_CHOICES", "Outcome", "RunRefused", "RunResult", "RunState", "Runner",
           "RunnerOptions", "StepRecord"]


class Outcome(enum.Enum):
    """How a sequence ended; ``exit_status`` is what the command line returns."""

    COMPLETE = 0
    REFUSED = 2
    FAULT = 3
    INTERRUPTED = 130

    @property
    def exit_status(self) -> int:
        return self.value


@dataclass(frozen=True)
class RunResult:
    """What :meth:`Runner.run` reports."""

    outcome: Outcome
    message: str
    records: list[StepRecord]


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
        See :class:`~viscorig.acquisition.session.RunnerOptions`.
    floors
        The floor of each adaptive run's rig where known (:mod:`viscorig.acquisition.forecast`),
        for the time left.
    holds, hold_resume, file_lock
        Automatic holds and the lock of the campaign file (:class:`RunEngine`).
    """

    def __init__(
        self,
        campaign: CampaignFile,
        sequence: Sequence,
        station: Station,
        analyser: Analyser,
        console: Console,
        options: RunnerOptions | None = None,
        floors: Mapping[str, Floor | None] | None = None,
        *,
        holds: list | None = None,
        hold_resume: str = "technician",
        file_lock=None,
    ) -> None:
        self.campaign = campaign
        self.analyser = analyser
        self.console = console
        self.options = options or RunnerOptions()
        self.floors = dict(floors or {})
        wiring = Wiring.from_station(station)
        self.session = Session(sequence, station, wiring, self.options, campaign.path,
                               resource=analyser.resource)
        self.session.table = self.session.station_table(campaign.rig)
        if self.options.chamber is None:
            rig = Rig(analyser, wiring, self.options.mount, self.options.real_time_waits,
                      self.options.poll_interval_s)
            self.engine = RunEngine(campaign, rig, console, holds=holds,
                                    hold_resume=hold_resume, file_lock=file_lock)
        else:
            rig = Rig(ChamberedAnalyser(analyser, self.options.chamber), wiring,
                      self.options.mount, self.options.real_time_waits,
                      self.options.poll_interval_s)
            self.engine = ChamberEngine(campaign, rig, console, self.options.chamber,
                                        holds=holds, hold_resume=hold_resume,
                                        file_lock=file_lock)
        self.console.time_label = "test time left" if self.options.time_base == "test" else "left"

    @property
    def records(self) -> list[StepRecord]:
        """One record per step of the sequence reached so far."""
        return self.session.records

    def run(self) -> RunResult:
        """Run every step not yet done; return the outcome (never raises for the operator's
        Ctrl-C or an instrument fault: both are outcomes with a message)."""
        try:
            self.engine.run(sequence_plan(self.session, self._time_after))
        except RunRefused as refused:
            return RunResult(Outcome.REFUSED, str(refused) + self._not_safe(), self.records)
        except (KeyboardInterrupt, SweepInterrupted):
            return RunResult(Outcome.INTERRUPTED, self._interrupted(), self.records)
        except ChamberNotSafeError as error:  # every step done, but the chamber is not safe
            return RunResult(Outcome.FAULT, self._done_not_safe(error), self.records)
        except InstrumentError as error:
            chamber = isinstance(error, ChamberFaultError)
            return RunResult(Outcome.FAULT, self._fault(single_line(str(error)), chamber),
                             self.records)
        except Exception as error:
            kinds = self.options.instrument_errors
            if not (kinds and isinstance(error, kinds)):
                raise
            message = single_line(str(error))
            if self.analyser.resource not in message:
                message = f"{self.analyser.resource}: {message}"
            return RunResult(Outcome.FAULT, self._fault(message), self.records)
        names = ", ".join(self.session.sequence.run_names)
        return RunResult(Outcome.COMPLETE, f"sequence complete: {names}", self.records)

    # -- time left ------------------------------------------------------------------------------
    def _status(self, run: str) -> str | None:
        if run not in self.campaign.run_names:
            return None
        return self.campaign.run_metadata(run).status

    def _time_after(self, index: int) -> float:
        """Test time of the later sweeps, their probes and waits."""
        forecasts = forecast_sequence(
            self.session.sequence, table_known=self.session.table is not None,
            floors=self.floors, force_limit_n=self.session.station.shaker_force_limit_n,
            status=self._status,
        )  # fmt: skip
        return sum(item.expected_s for item in forecasts[index + 1:])

    # -- endings --------------------------------------------------------------------------------
    def _current(self) -> StepRecord | None:
        started = [record for record in self.records if record.state != "skipped"]
        return started[-1] if started else None

    def _where_stopped(self) -> str:
        record = self._current()
        if record is None:
            return ""
        if record.kind == "temperature":
            at = "after" if record.state == "done" else "during"
            return f" {at} the soak at {record.name} (step {record.index + 1})"
        if record.kind != "sweep":
            return f" at step {record.index + 1} ({record.kind.replace('_', ' ')})"
        if self._status(record.name) is None:
            return f" before run '{record.name}' started"
        points = self.campaign.run(record.name).points
        return f" in run '{record.name}' after {points} points (kept)"

    def _resume_hint(self) -> str:
        return f"viscorig resume {self.campaign.path}"

    def _not_safe(self) -> str:
        """The chamber not left at its safe set point, as the end of the line ("" if it was)."""
        error = getattr(self.engine, "not_safe", None)
        return "" if error is None else f"; {single_line(str(error))}"

    def _check(self, chamber: bool) -> str:
        if chamber and self.options.chamber is not None:
            return f"Check the chamber controller at {self.options.chamber.address}"
        return "Check the analyser"

    def _interrupted(self) -> str:
        return (f"interrupted{self._where_stopped()}{self._not_safe()}; data measured so far "
                f"is kept in {self.campaign.path}. Continue with: {self._resume_hint()}")

    def _fault(self, message: str, chamber: bool = False) -> str:
        not_safe = self._not_safe()
        return (f"instrument fault: {message}. Stopped{self._where_stopped()}{not_safe}; "
                f"data measured so far is kept in {self.campaign.path}. "
                f"{self._check(chamber)} and its connection, then continue "
                f"with: {self._resume_hint()}")

    def _done_not_safe(self, error: ChamberNotSafeError) -> str:
        names = ", ".join(self.session.sequence.run_names)
        return (f"instrument fault: {single_line(str(error))}. Every step is done ({names}, "
                f"kept in {self.campaign.path}); check the chamber controller at "
                f"{error.controller} and its connection")
