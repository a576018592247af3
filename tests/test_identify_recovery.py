"""Identification recovers the truth from data the time-domain simulator measured.

Rigs are built here (or read from the paper presets); the simulator integrates them in time and
measures like the analyser; the core never sees the rig, only the FRFs.
"""

from __future__ import annotations

import numpy as np
import pytest
from simdata import DEFAULT_NOISE, PAPER_TABLE, rig_text, simulate_run

from viscorig.estimates import kstar_from_support, kstar_from_table, system_properties
from viscorig.fitting import fit, nelder_mead_fit
from viscorig.paper import PAPER_TABLE_1, PAPER_TABLE_2

TABLE = {"M_s": 3.4, "K_s": 50194.0, "C_s": 5.05}
VOIGT = {"mass_kg": 0.25, "model": "voigt", "stiffness_n_per_m": 1.5e5, "damping_ns_per_m": 114.59}
MAXWELL_ARMS = [[5.0e4, 5.0e4 / (2 * np.pi * 150)], [8.0e4, 8.0e4 / (2 * np.pi * 30)]]
MAXWELL = {
    "mass_kg": 0.25,
    "model": "maxwell",
    "static_stiffness_n_per_m": 1.2e5,
    "arms": MAXWELL_ARMS,
}


def within(result, truth: dict[str, float], sigmas: float = 4.0) -> dict[str, float]:
    """Deviation of each parameter from the truth, in standard errors."""
    return {
        name: abs(result.values[name] - value) / result.stderr[name]
        for name, value in truth.items()
    }


def test_bare_table_is_recovered_within_its_uncertainty() -> None:
    # 300 settle periods: the table's own resonance (19.3 Hz, 0.09 Hz wide) sits just below
    # the band, and 100 periods leave its start transient in the first points (a misfit the
    # error measure shows).
    run = simulate_run(rig_text(noise=DEFAULT_NOISE), seed=11, settle_cycles=300)
    result = fit("table", run.frf_data())
    deviations = within(result, TABLE)
    assert max(deviations.values()) < 4.0, deviations
    assert result.rms_error < 1.3 * result.noise_floor


@pytest.mark.parametrize("frfs", [("table",), ("support",), ("table", "support")])
def test_voigt_is_recovered_within_its_uncertainty(frfs: tuple[str, ...]) -> None:
    run = simulate_run(rig_text(VOIGT, noise=DEFAULT_NOISE), seed=12)
    result = fit("voigt", run.frf_data(), frfs=frfs, fixed=TABLE)
    truth = {"K_v": 1.5e5, "C_v": 114.59, "M_v": 0.25}
    deviations = within(result, truth)
    assert max(deviations.values()) < 4.0, deviations
    assert result.rms_error < 1.3 * result.noise_floor


def test_maxwell_order_is_chosen_by_bic_and_its_arms_recovered() -> None:
    run = simulate_run(rig_text(MAXWELL, noise=DEFAULT_NOISE), seed=13)
    result = fit("maxwell", run.frf_data(), fixed=TABLE)
    assert result.spec == "maxwell(2)"
    assert [spec for spec, _, _ in result.candidates][:3] == [
        "maxwell(1)",
        "maxwell(2)",
        "maxwell(3)",
    ]
    truth = {
        "K_0": 1.2e5,
        "K_1": MAXWELL_ARMS[0][0],  # arms come out ordered by relaxation time C_i/K_i
        "C_1": MAXWELL_ARMS[0][1],
        "K_2": MAXWELL_ARMS[1][0],
        "C_2": MAXWELL_ARMS[1][1],
        "M_v": 0.25,
    }
    deviations = within(result, truth)
    assert max(deviations.values()) < 4.0, deviations
    assert result.rms_error < 1.3 * result.noise_floor
    voigt = fit("voigt", run.frf_data(), fixed=TABLE)
    assert voigt.rms_error > 10 * result.rms_error  # the frequency dependence is real


def test_fractional_zener_is_recovered() -> None:
    device = {
        "mass_kg": 0.2,
        "model": "fractional",
        "static_stiffness_n_per_m": 1.5e5,
        "high_stiffness_n_per_m": 6.0e5,
        "tau_s": 2.0e-3,
        "alpha": 0.45,
    }
    run = simulate_run(rig_text(device, noise=DEFAULT_NOISE), seed=14)
    result = fit("fractional", run.frf_data(), fixed=TABLE)
    truth = {"K_0": 1.5e5, "K_inf": 6.0e5, "tau": 2.0e-3, "alpha": 0.45, "M_v": 0.2}
    for name, value in truth.items():  # the simulator's K* is a dense Prony approximation
        assert result.values[name] == pytest.approx(value, rel=0.05), name
    assert result.rms_error < 1.5 * result.noise_floor


def test_direct_estimates_agree_with_the_rig_without_fitting() -> None:
    run = simulate_run(rig_text(VOIGT, noise=DEFAULT_NOISE), seed=15)
    w = 2 * np.pi * run.frequency_hz
    truth = 1.5e5 + 1j * w * 114.59
    from_support = kstar_from_support(run.frequency_hz, run.accelerance_support, 0.25)
    from_table = kstar_from_table(run.frequency_hz, run.accelerance_table, TABLE, 0.25)
    assert np.median(np.abs(from_support / truth - 1)) < 0.01
    assert np.median(np.abs(from_table / truth - 1)) < 0.01


