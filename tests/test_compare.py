"""Comparing two fits: relative changes and their propagated uncertainty.

Checked against closed forms (a parameter compared as is; the Voigt loss factor ``η = ωC/K``),
against sampling the joint distribution the comparison assumes (a table error both fits
inherit, each fit's own error), which shares nothing with the finite differences of the code
under test, against refits of perturbed data (for the residuals' influence on a fit), and
against a campaign file's round trip. Coverage of a change's ± over replicates the time-domain
simulator measured is in ``test_coverage.py``.
"""

from __future__ import annotations

import math
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
from simdata import DEFAULT_NOISE, rig_text, simulate_run

from viscorig.compare import (
    Change,
    Pair,
    compare_fits,
    kstar_at,
    kstar_changes,
    system_changes,
)
from viscorig.fitting import FitResult, Known, fit
from viscorig.identify import read_fit, store_fit
from viscorig.models import Context, parse_spec
from viscorig.numbers import Estimate
from viscorig.storage import CampaignFile, FitRecord, RunSettings, Segment

VOIGT = parse_spec("voigt")
TABLE = {"M_s": 3.4, "K_s": 5e4, "C_s": 5.0}
FITTED = ("K_v", "C_v", "M_v")


def a_fit(spec: str, values: dict[str, float], names: tuple[str, ...], covariance,
          free: tuple[str, ...], inherited_from: str = "", rms_error: float = math.nan,
          noise_floor: float = math.nan) -> FitResult:
    """A fit with the given values and joint covariance of ``names``, and no residuals."""
    covariance = np.array(covariance, dtype=float)
    sigma = np.sqrt(np.diag(covariance))
    own = [names.index(name) for name in free]
    model = parse_spec(spec)
    return FitResult(model=model, values=dict(values), stderr=dict(zip(names, sigma, strict=True)),
                     free=free, covariance=covariance[np.ix_(own, own)], rms_error=rms_error,
                     noise_floor=noise_floor, band_hz=(20.0, 120.0), points=0,
                     frfs=model.frfs, frequency_hz=np.empty(0), residuals={}, bic=math.nan,
                     covariance_names=names, joint_covariance=covariance,
                     fits_noise=bool(rms_error <= 1.25 * noise_floor),
                     inherited_from=inherited_from)


def estimates(values: dict[str, float], names: tuple[str, ...], covariance,
              free: tuple[str, ...] | None = None, inherited_from: str = "",
              ratio: float = 1.0) -> FitResult:
    """A Voigt fit, ``ratio`` its rms_error over its noise floor."""
    return a_fit("voigt", {**TABLE, "M_v": 0.15, **values}, names, covariance, free or names,
                 inherited_from, rms_error=ratio * 1e-3, noise_floor=1e-3)


def voigt(k_v: float, c_v: float, covariance, ratio: float = 1.0) -> FitResult:
    return estimates({"K_v": k_v, "C_v": c_v}, ("K_v", "C_v"), covariance, ratio=ratio)


def test_a_parameter_change_has_the_closed_form_uncertainty():
    before = voigt(150e3, 100.0, [[600.0**2, 0.0], [0.0, 2.0**2]])
    after = voigt(164e3, 110.0, [[700.0**2, 0.0], [0.0, 1.0**2]])
    k_v, c_v = compare_fits(before, after, ["K_v", "C_v", "not_there"])
    ratio = 164e3 / 150e3
    assert k_v.relative == pytest.approx(ratio - 1)
    assert k_v.relative_stderr == pytest.approx(ratio * math.hypot(600 / 150e3, 700 / 164e3),
                                                rel=1e-6)
    assert (k_v.before_stderr, k_v.after_stderr) == (pytest.approx(600), pytest.approx(700))
    assert k_v.unit == "N/m" and k_v.significant and not k_v.independent
    assert k_v.basis == ("the two runs' noise independent",)
    assert k_v.percent() == "+9.3 ± 0.6 %"
    assert k_v.words() == "K_v rose 9.3 ± 0.6 %"
    assert k_v.words("with preload") == "K_v rose 9.3 ± 0.6 % with preload"
    assert c_v.relative == pytest.approx(0.1) and c_v.significant
    assert c_v.to_json() == {"value": pytest.approx(10.0), "stderr": pytest.approx(
        110 / 100 * math.hypot(2 / 100, 1 / 110) * 100), "unit": "%"}


