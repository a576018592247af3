"""Diagnosis on runs the time-domain simulator measured with a hidden effect planted in the rig.

Nothing here evaluates the core's model functions to make data: every run comes from
``rigsim`` (time-domain integration and correlation, like the analyser), so a diagnosis that
names the planted effect has found it in data it did not make.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import time
from datetime import UTC, datetime, timedelta
from pathlib import Path

import h5py
import numpy as np
import pytest
from rigsim.engine import RigSimulator
from rigsim.rigfile import parse_rig
from simdata import DEFAULT_NOISE, SimulatedRun, rig_text, simulate_run

from viscorig.cli import main
from viscorig.cli.diagnose import LADDER_HEADING, format_diagnosis
from viscorig.diagnosis import DiagnosisResult, diagnose, diagnose_run
from viscorig.diagnosis import findings as findings_module
from viscorig.diagnosis.findings import fit_term
from viscorig.diagnosis.scan import Residual, _grid, log_sensitivity, mode_stiffness
from viscorig.diagnosis.screening import screen
from viscorig.diagnosis.significance import alpha_of, judge, threshold
from viscorig.errors import InputError
from viscorig.models import EFFECTS
from viscorig.storage import CampaignFile, RunSettings, Segment

TABLE = {"M_s": 3.4, "K_s": 50194.0, "C_s": 5.05}
RIG_ATTRIBUTES = {
    "table_mass_kg": 3.4, "table_stiffness_n_per_m": 50194.0, "table_damping_ns_per_m": 5.05,
}
VOIGT = {"mass_kg": 0.25, "model": "voigt", "stiffness_n_per_m": 1.5e5, "damping_ns_per_m": 114.59}
FRACTIONAL = {
    "mass_kg": 0.25, "model": "fractional", "static_stiffness_n_per_m": 1.2e5,
    "high_stiffness_n_per_m": 4.0e5, "tau_s": 1 / (2 * np.pi * 300.0), "alpha": 0.5,
}
#: Sensor noise of the paper presets: relative FRF scatter of about 1e-4 to 1e-3.
QUIET = {key: value / 10 for key, value in DEFAULT_NOISE.items()}
FIXTURE_58 = {"frequency_hz": 58.0, "damping_ratio": 0.02, "mass_kg": 0.003}
DELAY = "[delays]\ntable_acceleration_s = 5e-5\ndisc_acceleration_s = 5e-5\n"
DRIFT = "[drift]\nmodulus_change_per_hour = -0.05\n"
AMPLITUDE = (
    "[amplitude]\nsoftening_fraction = 0.1\nreference_displacement_m = 2e-5\nexponent = 0.3\n"
)


def single(rig: str, seed: int = 3, step_hz: float = 0.5) -> DiagnosisResult:
    run = simulate_run(rig, seed=seed, step_hz=step_hz)
    return diagnose(run.frf_data("run"), "voigt", table=TABLE)


def top(diagnosis: DiagnosisResult) -> str:
    assert diagnosis.significant, "no significant finding"
    return diagnosis.significant[0].effect


def assert_at_floor_after(diagnosis: DiagnosisResult) -> DiagnosisResult:
    better = diagnosis.with_effect(diagnosis.significant[0])
    assert better.rms_error < diagnosis.rms_error / 3
    assert better.rms_error <= 1.5 * better.noise_floor
    return better


@pytest.mark.parametrize("seed", [11, 12, 13])
def test_clean_data_has_no_significant_finding_and_sits_at_the_noise_floor(seed: int) -> None:
    diagnosis = single(rig_text(VOIGT, noise=QUIET), seed=seed)
    assert diagnosis.at_noise_floor
    assert diagnosis.findings, "every candidate is fitted and reported"
    assert not diagnosis.significant
    assert diagnosis.auto() == [diagnosis]
    assert all("No clear sign" in finding.explanation for finding in diagnosis.findings)


def test_candidates_are_finished_only_where_one_may_pass(monkeypatch) -> None:
    """A candidate's first fit is carried on only where it may decide something: on clean data
    none comes near its threshold and none is finished; with a load cell some are."""
    finished: list[str] = []
    original = findings_module._finish

    def counted(first, data):
        finished.append(first.spec)
        return original(first, data)

    monkeypatch.setattr(findings_module, "_finish", counted)
    clean = single(rig_text(VOIGT, noise=QUIET), seed=11)
    assert clean.findings and not clean.significant
    assert all(f.delta_chi2 < 0.5 * f.threshold * f.dispersion for f in clean.findings)
    assert finished == []
    loaded = single(rig_text(VOIGT, noise=QUIET, load_cell_n_per_m=2.0e6))
    assert top(loaded) == "load_cell_compliance"
    assert any(spec.startswith("voigt+load_cell") for spec in finished)


@pytest.mark.slow
def test_fixture_mode_is_found_within_a_hertz() -> None:
    diagnosis = single(rig_text(VOIGT, noise=QUIET, fixtures=[FIXTURE_58]), step_hz=0.25)
    assert top(diagnosis) == "fixture_resonance"
    finding = diagnosis.significant[0]
    f_n = finding.parameters()["f_n"]["value"]
    assert abs(f_n - 58.0) < 1.0
    assert finding.model.startswith("voigt+fixture(5")
    assert any("narrow peak" in band.what and band.band_hz[0] <= 58 <= band.band_hz[1]
               for band in diagnosis.failures)  # fmt: skip
    assert_at_floor_after(diagnosis)


def test_a_mode_asked_for_far_above_the_band_is_diagnosed_not_refused(tmp_path) -> None:
    """A mode at 100 kHz (a spec identify fits) stops at the top of its window on the hard
    rubber; moving the window there built fixture(105000), past what a spec holds: 'fixture(F)
    needs a frequency in Hz, got 105000.0' from a spec the user never wrote."""
    from campaigndata import paper_campaign

    from viscorig.diagnosis import diagnose_run

    path = paper_campaign(tmp_path / "c.h5", runs=("table", "hard-10"))
    diagnosis = diagnose_run(CampaignFile.open(path), "hard-10", "voigt+fixture(1e5)")
    assert "fixture(100000)" in diagnosis.model  # its window left where it is


