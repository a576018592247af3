"""A fast subset of the held-out study (``studies/diagnosis``): planted effects, clean runs and
several effects at once, measured in the time domain by the rig simulator at 1 % noise.

The cases come from ``studies/diagnosis/heldout.py``, which imports the simulator only; the
full study (every effect at four strengths on every channel, three kinds of noise, two levels,
50 clean runs per kind) is ``studies/diagnosis/detection_table.py``.
"""

from __future__ import annotations

import sys
from pathlib import Path

import pytest

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "studies" / "diagnosis"))

from detection_table import run_case
from heldout import TABLE, Case, measure

from viscorig.diagnosis import diagnose
from viscorig.fitting import FrfData


@pytest.mark.parametrize("noise", ["white", "correlated", "heavy"])
@pytest.mark.parametrize("seed", [101, 102])
def test_clean_runs_give_no_finding_and_sit_at_the_noise_floor(noise: str, seed: int) -> None:
    result = run_case(Case("clean", None, 0.0, noise, 0.01, seed))
    assert result["false"] == []
    assert result["at_noise_floor"]


@pytest.mark.parametrize(
    ("effect", "channel", "strength"),
    [
        ("delay", "x_v", 3e-5),
        ("delay", "F_e", 3e-5),
        ("lowpass", "x_s", 3e-5),
        ("highpass", "F_v", 0.3),
        ("gain", "F_e", 0.03),
        ("fixture", None, 3e-4),
        ("load_cell", None, 1e-2),
        ("modulus", None, 0.1),
    ],
)
def test_a_planted_effect_is_named_and_nothing_else(
    effect: str, channel: str | None, strength: float
) -> None:
    result = run_case(Case(effect, channel, strength, "white", 0.01, 7, fixture_hz=83.0))
    assert result["found"], result
    assert result["false"] == [], result


@pytest.mark.slow
@pytest.mark.parametrize(("effect", "strength"), [("amplitude", 0.1), ("drift", 0.03)])
def test_amplitude_and_drift_are_found_with_the_runs_that_separate_them(
    effect: str, strength: float
) -> None:
    result = run_case(Case(effect, None, strength, "white", 0.01, 3))
    assert result["found"] and result["false"] == [], result


@pytest.mark.slow
@pytest.mark.parametrize("noise", ["white", "correlated"])
def test_auto_with_three_planted_effects_ends_within_one_and_a_half_times_the_true_noise(
    noise: str,
) -> None:
    case = Case("fixture", None, 3e-4, noise, 0.01, 5, fixture_hz=58.0,
                extra_effects=(("delay", "x_v", 3e-5), ("load_cell", None, 1e-2)))
    runs = measure(case)
    run = runs[0]
    data = FrfData(run.frequency_hz, run.table, run.support, run.time_s,
                   run.reference_amplitude, name="run", variance_table=run.variance_table,
                   variance_support=run.variance_support)
    ladder = diagnose(data, "voigt", table=TABLE).auto()
    final = ladder[-1]
    assert final.rms_error <= 1.5 * run.true_noise
    terms = final.model.split("+")
    # nothing but what was planted; with white noise all of it (with the drift, the smaller
    # effects can hide in what the noise model takes for drift)
    assert all(t in ("voigt", "load_cell", "delay(x_v)") or t.startswith("fixture(5")
               for t in terms), final.model
    if noise == "white":
        assert {"load_cell", "delay(x_v)"} <= set(terms) and "fixture(5" in final.model


@pytest.mark.slow
@pytest.mark.parametrize(("noise", "level", "seed"), [("white", 0.003, 11), ("heavy", 0.01, 1)])
def test_a_paper_like_preset_diagnosed_from_its_own_model_has_nothing_missing(
    noise: str, level: float, seed: int
) -> None:
    """The second case's fit puts the 38 Hz mode broad (ζ ≈ 0.2) at the edge of its window: a
    window moved after it would let it wander off and leave a second mode to be found."""
    result = run_case(Case("clean", None, 0.0, noise, level, seed, base="hard-10"))
    assert result["false"] == [] and result["at_noise_floor"], result


def test_a_mode_placed_off_its_frequency_follows_the_data_out_of_its_window() -> None:
    """A mode started 7 % below the fixture's 58 Hz (its ±5 % window stops short of it) ends at
    58 Hz and at the noise floor, as a mode found on the misfit of a wrong model must."""
    case = Case("fixture", None, 3e-4, "white", 0.01, 7, fixture_hz=58.0)
    run = measure(case)[0]
    data = FrfData(run.frequency_hz, run.table, run.support, run.time_s,
                   run.reference_amplitude, name="run", variance_table=run.variance_table,
                   variance_support=run.variance_support)
    diagnosis = diagnose(data, "voigt+fixture(54)", table=TABLE)
    f_n = next(v for k, v in diagnosis.fit.values.items() if k.startswith("f_n"))
    assert f_n == pytest.approx(58.0, rel=0.005)
    assert "fixture(54)" not in diagnosis.model
    assert diagnosis.rms_error < 1.5 * run.true_noise
