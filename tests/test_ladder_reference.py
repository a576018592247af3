"""The diagnosis ladder gives the same answers as recorded (``tests/ladder_reference.py`` made
the record): the same rungs and findings, every final parameter within its standard error, so
that a change of the computation (vectorised Jacobians, warm starts, caching) cannot move them
unnoticed. And the record is right: every preset's ladder ends at the simulator's own rig, its
fractional rubber, load cell and three local modes, with the rubber's parameters and the disc's
mass within three standard errors of the values in the simulator's rig file (the static
stiffness within 0.25 %)."""

from __future__ import annotations

import json
import re

import numpy as np
import pytest
from ladder_reference import FIXTURE, PRESETS, TABLE, climb, frequencies, measured_run, shape
from rigsim.rigfile import load_preset

RECORD = json.loads(FIXTURE.read_text())
BY_RUN = {run["run"]: run for run in RECORD["runs"]}
#: A fixture's frequency in a spec is its fitted value rounded to 0.01 Hz.
FREQUENCY_TOLERANCE = 0.002


def by_relaxation_time(final: dict) -> dict:
    """The final parameters with a Maxwell K*'s arms numbered by increasing ``τ = C/K``: the
    model is the same whichever arm is called 1, so only their order tells fits apart."""
    arms = sorted(int(name[2:]) for name in final if re.fullmatch(r"K_[1-9][0-9]*", name))
    if not all(f"C_{i}" in final for i in arms):
        return final
    order = sorted(arms, key=lambda i: final[f"C_{i}"]["value"] / final[f"K_{i}"]["value"])
    out = dict(final)
    for new, old in zip(arms, order, strict=True):
        out[f"K_{new}"], out[f"C_{new}"] = final[f"K_{old}"], final[f"C_{old}"]
    return out


def assert_same_ladder(before: dict, after: dict) -> None:
    models_before = [rung["model"] for rung in before["rungs"]]
    models_after = [rung["model"] for rung in after["rungs"]]
    assert [shape(m) for m in models_after] == [shape(m) for m in models_before]
    for old, new in zip(models_before, models_after, strict=True):
        np.testing.assert_allclose(frequencies(new), frequencies(old),
                                   rtol=FREQUENCY_TOLERANCE)
    for old, new in zip(before["rungs"], after["rungs"], strict=True):
        assert new["rms_over_floor"] == pytest.approx(old["rms_over_floor"], rel=0.02)
    assert [shape(f["term"]) for f in after["first_findings"]] == [
        shape(f["term"]) for f in before["first_findings"]]
    assert [f["effect"] for f in after["first_findings"]] == [
        f["effect"] for f in before["first_findings"]]
    assert set(after["final"]) == set(before["final"])
    final_before, final_after = by_relaxation_time(before["final"]), by_relaxation_time(
        after["final"])
    for name, old in final_before.items():
        new = final_after[name]
        assert abs(new["value"] - old["value"]) <= old["stderr"], name
        assert new["stderr"] == pytest.approx(old["stderr"], rel=0.25), name


def test_reference_covers_every_specimen_preset():
    assert sorted(BY_RUN) == sorted(PRESETS)
    assert all(len(run["rungs"]) >= 2 for run in RECORD["runs"] if run["run"] != "soft-0")


def test_first_diagnosis_of_hard_10_as_recorded():
    from viscorig.diagnosis import diagnose

    with np.errstate(all="ignore"):
        first = diagnose(measured_run("hard-10"), "voigt", table=TABLE)
    before = BY_RUN["hard-10"]
    assert first.model == before["rungs"][0]["model"]
    assert first.rms_error / first.noise_floor == pytest.approx(
        before["rungs"][0]["rms_over_floor"], rel=0.02)
    assert [(f.effect, shape(f.term)) for f in first.significant] == [
        (f["effect"], shape(f["term"])) for f in before["first_findings"]]


#: The simulator's rig file (``sim/rigs/PRESET.toml``, ``[device]``) -> the identified name.
TRUTH_NAMES = {"high_stiffness_n_per_m": "K_inf", "tau_s": "tau", "alpha": "alpha",
               "mass_kg": "M_v"}
#: The static stiffness comes out 0.08 to 0.17 % high on every preset (1.4 standard errors on
#: the soft rubber, 8 on the hard one, whose ± is the smallest): the rig files' frame (2,000 kg
#: on 3 Hz isolators) stiffens the disc's support by about ``K*²/(M_f ω²)`` at the band's low
#: end, below what the tests find at this noise (:func:`test_static_stiffness_bias_is_the_frame`).
STATIC_STIFFNESS_BIAS = 0.0025
#: The simulator's local modes (``[[fixture]]``), Hz.
MODES_HZ = (38.0, 58.0, 92.0)


def assert_the_simulators_rig(preset: str, final: dict, spec: str) -> None:
    device = load_preset(preset).device
    assert shape(spec) == "fractional+load_cell+fixture()+fixture()+fixture()", spec
    for field, name in TRUTH_NAMES.items():
        truth = getattr(device if field == "mass_kg" else device.material, field)
        assert abs(final[name]["value"] - truth) <= 3 * final[name]["stderr"], (name, truth)
    static = device.material.static_stiffness_n_per_m
    assert final["K_0"]["value"] == pytest.approx(static, rel=STATIC_STIFFNESS_BIAS)
    modes = sorted(final[n]["value"] for n in final if n.startswith("f_n"))
    np.testing.assert_allclose(modes, MODES_HZ, rtol=1e-3)