def test_load_cell_compliance_is_found_from_eq4_against_eq5() -> None:
    diagnosis = single(rig_text(VOIGT, noise=QUIET, load_cell_n_per_m=2.0e6))
    assert top(diagnosis) == "load_cell_compliance"
    k_c = diagnosis.significant[0].parameters()["K_c"]["value"]
    assert k_c == pytest.approx(2.0e6, rel=0.05)
    assert "Eq. 4" in diagnosis.significant[0].explanation
    assert_at_floor_after(diagnosis)


def test_sensor_delay_is_found_from_a_linear_phase_error() -> None:
    diagnosis = single(rig_text(VOIGT, noise=QUIET, extra=DELAY))
    assert top(diagnosis) == "sensor_delay"
    assert diagnosis.significant[0].parameters()["tau_d"]["value"] == pytest.approx(5e-5, rel=0.05)
    assert any("phase trend" in band.what for band in diagnosis.failures)
    assert_at_floor_after(diagnosis)


@pytest.mark.parametrize(
    ("lines", "term", "name", "value", "words"),
    [
        ("[delays]\ndisc_acceleration_s = 3.5e-5\n", "delay(x_v)", "tau_x_v", 3.5e-5,
         "disc accelerometer (ẍ_v) lags the device load cell (F_v) by 3"),
        ("[delays]\ndevice_force_s = 2e-5\n", "delay(F_v)", "tau_F_v", 2e-5,
         "device load cell (F_v) lags the disc accelerometer (ẍ_v) by "),
        ("[sensors.excitation_force]\nhighpass_hz = 0.5\n", "highpass(F_e)", "f_hp_F_e", 0.5,
         "excitation force transducer (F_e) is high-pass filtered with a corner at 0."),
        ("[sensors.device_force]\ngain = 1.02\n", "gain(x_v)", "gain_x_v", 1 / 1.02,
         "disc accelerometer (ẍ_v) reads 1.9"),
    ],
)
def test_a_sensor_effect_is_named_with_its_channel_and_its_value(
    lines: str, term: str, name: str, value: float, words: str
) -> None:
    diagnosis = single(rig_text(VOIGT, noise=QUIET, extra=lines))
    best = diagnosis.significant[0]
    assert best.term == term and best.model == f"voigt+{term}"
    estimate = best.parameters()[name]
    assert estimate["value"] == pytest.approx(value, abs=4 * estimate["stderr"])
    assert words in best.explanation and " ± " in best.explanation
    assert len(diagnosis.significant) == 1
    assert_at_floor_after(diagnosis)