def test_a_change_within_its_uncertainty_and_one_taken_as_independent_say_so():
    flat = Change("C_v", "N·s/m", 100.0, 5.0, 101.0, 5.0, 0.01, 0.0707)
    assert not flat.significant
    assert flat.words() == "C_v did not change beyond its uncertainty: +1 ± 7 %"
    assert Change("xi", "", 1, 0, 1, 0, 0.0904, 0.0041).percent() == "+9.0 ± 0.4 %"
    # Misfitting fits with nothing to pair them by: independent, and the words say so.
    before = voigt(150e3, 100.0, [[600.0**2, 0.0], [0.0, 2.0**2]], ratio=10.0)
    after = voigt(164e3, 110.0, [[700.0**2, 0.0], [0.0, 1.0**2]], ratio=10.0)
    (k_v,) = compare_fits(before, after, ["K_v"])
    assert k_v.independent and "taken as independent" in k_v.basis[-1]
    assert k_v.words().endswith("(the two fits taken as independent)")


def test_loss_factor_uncertainty_follows_the_correlated_closed_form():
    covariance = [[800.0**2, -0.6 * 800 * 3.0], [-0.6 * 800 * 3.0, 3.0**2]]
    f = 70.0
    (k, u_k), (eta, u_eta) = kstar_at(voigt(150e3, 100.0, covariance), f)
    w = 2 * math.pi * f
    assert k == pytest.approx(150e3) and u_k == pytest.approx(800.0, rel=1e-6)
    assert eta == pytest.approx(w * 100 / 150e3)
    gradient = np.array([-w * 100 / 150e3**2, w / 150e3])
    assert u_eta == pytest.approx(math.sqrt(gradient @ np.array(covariance) @ gradient), rel=1e-5)


def test_propagation_agrees_with_sampling_the_covariance():
    rng = np.random.default_rng(7)
    model = parse_spec("maxwell(2)")
    values = {**TABLE, "K_0": 1.2e5, "K_1": 3e4, "C_1": 60.0, "K_2": 2e4, "C_2": 4.0,
              "M_v": 0.15}
    free = ("K_0", "K_1", "C_1", "K_2", "C_2")
    assert set(free) <= set(model.names)
    sigma = np.array([300.0, 400.0, 0.6, 300.0, 0.06])
    covariance = (np.eye(5) + 0.3 * (np.ones((5, 5)) - np.eye(5))) * np.outer(sigma, sigma)
    fit_ = a_fit(model.spec, values, free, covariance, free)
    (k, u_k), (_, u_eta) = kstar_at(fit_, 60.0)
    samples = rng.multivariate_normal([values[n] for n in free], covariance, size=4000)
    context = Context(np.array([60.0]))
    kstars = np.array([model.kstar(context, {**values, **dict(zip(free, s, strict=True))})[0]
                       for s in samples])
    assert k == pytest.approx(np.mean(kstars.real), rel=1e-3)
    assert u_k == pytest.approx(np.std(kstars.real), rel=0.06)
    assert u_eta == pytest.approx(np.std(kstars.imag / kstars.real), rel=0.06)


# -- the table two fits share --------------------------------------------------------------------

TABLE_COVARIANCE = np.array([[4e-4**2, 0.5 * 4e-4 * 40, 0.0],
                             [0.5 * 4e-4 * 40, 40.0**2, 0.2 * 40 * 0.03],
                             [0.0, 0.2 * 40 * 0.03, 0.03**2]])
#: How each fit's K_v, C_v, M_v follow the table's M_s, K_s, C_s (on X_s/F_e, K_s + K_v and
#: M_s + M_v are what the data fix).
LEVER = np.array([[3e3, -1.0, 0.0], [0.0, 0.0, -1.0], [-1.0, 0.0, 0.0]])
OWN = {"before": np.diag([25.0, 0.04, 2e-4]) ** 2, "after": np.diag([30.0, 0.05, 2e-4]) ** 2}
CENTRE = {"before": {"K_v": 150e3, "C_v": 100.0, "M_v": 0.15},
          "after": {"K_v": 164e3, "C_v": 110.0, "M_v": 0.151}}


def _inheriting(which: str, source: str) -> FitResult:
    """A fit whose parameters are ``p = centre + LEVER (q − q0) + e``, as the module text says."""
    c_pq = LEVER @ TABLE_COVARIANCE
    joint = np.block([[OWN[which] + c_pq @ LEVER.T, c_pq], [c_pq.T, TABLE_COVARIANCE]])
    return estimates(CENTRE[which], FITTED + tuple(TABLE), joint, FITTED, source)


