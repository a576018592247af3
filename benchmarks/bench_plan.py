"""Rig time: the paper's plan against the adaptive plan, and both against the physical floor.

On a simulated Voigt rig where the model is exact (the paper's table and soft-rubber Table 1
values, rigid link, the presets' transducers and noise; ``rigsim`` in the time domain), at the
paper's 1.4 m/s² peak:

- the paper plan: 20-120 Hz every 0.25 Hz, 100 settle and 100 integration periods per point;
- the adaptive plan (:mod:`viscorig.planning`) asked for the paper plan's achieved relative
  standard error of K_v and C_v (each repeat its own paper run, its own target);
- the floor: the least rig time of any plan for the same target (optimal design over every
  analyser frequency in the band, settle included, :func:`viscorig.planning.design_bound`).

Both plans are fitted by the project's estimator, as ``identify`` fits a run: each point
weighted by its noise (:func:`viscorig.fitting.fit`, ``weighting="noise"``), the run read as
analysis reads it (the adaptive plan's repeats merged, :meth:`viscorig.storage.RunRecord.merged`),
the noise estimated as ``identify`` estimates it; the paper's uniform weighting of the paper
plan is shown beside it. Then a loose target (0.2 % on K_v and C_v, a damper datasheet's need),
the floor for each rig preset of the paper (``sim/rigs``), and diagnosis on what the adaptive
plan measured against diagnosis on the paper's full sweep.

Run: ``python benchmarks/bench_plan.py [--repeats N] [--ladder]`` (needs the project installed; uses
tests/planning_rig).
"""

from __future__ import annotations

import argparse
import statistics
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))

from planning_rig import TABLE, VOIGT_RIG, VOIGT_TRUTH, SimulatedRig, paper_sweep
from rigsim.rigfile import load_preset

from viscorig.diagnosis import diagnose
from viscorig.fitting import fit
from viscorig.planning import (
    AdaptivePlan,
    AdaptiveSettings,
    InformationModel,
    design_bound,
    fit_noise_forecast,
    point_noise_power,
    shared_noise,
)

LEVEL = 1.4
BAND = (20.0, 120.0)
TARGETS = ("K_v", "C_v")
PRESETS = ("soft-0", "soft-10", "medium-0", "medium-10", "hard-0", "hard-10")


def relative(result, name: str) -> float:
    return float(result.stderr[name] / abs(result.values[name]))


def settings(targets: dict[str, float], **changes) -> AdaptiveSettings:
    return AdaptiveSettings("voigt", targets, BAND, LEVEL, fixed=TABLE, force_limit_n=100.0,
                            **changes)  # fmt: skip


def bound_for(points, result, targets: dict[str, float], values=None):
    power, source = point_noise_power(points)
    noise = fit_noise_forecast(points, power, source)
    return design_bound(result.model, values or result.values, result.free, noise, LEVEL, BAND,
                        targets, force_limit_n=100.0), noise  # fmt: skip


def identify(points, spec: str = "voigt", weighting: str = "noise"):
    """The fit ``identify`` makes of a run of these points: merged (one point per frequency),
    its noise estimated from the run, table fixed."""
    data = points.merged().frf_data()
    return fit(spec, data, fixed=TABLE, weighting=weighting)


