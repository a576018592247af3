"""Coverage of the reported standard errors, on replicates the time-domain simulator measured.

A replicate is a campaign in small: a noisy bare-table run (the paper's table sweep, 12-28 Hz
at 0.125 Hz, 200 settle periods), then a noisy run of a Voigt specimen on the same table
(20-120 Hz at 0.25 Hz, 100 + 100 periods, rigid link: the model is exact), each with its own
noise. The table is identified from its run and the specimen fitted with the table held at
those values, their covariance propagated, each point weighted by its noise, as ``viscorig
identify`` does. The deviation of each
fitted parameter from the simulator's truth, in reported standard errors, is recorded.

The same for the change between two runs of one specimen, without and with preload, on one
table (:func:`change_replicate`): the comparison's ± against the simulator's true change.

Used by ``tests/test_coverage.py`` (a few dozen replicates, in CI) and by
``studies/coverage.py`` (hundreds, printed as tables).
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass

import numpy as np
from simdata import DEFAULT_NOISE, rig_text, simulate_run

from viscorig.compare import compare_fits
from viscorig.fitting import Known, fit

VOIGT = {"mass_kg": 0.25, "model": "voigt", "stiffness_n_per_m": 1.5e5, "damping_ns_per_m": 114.59}
TRUTH = {"K_v": 1.5e5, "C_v": 114.59, "M_v": 0.25}
TABLE_NAMES = ("M_s", "K_s", "C_s")

#: White sensor noise of the coverage rigs (relative FRF scatter of about 1e-4 to 1e-3).
WHITE = dict(DEFAULT_NOISE)
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
    table = fit("table", table_run.frf_data("table"), weighting="noise")
    known = Known.from_fit(table, TABLE_NAMES, "run 'table'")
    specimen = simulate_run(rig_text(VOIGT, noise=noise), seed=2 * seed + 2)
    result = fit("voigt", specimen.frf_data("specimen"), frfs=frfs, known=known,
                 weighting="noise")
    return Replicate(
        {name: (result.values[name] - value) / result.stderr[name] for name, value in
         TRUTH.items()},
        result.rms_error / result.noise_floor,
        result.fits_noise,
    )  # fmt: skip


def coverage(replicates: Iterable[Replicate]) -> dict[str, dict[str, float]]:
    """Per parameter: fraction within 1 and 2 stderr, rms of error/stderr, and the count."""
    replicates = list(replicates)
    return {name: _within(np.array([r.deviation[name] for r in replicates])) for name in TRUTH}


def _within(z: np.ndarray) -> dict[str, float]:
    """Fraction of ``|z|`` below 1 and 2, rms of ``z``, and the count."""
    return {"within_1": float(np.mean(np.abs(z) < 1.0)),
            "within_2": float(np.mean(np.abs(z) < 2.0)),
            "rms": float(np.sqrt(np.mean(z**2))), "count": int(z.size)}


# -- the change between two runs on one table --------------------------------------------------

#: The same specimen stiffened by preload, as the paper's soft rubber: K_v +9.3 %, C_v +9.0 %.
PRELOADED = {**VOIGT, "stiffness_n_per_m": 1.64e5, "damping_ns_per_m": 124.9}
TRUE_CHANGE = {"K_v": 1.64e5 / 1.5e5 - 1, "C_v": 124.9 / 114.59 - 1}
#: Two local modes of the fixture on the disc (a few grams, as the paper rig's presets have),
#: the same in both runs and left out of the model: a misfit both fits share.
FIXTURES = [{"frequency_hz": 58.0, "damping_ratio": 0.02, "mass_kg": 0.003},
            {"frequency_hz": 92.0, "damping_ratio": 0.02, "mass_kg": 0.002}]


@dataclass(frozen=True)
class ChangeReplicate:
    """``(change − true change)/stderr`` of K_v and C_v, with the comparison's ± and with the
    two fits taken as independent, and the fits' error against the floor."""

    deviation: dict[str, float]
    independent: dict[str, float]
    stderr_ratio: dict[str, float]
    """The comparison's ± over the independent one."""
    rms_over_floor: float


def change_replicate(noise: dict, seed: int, fixtures: list[dict] | None = None,
                     frfs: tuple[str, ...] | None = None) -> ChangeReplicate:
    """A noisy bare-table run, then the specimen without and with preload on that table, each
    run with its own noise; both specimen fits inherit the one table fit, every point weighted
    the same (the paper's method, as ``summary`` and the report fit the runs they compare)."""
    table_run = simulate_run(
        rig_text(noise=noise), seed=3 * seed + 1, start_hz=12.0, stop_hz=28.0, step_hz=0.125,
        settle_cycles=200.0,
    )  # fmt: skip
    table = fit("table", table_run.frf_data("table"), weighting="uniform")
    known = Known.from_fit(table, TABLE_NAMES, "run 'table'")
    fits = [fit("voigt", simulate_run(rig_text(device, noise=noise, fixtures=fixtures),
                                      seed=3 * seed + k).frf_data(), frfs=frfs, known=known,
                weighting="uniform")
            for k, device in ((2, VOIGT), (3, PRELOADED))]
    deviation, independent, ratio = {}, {}, {}
    for change in compare_fits(*fits, TRUE_CHANGE):
        name = change.quantity
        alone = (1 + change.relative) * np.hypot(change.before_stderr / change.before,
                                                 change.after_stderr / change.after)
        error = change.relative - TRUE_CHANGE[name]
        deviation[name] = error / change.relative_stderr
        independent[name] = error / alone
        ratio[name] = change.relative_stderr / alone
    return ChangeReplicate(deviation, independent, ratio,
                           max(f.rms_error / f.noise_floor for f in fits))


def change_coverage(replicates: Iterable[ChangeReplicate]) -> dict[str, dict[str, float]]:
    """Per quantity: within 1 and 2 stderr and rms of error/stderr, for the comparison's ± and
    for the two fits taken as independent; the mean ratio of the two ±."""
    replicates = list(replicates)
    table = {}
    for name in TRUE_CHANGE:
        alone = np.array([r.independent[name] for r in replicates])
        table[name] = {
            **_within(np.array([r.deviation[name] for r in replicates])),
            "independent_rms": float(np.sqrt(np.mean(alone**2))),
            "stderr_ratio": float(np.mean([r.stderr_ratio[name] for r in replicates])),
            "rms_over_floor": float(np.mean([r.rms_over_floor for r in replicates])),
        }
    return table