def _sampled_changes(shared: bool, count: int = 40_000) -> dict[str, np.ndarray]:
    """Changes of K_v and f_r over draws of the generative model (no derivatives)."""
    rng = np.random.default_rng(3)
    q0 = np.array(list(TABLE.values()))
    draws = {}
    for which in ("before", "after"):
        q = rng.multivariate_normal(q0, TABLE_COVARIANCE, size=count)
        if shared:
            q = draws["before"][1] if which == "after" else q
        e = rng.multivariate_normal(np.zeros(3), OWN[which], size=count)
        p = np.array([CENTRE[which][n] for n in FITTED]) + (q - q0) @ LEVER.T + e
        draws[which] = (p, q)
    values = {which: {**{n: p[:, i] for i, n in enumerate(FITTED)},
                      **{n: q[:, i] for i, n in enumerate(TABLE)}}
              for which, (p, q) in draws.items()}
    def f_r(v: dict[str, np.ndarray]) -> np.ndarray:
        return np.sqrt((v["K_s"] + v["K_v"]) / (v["M_s"] + v["M_v"])) / (2 * np.pi)

    return {"K_v": values["after"]["K_v"] / values["before"]["K_v"] - 1,
            "f_r": f_r(values["after"]) / f_r(values["before"]) - 1}


@pytest.mark.parametrize("shared", [True, False])
def test_a_shared_table_counts_once_as_sampling_the_joint_distribution_shows(shared: bool):
    before = _inheriting("before", "run 'table'")
    after = _inheriting("after", "run 'table'" if shared else "run 'table-2'")
    sampled = _sampled_changes(shared)
    (k_v,) = compare_fits(before, after, ["K_v"])
    f_r = next(c for c in system_changes(before, after) if c.quantity == "f_r")
    for change, spread in ((k_v, sampled["K_v"]), (f_r, sampled["f_r"])):
        assert change.relative_stderr == pytest.approx(np.std(spread), rel=0.03), change
        assert change.relative == pytest.approx(np.mean(spread), abs=0.03 * np.std(spread))
    pair = Pair(before, after)
    assert pair.shared == (tuple(TABLE) if shared else ())
    if shared:
        assert "M_s, K_s, C_s shared (run 'table'), counted once" in k_v.basis
        independent = compare_fits(before, _inheriting("after", "run 'table-2'"), ["K_v"])[0]
        assert k_v.relative_stderr < 0.6 * independent.relative_stderr  # the table cancels


def _stored(fit_id: str, values: dict[str, float], sigma: dict[str, float],
            correlation: np.ndarray) -> FitRecord:
    names = tuple(sigma)
    parameters = {name: Estimate(value, sigma.get(name, math.nan), "")
                  for name, value in values.items()}
    return FitRecord(fit_id, "r", "voigt", (20.0, 120.0), 1e-3, 1e-3, "", parameters,
                     (names, correlation))


def test_stored_fits_use_their_correlation_and_a_table_given_alike_is_shared():
    names = FITTED + tuple(TABLE)
    inherited = {which: _inheriting(which, "run 'table'") for which in ("before", "after")}
    stored = {}
    for which, fit_ in inherited.items():
        sigma = np.sqrt(np.diag(fit_.joint_covariance))
        correlation = fit_.joint_covariance / np.outer(sigma, sigma)
        stored[which] = _stored(which, fit_.values, dict(zip(names, sigma, strict=True)),
                                correlation)
    from_file = compare_fits(read_fit(stored["before"]), read_fit(stored["after"]),
                             ["K_v", "C_v"])
    from_fits = compare_fits(inherited["before"], inherited["after"], ["K_v", "C_v"])
    for a, b in zip(from_file, from_fits, strict=True):
        assert a.relative_stderr == pytest.approx(b.relative_stderr, rel=1e-9)
    assert Pair(read_fit(stored["before"]), read_fit(stored["after"])).shared == tuple(TABLE)
    # The table given differently in one of them: two tables, independent.
    other = dict(stored["after"].parameters)
    other["K_s"] = Estimate(other["K_s"].value + 1.0, other["K_s"].stderr, "")
    moved = replace(stored["after"], parameters=other)
    assert Pair(read_fit(stored["before"]), read_fit(moved)).shared == ("M_s", "C_s")


# -- fits made here: the residuals' influence, a file's round trip ---------------------------------

VOIGT_RIG = {"mass_kg": 0.25, "model": "voigt", "stiffness_n_per_m": 1.5e5,
             "damping_ns_per_m": 114.59}


@pytest.fixture(scope="module")
def table_known() -> Known:
    run = simulate_run(rig_text(noise=DEFAULT_NOISE), seed=41, start_hz=12.0, stop_hz=28.0,
                       step_hz=0.125, settle_cycles=200.0)
    return Known.from_fit(fit("table", run.frf_data("table")), tuple(TABLE), "run 'table'")