def test_a_gain_below_what_a_calibration_resolves_is_not_sent_to_the_sensors() -> None:
    """A gain of 0.05 % is significant on quiet data, but no calibration resolves it. The
    advice to check both sensitivities sent a technician after 38 ppm on a campaign swept from
    15 Hz on a rig standing on a frame (none on the same campaign without the frame)."""
    gain = "[sensors.device_force]\ngain = 1.0005\n"
    diagnosis = single(rig_text(VOIGT, noise=QUIET, extra=gain))
    best = diagnosis.significant[0]
    assert best.term == "gain(x_v)"
    estimate = best.parameters()["gain_x_v"]
    assert estimate["value"] == pytest.approx(1 / 1.0005, abs=4 * estimate["stderr"])
    assert "below what any transducer calibration resolves" in best.explanation
    assert "Check both sensitivities" not in best.explanation


#: What screening proposes at most one term of: both FRFs' delay, each FRF's delay, high-pass
#: and gain (the channel named by the sign of its linear estimate), amplitude and drift.
SCREENED_FAMILIES = (
    ("delay",), ("delay(x_s)", "delay(F_e)"), ("highpass(x_s)", "highpass(F_e)"),
    ("gain(x_s)",), ("delay(x_v)", "delay(F_v)"), ("highpass(x_v)", "highpass(F_v)"),
    ("gain(x_v)",), ("amplitude",), ("drift",),
)


@pytest.mark.parametrize("extra", ["", "[delays]\ndisc_acceleration_s = 3.5e-5\n"])
def test_a_term_screening_leaves_out_far_from_the_noise_could_not_have_passed(
    extra: str,
) -> None:
    """Voigt on a fractional rubber misfits the data thousands of times the noise, and every
    term soaks up some of that: screening counts a term's linear Δχ² in units of that misfit,
    as the test after a fit does. Each term of a family it leaves out is fitted here anyway,
    and fails its test."""
    diagnosis = single(rig_text(FRACTIONAL, noise=QUIET, extra=extra))
    current, data = diagnosis.likelihood, diagnosis.data
    assert current.chi2 > 100 * data.residual_count
    proposed = {term for candidate in screen(current, data, Residual(current, data))
                for term in (candidate.term, *candidate.alternatives)}
    left_out = [term for family in SCREENED_FAMILIES if not proposed & set(family)
                for term in family]
    assert left_out and "delay(x_v)" in proposed
    alpha = alpha_of(current.model, data)
    for term in left_out:
        needed = threshold(1, alpha / 2 if term.startswith("delay(") else alpha)
        judgement = judge(current, fit_term(current, data, term, {}), needed, data, term)
        assert not judgement.passes and judgement.shortfall, term


def test_a_family_of_templates_measures_what_its_projected_templates_do() -> None:
    """The scan measures a family of mode templates through inner products, never forming the
    projected templates: norms, the residual's components and the arc length must be those of
    the templates themselves, projected and normalised one by one; a zero template is left
    out of the length."""
    diagnosis = single(rig_text(VOIGT, noise=QUIET, fixtures=[FIXTURE_58]))
    current, data = diagnosis.likelihood, diagnosis.data
    residual = Residual(current, data)
    omega = 2 * np.pi * data.data.frequency_hz
    sensitivity = log_sensitivity(current.model, current.values, data)
    u = mode_stiffness(omega, np.geomspace(30.0, 90.0, 40), 0.02)
    u[:, 17] = 0.0  # removed: its neighbours are then joined across it
    change = {frf: sensitivity[frf][:, None] * u for frf in data.frfs}
    family = residual.family(change)
    t = residual.template(change)
    norm = np.linalg.norm(t, axis=0)
    assert not family.ok[17] and family.ok.sum() == 39
    kept = family.ok
    np.testing.assert_allclose(family.norm[kept], norm[kept], rtol=1e-9)
    np.testing.assert_allclose(family.along_e, residual.e @ t, rtol=1e-8,
                               atol=1e-10 * np.linalg.norm(residual.e) * norm.max())
    np.testing.assert_allclose(family.along_clipped, residual.clipped @ t, rtol=1e-8,
                               atol=1e-10 * np.linalg.norm(residual.clipped) * norm.max())
    unit = t[:, kept] / norm[kept]
    length = float(np.sum(np.linalg.norm(np.diff(unit, axis=1), axis=0)))
    assert family.length == pytest.approx(length, rel=1e-9)
    assert family.length > 10 * np.linalg.norm(unit[:, 1] - unit[:, 0])