def voigt_rig(repeats: int) -> None:
    rows = []
    started = time.perf_counter()
    for seed in range(repeats):
        paper = paper_sweep(SimulatedRig(VOIGT_RIG, LEVEL, seed=1000 + seed))
        paper_fit = identify(paper)
        uniform = identify(paper, weighting="uniform")
        targets = {name: relative(paper_fit, name) for name in TARGETS}
        plan = AdaptivePlan(settings(targets))
        outcome = plan.run(SimulatedRig(VOIGT_RIG, LEVEL, seed=2000 + seed))
        run_fit = identify(outcome.points)  # what identify reports on the adaptive run
        rows.append({
            "paper_s": paper.test_time_s,
            "adaptive_s": outcome.test_time_s,
            "targets_met": outcome.targets_met,
            "plan_ratio": max(outcome.relative_stderr[n] / targets[n] for n in TARGETS),
            "stderr_ratio": max(relative(run_fit, n) / targets[n] for n in TARGETS),
            "z": [abs(run_fit.values[n] - VOIGT_TRUTH[n]) / run_fit.stderr[n] for n in TARGETS],
            "paper_z": [abs(paper_fit.values[n] - VOIGT_TRUTH[n]) / paper_fit.stderr[n]
                        for n in TARGETS],
            "targets": targets,
            "uniform": {n: relative(uniform, n) for n in TARGETS},
            "batches": sum(1 for s in outcome.history if s.state.value == "decide"),
            "paper": paper, "paper_fit": paper_fit,
        })  # fmt: skip
    elapsed = time.perf_counter() - started
    median = statistics.median
    first = rows[0]
    target = {n: median(r["targets"][n] for r in rows) for n in TARGETS}
    bound, _ = bound_for(first["paper"], first["paper_fit"], target, VOIGT_TRUTH)
    paper_s = median(r["paper_s"] for r in rows)
    adaptive_s = median(r["adaptive_s"] for r in rows)
    z = np.array([r["z"] for r in rows])
    paper_z = np.array([r["paper_z"] for r in rows])
    print(f"Voigt rig (model exact), {LEVEL} m/s², {repeats} repeats (medians); every fit is "
          "the project's estimator as identify fits the run")
    print(f"  paper plan        {paper_s:8.1f} s   K_v ± {target['K_v']:.3g}, "
          f"C_v ± {target['C_v']:.3g} (each point weighted by its noise)")
    uniform_k = median(r["uniform"]["K_v"] for r in rows)
    uniform_c = median(r["uniform"]["C_v"] for r in rows)
    print(f"                               the paper's uniform weighting of the same runs: "
          f"K_v ± {uniform_k:.3g}, C_v ± {uniform_c:.3g} "
          f"({uniform_k / target['K_v']:.1f}× and {uniform_c / target['C_v']:.1f}×)")
    print(f"  floor (any plan)  {bound.plan_time_s:8.1f} s   (integration ≥ "
          f"{bound.integration_floor_s:.1f} s, certified; settle {bound.settle_s:.1f} s; at "
          + ", ".join(f"{f:.2f}" for f in sorted({p.frequency_hz for p in bound.plan}))
          + " Hz)")
    print(f"  adaptive plan     {adaptive_s:8.1f} s   "
          f"(median {median(r['batches'] for r in rows):.0f} chosen batches)")
    print(f"  dwell ratio adaptive/paper   {adaptive_s / paper_s:.3f}   (goal ≤ 0.45; "
          f"floor/paper {bound.plan_time_s / paper_s:.3f})")
    ratios = [r["adaptive_s"] / bound.plan_time_s for r in rows]
    print(f"  adaptive/floor               {median(ratios):.3f}   (worst {max(ratios):.3f}; "
          f"goal ≤ 1.2)")
    stderr_ratio = [r["stderr_ratio"] for r in rows]
    plan_ratio = [r["plan_ratio"] for r in rows]
    print(f"  stderr ratio adaptive/paper  {median(stderr_ratio):.3f}   (worst "
          f"{max(stderr_ratio):.3f}; goal ≤ 1.1; identify on the run, the worse of K_v and "
          f"C_v; the plan's own fit {median(plan_ratio):.3f}); targets met in "
          f"{sum(r['targets_met'] for r in rows)}/{repeats}")
    for label, values in (("adaptive", z), ("paper", paper_z)):
        within = [float(np.mean(np.all(values <= k, axis=1))) for k in (1, 2, 3)]
        single = [float(np.mean(values <= k)) for k in (1, 2)]
        print(f"  truth within 3 stderr ({label:8s}) {within[2]:.0%} of repeats (K_v and C_v "
              f"together; goal ≥ 95 %); each parameter within 1/2 stderr "
              f"{single[0]:.0%}/{single[1]:.0%}")
    print(f"  wall time {elapsed / repeats:.2f} s per repeat (simulation, fits, plan)")


def loose_target(repeats: int) -> None:
    times = []
    for seed in range(repeats):
        outcome = AdaptivePlan(settings({"K_v": 2e-3, "C_v": 2e-3})).run(
            SimulatedRig(VOIGT_RIG, LEVEL, seed=3000 + seed)
        )
        assert outcome.targets_met
        times.append(outcome.test_time_s)
    print(f"Loose target (0.2 % on K_v and C_v): adaptive dwell "
          f"{statistics.median(times) / 60:.2f} min (median of {repeats}; paper plan "
          f"{paper_sweep(SimulatedRig(VOIGT_RIG, LEVEL)).test_time_s / 60:.1f} min)")