@pytest.mark.slow
def test_standard_errors_are_honest_over_many_noise_seeds() -> None:
    """About 68 % of estimates fall within one standard error of the truth."""
    rig = rig_text(VOIGT, noise=DEFAULT_NOISE)
    truth = {"K_v": 1.5e5, "C_v": 114.59, "M_v": 0.25}
    inside, total = 0, 0
    for seed in range(60):
        result = fit("voigt", simulate_run(rig, seed=1000 + seed).frf_data(), fixed=TABLE)
        for deviation in within(result, truth).values():
            inside += deviation < 1.0
            total += 1
    fraction = inside / total
    assert 0.58 < fraction < 0.78, fraction


# Generic start of a direct search, as a user would guess without the rig at hand.
GENERIC_START = {"K_v": 1.0e5, "C_v": 50.0, "M_v": 0.5}


@pytest.mark.slow
def test_converges_on_every_paper_rig_where_a_direct_search_does_not() -> None:
    """Soft to hard, with and without preload: the paper presets (with load cell, fixture
    modes and frame). Voigt on X_s/F_e with the table fixed, every point weighted the same as
    the paper weighs them, gives Table 1; Nelder-Mead from a generic start (the paper's
    method) misses on some of the same data."""
    table_run = simulate_run("table", seed=21)
    table = fit("table", table_run.frf_data(), band_hz=(20, 120), weighting="uniform").values
    table = {name: table[name] for name in ("M_s", "K_s", "C_s")}
    failures = []
    for index, name in enumerate(PAPER_TABLE_1):
        data = simulate_run(name, seed=22 + index).frf_data(name)
        ours = fit("voigt", data, frfs=("table",), fixed=table, band_hz=(20, 120),
                   weighting="uniform")
        k_v, c_v = PAPER_TABLE_1[name]
        assert ours.values["K_v"] == pytest.approx(k_v, rel=0.01), name
        assert ours.values["C_v"] == pytest.approx(c_v, rel=0.02), name
        band = data.in_band((20, 120))
        values, rms = nelder_mead_fit("voigt", band, GENERIC_START, frfs=("table",), fixed=table)
        assert rms >= ours.rms_error * (1 - 1e-6), name  # never better than ours
        if rms > 1.5 * ours.rms_error or abs(values["K_v"] / k_v - 1) > 0.05:
            failures.append(name)
    assert failures, "the direct search from a generic start succeeded everywhere"


def test_paper_presets_give_back_table_1_and_table_2() -> None:
    """Table 1 within 1 % (K_v) and 2 % (C_v); Table 2's ξ and B_r within 12 %; f_r within 4 % where
    the paper's f_r agrees with its own K_v (soft, medium). For the hard rubber the paper's f_r
    implies a total mass of 4.1-4.3 kg against M_s = 3.4 kg, which no rig reproduces together
    with Table 1 (physics.md), so only ξ is compared there. Every point weighted the same, as
    the paper weighs them (the presets were calibrated to that)."""
    table_run = simulate_run("table", seed=31)
    table_fit = fit("table", table_run.frf_data(), band_hz=(20, 120), weighting="uniform")
    assert table_fit.values["M_s"] == pytest.approx(PAPER_TABLE["mass_kg"], rel=0.01)
    assert table_fit.values["K_s"] == pytest.approx(PAPER_TABLE["stiffness_n_per_m"], rel=0.01)
    assert table_fit.values["C_s"] == pytest.approx(PAPER_TABLE["damping_ns_per_m"], rel=0.05)
    table = {name: table_fit.values[name] for name in ("M_s", "K_s", "C_s")}
    for index, name in enumerate(PAPER_TABLE_1):
        data = simulate_run(name, seed=32 + index).frf_data(name)
        result = fit("voigt", data, frfs=("table",), fixed=table, band_hz=(20, 120),
                     weighting="uniform")
        k_v, c_v = PAPER_TABLE_1[name]
        assert result.values["K_v"] == pytest.approx(k_v, rel=0.01), name
        assert result.values["C_v"] == pytest.approx(c_v, rel=0.02), name
        system = system_properties(result.values)
        f_r, xi, b_r = PAPER_TABLE_2[name]
        assert system.damping_factor == pytest.approx(xi, rel=0.12), name
        if not name.startswith("hard"):
            assert system.natural_frequency_hz == pytest.approx(f_r, rel=0.04), name
            assert system.bandwidth_hz == pytest.approx(b_r, rel=0.12), name