def test_the_scan_forms_its_templates_from_shared_columns_as_from_each_frf_s_own() -> None:
    """The scan's templates, one vector per FRF times columns every FRF shares, formed part by
    part in the whitening's layout: the same families as the complex changes of each FRF, an
    outlier point left out and an FRF missing from the change counted as unchanged; and the
    mode's stiffness is ``−ω² s/(s − ω²)``, ``s = ω_n² + 2iζω_nω``."""
    diagnosis = single(rig_text(VOIGT, noise=QUIET, fixtures=[FIXTURE_58]))
    current, data = diagnosis.likelihood, diagnosis.data
    kept = {frf: ~mask for frf, mask in data.outliers.items()}
    kept["table"][[3, 200]] = False
    object.__setattr__(data, "_kept", kept)  # two outlier points, on both paths
    data.__dict__.pop("_left_out_rows", None)  # (and the rows derived from them)
    spiked = {frf: r.copy() for frf, r in current.residuals.items()}
    spiked["table"][3] += 1e3  # an outlier point counts as zero, whatever it holds
    np.testing.assert_array_equal(data.whiten(spiked), data.whiten(current.residuals))
    residual = Residual(current, data)
    omega = 2 * np.pi * data.data.frequency_hz
    f_n = np.geomspace(25.0, 110.0, 30)
    zeta = np.repeat([0.01, 0.05], 15)
    u = mode_stiffness(omega, f_n, zeta)
    w, w_n = omega[:, None], 2 * np.pi * f_n[None, :]
    s = w_n**2 + 2j * zeta[None, :] * w_n * w
    np.testing.assert_allclose(u, -(w**2) * s / (s - w**2), rtol=1e-12)
    sensitivity = log_sensitivity(current.model, current.values, data)
    for along in (sensitivity, {"support": sensitivity["support"]}):
        shared = residual.families(along, [10, 20], shared=u)
        alone = residual.families({frf: along[frf][:, None] * u for frf in along}, [10, 20])
        for a, b in zip(shared, alone, strict=True):
            np.testing.assert_array_equal(a.ok, b.ok)
            for name in ("norm", "along_e", "along_clipped"):
                np.testing.assert_allclose(getattr(a, name), getattr(b, name), rtol=1e-9,
                                           atol=1e-12 * np.abs(getattr(b, name)).max())
            assert a.length == pytest.approx(b.length, rel=1e-9)


def test_the_scan_s_templates_follow_the_frequencies_they_are_asked_for() -> None:
    """The grid and templates kept from the last scan serve the same frequencies only: other
    frequencies get their own, as formed afresh, and the kept templates cannot be written to."""
    first, second = np.arange(10.0, 100.0, 0.25), np.arange(12.0, 80.0, 0.5)
    for f in (first, second, first):
        grid, u = _grid(f)
        assert all(f_n.min() > f.min() and f_n.max() < f.max() for _, f_n in grid)
        f_n = np.concatenate([f_n for _, f_n in grid])
        zeta = np.concatenate([np.full(f_n.size, z) for z, f_n in grid])
        np.testing.assert_array_equal(u, mode_stiffness(2 * np.pi * f, f_n, zeta))
        assert _grid(f)[1] is u
        with pytest.raises(ValueError):
            u[0, 0] = 0.0


def test_the_support_frf_alone_is_diagnosed_without_the_table() -> None:
    """Without the table's values only ẍ_v/F_v can be diagnosed (``--frf support``): the
    candidates' likelihoods, a local mode renamed by its fitted frequency included, are
    evaluated on that FRF alone, though the model predicts both."""
    run = simulate_run(rig_text(VOIGT, noise=QUIET, fixtures=[FIXTURE_58]), seed=3, step_hz=0.5)
    diagnosis = diagnose(run.frf_data("run"), "voigt", frfs=["support"])
    assert diagnosis.fit.frfs == ("support",)
    modes = [f for f in diagnosis.findings if f.effect == "fixture_resonance"]
    assert modes and all(f.likelihood.whitened.size == 2 * run.frf_data("run").frequency_hz.size
                         for f in modes)
    assert any(f.significant and 55.0 < float(f.term[8:-1]) < 61.0 for f in modes)


