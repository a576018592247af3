"""The steps of a test sequence: small, typed, validated, composed into a list.

A sequence (:class:`Sequence`) is a list of steps run in order, in the manner of Bluesky
plans: each step does one thing. The runner interprets them; these classes only describe.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

from viscorig.sequences import segments

#: What to do with a sweep whose predicted shaker force exceeds the limit.
OVER_LIMIT_CHOICES = ("refuse", "reduce")


@dataclass(frozen=True)
class PromptStep:
    """Ask the operator to do something (mount specimens, set preload) and wait for Enter.

    ``simulated_rig`` names the simulated rig preset (``sim/rigs/<name>.toml``) that stands
    for the rig after this step; it is ignored on real hardware.
    """

    message: str
    simulated_rig: str | None = None


@dataclass(frozen=True)
class WaitStep:
    """Wait a fixed time (thermal settling after mounting, for example)."""

    seconds: float
    message: str = ""


@dataclass(frozen=True)
class SweepStep:
    """Measure one run: a stepped-sine sweep at constant reference acceleration.

    Frequencies in Hz, level in m/s² peak; ``level`` keeps the text as written. A ``"full"``
    plan measures every frequency of the band at ``resolution_hz`` with the same settle and
    integration; an ``"adaptive"`` plan chooses its points (``model``, ``targets``,
    ``dwell_limit_s``), and ``resolution_hz``, ``settle_cycles``, ``integrate_cycles`` are then
    bounds (``None``: the analyser's own).
    """

    run: str
    specimen: str
    """Free text; ``"none"`` for the bare table."""
    band_hz: tuple[float, float]
    resolution_hz: float | None
    settle_cycles: int | None
    integrate_cycles: int | None
    level_m_per_s2: float
    level: str
    tolerance_db: float
    """Auto-level tolerance around the level (analyser: 0.1-20 dB)."""
    direction: str
    hardness_shore_a: float = math.nan
    preload_strain: float = 0.0
    temperature_c: float = math.nan
    segment_s: float = segments.DEFAULT_SEGMENT_S
    """Longest test time between two commits of the run."""
    segment_points: int = segments.ANALYSER_MAX_POINTS
    """Most points per segment (one analyser sweep; at most 801)."""
    over_limit: str = "refuse"
    """A predicted force above the shaker limit: "refuse" the run or "reduce" its level
    (``viscorig run --over-limit`` overrides it)."""
    plan: str = "full"
    """``"full"`` or ``"adaptive"``."""
    model: str | None = None
    """Model spec an adaptive plan fits."""
    target_uncertainty: tuple[tuple[str, float], ...] = ()
    """Relative standard uncertainty wanted per parameter (adaptive plan), in file order."""
    dwell_limit_s: float | None = None
    """Rig time an adaptive plan may use at most."""

    @property
    def bare_table(self) -> bool:
        """True for a run without damper (specimen "none")."""
        return self.specimen == "none"

    @property
    def adaptive(self) -> bool:
        """The plan chooses the points (``plan = "adaptive"``)."""
        return self.plan == "adaptive"

    @property
    def targets(self) -> dict[str, float]:
        """``target_uncertainty`` as a dict."""
        return dict(self.target_uncertainty)

    def full_plan(self) -> tuple[float, int, int]:
        """``resolution_hz``, ``settle_cycles``, ``integrate_cycles`` of a full plan (all set);
        ``ValueError`` for an adaptive one."""
        if self.adaptive or self.resolution_hz is None or self.settle_cycles is None \
                or self.integrate_cycles is None:
            raise ValueError(f"run {self.run!r}: an adaptive plan has no fixed grid")
        return self.resolution_hz, self.settle_cycles, self.integrate_cycles

    @property
    def points(self) -> int:
        """Number of frequency points of the whole run (a full plan)."""
        return segments.point_count(self.band_hz, self.full_plan()[0])

    def frequencies_hz(self) -> NDArray[np.float64]:
        """Frequencies in measurement order (a full plan)."""
        return segments.sweep_frequencies(self.band_hz, self.full_plan()[0], self.direction)

    def segments(self, overhead_s_per_point: float = 0.0) -> list[slice]:
        """The run's segments as slices of :meth:`frequencies_hz` (a full plan)."""
        _, settle, integrate = self.full_plan()
        return segments.plan_segments(
            self.frequencies_hz(), settle, integrate,
            max_segment_s=self.segment_s, max_points=self.segment_points,
            overhead_s_per_point=overhead_s_per_point,
        )

    def duration_s(self, overhead_s_per_point: float = 0.0) -> float:
        """Test time of the whole run, s (a full plan: an adaptive plan's is a forecast,
        :mod:`viscorig.acquisition.forecast`)."""
        _, settle, integrate = self.full_plan()
        return segments.time_left_s(self.frequencies_hz(), 0, settle, integrate,
                                    overhead_s_per_point)


@dataclass(frozen=True)
class IdentifyTableStep:
    """Identify the table's M_s, K_s, C_s from a bare-table run (optionally in a band)."""

    run: str
    band_hz: tuple[float, float] | None = None


@dataclass(frozen=True)
class TemperatureStep:
    """Bring the specimens to ``set_point_c``: write the set point and its ramp, then wait until
    the specimen thermocouple has stayed within ``± soak_band_k`` for ``soak_minutes``
    (a chamber fault after ``time_limit_minutes``)."""

    set_point_c: float
    ramp_c_per_min: float = 0.0
    soak_band_k: float = 1.0
    soak_minutes: float = 10.0
    time_limit_minutes: float = 240.0
    origin: tuple = field(default=(), compare=False, repr=False)
    """Where the step is written in its file (a repeat's table for the steps it unrolls)."""

    @property
    def soak_s(self) -> float:
        return 60.0 * self.soak_minutes

    @property
    def time_limit_s(self) -> float:
        return 60.0 * self.time_limit_minutes

    def duration_s(self, from_c: float, specimen_time_constant_s: float,
                   heating_rate_k_per_min: float | None = None,
                   cooling_rate_k_per_min: float | None = None) -> float:
        """Predicted time of the step from a specimen at ``from_c``, s.

        The air moves at the slower of the ramp and the chamber's heating or cooling rate
        (``None``: as fast as asked); the specimens follow it with their time constant ``τ``,
        trailing a moving air by ``rate τ``, so after the air arrives they still need
        ``τ ln(min(gap, rate τ) / band)`` to come within the band; then the soak.
        """
        gap = abs(self.set_point_c - from_c)
        rates = [rate for rate in (self.ramp_c_per_min,
                                   heating_rate_k_per_min if self.set_point_c > from_c
                                   else cooling_rate_k_per_min)
                 if rate is not None and rate > 0.0]
        rate_k_per_s = min(rates) / 60.0 if rates else math.inf
        ramp = gap / rate_k_per_s if math.isfinite(rate_k_per_s) else 0.0
        trailing = min(gap, rate_k_per_s * specimen_time_constant_s)
        lag = (specimen_time_constant_s * math.log(trailing / self.soak_band_k)
               if trailing > self.soak_band_k else 0.0)
        return ramp + lag + self.soak_s


Step = PromptStep | WaitStep | SweepStep | IdentifyTableStep | TemperatureStep


@dataclass(frozen=True)
class Sequence:
    """A parsed, validated test sequence."""

    name: str
    description: str
    steps: tuple[Step, ...]
    source: str = ""
    """The file it was read from (for messages)."""

    @property
    def sweeps(self) -> tuple[SweepStep, ...]:
        """The sweep steps, in order."""
        return tuple(step for step in self.steps if isinstance(step, SweepStep))

    @property
    def soaks(self) -> tuple[TemperatureStep, ...]:
        """The temperature steps, in order."""
        return tuple(step for step in self.steps if isinstance(step, TemperatureStep))

    @property
    def run_names(self) -> tuple[str, ...]:
        """Run names, in order."""
        return tuple(step.run for step in self.sweeps)

    def sweep(self, run: str) -> SweepStep:
        """The sweep step of a run."""
        for step in self.sweeps:
            if step.run == run:
                return step
        raise KeyError(run)

    def duration_s(self, overhead_s_per_point: float = 0.0) -> float:
        """Test time of every full sweep and wait (prompts and adaptive plans excluded: their
        time is a forecast, :mod:`viscorig.acquisition.forecast`), s."""
        waits = sum(step.seconds for step in self.steps if isinstance(step, WaitStep))
        return waits + sum(step.duration_s(overhead_s_per_point) for step in self.sweeps
                           if not step.adaptive)
