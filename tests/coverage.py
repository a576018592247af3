"""Coverage of the reported standard errors, on replicates the time-domain simulator measured.

A replicate is a campaign in small: a noisy bare-table run (the paper's table sweep, 12-28 Hz
at 0.125 Hz, 200 settle periods), then a noisy run of a Voigt specimen on the same table
(20-120 Hz at 0.25 Hz, 100 + 100 periods, rigid link: the model is exact), each with its own
noise. The table is identified from its run and the specimen fitted with the table held at
those values, their covariance propagated, as ``viscorig identify`` does. The deviation of each
fitted parameter from the simulator's truth, in reported standard errors, is recorded.

Used by ``tests/test_coverage.py`` (a few dozen replicates, in CI) and by
``studies/coverage.py`` (hundreds, printed as a table).
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass

import numpy as np
from simdata import rig_text, simulate_run

from viscorig.fitting import Known, fit

VOIGT = {"mass_kg": 0.25, "model": "voigt", "stiffness_n_per_m": 1.5e5, "damping_ns_per_m": 114.59}
TRUTH = {"K_v": 1.5e5, "C_v": 114.59, "M_v": 0.25}

#: White sensor noise of the coverage rigs (relative FRF scatter of about 1e-4 to 1e-3).
WHITE = {
    "excitation_force_n_per_sqrt_hz": 2e-3,
    "table_acceleration_m_per_s2_per_sqrt_hz": 2e-4,
    "device_force_n_per_sqrt_hz": 2e-3,
    "disc_acceleration_m_per_s2_per_sqrt_hz": 2e-4,
}
#: The same, plus each transducer's sensitivity drifting by 0.1 % rms with a 30 s correlation
#: time: on the paper's sweep (3.6 s per point on average) the drift dominates the scatter.
CORRELATED = {**WHITE, "sensitivity_drift_rms": 1e-3, "sensitivity_drift_time_s": 30.0}
NOISES = {"white": WHITE, "correlated": CORRELATED}


@dataclass(frozen=True)
class Replicate:
    """Deviations ``(fitted − truth)/stderr`` of one replicate, and its error measures."""

    deviation: dict[str, float]
    rms_over_floor: float
    fits_noise: bool


def replicate(noise: dict, seed: int, frfs: tuple[str, ...] | None = None) -> Replicate:
    """One table run and one specimen run, each with its own noise (see the module text)."""
    table_run = simulate_run(
        rig_text(noise=noise), seed=2 * seed + 1, start_hz=12.0, stop_hz=28.0, step_hz=0.125,
        settle_cycles=200.0,
    )  # fmt: skip
    table = fit("table", table_run.frf_data("table"))
    index = [table.covariance_names.index(name) for name in ("M_s", "K_s", "C_s")]
    known = Known(
        {name: table.values[name] for name in ("M_s", "K_s", "C_s")},
        ("M_s", "K_s", "C_s"),
        np.asarray(table.joint_covariance)[np.ix_(index, index)],
        "run 'table'",
    )
    specimen = simulate_run(rig_text(VOIGT, noise=noise), seed=2 * seed + 2)
    result = fit("voigt", specimen.frf_data("specimen"), frfs=frfs, known=known)
    return Replicate(
        {name: (result.values[name] - value) / result.stderr[name] for name, value in
         TRUTH.items()},
        result.rms_error / result.noise_floor,
        result.fits_noise,
    )  # fmt: skip


def coverage(replicates: Iterable[Replicate]) -> dict[str, dict[str, float]]:
    """Per parameter: fraction within 1 and 2 stderr, rms of error/stderr, and the count."""
    replicates = list(replicates)
    table = {}
    for name in TRUTH:
        z = np.array([r.deviation[name] for r in replicates])
        table[name] = {
            "within_1": float(np.mean(np.abs(z) < 1.0)),
            "within_2": float(np.mean(np.abs(z) < 2.0)),
            "rms": float(np.sqrt(np.mean(z**2))),
            "count": int(z.size),
        }
    return table