def test_an_anti_alias_filter_reads_as_a_lag_of_its_channel() -> None:
    lag = 3e-5
    lines = f"[sensors.table_acceleration]\nlowpass_hz = {1 / (2 * np.pi * lag)}\n"
    diagnosis = single(rig_text(VOIGT, noise=QUIET, extra=lines))
    best = diagnosis.significant[0]
    assert best.effect == "sensor_delay" and best.term in ("delay(x_s)", "lowpass(x_s)")
    assert "table accelerometer" in best.explanation
    assert_at_floor_after(diagnosis)


@pytest.mark.slow
def test_an_effect_that_does_not_pay_in_the_final_model_is_taken_out() -> None:
    """Backward elimination: on clean data a local mode put in by hand does not pay for itself,
    the planted one does."""
    run = simulate_run(rig_text(VOIGT, noise=QUIET, fixtures=[FIXTURE_58]), seed=3, step_hz=0.5)
    diagnosis = diagnose(run.frf_data("run"), "voigt+fixture(58)+fixture(83)", table=TABLE)
    lighter = diagnosis.without_unpaid()
    assert lighter is not None and lighter.model == "voigt+fixture(58)"
    assert lighter.without_unpaid() is None


def test_soft_0_without_drift_or_amplitude_dependence_reports_neither() -> None:
    """The paper's soft-0 (fractional rubber, load cell, three local modes) from Voigt."""
    run = simulate_run("soft-0", seed=2, level_m_per_s2=1.4, step_hz=0.5)
    diagnosis = diagnose(run.frf_data("soft-0"), "voigt", table=TABLE)
    effects = {finding.effect for finding in diagnosis.significant}
    assert "frequency_dependent_modulus" in effects
    assert not effects & {"thermal_drift", "amplitude_dependence"}
    drift = next(f for f in diagnosis.findings if f.effect == "thermal_drift")
    assert not drift.significant and "No clear sign" in drift.explanation


def test_frequency_dependent_modulus_replaces_voigt() -> None:
    diagnosis = single(rig_text(FRACTIONAL, noise=QUIET))
    assert top(diagnosis) == "frequency_dependent_modulus"
    assert not diagnosis.significant[0].model.startswith("voigt")
    assert_at_floor_after(diagnosis)


def test_a_finding_that_does_not_pass_says_which_part_of_its_test_it_fails() -> None:
    """Far from the noise every test counts ``Δχ²`` in units of the misfit ``φ`` the model with
    the effect leaves: a candidate whose raw ``Δχ²`` is in the hundreds of thousands may still
    be within that misfit, or remove too little of it. What the text says matches the numbers
    the JSON carries (``delta_chi2 / dispersion`` against ``threshold``)."""
    diagnosis = single(rig_text(FRACTIONAL, noise=QUIET, fixtures=[FIXTURE_58]))
    said = format_diagnosis(diagnosis, "c.h5")
    for finding in diagnosis.findings:
        per_misfit = finding.delta_chi2 / finding.dispersion
        assert f"Δχ²/φ {per_misfit:.4g} (needs {finding.threshold:.3g})" in said
        document = finding.to_json()
        assert document["delta_chi2"] / document["dispersion"] == pytest.approx(per_misfit)
        if finding.significant:
            continue
        text = finding.explanation
        if finding.passes_alone:  # it failed next to the effect found before it
            assert "next to fractional it no longer pays for itself" in text
            continue
        if per_misfit <= finding.threshold:
            assert f"(Δχ²/φ {per_misfit:.1f}, needs {finding.threshold:.1f})" in text, text
        else:
            assert "within what" not in text and "of the χ² beyond the noise" in text, text
    assert any(not f.passes_alone and f.delta_chi2 / f.dispersion > f.threshold
               for f in diagnosis.findings)  # the case a raw Δχ² read wrongly


def add_run(
    campaign: CampaignFile, name: str, run: SimulatedRun, level: float, direction: str = "up"
) -> None:
    settings = RunSettings(
        specimen="soft", level_m_per_s2=level, direction=direction, settle_cycles=100,
        integrate_cycles=100, resolution_hz=0.5, hardness_shore_a=25.0, simulated=True,
    )
    campaign.start_run(name, settings)
    campaign.append_segment(name, Segment(
        run.frequency_hz, run.time_s, run.accelerance_table, run.accelerance_support,
        run.reference_amplitude, np.ones_like(run.time_s), run.force_amplitude, run.flags,
    ))  # fmt: skip
    campaign.finish_run(name)