@pytest.mark.slow
@pytest.mark.parametrize("preset", PRESETS)
def test_ladder_as_recorded(preset):
    climbed = climb(preset)
    assert_same_ladder(BY_RUN[preset], climbed)
    assert_the_simulators_rig(preset, climbed["final"], climbed["rungs"][-1]["model"])


@pytest.mark.parametrize("preset", PRESETS)
def test_the_record_is_the_simulators_rig(preset):
    run = BY_RUN[preset]
    assert_the_simulators_rig(preset, run["final"], run["rungs"][-1]["model"])


@pytest.mark.slow
def test_removal_fits_cut_short_keep_only_terms_that_pay():
    """The backward step stops a removal fit after its first pass when the term still costs
    many times its threshold; finished, every such fit still finds the term paying. soft-10's
    final model is the case: without one of its modes, the Maxwell arms wander for 200 steps.
    A mode put in by hand where there is none is still taken out."""
    from viscorig.diagnosis import diagnose
    from viscorig.diagnosis.findings import (
        CLEARLY_PAID,
        _first_pass,
        carried_values,
        term_threshold,
        unpaid_term,
    )
    from viscorig.diagnosis.significance import alpha_of, dispersion
    from viscorig.diagnosis.weighted import ml_fit
    from viscorig.models import parse_spec

    final = BY_RUN["soft-10"]["rungs"][-1]["model"]
    with np.errstate(all="ignore"):
        diagnosis = diagnose(measured_run("soft-10"), final, table=TABLE)
        current, data = diagnosis.likelihood, diagnosis.data
        phi = dispersion(current.chi2, data.residual_count, len(current.free))
        alpha = alpha_of(current.model, data)
        cut_short = 0
        for term in current.model.effects:
            reduced = parse_spec("+".join(t.spec for t in current.model.terms if t is not term))
            start = {**reduced.defaults(), **carried_values(current, reduced)}
            need = phi * term_threshold(term, diagnosis.scan.threshold, alpha)
            quick = (_first_pass(reduced, data, start).chi2 - current.chi2) / need
            full = (ml_fit(reduced, data, start).chi2 - current.chi2) / need
            assert full <= quick * (1 + 1e-9), term.spec
            if quick >= CLEARLY_PAID:
                cut_short += 1
                assert full >= 1.0, term.spec
        assert cut_short >= 3
        assert unpaid_term(current, data, diagnosis.scan.threshold) is None
        padded = diagnose(measured_run("soft-10"), f"{final}+fixture(75)", table=TABLE)
        found = unpaid_term(padded.likelihood, padded.data, padded.scan.threshold)
    assert found is not None and found[0] == "fixture(75)"


def test_arms_compared_by_relaxation_time_whatever_their_numbers():
    fast = {"value": 1e5, "stderr": 1.0}, {"value": 10.0, "stderr": 0.1}
    slow = {"value": 2e4, "stderr": 2.0}, {"value": 200.0, "stderr": 0.2}
    one = {"K_0": {"value": 1.0, "stderr": 0.0}, "K_1": fast[0], "C_1": fast[1],
           "K_2": slow[0], "C_2": slow[1]}
    other = {**one, "K_1": slow[0], "C_1": slow[1], "K_2": fast[0], "C_2": fast[1]}
    assert by_relaxation_time(other) == by_relaxation_time(one) == one
    assert by_relaxation_time({"K_v": fast[0], "C_v": fast[1]}) == {"K_v": fast[0],
                                                                     "C_v": fast[1]}


@pytest.mark.slow
def test_static_stiffness_bias_is_the_frame():
    """The same run of hard-0 without its frame gives the static stiffness within its standard
    error; with it, many standard errors high (the final model has no frame term)."""
    import dataclasses

    from ladder_reference import measured_run

    from viscorig.diagnosis.data import combine
    from viscorig.diagnosis.weighted import ml_fit
    from viscorig.models import parse_spec

    rig = load_preset("hard-0")
    material = rig.device.material
    model = parse_spec("fractional+load_cell+fixture(38)+fixture(58)+fixture(92)")
    start = {**model.defaults(), "K_0": material.static_stiffness_n_per_m,
             "K_inf": material.high_stiffness_n_per_m, "tau": material.tau_s,
             "alpha": material.alpha, "M_v": rig.device.mass_kg, "K_c": 1e7}
    off = {}
    for label, variant in (("frame", rig), ("no frame", dataclasses.replace(rig, frame=None))):
        data = combine([("hard-0", measured_run("hard-0", rig=variant))], table=TABLE)
        fitted = ml_fit(model, data, start)
        off[label] = ((fitted.values["K_0"] - material.static_stiffness_n_per_m)
                      / fitted.stderr()["K_0"])
    assert abs(off["no frame"]) < 2.0 and off["frame"] > 4.0, off
