"""What a session of the runner knows and how it was told to run: options, step records and the
rig as known so far (the table, the specimen measured last, the mounting, the simulated preset).

Plans (:mod:`viscorig.acquisition.plans`) read and update a :class:`Session`; it holds no
instrument and no file, only knowledge.
"""

from __future__ import annotations

import enum
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from viscorig.acquisition.limits import RigEstimate, source_limit_v
from viscorig.acquisition.sweep import SweepSettings, Wiring
from viscorig.sequences import OVER_LIMIT_CHOICES, Sequence, Station, SweepStep
from viscorig.storage import RunSettings

__all__ = ["RunState", "RunnerOptions", "Session", "StepRecord"]


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
    chamber: Any = None
    """The temperature chamber (:class:`viscorig.acquisition.chamber.ChamberMonitor`), if the
    station has one."""

    def __post_init__(self) -> None:
        if self.over_limit not in (None, *OVER_LIMIT_CHOICES):
            raise ValueError(f"over_limit must be None or one of {OVER_LIMIT_CHOICES}")


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


@dataclass
class StepRecord:
    """Metadata of one executed (or skipped) step of a sequence."""

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


@dataclass
class Session:
    """What a run of a sequence knows (module text).

    Attributes
    ----------
    sequence, station, wiring, options
        What is run, on what, how.
    campaign_path
        The campaign file (for messages).
    instrument, resource
        The analyser's identity and resource (recorded with every run).
    table
        The table's suspension as known (station, ``/rig``, an identified bare-table run).
    specimen
        ``(stiffness, damping, disc mass, motion ratio, run)`` of the last specimen measured.
    mounting_known
        A run was measured in this session and no prompt came since (same mounting).
    preset_wanted, preset_mounted
        The simulated rig preset the sequence mounts, and the one mounted.
    records
        One record per step, in order.
    shaker_gain_n_per_v
        The gain measured for the run being measured (:mod:`viscorig.acquisition.gain`).
    """

    sequence: Sequence
    station: Station
    wiring: Wiring
    options: RunnerOptions
    campaign_path: Path
    resource: str = ""
    instrument: str = ""
    table: RigEstimate | None = None
    specimen: tuple[float, float, float, float, str] | None = None
    mounting_known: bool = False
    preset_wanted: str | None = None
    preset_mounted: str | None = None
    records: list[StepRecord] = field(default_factory=list)
    shaker_gain_n_per_v: float | None = None
    """The amplifier-and-shaker gain measured before the adaptive run being measured (its
    start levels use it), N/V; ``None``: the station's."""

    def station_table(self, rig: dict) -> RigEstimate | None:
        """The table the station gives, else the file's ``/rig``."""
        table = self.station.table
        if table is None:
            keys = ("table_mass_kg", "table_stiffness_n_per_m", "table_damping_ns_per_m")
            if all(key in rig for key in keys):
                mass, stiffness, damping = (float(rig[key]) for key in keys)
                return RigEstimate(mass, stiffness, damping, basis="/rig")
            return None
        return RigEstimate(table.mass_kg, table.stiffness_n_per_m, table.damping_ns_per_m,
                           basis="the station's table")

    def set_table(self, values: dict[str, float], basis: str) -> None:
        """The table as identified (``M_s``, ``K_s``, ``C_s``)."""
        self.table = RigEstimate(values["M_s"], values["K_s"], values["C_s"], basis=basis)

    def source_limit_v(self) -> float:
        """The source limit the shaker's limit and gain allow."""
        return source_limit_v(self.station.source_limit_v, self.station.shaker_force_limit_n,
                              self.station.shaker_gain_n_per_v)

    def sweep_settings(self, step: SweepStep, level: float) -> SweepSettings:
        """How ``step`` is measured at ``level``."""
        return SweepSettings(
            step=step, level_m_per_s2=level, force_limit_n=self.station.shaker_force_limit_n,
            source_limit_v=self.source_limit_v(), time_base=self.options.time_base,
            poll_interval_s=self.options.poll_interval_s,
            source_slew_v_per_s=self.station.source_slew_v_per_s,
        )

    def run_settings(self, step: SweepStep, level: float) -> RunSettings:
        """The run's attributes (an adaptive plan's settle and integration are its bounds)."""
        return RunSettings(
            specimen=step.specimen, level_m_per_s2=level, direction=step.direction,
            settle_cycles=step.settle_cycles if step.settle_cycles is not None else 0,
            integrate_cycles=step.integrate_cycles if step.integrate_cycles is not None else 0,
            resolution_hz=step.resolution_hz if step.resolution_hz is not None else 0.0,
            hardness_shore_a=step.hardness_shore_a, preload_strain=step.preload_strain,
            temperature_c=step.temperature_c, instrument=self.instrument,
            resource=self.resource, simulated=self.options.simulated,
        )

    def over_limit_mode(self, step: SweepStep) -> tuple[str, str]:
        """(refuse | reduce, where the choice comes from): the command line wins."""
        if self.options.over_limit is not None:
            return self.options.over_limit, "command line"
        return step.over_limit, "sequence"