def write_campaign(path: Path, runs: list[tuple[str, SimulatedRun, float, str, float]]) -> Path:
    """Runs ``(name, run, level, direction, start_s)``; ``started`` stamps follow ``start_s``."""
    with CampaignFile.create(path, sequence_text="", rig=RIG_ATTRIBUTES, durable=False) as campaign:
        for name, run, level, direction, _ in runs:
            add_run(campaign, name, run, level, direction)
    origin = datetime(2026, 1, 5, 9, 0, tzinfo=UTC)
    with h5py.File(path, "a") as h5:
        for name, _, _, _, start_s in runs:
            h5[f"runs/{name}"].attrs["started"] = (origin + timedelta(seconds=start_s)).isoformat()
    return path


def on_run_clock(run: SimulatedRun, start_s: float) -> SimulatedRun:
    run.time_s = run.time_s - start_s
    return run


@pytest.mark.slow
def test_amplitude_dependence_is_found_with_two_levels(tmp_path: Path) -> None:
    rig = rig_text(VOIGT, noise=QUIET, extra=AMPLITUDE)
    low = simulate_run(rig, seed=3, step_hz=0.5, level_m_per_s2=1.0)
    high = simulate_run(rig, seed=4, step_hz=0.5, level_m_per_s2=3.0)
    path = write_campaign(tmp_path / "c.h5", [
        ("soft-0", low, 1.0, "up", 0.0), ("soft-0-level2", high, 3.0, "up", 3600.0),
    ])  # fmt: skip
    with CampaignFile.open(path) as campaign:
        diagnosis = diagnose_run(campaign, "soft-0")
    assert diagnosis.data.runs == ("soft-0", "soft-0-level2")
    assert top(diagnosis) == "amplitude_dependence"
    assert not diagnosis.significant[0].alternatives
    assert_at_floor_after(diagnosis)


def test_one_level_cannot_separate_amplitude_and_says_which_run_would() -> None:
    diagnosis = single(rig_text(VOIGT, noise=QUIET, extra=AMPLITUDE))
    best = diagnosis.significant[0]
    assert best.effect in ("amplitude_dependence", "thermal_drift")
    assert best.alternatives
    assert any('run = "run-level2"' in text for text in diagnosis.advice)


def test_thermal_drift_is_found_with_an_up_and_a_down_sweep(tmp_path: Path) -> None:
    rig = parse_rig(rig_text(VOIGT, noise=QUIET, extra=DRIFT), "drift rig")
    simulator = RigSimulator(rig, seed=5)  # one specimen, one clock: the down sweep follows
    up = simulate_run(rig, step_hz=0.5, simulator=simulator)
    start_down = float(simulator.clock_s)
    down = on_run_clock(simulate_run(rig, step_hz=0.5, simulator=simulator, direction="down"),
                        start_down)  # fmt: skip
    path = write_campaign(tmp_path / "c.h5", [
        ("soft-0", up, 1.0, "up", 0.0), ("soft-0-down", down, 1.0, "down", start_down),
    ])  # fmt: skip
    with CampaignFile.open(path) as campaign:
        diagnosis = diagnose_run(campaign, "soft-0")
    assert diagnosis.data.directions == ("up", "down")
    assert top(diagnosis) == "thermal_drift"
    kappa = diagnosis.significant[0].parameters()["kappa"]["value"]
    assert kappa * 3600 == pytest.approx(-0.05, rel=0.1)
    assert_at_floor_after(diagnosis)


def test_a_damaged_run_of_another_specimen_does_not_stop_the_diagnosis(tmp_path: Path) -> None:
    """Companions are picked by their attributes first: another specimen's run is not read."""
    run = simulate_run(rig_text(VOIGT, noise=QUIET), seed=6, step_hz=0.5)
    path = write_campaign(tmp_path / "c.h5", [
        ("soft-0", run, 1.0, "up", 0.0), ("hard-0", run, 1.0, "up", 3600.0),
    ])  # fmt: skip
    with h5py.File(path, "a") as h5:
        h5["runs/hard-0"].attrs["specimen"] = "hard"
        del h5["runs/hard-0/accelerance_support"]
    with CampaignFile.open(path) as campaign:
        with pytest.raises(InputError):
            campaign.run("hard-0")
        assert campaign.run_metadata("hard-0").specimen == "hard"
        diagnosis = diagnose_run(campaign, "soft-0")
    assert diagnosis.data.runs == ("soft-0",)