@pytest.fixture(scope="module")
def runs():
    stiffer = {**VOIGT_RIG, "stiffness_n_per_m": 1.64e5, "damping_ns_per_m": 124.9}
    return [simulate_run(rig_text(device, noise=DEFAULT_NOISE), seed=seed)
            for seed, device in ((42, VOIGT_RIG), (43, stiffer))]


def test_the_influence_predicts_a_refit_of_perturbed_data(table_known):
    """``δp = influence @ ε`` for data perturbed by a relative ``ε`` below the residuals (a
    larger one meets them in second order)."""
    quiet = {name: value / 10 for name, value in DEFAULT_NOISE.items()}
    data = simulate_run(rig_text(VOIGT_RIG, noise=quiet), seed=44).frf_data()
    result = fit("voigt", data, known=table_known)
    rng = np.random.default_rng(5)
    n = data.frequency_hz.size
    epsilon = 3e-4 * (rng.standard_normal((2, n)) + 1j * rng.standard_normal((2, n)))
    perturbed = replace(data, table=data.table * (1 + epsilon[0]),
                        support=data.support * (1 + epsilon[1]))
    refit = fit("voigt", perturbed, known=table_known, noise=result.noise)
    # r = H_model/H_measured − 1 moves by about −ε: δp = −influence @ δr = influence @ ε.
    stacked = np.concatenate([epsilon.real.ravel(), epsilon.imag.ravel()])
    predicted = result.influence @ stacked
    for i, name in enumerate(result.free):
        moved = refit.values[name] - result.values[name]
        assert abs(moved) > 1e-6 * abs(result.values[name])  # far above the fit's tolerance
        assert predicted[i] == pytest.approx(moved, rel=0.03), name


def test_a_stored_pair_compares_as_the_fits_do_without_their_residuals(tmp_path: Path, runs,
                                                                        table_known):
    results = [fit("voigt", run.frf_data(), known=table_known) for run in runs]
    path = tmp_path / "c.h5"
    with CampaignFile.create(path, sequence_text="", durable=False) as campaign:
        for name, run in zip(("soft-0", "soft-10"), runs, strict=True):
            campaign.start_run(name, RunSettings(specimen="soft", level_m_per_s2=1.0,
                                                 direction="up", settle_cycles=100,
                                                 integrate_cycles=100, resolution_hz=0.25,
                                                 simulated=True))
            campaign.append_segment(name, Segment(
                run.frequency_hz, run.time_s, run.accelerance_table, run.accelerance_support,
                run.reference_amplitude, np.ones_like(run.time_s), run.force_amplitude,
                run.flags))
        for name, result in zip(("soft-0", "soft-10"), results, strict=True):
            store_fit(campaign, name, result)
        stored = [read_fit(campaign.fits(name)[0]) for name in ("soft-0", "soft-10")]
    from_file = compare_fits(*stored, FITTED)
    unpaired = [replace(r, influence=None) for r in results]
    for a, b in zip(from_file, compare_fits(*unpaired, FITTED), strict=True):
        assert a.relative == pytest.approx(b.relative, rel=1e-12)
        assert a.relative_stderr == pytest.approx(b.relative_stderr, rel=1e-9)
    assert "M_s, K_s, C_s shared" in from_file[0].basis[0]
    # At the noise floor, pairing the residuals changes little: the noises are independent.
    paired = compare_fits(*results, FITTED)
    assert "residuals paired at 401 frequencies" in paired[0].basis[-1]
    for a, b in zip(paired, from_file, strict=True):
        assert a.relative_stderr == pytest.approx(b.relative_stderr, rel=0.25), a.quantity


def test_kstar_changes_of_two_models(runs, table_known):
    before, after = (fit("maxwell(1)", run.frf_data(), known=table_known) for run in runs)
    changes = kstar_changes(before, after, [20.0, 120.0])
    assert [c.quantity for c in changes] == ["K' at 20 Hz", "η at 20 Hz", "K' at 120 Hz",
                                             "η at 120 Hz"]
    truth = 1.64 / 1.5 - 1  # a Voigt rubber stiffened: K' = K_v at every frequency
    for change in changes[::2]:
        assert abs(change.relative - truth) < 3 * change.relative_stderr, change
    other = fit("voigt", runs[1].frf_data(), known=table_known)
    mixed = kstar_changes(before, other, [60.0])  # two models: compared through K* alone
    assert mixed[0].independent is False and abs(mixed[0].relative - truth) < 0.01
