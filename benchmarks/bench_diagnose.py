"""How long a diagnosis takes: a 401-point run, both FRFs, every candidate effect fitted.

The run is the paper's sweep (20-120 Hz at 0.25 Hz) of a rig preset (``hard-10`` by default,
or the one named on the command line) measured on the time-domain simulator, with the
analyser's normalized variance as a campaign file holds it: fractional rubber, finite load cell,
three fixture modes and the frame under the table. From Voigt, every candidate (the modulus, the
load cell, the scan for local modes, delay, high-pass and gain of each FRF's channels, the
frame, amplitude, drift) is screened, fitted and tested. Targets: ``diagnose`` under 2 s,
``diagnose --auto`` under 5 s.

Baseline, measured in this process: one ``identify``-style fit of the Voigt model to the same
run; the ratio says how many such fits a diagnosis costs.

Run: ``python benchmarks/bench_diagnose.py``. BLAS runs single-threaded here (set before numpy
loads): the matrices are small (802 x 17), and on a busy two-core machine threaded SVDs in the
least-squares steps cost ten times more than they save. Measured: diagnose --auto on hard-10
1.9 s single-threaded against 17 s with default threads under load.
"""

from __future__ import annotations

import os

for _variable in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_variable, "1")

import sys  # noqa: E402
import time  # noqa: E402

import numpy as np  # noqa: E402
from rigsim.engine import RigSimulator  # noqa: E402
from rigsim.measurement import SourceControl, SweepRequest  # noqa: E402
from rigsim.rigfile import load_preset  # noqa: E402

from viscorig.diagnosis import diagnose  # noqa: E402
from viscorig.fitting import FrfData, fit  # noqa: E402

TABLE = {"M_s": 3.4, "K_s": 50194.0, "C_s": 5.05}
TARGET_S = 2.0
AUTO_TARGET_S = 5.0


def measured_run(preset: str = "hard-10") -> FrfData:
    """The paper's sweep of a preset, as the analyser would give it."""
    rig = load_preset(preset)
    frequency = np.arange(20.0, 120.125, 0.25)
    sensors = rig.sensors
    control = SourceControl(
        source_vpk=0.05, auto_level=True, reference_channel=4,
        reference_vpk=1.4 * sensors.acceleration_v_per_m_s2, tolerance_db=0.5,
        source_limit_vpk=rig.shaker.force_limit_n / rig.shaker.force_n_per_v,
    )
    record = RigSimulator(rig, seed=1).sweep(
        SweepRequest(frequency, 100 / frequency, 100 / frequency, control)
    )
    v = record.channel_v
    force, accel = sensors.force_v_per_n, sensors.acceleration_v_per_m_s2
    variance = record.variance
    return FrfData(
        frequency,
        (v[:, 1] / accel) / (v[:, 0] / force),
        (v[:, 3] / accel) / (v[:, 2] / force),
        record.end_time_s,
        np.abs(v[:, 3] / accel),
        name=preset,
        variance_table=variance[:, 0] + variance[:, 1],
        variance_support=variance[:, 2] + variance[:, 3],
    )


def best_of(repeats: int, action) -> tuple[float, object]:
    times, result = [], None
    for _ in range(repeats):
        start = time.perf_counter()
        result = action()
        times.append(time.perf_counter() - start)
    return min(times), result


def main(preset: str = "hard-10") -> None:
    data = measured_run(preset)
    points = data.frequency_hz.size
    fit_s, _ = best_of(5, lambda: fit("voigt", data, fixed=TABLE))
    diagnose_s, diagnosis = best_of(3, lambda: diagnose(data, "voigt", table=TABLE))
    auto_s, ladder = best_of(3, lambda: diagnose(data, "voigt", table=TABLE).auto())
    print(f"{preset}, {points} points, both FRFs, {len(diagnosis.findings)} candidates fitted")
    print(f"  one Voigt fit (baseline)   {fit_s * 1e3:8.1f} ms")
    print(f"  diagnose                   {diagnose_s * 1e3:8.1f} ms   "
          f"{diagnose_s / fit_s:6.1f} x baseline   target {TARGET_S:.1f} s: "
          f"{'met' if diagnose_s < TARGET_S else 'MISSED'}")
    print(f"  diagnose --auto ({len(ladder) - 1} steps)  {auto_s * 1e3:8.1f} ms   "
          f"{auto_s / fit_s:6.1f} x baseline   target {AUTO_TARGET_S:.1f} s: "
          f"{'met' if auto_s < AUTO_TARGET_S else 'MISSED'}")
    for step in ladder:
        print(f"    {step.model:<48} rms {step.rms_error:.3e}  "
              f"({step.rms_error / step.noise_floor:.2f} x floor)")


if __name__ == "__main__":
    main(*sys.argv[1:2])