@pytest.mark.slow
def test_auto_finds_both_of_two_planted_effects() -> None:
    rig = rig_text(VOIGT, noise=QUIET, fixtures=[FIXTURE_58], extra=DELAY)
    ladder = single(rig, step_hz=0.25).auto()
    final = ladder[-1]
    assert "delay" in final.model and "fixture(5" in final.model
    assert final.at_noise_floor
    errors = [step.rms_error for step in ladder]
    assert errors == sorted(errors, reverse=True) and len(ladder) in (2, 3)
    assert len(final.model.split("+")) == 3  # voigt and the two planted effects, nothing else


@pytest.fixture(scope="module")
def fixture_campaign(tmp_path_factory: pytest.TempPathFactory) -> Path:
    run = simulate_run(rig_text(VOIGT, noise=QUIET, fixtures=[FIXTURE_58]), seed=3, step_hz=0.25)
    path = tmp_path_factory.mktemp("diagnose") / "c.h5"
    return write_campaign(path, [("soft-0", run, 1.0, "up", 0.0)])


@pytest.mark.slow
def test_diagnose_json_follows_the_design(
    fixture_campaign: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    assert main(["diagnose", str(fixture_campaign), "--run", "soft-0", "--auto", "--json"]) == 0
    document = json.loads(capsys.readouterr().out)
    for key, kind in {"run": str, "model": str, "rms_error": float, "noise_floor": float,
                      "at_noise_floor": bool, "failures": list, "findings": list,
                      "ladder": list}.items():  # fmt: skip
        assert isinstance(document[key], kind), key
    assert document["run"] == "soft-0" and document["model"] == "voigt"
    # what the thresholds rest on
    assert document["noise"] and all(isinstance(line, str) for line in document["noise"])
    assert document["scan"]["threshold_delta_chi2"] > 10.8
    assert isinstance(document["outlier_points"], int)
    for band in document["failures"]:
        assert set(band) >= {"band_hz", "frf", "what"} and len(band["band_hz"]) == 2
    vocabulary = set(EFFECTS)
    for finding in document["findings"]:
        assert set(finding) >= {"effect", "model", "rms_error", "delta_bic", "significant",
                                "explanation", "parameters"}  # fmt: skip
        assert finding["effect"] in vocabulary
    marks = [finding["significant"] for finding in document["findings"]]
    assert marks == sorted(marks, reverse=True)  # the significant ones first
    rest = [finding["delta_bic"] for finding in document["findings"] if not finding["significant"]]
    assert rest == sorted(rest)
    best = document["findings"][0]
    assert best["effect"] == "fixture_resonance" and best["significant"]
    assert best["delta_chi2"] > best["threshold"] >= document["scan"]["threshold_delta_chi2"]
    assert document["ladder"][0]["model"] == "voigt"
    assert document["ladder"][-1]["rms_error"] < document["ladder"][0]["rms_error"] / 3
    # the finding's model is accepted by identify as is, and weighted as the diagnosis weighs
    # its fits, gives the rms error the diagnosis reported
    assert main(["identify", str(fixture_campaign), "--run", "soft-0", "--model", best["model"],
                 "--weights", "uniform", "--no-store", "--json"]) == 0  # fmt: skip
    fitted = json.loads(capsys.readouterr().out)
    assert fitted["rms_error"] == pytest.approx(best["rms_error"], rel=1e-3)


def test_diagnose_text_names_the_effect_and_the_next_command(
    fixture_campaign: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    assert main(["diagnose", str(fixture_campaign), "--run", "soft-0"]) == 0
    text = capsys.readouterr().out
    assert "most likely missing: fixture_resonance" in text
    command = f"next: viscorig identify {fixture_campaign} --run soft-0 --model 'voigt+fixture(5"
    assert command in text
    assert text.split(command)[1].split("\n")[0].endswith(" --weights uniform")


def test_diagnose_auto_text_is_the_diagnosis_then_each_rung_of_its_ladder(
    fixture_campaign: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """The streamed text is the whole diagnosis, then the ladder, as one piece of text would
    have it."""
    assert main(["diagnose", str(fixture_campaign), "--run", "soft-0", "--auto",
                 "--jobs", "1"]) == 0
    streamed = capsys.readouterr().out
    with CampaignFile.open(fixture_campaign) as campaign:
        first = diagnose_run(campaign, "soft-0")
    ladder = first.auto()
    assert len(ladder) >= 2
    assert streamed == format_diagnosis(first, str(fixture_campaign), ladder) + "\n"


def test_diagnose_auto_prints_the_first_answer_while_it_climbs(fixture_campaign: Path) -> None:
    """``diagnose --auto`` shows what is most likely missing, and the command that adds it,
    before the ladder is climbed: the last rung arrives well after them (a rung is a refit and
    a diagnosis step, half a second here), not microseconds after them as from one write."""
    process = subprocess.Popen(
        [sys.executable, "-m", "viscorig", "diagnose", str(fixture_campaign), "--run", "soft-0",
         "--auto", "--jobs", "1"], stdout=subprocess.PIPE, stderr=subprocess.DEVNULL)
    assert process.stdout is not None
    received: list[tuple[float, bytes]] = []
    while chunk := os.read(process.stdout.fileno(), 65536):
        received.append((time.monotonic(), chunk))
    assert process.wait(timeout=120) == 0
    text = b"".join(part for _, part in received).decode()
    first, ladder = text.split(LADDER_HEADING)
    assert "most likely missing: fixture_resonance" in first
    assert "\nnext: viscorig identify" in first
    rungs = [line for line in ladder.splitlines() if line.startswith("  ")]
    assert rungs[0].split()[0] == "voigt" and len(rungs) >= 2
    heading_at = next(at for at, part in received if LADDER_HEADING.encode() in part)
    assert received[-1][0] - heading_at > 0.1


def test_diagnose_bad_input_is_one_line(
    fixture_campaign: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    arguments = ["diagnose", str(fixture_campaign), "--run", "soft-0", "--model", "voigt+nope"]
    assert main(arguments) == 2
    error = capsys.readouterr().err
    assert error.count("\n") == 1 and "unknown term 'nope'" in error


def test_identify_finds_a_fixture_frequency_by_itself() -> None:
    """``fixture`` without a frequency: the start comes from the residual's largest peak."""
    from viscorig.fitting import fit

    run = simulate_run(rig_text(VOIGT, noise=QUIET, fixtures=[FIXTURE_58]), seed=4)
    result = fit("voigt+fixture", run.frf_data(), fixed=TABLE)
    assert result.values["f_n"] == pytest.approx(58.0, abs=0.5)
    assert result.rms_error <= 1.5 * result.noise_floor


@pytest.mark.slow
def test_hard_10_preset_reads_sensibly() -> None:
    """hard-10: stiff rubber, preload, K_c = 1e7 N/m, fixture modes at 38, 58, 92 Hz."""
    run = simulate_run("hard-10", seed=1, level_m_per_s2=1.4, step_hz=0.5)
    diagnosis = diagnose(run.frf_data("hard-10"), "voigt", table=TABLE)
    effects = [finding.effect for finding in diagnosis.significant]
    assert effects[0] in ("load_cell_compliance", "frequency_dependent_modulus")
    ladder = diagnosis.auto()
    final = ladder[-1].model
    assert "load_cell" in final and not final.startswith("voigt")
    assert ladder[-1].rms_error < diagnosis.rms_error / 10


def test_example_sequence_measures_the_runs_diagnosis_asks_for() -> None:
    from viscorig.sequences.sequence import load_sequence

    sequence = load_sequence(Path(__file__).parents[1] / "sequences" / "separate-effects.toml")
    soft = {step.run: step for step in sequence.sweeps if step.specimen == "soft"}
    assert soft["soft-0-level2"].level_m_per_s2 == 2 * soft["soft-0"].level_m_per_s2
    assert soft["soft-0-down"].direction == "down" and soft["soft-0"].direction == "up"


@pytest.mark.parametrize(("stiffness_error", "expected"), [
    (4.1e-5 + 0j, "model stiffness too high (by 0.0041 % of |K*| near 20.0 Hz)"),
    (-2.5e-3j, "model damping too low (by 0.25 % of |K*| near 20.0 Hz)"),
    (-0.123 + 0j, "model stiffness too low (by 12 % of |K*| near 20.0 Hz)"),
])
def test_a_failing_band_says_its_size_to_two_significant_digits(stiffness_error, expected):
    # a model near the noise floor fails by thousandths of a per cent: one decimal wrote 0.0 %
    from viscorig.diagnosis.residuals import FrfResidual, _describe

    f = np.linspace(20.0, 60.0, 41)
    error = np.full(f.size, 1e-5 + 0j)
    residual = FrfResidual("r", "support", f, error, np.zeros(f.size), np.zeros(f.size),
                           np.ones(f.size), np.full(f.size, stiffness_error))
    assert _describe(residual, slice(0, f.size)) == expected