def presets() -> None:
    print("Floor for each preset of the paper's rigs (Voigt K_v and C_v at the paper plan's "
          "noise-limited stderr; the rubber is fractional, so K_v, C_v are the band-average "
          "Voigt values of the paper's Table 1)")
    for name in PRESETS:
        rig = load_preset(name)
        paper = paper_sweep(SimulatedRig(rig, LEVEL, seed=7))
        flagged = int(np.count_nonzero(paper.flags & 8))
        result = fit("voigt", paper.frf_data(), fixed=TABLE, weighting="uniform")
        power, source = point_noise_power(paper)
        noise = fit_noise_forecast(paper, power, source)
        info = InformationModel(result.model, result.values, result.free, noise, LEVEL, 100.0)
        covariance = np.linalg.inv(info.of_points(paper.frequency_hz, paper.integrate_s))
        noise_only = {n: float(np.sqrt(covariance[i, i]))
                      for i, n in enumerate(result.free) if n in TARGETS}  # fmt: skip
        bound = design_bound(result.model, result.values, result.free, noise, LEVEL, BAND,
                             noise_only, force_limit_n=100.0)  # fmt: skip
        support = sorted({round(p.frequency_hz, 2) for p in bound.plan})
        print(f"  {name:10s} paper {paper.test_time_s:7.1f} s, K_v ± {noise_only['K_v']:.2g}, "
              f"C_v ± {noise_only['C_v']:.2g}; floor {bound.plan_time_s:6.1f} s "
              f"({bound.plan_time_s / paper.test_time_s:.3f} of the paper's dwell) at "
              f"{', '.join(f'{f:g}' for f in support)} Hz; Voigt misfit "
              f"{result.rms_error:.2%}" + (f"; {flagged} points over the force limit"
                                           if flagged else ""))  # fmt: skip


def hard_rubber_physics() -> None:
    """The floor on hard-10 with a model that fits it to the noise (fractional rubber, load
    cell, three fixture modes): the fixture modes' parameters are nuisances the design must
    learn too, so it visits each mode."""
    spec = "fractional+load_cell+fixture(38)+fixture(58)+fixture(92)"
    paper = paper_sweep(SimulatedRig("hard-10", LEVEL, seed=3))
    result = fit(spec, paper.frf_data(), noise=shared_noise(paper), fixed=TABLE,
                 weighting="noise")
    power, source = point_noise_power(paper)
    noise = fit_noise_forecast(paper, power, source)
    info = InformationModel(result.model, result.values, result.free, noise, LEVEL, 100.0)
    covariance = np.linalg.pinv(info.of_points(paper.frequency_hz, paper.integrate_s))
    targets = {n: float(np.sqrt(covariance[result.free.index(n), result.free.index(n)]))
               for n in ("K_0", "alpha")}  # fmt: skip
    bound = design_bound(result.model, result.values, result.free, noise, LEVEL, BAND, targets,
                         force_limit_n=100.0, resolution_hz=0.25)  # fmt: skip
    support = ", ".join(f"{f:g}" for f in sorted({round(p.frequency_hz, 2) for p in bound.plan}))
    print(f"  hard-10 with {spec} (rms error {result.rms_error:.2e}, noise floor "
          f"{result.noise_floor:.2e}; {len(result.free)} parameters): K_0 ± {targets['K_0']:.2g}, "
          f"alpha ± {targets['alpha']:.2g} in the paper's {paper.test_time_s:.0f} s; floor "
          f"{bound.plan_time_s:.0f} s ({bound.plan_time_s / paper.test_time_s:.3f}; integration "
          f"≥ {bound.integration_floor_s:.0f} s certified) at {support} Hz")


def coverage(ladder: bool) -> None:
    """Diagnosis on what the adaptive plan measured (one point per frequency: repeats joined)
    against diagnosis on the paper's full sweep, for every preset. Voigt misfits these rubbers,
    so the plan stops after its first look and the band's coverage ("model misfit")."""
    print("Diagnosis on the adaptive plan's points vs the paper's sweep (first effect"
          + (", then the diagnose --auto ladder" if ladder else "") + ")")
    for name in PRESETS:
        paper = paper_sweep(SimulatedRig(name, LEVEL, seed=3))
        full = diagnose(paper.frf_data(name), table=TABLE)
        plan = AdaptivePlan(settings({"K_v": 2e-5, "C_v": 2e-4}))
        outcome = plan.run(SimulatedRig(name, LEVEL, seed=4))
        merged = outcome.points.merged()
        mine = diagnose(merged.frf_data(name), table=TABLE)
        line = (f"  {name:10s} paper {paper.test_time_s:6.0f} s: {full.findings[0].effect}; "
                f"adaptive {outcome.test_time_s:4.0f} s ({outcome.reason}, {len(merged)} "
                f"frequencies): {mine.findings[0].effect}")
        if ladder:
            line += (f"\n{'':14s}ladder: paper {full.auto()[-1].model}; "
                     f"adaptive {mine.auto()[-1].model}")
        print(line)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--repeats", type=int, default=20)
    parser.add_argument("--ladder", action="store_true", help="climb diagnose's ladder too")
    arguments = parser.parse_args()
    voigt_rig(arguments.repeats)
    loose_target(max(3, arguments.repeats // 4))
    presets()
    hard_rubber_physics()
    coverage(arguments.ladder)


if __name__ == "__main__":
    main()
