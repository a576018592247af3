"""Cost of honest uncertainties: the noise model, the propagation of the table's covariance and
the weighting of each point by its noise, added to a Voigt fit (goal: at most 2x).

Baseline, in the same process on the same data: the same Voigt fit with every point weighted the
same, the noise model given (no estimate) and the table held exact (nothing propagated). Full:
the fit as ``identify`` makes it, estimating the noise model from the data (and the analyser's
variance), weighting each point by its noise and propagating the bare-table run's covariance.
The fastest of many repeats (wall time; on a shared machine the fastest is the one least
disturbed by others), for white sensor noise and for noise correlated along the sweep. Both
FRFs of a 401-point run (20-120 Hz).

Run: ``python benchmarks/bench_uncertainty.py`` (needs the project installed; uses tests/).
"""

from __future__ import annotations

import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))

from coverage import NOISES, VOIGT
from simdata import rig_text, simulate_run

from viscorig.fitting import Known, estimate_noise, fit

REPEATS = 101


def cpu_fastest(function, repeats: int = REPEATS) -> float:
    """Fastest wall time of ``function()`` in seconds, over ``repeats`` calls."""
    times = []
    for _ in range(repeats):
        start = time.perf_counter()
        function()
        times.append(time.perf_counter() - start)
    return min(times)


def main() -> None:
    print(f"{'noise':<11} {'fit alone':>10} {'noise model':>12} {'full fit':>9} {'ratio':>6}")
    for label, noise in NOISES.items():
        table_run = simulate_run(rig_text(noise=noise), seed=1, start_hz=12.0, stop_hz=28.0,
                                 step_hz=0.125, settle_cycles=200.0)
        table = fit("table", table_run.frf_data("table"), weighting="noise")
        known = Known.from_fit(table, ("M_s", "K_s", "C_s"), "run 'table'")
        data = simulate_run(rig_text(VOIGT, noise=noise), seed=2).frf_data("specimen")
        given = estimate_noise(data, ("table", "support"))
        baseline = cpu_fastest(lambda: fit("voigt", data, fixed=known.values, noise=given))  # noqa: B023
        estimate = cpu_fastest(lambda: estimate_noise(data, ("table", "support")))  # noqa: B023
        full = cpu_fastest(lambda: fit("voigt", data, known=known, weighting="noise"))  # noqa: B023
        print(f"{label:<11} {baseline * 1e3:>8.2f}ms {estimate * 1e3:>10.2f}ms "
              f"{full * 1e3:>7.2f}ms {full / baseline:>6.2f}")


if __name__ == "__main__":
    main()
