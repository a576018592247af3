"""How fast the simulated rig measures the paper's sweep, against real time and a naive integrator.

The paper's sweep: 20-120 Hz at 0.25 Hz (401 points), 100 settle + 100 integration cycles, four
channels, auto level on. On the real rig that is about 1,433 s of pure dwell. The simulator
solves each point exactly (modal closed form), so its time should not grow with the cycle count.

Baselines, both measured or computed in this process:
- real time: the simulator's own clock (test time the sweep represents, controller passes
  included) and the nominal 1,433 s of dwell;
- a naive fixed-step integration of the same rig (exact zero-order-hold discretisation, 64 steps
  per cycle, correlation by summation) timed on one point and scaled to the sweep.

Run: ``python benchmarks/bench_simulator.py``.
"""

from __future__ import annotations

import time

import numpy as np
from rigsim.dynamics import build_state_space
from rigsim.engine import RigSimulator
from rigsim.measurement import SourceControl, SweepRequest
from rigsim.rigfile import load_preset
from scipy.linalg import expm

PRESET = "soft-0"


def paper_request(points: int = 401, cycles: float = 100.0) -> SweepRequest:
    frequency = np.linspace(20.0, 120.0, points)
    control = SourceControl(
        source_vpk=0.05, auto_level=True, reference_channel=4, reference_vpk=0.0102,
        tolerance_db=2.0, source_limit_vpk=2.0, input_limit_channel=1, input_limit_vpk=1.124,
    )
    return SweepRequest(frequency, cycles / frequency, cycles / frequency, control)


def best_time(function, repeats: int = 5) -> float:
    best = np.inf
    for _ in range(repeats):
        start = time.perf_counter()
        function()
        best = min(best, time.perf_counter() - start)
    return best


def naive_point_seconds(
    frequency_hz: float = 40.0, cycles: int = 200, per_cycle: int = 64
) -> float:
    """Wall time of one point integrated step by step (the obvious implementation)."""
    space = build_state_space(load_preset(PRESET))
    dt = 1.0 / (frequency_hz * per_cycle)
    size = space.a.shape[0]
    augmented = np.zeros((size + 1, size + 1))
    augmented[:size, :size] = space.a * dt
    augmented[:size, size] = space.b * dt
    step = expm(augmented)
    phi, gamma = step[:size, :size], step[:size, size]
    w = 2 * np.pi * frequency_hz

    def run() -> None:
        state = np.zeros(size)
        total = np.zeros(4, dtype=complex)
        for n in range(cycles * per_cycle):
            t = n * dt
            force = 5.0 * np.cos(w * t)
            state = phi @ state + gamma * force
            if n >= cycles * per_cycle // 2:
                total += (space.c @ state + space.d * force) * np.exp(-1j * w * t)

    return best_time(run, repeats=1)


def main() -> None:
    rig = load_preset(PRESET)
    request = paper_request()
    nominal_dwell = float(np.sum(request.settle_s + request.integrate_s))
    simulator = RigSimulator(rig, seed=1)
    record = simulator.sweep(request)
    represented = float(record.end_time_s[-1])
    wall = best_time(lambda: RigSimulator(rig, seed=1).sweep(request))
    print(f"paper sweep on preset {PRESET!r}: 401 points, 100+100 cycles, auto level, 4 channels")
    print(f"  wall time (best of 5)           {wall * 1e3:8.1f} ms")
    print(f"  nominal dwell                   {nominal_dwell:8.1f} s   ->"
          f" {nominal_dwell / wall:9.0f}x real time")
    passes = int(record.extras["iterations"].sum())
    print(f"  test time incl. controller      {represented:8.1f} s   ->"
          f" {represented / wall:9.0f}x real time ({passes} passes)")

    naive = naive_point_seconds()
    print(f"  naive fixed-step, one point     {naive * 1e3:8.1f} ms  -> sweep about"
          f" {naive * 401:.1f} s, {naive * 401 / wall:.0f}x slower than the simulator")

    print("growth with points (100+100 cycles):")
    base = None
    for points in (101, 401, 1601):
        seconds = best_time(lambda p=points: RigSimulator(rig, seed=1).sweep(paper_request(p)))
        base = base or seconds
        print(f"  {points:5d} points  {seconds * 1e3:8.1f} ms  ({seconds / base:5.2f}x of 101)")
    print("growth with cycles (401 points):")
    base = None
    for cycles in (10, 100, 1000):
        seconds = best_time(lambda c=cycles: RigSimulator(rig, seed=1).sweep(paper_request(401, c)))
        base = base or seconds
        print(f"  {cycles:5d} cycles  {seconds * 1e3:8.1f} ms  ({seconds / base:5.2f}x of 10)")

    drifting = load_preset(PRESET)
    from dataclasses import replace

    from rigsim.rigfile import Drift

    drifting = replace(drifting, drift=Drift(modulus_change_per_hour=-0.02))
    seconds = best_time(lambda: RigSimulator(drifting, seed=1).sweep(request), repeats=2)
    print(f"with thermal drift (one eigen-decomposition per point): {seconds * 1e3:.1f} ms"
          f" ({nominal_dwell / seconds:.0f}x real time)")


if __name__ == "__main__":
    main()