def test_maxwell_orders_compared_from_projected_starts_match_full_fits() -> None:
    """The order search scores each order after a few steps from its projected start; a full
    fit of the same order may only be slightly better, never enough to change the choice.
    Orders are compared on the error measure (uniform fits); the chosen order is then weighted
    by the noise, as every fit is."""
    data = simulate_run(rig_text(MAXWELL, noise=DEFAULT_NOISE), seed=16).frf_data()
    result = fit("maxwell", data, fixed=TABLE, weighting="uniform")
    assert result.spec == "maxwell(2)"
    assert len(result.candidates) >= 3
    for spec, bic, rms_error in result.candidates:
        full = fit(spec, data, fixed=TABLE, weighting="uniform")
        assert bic >= full.bic - 1e-6, spec  # an honest score: never better than the optimum
        assert bic - full.bic < 2.0, spec  # and close to it
        assert rms_error == pytest.approx(full.rms_error, rel=0.01), spec
    assert result.bic == pytest.approx(
        fit("maxwell(2)", data, fixed=TABLE, weighting="uniform").bic, abs=1e-6)
    weighted = fit("maxwell", data, fixed=TABLE, weighting="noise")
    assert weighted.spec == "maxwell(2)" and weighted.weighting == "noise"
    assert weighted.candidates == result.candidates


@pytest.mark.slow
def test_maxwell_with_effect_terms_never_keeps_a_dead_arm() -> None:
    """A stiff two-arm rubber behind a load cell, with a fixture mode, paper-like noise; fitted
    with the order open. A three-arm fit can mimic two arms with K_0 switched off and its
    slowest arm standing in as a spring; that order is the order below in disguise, and the
    two-arm fit restarted from its live arms beats it."""
    from viscorig.fitting.arms import DEAD_ARM_CONTRIBUTION, arm_contributions, dead_arms

    arms = [[1.5e5, 1.5e5 / (2 * np.pi * 150)], [6.0e4, 6.0e4 / (2 * np.pi * 30)]]
    device = {**MAXWELL, "mass_kg": 0.15, "static_stiffness_n_per_m": 1.0e6, "arms": arms}
    fixture = {"frequency_hz": 92.0, "damping_ratio": 0.02, "mass_kg": 0.002}
    quiet = {name: value / 10 for name, value in DEFAULT_NOISE.items()}
    rig = rig_text(device, load_cell_n_per_m=1.0e7, fixtures=[fixture], noise=quiet)
    data = simulate_run(rig, seed=17).frf_data()
    result = fit("maxwell+load_cell+fixture(92)", data, fixed=TABLE)
    assert result.spec == "maxwell(2)+load_cell+fixture(92)", result.candidates
    assert dead_arms(result) == {}
    contributions = arm_contributions(result.model, result.values, result.frequency_hz)
    assert np.all(contributions > 10 * DEAD_ARM_CONTRIBUTION), contributions
    truth = {"K_0": 1.0e6, "K_1": arms[0][0], "C_1": arms[0][1], "K_2": arms[1][0],
             "C_2": arms[1][1], "K_c": 1.0e7}  # fmt: skip
    for name, value in truth.items():
        assert result.values[name] == pytest.approx(value, rel=0.02), name
    scores = {spec: bic for spec, bic, _ in result.candidates}
    assert min(scores, key=scores.get) == result.spec  # the lower order was not left stuck


FRAME = "[frame]\nmass_kg = 2000.0\nfrequency_hz = 3.0\ndamping_ratio = 0.1\n"


def test_the_frame_under_the_table_biases_k_s_unless_modelled() -> None:
    """The paper's table on a 2000 kg frame (3 Hz isolators), swept as the paper's sequence
    does: without the frame term K_s reads +0.17 % (many stderr) at the noise floor of the
    error measure (the uniform fit, which minimises it); with ``frame(2000)`` the table is
    recovered within its uncertainty."""
    preset_noise = {name: value / 10 for name, value in DEFAULT_NOISE.items()}
    rig = rig_text(noise=preset_noise, extra=FRAME)
    run = simulate_run(rig, seed=41, start_hz=12.0, stop_hz=28.0, step_hz=0.125,
                       settle_cycles=200.0)
    plain = fit("table", run.frf_data(), weighting="uniform")
    assert plain.values["K_s"] / TABLE["K_s"] - 1 == pytest.approx(3.4 / 2000, rel=0.2)
    assert within(plain, {"K_s": TABLE["K_s"]})["K_s"] > 20
    assert plain.fits_noise  # the error measure cannot tell
    framed = fit("table+frame(2000)", run.frf_data())
    assert max(within(framed, TABLE).values()) < 3.0
    assert framed.values["K_s"] == pytest.approx(TABLE["K_s"], rel=3e-4)


def test_frame_term_is_exact_on_a_specimen_rig_with_a_load_cell() -> None:
    rig = rig_text(VOIGT, load_cell_n_per_m=1e7, extra=FRAME)
    run = simulate_run(rig, seed=42, settle_cycles=300.0)
    result = fit("voigt+load_cell+frame(2000)", run.frf_data(variance=False), fixed=TABLE)
    assert result.rms_error < 1e-6
    truth = {"K_v": 1.5e5, "C_v": 114.59, "M_v": 0.25, "K_c": 1e7, "f_g": 3.0, "zeta_g": 0.1}
    for name, value in truth.items():
        assert result.values[name] == pytest.approx(value, rel=1e-3), name
