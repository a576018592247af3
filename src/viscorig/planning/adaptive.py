"""The adaptive sweep plan: look, fit, choose the points that teach most per second, repeat.

A small state machine in the manner of a Bluesky plan: explicit states, small steps, each
recorded with its metadata, and no instrument in sight. The plan asks for points through
:class:`NextPoints` and is given :class:`~viscorig.planning.points.MeasuredPoints` back;
:meth:`AdaptivePlan.run` drives it with any *measure* callable (the simulated rig in tests and
benchmarks, the analyser driver in a sequence step), :meth:`AdaptivePlan.steps` exposes it as
a generator for a runner that interleaves storage and display.

States::

    LOOK ──► MEASURE ──► FIT ──► DECIDE ──► MEASURE ──► FIT ──► ... ──► DONE
                                   │
                                   └─ targets met, model misfit, dwell limit ──► DONE

- LOOK: a sparse logarithmic look over the band, on the coverage grid
  (:func:`~viscorig.planning.coverage.log_grid`), settled for a prior damping (the mode is not
  known yet).
- FIT: every point so far is fitted by the project's estimator (:func:`viscorig.fitting.fit`,
  noise-weighted under the core's noise model of the points, as ``identify`` fits the run); the
  planning noise model is fitted to the points' noise (:mod:`~viscorig.planning.noise`), the
  modes are read off the fitted model, the instrument's time per point is calibrated from
  repeats, the information the points hold is computed from their measured noise (and compared
  with the fit's own covariance), and a visit's first long point is checked against its repeats
  for a transient the settle left.
- DECIDE: stop when every target's relative standard error (the fit's own) is met, when the model
  does not fit to the noise (its targets would be the precision of a biased value), or at the dwell
  limit (within :data:`DWELL_MARGIN` of it); otherwise solve the minimum-time design given what is
  known (:func:`~viscorig.planning.design.minimum_time_design`) and measure a batch of it (the
  first batch a fraction, to refit on better estimates before committing the rest), with the band's
  coverage points (:func:`~viscorig.planning.coverage.coverage_grid`) the first time, each
  frequency's integration adjusted for where the auto level will land
  (:func:`~viscorig.planning.batch.landing_db`), settled by the transient model, in one direction,
  with short lead-in points taking the controller's passes.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from enum import StrEnum
from itertools import pairwise

import numpy as np
from numpy.typing import NDArray

from viscorig.errors import InputError
from viscorig.fitting import FitResult, fit
from viscorig.models import parse_spec
from viscorig.planning.batch import (
    allocation_points,
    landing_db,
    merge_neighbours,
    order_points,
    point_context,
    settle_points,
)
from viscorig.planning.coverage import coverage_grid, coverage_ratio, log_grid
from viscorig.planning.design import minimum_time_design
from viscorig.planning.information import InformationModel
from viscorig.planning.instrument import (
    ANALYSER,
    SIMULATED_TIMING,
    AnalyserLimits,
    PointTiming,
)
from viscorig.planning.noise import fit_noise_forecast, point_noise_power, shared_noise
from viscorig.planning.points import MeasuredPoints, MeasureFunction, PlannedPoint
from viscorig.planning.transient import Mode, identified_modes, settle_s

__all__ = [
    "AdaptivePlan",
    "AdaptiveSettings",
    "NextPoints",
    "PlanOutcome",
    "PlanStep",
    "State",
    "expected_time_s",
    "weighted_fit_function",
]


#: A plan stops at its dwell limit once less than this fraction of it is left: a batch that
#: small would be mostly settling (and each one costs a refit).
DWELL_MARGIN = 0.1


class State(StrEnum):
    """States of the adaptive plan."""

    LOOK = "look"
    MEASURE = "measure"
    FIT = "fit"
    DECIDE = "decide"
    DONE = "done"


@dataclass(frozen=True)
class AdaptiveSettings:
    """What an adaptive sweep step asks for.

    Attributes
    ----------
    spec
        Model spec fitted (``"voigt"``).
    targets
        Wanted relative standard error of each named parameter (``{"K_v": 1e-3}``).
    band_hz
        Frequencies the plan may use.
    level_m_per_s2
        Reference acceleration held by the controller (peak).
    fixed
        Parameters held fixed in the fit (the table's ``M_s, K_s, C_s``).
    dwell_limit_s
        Rig time the plan may use at most (``None``: no limit).
    resolution_hz
        Spacing of the candidate frequencies (a multiple of the analyser's step).
    max_settle_cycles, max_integrate_cycles
        Bounds on any point's settle and integration (the sequence step's values).
    force_limit_n
        The shaker's force limit, if known.
    look_points
        Points of the first look.
    look_integrate_cycles, cover_integrate_cycles
        Integration of the first look's points and of the coverage points.
    prior_damping_ratio
        Damping assumed (at the band's lower edge) to settle the first look.
    look_noise
        Relative noise assumed for the first look's settle.
    coverage_damping_ratio, points_per_bandwidth
        Coverage of the band for diagnosis (:mod:`~viscorig.planning.coverage`); ``None``
        damping ratio: no coverage beyond the first look.
    bias_fraction
        A settle keeps the transient's bias below this fraction of the point's noise.
    first_fraction
        Share of the predicted remaining time measured by the first chosen batch.
    aim
        The design aims at ``aim × target`` (a margin for the scatter of the fit's own
        standard error).
    max_batches
        Chosen batches at most.
    max_batch_s
        Rig time of one batch at most (a refit at least that often).
    misfit_limit
        Stop (once the band is covered) when the fit's covariance had to be scaled by more than
        this for the model's misfit (:attr:`~viscorig.fitting.FitResult.misfit_scale`): the
        model is wrong for this specimen, and diagnosis says which one is right.
    timing, limits
        Point timing and analyser limits.
    """

    spec: str
    targets: Mapping[str, float]
    band_hz: tuple[float, float]
    level_m_per_s2: float
    fixed: Mapping[str, float] = field(default_factory=dict)
    dwell_limit_s: float | None = None
    resolution_hz: float = 0.25
    max_settle_cycles: int | None = None
    max_integrate_cycles: int | None = None
    force_limit_n: float | None = None
    look_points: int = 10
    look_integrate_cycles: int = 10
    cover_integrate_cycles: int = 5
    prior_damping_ratio: float = 0.05
    look_noise: float = 5e-4
    coverage_damping_ratio: float | None = 0.02
    points_per_bandwidth: float = 1.0
    bias_fraction: float = 0.3
    first_fraction: float = 0.6
    aim: float = 0.99
    max_batches: int = 12
    max_batch_s: float = 4 * 3600.0
    misfit_limit: float = 4.0
    timing: PointTiming = SIMULATED_TIMING
    limits: AnalyserLimits = ANALYSER

    def __post_init__(self) -> None:
        lo, hi = self.band_hz
        if not (np.isfinite(lo) and np.isfinite(hi) and 0 < lo < hi):
            raise InputError(f"band {lo}:{hi} Hz must have 0 < LO < HI", "adaptive plan")
        if not self.targets:
            raise InputError("needs at least one target uncertainty", "adaptive plan")
        for name, value in self.targets.items():
            if not (np.isfinite(value) and value > 0):
                raise InputError(f"target uncertainty of {name} must be > 0", "adaptive plan")
        if not self.level_m_per_s2 > 0:
            raise InputError("level must be > 0", "adaptive plan")
        model = parse_spec(self.spec)
        if not model.is_open:
            free = set(model.names) - set(self.fixed)
            unknown = sorted(set(self.targets) - free)
            if unknown:
                raise InputError(
                    f"targets {', '.join(unknown)} are not fitted parameters of "
                    f"'{model.spec}' (fitted: {', '.join(sorted(free))})",
                    "adaptive plan",
                )

    @property
    def integrate_cap(self) -> int:
        cap = self.limits.max_integrate_cycles
        return cap if self.max_integrate_cycles is None else min(cap, self.max_integrate_cycles)


@dataclass(frozen=True)
class NextPoints:
    """Points the plan wants measured next, in order, and what it expects them to cost."""

    points: tuple[PlannedPoint, ...]
    state: State
    predicted_s: float


@dataclass(frozen=True)
class PlanStep:
    """One step of the plan, with what it knew then.

    Attributes
    ----------
    state
        The state the step ran in.
    test_time_s
        Rig time used before the step.
    points
        Points measured before the step.
    note
        What happened, in one line.
    relative_stderr
        The targets' relative standard errors (the fit's own) when known.
    predicted_s
        FIT: predicted integration still needed; DECIDE: predicted time of the batch.
    """

    state: State
    test_time_s: float
    points: int
    note: str
    relative_stderr: Mapping[str, float] = field(default_factory=dict)
    predicted_s: float | None = None


@dataclass
class PlanOutcome:
    """How the plan ended.

    Attributes
    ----------
    reason
        ``"targets met"``, ``"model misfit"``, ``"dwell limit"``, ``"batch limit"`` or
        ``"no progress"``.
    points
        Every point measured, in measurement order.
    fit
        The last fit (of every point).
    relative_stderr
        The targets' relative standard errors of that fit.
    history
        Every step.
    """

    reason: str
    points: MeasuredPoints
    fit: FitResult
    relative_stderr: dict[str, float]
    history: list[PlanStep]

    @property
    def targets_met(self) -> bool:
        return self.reason == "targets met"

    @property
    def test_time_s(self) -> float:
        return self.points.test_time_s


#: ``points -> FitResult``: the fit the plan judges its targets by.
FitFunction = Callable[[MeasuredPoints], FitResult]


def weighted_fit_function(spec: str, fixed: Mapping[str, float]) -> FitFunction:
    """The project's fit of ``spec`` (:func:`viscorig.fitting.fit`, weighted by the noise) under
    the core's noise model of the points (:func:`~viscorig.planning.noise.shared_noise`)."""

    def run(points: MeasuredPoints) -> FitResult:
        return fit(spec, points.frf_data(), fixed=dict(fixed), noise=shared_noise(points),
                   weighting="noise")

    return run


def _never_fitted(points: MeasuredPoints) -> FitResult:
    raise AssertionError("the first request of a plan fits nothing")


def expected_time_s(
    settings: AdaptiveSettings, floor_s: float | None = None
) -> tuple[float, float]:
    """The rig time an adaptive step is expected to take, before anything is measured.

    The first look's time is known exactly (its points, cycles and prior settles); the band's
    coverage between ``Σ cycles/f`` (no settle, one pass) and two passes with the first look's
    settles. The chosen points need about the floor of a known rig (``floor_s``: the
    :attr:`~viscorig.planning.bound.DesignBound.plan_time_s` of a similar specimen, or
    ``None`` when nothing is known): between 0.9 and 1.3 times it. The longest is capped at
    the step's dwell limit; without a floor and without a limit it is unbounded.

    Returns
    -------
    (shortest, longest)
        Seconds of rig time.
    """
    plan = AdaptivePlan(settings, fit_function=_never_fitted)
    look = plan.request
    assert look is not None
    low = high = look.predicted_s
    if settings.coverage_damping_ratio is not None:
        f_look = np.array([p.frequency_hz for p in look.points])
        cover = coverage_grid(
            settings.band_hz, f_look, narrowest_damping_ratio=settings.coverage_damping_ratio,
            points_per_bandwidth=settings.points_per_bandwidth, limits=settings.limits,
        )  # fmt: skip
        cycles = min(settings.cover_integrate_cycles, settings.integrate_cap)
        settle = max(p.settle_cycles / p.frequency_hz for p in look.points)
        low += float(np.sum(cycles / cover))
        high += float(np.sum(2.0 * (settle + cycles / cover)))
    if floor_s is not None:
        low, high = low + 0.9 * floor_s, high + 1.3 * floor_s
    else:
        high = np.inf
    if settings.dwell_limit_s is not None:
        low, high = min(low, settings.dwell_limit_s), min(high, settings.dwell_limit_s)
    return float(low), float(high)


class AdaptivePlan:
    """The adaptive plan of one run (module docstring).

    Parameters
    ----------
    settings
        The step's settings.
    fit_function
        ``FrfData -> FitResult``; default: :func:`viscorig.fitting.fit` of ``settings.spec``
        with ``settings.fixed`` held.
    """

    def __init__(self, settings: AdaptiveSettings, fit_function: FitFunction | None = None):
        self.settings = settings
        self.fit_function = fit_function or weighted_fit_function(settings.spec, settings.fixed)
        self.state = State.LOOK
        self.history: list[PlanStep] = []
        self.points: MeasuredPoints | None = None
        self.planned: list[PlannedPoint] = []
        self.result: FitResult | None = None
        self.outcome: PlanOutcome | None = None
        self._timing = settings.timing
        self._info: InformationModel | None = None
        self._modes: list[Mode] = []
        self._calibration: NDArray[np.float64] | None = None
        self._held: NDArray[np.float64] | None = None
        self._covered = False
        self._batches = 0
        self._settle_factor = 1.0
        self._checked = 0
        self._pending: NextPoints | None = self._look()

    # ------------------------------------------------------------------ driving

    @property
    def request(self) -> NextPoints | None:
        """The points the plan waits for (``None`` once it is done)."""
        return self._pending

    def deliver(self, measured: MeasuredPoints) -> None:
        """Hand over the points of :attr:`request`; the plan fits and decides what next."""
        if self._pending is None:
            raise RuntimeError("the plan is not waiting for points")
        if len(measured) != len(self._pending.points):
            raise ValueError(
                f"{len(measured)} points delivered for {len(self._pending.points)} requested"
            )
        self.planned += self._pending.points
        self._pending = None
        self.points = measured if self.points is None else self.points.concatenate(measured)
        # the instrument's own time per point, from repeats at one frequency (one controller
        # pass each, nothing to settle): what they took beyond their integration
        p = self.points
        repeat = np.r_[False, p.frequency_hz[1:] == p.frequency_hz[:-1]]
        if np.any(repeat):
            self._timing = self.settings.timing.calibrated(
                p.frequency_hz[repeat], p.settle_cycles[repeat], p.integrate_cycles[repeat],
                p.duration_s[repeat],
            )  # fmt: skip
        self._fit()
        self._pending = self._decide()

    def run(self, measure: MeasureFunction) -> PlanOutcome:
        """Run the plan to its end with ``measure`` (:attr:`request` and :meth:`deliver` in a
        loop, as the acquisition drives it point group by point group)."""
        while self._pending is not None:
            self.deliver(measure(self._pending.points))
        assert self.outcome is not None
        return self.outcome

    # ------------------------------------------------------------------ states

    def _record(self, note: str, predicted_s: float | None = None) -> None:
        points = self.points
        self.history.append(
            PlanStep(
                self.state,
                0.0 if points is None else points.test_time_s,
                0 if points is None else len(points),
                note,
                self._relative_stderr() if self.result is not None else {},
                predicted_s,
            )
        )

    def _look(self) -> NextPoints:
        s = self.settings
        f = log_grid(s.band_hz, s.look_points, s.limits)
        if s.coverage_damping_ratio is not None:  # on the coverage grid: it fills in exactly
            ratio = coverage_ratio(s.coverage_damping_ratio, s.points_per_bandwidth)
            lo, hi = s.band_hz
            full = log_grid(s.band_hz, math.ceil(math.log(hi / lo) / math.log(ratio)) + 1,
                            s.limits)  # fmt: skip
            pick = np.unique(np.round(np.linspace(0, full.size - 1, s.look_points)).astype(int))
            f = full[pick]
        prior = [Mode(s.band_hz[0], s.prior_damping_ratio)]
        cycles = min(s.look_integrate_cycles, s.integrate_cap)
        planned, seconds = [], 0.0
        previous = None
        for frequency in f:
            wait = settle_s(
                frequency, previous, prior, mismatch=1.0, noise_sd=s.look_noise,
                integrate_s=cycles / frequency, bias_fraction=s.bias_fraction,
            )  # fmt: skip
            settle = int(s.limits.settle_cycles(wait * frequency))
            if s.max_settle_cycles is not None:
                settle = min(settle, s.max_settle_cycles)
            planned.append(PlannedPoint(float(frequency), settle, cycles, "look"))
            seconds += float(self._timing.point_s(frequency, settle, cycles, 2.0))
            previous = frequency
        self._record(f"first look: {len(planned)} points", seconds)
        self.state = State.MEASURE
        return NextPoints(tuple(planned), State.LOOK, seconds)

    def _relative_stderr(self) -> dict[str, float]:
        result = self.result
        assert result is not None
        return {
            name: float(result.stderr[name] / abs(result.values[name]))
            if result.values[name] != 0 else float("inf")
            for name in self.settings.targets
        }  # fmt: skip

    def _fit(self) -> None:
        self.state = State.FIT
        s = self.settings
        assert self.points is not None
        result = self.fit_function(self.points)
        missing = sorted(set(s.targets) - set(result.free))
        if missing:
            raise InputError(
                f"targets {', '.join(missing)} are not fitted by '{result.spec}'", "adaptive plan"
            )
        self.result = result
        power, source = point_noise_power(self.points, result.noise)
        noise = fit_noise_forecast(self.points, power, source).calibrated(self.points, power)
        self._info = InformationModel(
            result.model, dict(result.values), tuple(result.free), noise, s.level_m_per_s2,
            s.force_limit_n,
        )  # fmt: skip
        self._modes = identified_modes(result.model, result.values, s.band_hz)
        self._check_settle()
        self._held = self._info.of_measured(self.points.frequency_hz, power)
        predicted = np.diag(np.linalg.pinv(self._held))
        index = [result.free.index(name) for name in s.targets]
        reported = np.array([self._relative_stderr()[name] for name in s.targets]) ** 2
        with np.errstate(divide="ignore", invalid="ignore"):
            ratio = reported / predicted[index]
        self._calibration = np.where(np.isfinite(ratio), ratio, 1.0)
        stderr = self._relative_stderr()
        text = ", ".join(f"{name} {stderr[name]:.3g}" for name in s.targets)
        self._record(
            f"fit {result.spec} on {len(self.points)} points: relative stderr {text}; "
            f"noise from {source}; modes "
            + ", ".join(f"{m.frequency_hz:.1f} Hz ζ {m.damping_ratio:.3f}" for m in self._modes)
        )

    def _check_settle(self) -> None:
        """Compare, at every frequency visited with repeats since the last check, the first
        long point with the mean of the others: a difference well beyond their noise
        (``|δ|² > 9 E|δ|²``, 1 in 8000 for noise alone) is a transient the settle left, and
        every later settle is doubled."""
        points = self.points
        assert points is not None and self._info is not None
        start, self._checked = self._checked, len(points)
        f = points.frequency_hz[start:]
        if f.size < 3:
            return
        predicted = self._info.noise_power(f, points.integrate_s[start:])
        measured = {"table": points.variance_table, "support": points.variance_support}
        frfs = {"table": points.accelerance_table, "support": points.accelerance_support}
        edges = np.r_[0, np.nonzero(np.diff(f) != 0)[0] + 1, f.size]
        worst, where = 0.0, 0.0
        for a, b in pairwise(edges):
            index = np.arange(a, b)
            index = index[points.integrate_cycles[start + index] > 1]
            if index.size < 3:
                continue
            for name, values in frfs.items():
                if values is None or name not in predicted:
                    continue
                h = values[start + index]
                given = measured[name]
                power = given[start + index] if given is not None else predicted[name][index]
                rest = 1.0 / np.sum(1.0 / power[1:])
                mean = np.sum(h[1:] / power[1:]) * rest
                ratio = abs(h[0] / mean - 1.0) ** 2 / (power[0] + rest)
                if ratio > worst:
                    worst, where = float(ratio), float(f[a])
        if worst > 9.0 and self._settle_factor < 16.0:
            self._settle_factor *= 2.0
            self._record(
                f"transient left at {where:.2f} Hz ({np.sqrt(worst):.1f} σ after the settle): "
                f"settles now × {self._settle_factor:g}"
            )

    def _finish(self, reason: str) -> None:
        assert self.points is not None and self.result is not None
        self.state = State.DONE
        self._record(reason)
        self.outcome = PlanOutcome(
            reason, self.points, self.result, self._relative_stderr(), self.history
        )

    def _decide(self) -> NextPoints | None:
        self.state = State.DECIDE
        s = self.settings
        assert self.points is not None and self._info is not None
        stderr = self._relative_stderr()
        met = all(stderr[name] <= target for name, target in s.targets.items())
        wants_cover = not self._covered and s.coverage_damping_ratio is not None
        if met and not wants_cover:
            self._finish("targets met")
            return None
        # a model that leaves far more than the noise is wrong: time spent on its targets
        # buys the precision of a biased value; measure the coverage for diagnosis and stop
        misfit = self.result is not None and self.result.misfit_scale > s.misfit_limit
        if misfit and not wants_cover:
            self._finish("model misfit")
            return None
        used = self.points.test_time_s
        if s.dwell_limit_s is not None and used >= (1.0 - DWELL_MARGIN) * s.dwell_limit_s:
            self._finish("dwell limit")
            return None
        if self._batches >= s.max_batches:
            self._finish("batch limit")
            return None
        planned, seconds, note = self._batch(used, choose=not (met or misfit))
        if not planned:
            self._finish(note)
            return None
        self._batches += 1
        self._record(note, seconds)
        self.state = State.MEASURE
        return NextPoints(tuple(planned), State.DECIDE, seconds)

    # ------------------------------------------------------------------ choosing points

    def _design_targets(self) -> tuple[list[int], NDArray[np.float64]]:
        s = self.settings
        assert self.result is not None and self._calibration is not None
        index = [self.result.free.index(name) for name in s.targets]
        wanted = np.array([s.targets[name] for name in s.targets]) * s.aim
        calibration = np.ones(len(index))
        if self._covered:  # the prediction is calibrated once chosen points carry the fit
            calibration = np.clip(self._calibration, 0.25, 100.0)
        return index, wanted / np.sqrt(calibration)

    def _allocation(
        self, fraction: float, cover: list[tuple[float, int]]
    ) -> tuple[NDArray, NDArray, float]:
        """Candidate frequencies and the integration time the next batch gives each, counting
        what is held and what the batch's ``cover`` points will add."""
        s = self.settings
        info = self._info
        assert info is not None and self.points is not None and self._held is not None
        candidates = s.limits.grid(s.band_hz, s.resolution_hz)
        held = self._held
        if cover:
            f = np.array([c[0] for c in cover])
            held = held + info.of_points(f, np.array([c[1] for c in cover]) / f)
        index, wanted = self._design_targets()
        design = minimum_time_design(candidates, info.rate(candidates), index, wanted, prior=held)
        support = design.support(1e-4)
        if support.size == 0:
            return candidates[:0], candidates[:0], 0.0
        merged = merge_neighbours(
            candidates[support], design.integrate_s[support], 2.5 * s.resolution_hz, s.limits
        )
        exact = minimum_time_design(merged, info.rate(merged), index, wanted, prior=held)
        return merged, exact.integrate_s * fraction, exact.total_s

    def _batch(self, used: float, choose: bool = True) -> tuple[list[PlannedPoint], float, str]:
        """The next batch: the design's points (``choose``) and, the first time, the band's
        coverage; trimmed to the dwell limit."""
        s = self.settings
        assert self.points is not None and self._info is not None
        fraction = s.first_fraction if not self._covered else 1.0
        cover: list[tuple[float, int]] = []
        if not self._covered and s.coverage_damping_ratio is not None:
            grid = coverage_grid(
                s.band_hz, self.points.frequency_hz,
                narrowest_damping_ratio=s.coverage_damping_ratio,
                points_per_bandwidth=s.points_per_bandwidth, limits=s.limits,
            )  # fmt: skip
            cycles = min(s.cover_integrate_cycles, s.integrate_cap)
            cover = [(float(f), cycles) for f in grid]
        if choose:
            frequency, integrate, remaining = self._allocation(fraction, cover)
        else:
            frequency, integrate, remaining = np.zeros(0), np.zeros(0), 0.0
        room = np.inf if s.dwell_limit_s is None else s.dwell_limit_s - used
        room = min(room, s.max_batch_s)
        if integrate.sum() > room:  # no batch beyond the room left: scale it down first
            integrate = integrate * room / integrate.sum()
        integrate = self._for_landing(frequency, integrate, cover)
        refine = allocation_points(
            frequency, integrate, max_integrate_cycles=s.integrate_cap, limits=s.limits
        )
        planned, seconds = self._settled(refine, cover)
        for _ in range(60):
            if seconds.sum() <= room or not refine:
                break
            integrate = integrate * 0.85
            refine = allocation_points(
                frequency, integrate, max_integrate_cycles=s.integrate_cap, limits=s.limits
            )
            planned, seconds = self._settled(refine, cover)
        if seconds.sum() > room:
            return [], 0.0, "dwell limit"
        self._covered = True
        if not planned:
            limited = choose and s.dwell_limit_s is not None and room < s.max_batch_s
            return [], 0.0, "dwell limit" if limited else "no progress"
        chosen = ", ".join(f"{f:.2f}" for f in np.unique(frequency[integrate > 0]))
        note = f"batch of {len(planned)} points ({len(refine)} chosen, {len(cover)} coverage)"
        if chosen:
            note += f" at {chosen} Hz; predicted integration still needed {remaining:.1f} s"
        return planned, float(seconds.sum()), note

    def _reference_db(self) -> float:
        """Where the last point's reference stood from the level, dB."""
        assert self.points is not None
        level = self.settings.level_m_per_s2
        return float(20.0 * np.log10(self.points.reference_amplitude[-1] / level))

    def _for_landing(
        self, frequency: NDArray, integrate: NDArray, cover: list[tuple[float, int]]
    ) -> NDArray[np.float64]:
        """The allocation lengthened (or shortened) where the auto level will land below (or
        above) the level asked for (:func:`~viscorig.planning.batch.landing_db`), so that each
        frequency gets the information the design gave it."""
        assert self.points is not None and self._info is not None
        if not integrate.size:
            return integrate
        last = float(self.points.frequency_hz[-1])
        tagged = [(f, 1, "refine") for f, t in zip(frequency, integrate, strict=True) if t > 0]
        ordered = order_points(tagged + [(f, c, "cover") for f, c in cover], last)
        landing, _ = landing_db(ordered, last, point_context(self._info, self._modes),
                                self._timing, self._reference_db())  # fmt: skip
        factor = {p[0]: 10.0 ** (-x / 10.0) for p, x in zip(ordered, landing, strict=True)
                  if p[2] == "refine"}  # fmt: skip
        return np.array([t * factor.get(f, 1.0) for f, t in zip(frequency, integrate,
                                                                  strict=True)])  # fmt: skip

    def _settled(
        self, refine: list[tuple[float, int]], cover: list[tuple[float, int]]
    ) -> tuple[list[PlannedPoint], NDArray[np.float64]]:
        s = self.settings
        assert self.points is not None and self._info is not None
        last = float(self.points.frequency_hz[-1])
        tagged = [(f, c, "refine") for f, c in refine] + [(f, c, "cover") for f, c in cover]
        return settle_points(
            order_points(tagged, last), last, point_context(self._info, self._modes),
            bias_fraction=s.bias_fraction, max_settle_cycles=s.max_settle_cycles,
            timing=self._timing, limits=s.limits, settle_factor=self._settle_factor,
            start_db=self._reference_db(),
        )  # fmt: skip
