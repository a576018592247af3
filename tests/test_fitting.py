"""The fitting core on hand-made data: starts, noise floor, result shapes, bad input.

No truth recovery here (that is tests/test_identify_recovery.py, on simulator data): these
tests pin exact algebraic properties that need no simulator.
"""

from __future__ import annotations

import numpy as np
import pytest

from viscorig.errors import InputError
from viscorig.estimates import equivalent_damping, loss_factor, measured_resonance, storage_modulus
from viscorig.fitting import FrfData, fit, linear_start, local_noise_power, noise_floor
from viscorig.fitting.starts import table_linear_fit
from viscorig.models import Fixture, Model, Voigt, parse_spec
from viscorig.models.modulus import prony_nnls
from viscorig.rig import RigDescription, geometry_factor

FREQUENCY = np.arange(20.0, 120.001, 0.25)
OMEGA = 2 * np.pi * FREQUENCY


def accelerance_of_stiffness(z: np.ndarray) -> np.ndarray:
    """Accelerance of a hand-written dynamic stiffness polynomial."""
    return -(OMEGA**2) / z


def test_table_linear_start_is_exact_on_a_polynomial() -> None:
    z = 50194.0 - OMEGA**2 * 3.4 + 1j * OMEGA * 5.05
    start = table_linear_fit(FrfData(FREQUENCY, accelerance_of_stiffness(z)))
    assert start == pytest.approx({"M_s": 3.4, "K_s": 50194.0, "C_s": 5.05}, rel=1e-9)


def test_voigt_linear_start_is_exact_with_the_table_known() -> None:
    table = {"M_s": 3.4, "K_s": 50194.0, "C_s": 5.05}
    z_disc = 2.0e5 + 1j * OMEGA * 120.0 - OMEGA**2 * 0.3
    z_table = table["K_s"] - OMEGA**2 * table["M_s"] + 1j * OMEGA * table["C_s"] + z_disc
    data = FrfData(FREQUENCY, accelerance_of_stiffness(z_table), accelerance_of_stiffness(z_disc))
    model = parse_spec("voigt")
    for frfs in (("table",), ("support",), ("table", "support")):
        start = linear_start(model, data, frfs, table)
        assert start["K_v"] == pytest.approx(2.0e5, rel=1e-9)
        assert start["C_v"] == pytest.approx(120.0, rel=1e-9)
        assert start["M_v"] == pytest.approx(0.3, rel=1e-9)


def test_nnls_prony_start_finds_the_arms_of_an_exact_series() -> None:
    taus = np.array([1e-4, 3e-3])
    gains = np.array([4e4, 9e4])
    iwt = 1j * OMEGA[:, None] * taus
    d_disc = 1.5e5 + (gains * iwt / (1 + iwt)).sum(axis=1) - OMEGA**2 * 0.2
    found_taus, found_gains, k_0, m_v = prony_nnls(OMEGA, d_disc, 1 / np.abs(d_disc))
    iwt_found = 1j * OMEGA[:, None] * found_taus
    rebuilt = k_0 + (found_gains * iwt_found / (1 + iwt_found)).sum(axis=1) - OMEGA**2 * m_v
    assert np.max(np.abs(rebuilt / d_disc - 1)) < 1e-2  # neighbours merged: a start, not a fit
    assert np.all(found_gains > 0) and k_0 >= 0 and m_v >= 0
    # two relaxation times three decades apart stay apart after merging neighbours
    start = parse_spec("maxwell(2)").modulus_term.start(OMEGA, d_disc, 1 / np.abs(d_disc))
    found = sorted(start[f"C_{i}"] / start[f"K_{i}"] for i in (1, 2))
    assert found == pytest.approx(taus, rel=0.01)
    assert [start["K_1"], start["K_2"], start["K_0"]] == pytest.approx([*gains, 1.5e5], rel=0.01)


def test_noise_floor_matches_known_complex_gaussian_noise() -> None:
    rng = np.random.default_rng(7)
    clean = accelerance_of_stiffness(2.5e5 - OMEGA**2 * 3.6 + 1j * OMEGA * 120.0)
    sigma = 1e-3 * (1 + 4 * (FREQUENCY - 20) / 100)  # noise growing fivefold along the band
    noise = sigma * (rng.normal(size=FREQUENCY.size) + 1j * rng.normal(size=FREQUENCY.size))
    measured = clean * (1 + noise / np.sqrt(2))
    truth = np.sqrt(np.mean(sigma**2))
    assert noise_floor([measured]) == pytest.approx(truth, rel=0.15)
    local = local_noise_power(measured)
    assert local.shape == FREQUENCY.shape
    assert np.sqrt(local[-40:].mean()) > 3 * np.sqrt(local[:40].mean())


def test_noise_floor_of_a_noiseless_resonance_is_far_below_measured_noise() -> None:
    # ξ = 0.02 at 42 Hz: a half-power width of 1.8 Hz, 7 steps of 0.25 Hz
    clean = accelerance_of_stiffness(2.5e5 - OMEGA**2 * 3.6 + 1j * OMEGA * 40.0)
    assert noise_floor([clean]) < 3e-5
    damped = accelerance_of_stiffness(2.5e5 - OMEGA**2 * 3.6 + 1j * OMEGA * 120.0)
    assert noise_floor([damped]) < 1e-6


def test_fit_result_has_every_parameter_and_evaluates_on_any_grid() -> None:
    rng = np.random.default_rng(3)
    z = 50194.0 - OMEGA**2 * 3.4 + 1j * OMEGA * 5.05
    noisy = accelerance_of_stiffness(z) * (1 + 1e-3 * rng.normal(size=FREQUENCY.size))
    result = fit("table", FrfData(FREQUENCY, noisy))
    assert set(result.parameters) == {"M_s", "K_s", "C_s"}
    assert result.parameters["K_s"].unit == "N/m"
    assert result.covariance.shape == (3, 3)
    assert result.points == FREQUENCY.size
    assert result.residuals["table"].shape == FREQUENCY.shape
    grid = np.linspace(5.0, 200.0, 17)
    assert result.predict(grid)["table"].shape == grid.shape
    document = result.to_json("table")
    assert document["model"] == "table"
    assert set(document) >= {"run", "model", "band_hz", "points", "rms_error", "noise_floor"}
    assert document["parameters"]["M_s"]["unit"] == "kg"


def test_band_selects_points_and_is_reported() -> None:
    z = 50194.0 - OMEGA**2 * 3.4 + 1j * OMEGA * 5.05
    result = fit("table", FrfData(FREQUENCY, accelerance_of_stiffness(z)), band_hz=(30, 60))
    assert result.band_hz == (30.0, 60.0)
    assert result.points == 121


@pytest.mark.parametrize(
    ("kwargs", "words"),
    [
        ({"band_hz": (30.0, 31.0)}, "at least"),
        ({"band_hz": (60.0, 30.0)}, "LO < HI"),
        ({"frfs": ("support",)}, "accelerance_support"),
    ],
)
def test_bad_fit_requests_name_what_is_wrong(kwargs: dict, words: str) -> None:
    z = 50194.0 - OMEGA**2 * 3.4 + 1j * OMEGA * 5.05
    data = FrfData(FREQUENCY, accelerance_of_stiffness(z), name="run 'x'")
    model = "voigt" if "frfs" in kwargs else "table"
    with pytest.raises(InputError, match=words):
        fit(model, data, fixed={"M_s": 3.4, "K_s": 5e4, "C_s": 5.0}, **kwargs)


def test_nan_in_the_band_is_refused_and_named() -> None:
    z = 50194.0 - OMEGA**2 * 3.4 + 1j * OMEGA * 5.05
    h = accelerance_of_stiffness(z)
    h[100] = np.nan
    with pytest.raises(InputError, match="accelerance_table, ẍ_s/F_e has 1 NaN"):
        fit("table", FrfData(FREQUENCY, h, name="run 'x'"))


def test_specimen_model_on_the_table_frf_needs_the_table() -> None:
    z = 2.0e5 - OMEGA**2 * 3.6 + 1j * OMEGA * 120.0
    h = accelerance_of_stiffness(z)
    with pytest.raises(InputError, match="needs the table's M_s, K_s, C_s"):
        fit("voigt", FrfData(FREQUENCY, h, h), frfs=("table",))


def test_model_needing_time_is_refused_without_time() -> None:
    class Drifty(parse_spec("voigt").modulus_term.__class__):  # a K* term that needs time_s
        keyword = "voigt"
        requires = ("time_s",)

    model = parse_spec("voigt")
    model.terms = (Drifty(),)
    h = accelerance_of_stiffness(2.0e5 - OMEGA**2 * 0.3 + 1j * OMEGA * 120.0)
    with pytest.raises(InputError, match="needs time_s"):
        fit(model, FrfData(FREQUENCY, None, h))


def test_geometry_factor_arrangements_differ_as_documented() -> None:
    paper = geometry_factor(0.02, 0.012)
    assert paper == pytest.approx(np.pi * 0.02**2 / (8 * 0.012))
    assert geometry_factor(0.02, 0.012, 2, "parallel") == pytest.approx(4 * paper)
    assert RigDescription(specimen_diameter_m=0.02, specimen_height_m=0.012).theta == paper
    assert RigDescription(geometry_factor_m=1.5).theta == 1.5
    assert RigDescription().theta is None
    with pytest.raises(InputError, match="unknown arrangement"):
        geometry_factor(0.02, 0.012, 2, "diagonal")


def test_a_geometry_no_specimen_has_is_refused_by_name() -> None:
    """A diameter of 1e300 m ended the report in an OverflowError; a negative θ given outright
    turned every E' negative; a count of 0 was read as 2."""
    with pytest.raises(InputError, match="between 1e-06 and 10 m"):
        _ = RigDescription(specimen_diameter_m=1e300, specimen_height_m=0.012).theta
    with pytest.raises(InputError, match="must be > 0"):
        _ = RigDescription(geometry_factor_m=-0.01).theta
    rig = RigDescription.from_attributes({"specimen_count": 0, "specimen_diameter_m": 0.02,
                                          "specimen_height_m": 0.012})
    assert rig.specimen_count == 0
    with pytest.raises(InputError, match="at least 1"):
        geometry_factor(0.02, 0.012, rig.specimen_count, "parallel")
    assert RigDescription.from_attributes({"specimen_count": float("nan")}).specimen_count == 2


def test_moduli_and_equivalent_damping_follow_eq_7_8_12() -> None:
    kstar = np.array([2.0e5 + 3.0e4j])
    assert storage_modulus(kstar, 0.5) == pytest.approx([4.0e5])
    assert loss_factor(kstar) == pytest.approx([0.15])
    assert equivalent_damping([50.0], kstar) == pytest.approx([3.0e4 / (2 * np.pi * 50)])


def test_measured_half_power_bandwidth_of_a_light_resonance() -> None:
    f = np.arange(20.0, 80.0, 0.05)
    w = 2 * np.pi * f
    m, k, xi = 3.6, 2.0e5, 0.03
    c = 2 * xi * np.sqrt(k * m)
    resonance = measured_resonance(f, -(w**2) / (k - w**2 * m + 1j * w * c))
    f_n = np.sqrt(k / m) / (2 * np.pi)
    assert resonance.peak_hz == pytest.approx(f_n * np.sqrt(1 - 2 * xi**2), rel=1e-3)
    assert resonance.bandwidth_hz == pytest.approx(2 * xi * f_n, rel=0.01)


@pytest.mark.parametrize(
    ("spec", "values"),
    [
        ("table", {}),
        ("voigt", {"K_v": 2.0e5, "C_v": 120.0, "M_v": 0.3}),
        (
            "maxwell(2)",
            {"K_0": 1.2e5, "K_1": 5e4, "C_1": 53.0, "K_2": 8e4, "C_2": 424.0, "M_v": 0.25},
        ),
        ("fractional", {"K_0": 1.5e5, "K_inf": 6e5, "tau": 2e-3, "alpha": 0.45, "M_v": 0.2}),
        (
            "fractional+load_cell+fixture(38)+fixture(92)",
            {"K_0": 1.5e5, "K_inf": 6e5, "tau": 2e-3, "alpha": 0.45, "M_v": 0.2, "K_c": 3e6,
             "m_1": 4e-3, "zeta_1": 0.03, "m_2": 2e-3, "f_n_2": 90.0},
        ),
        (
            "voigt+delay+gain(x_v)+highpass(F_e)+lowpass(x_s)",
            {"K_v": 2.0e5, "C_v": 120.0, "M_v": 0.3, "tau_d": 2e-4, "gain_x_v": 1.03,
             "f_hp_F_e": 2.0, "f_lp_x_s": 400.0},
        ),
        (
            "maxwell(1)+load_cell+delay(F_v)+lowpass(F_e)",
            {"K_0": 1.2e5, "K_1": 5e4, "C_1": 53.0, "M_v": 0.25, "K_c": 1e6,
             "tau_F_v": -1e-4, "f_lp_F_e": 300.0},
        ),
    ],
)
def test_analytic_derivatives_match_finite_differences_of_the_prediction(
    spec: str, values: dict
) -> None:
    """∂H/∂p through every stage (K*, the disc's modes, the load cell, the measuring chain)
    against central differences of the prediction, for every parameter."""
    model = parse_spec(spec)
    ctx = FrfData(FREQUENCY, np.ones(FREQUENCY.size)).context()
    point = {**model.defaults(), "M_s": 3.4, "K_s": 50194.0, "C_s": 5.05, **values}
    names = model.names
    derivatives = model.derivatives(ctx, point, names)
    assert derivatives is not None and set(derivatives) == set(model.frfs)
    predicted = model.predict(ctx, point)
    for j, name in enumerate(names):
        step = 1e-6 * abs(point[name])
        up, down = dict(point), dict(point)
        up[name] += step
        down[name] -= step
        for frf in model.frfs:
            numeric = (model.predict(ctx, up)[frf] - model.predict(ctx, down)[frf]) / (2 * step)
            scale = np.max(np.abs(predicted[frf])) / abs(point[name])
            error = np.max(np.abs(derivatives[frf][:, j] - numeric))
            assert error < 1e-6 * scale, (frf, name)


def test_derivatives_of_some_parameters_are_those_columns_of_all_of_them() -> None:
    """A fit that holds the local modes asks for the other columns only: they are the same
    numbers, and the held modes' own derivatives are not needed for them."""
    model = parse_spec("fractional+load_cell+fixture(38)+fixture(92)")
    ctx = FrfData(FREQUENCY, np.ones(FREQUENCY.size)).context()
    point = {**model.defaults(), "M_s": 3.4, "K_s": 50194.0, "C_s": 5.05, "K_0": 1.5e5,
             "K_inf": 6e5, "tau": 2e-3, "alpha": 0.45, "M_v": 0.2, "K_c": 3e6, "m_1": 4e-3}
    every = model.derivatives(ctx, point, model.names)
    some = ("K_0", "alpha", "M_v", "K_c")
    asked = model.derivatives(ctx, point, some)
    assert every is not None and asked is not None
    columns = [model.names.index(name) for name in some]
    for frf in model.frfs:
        np.testing.assert_allclose(asked[frf], every[frf][:, columns], rtol=1e-12)

    class Opaque(Fixture):
        def disc_stiffness_derivatives(self, ctx, p):
            return None

    held = Model([*parse_spec("fractional+load_cell").terms, Opaque(38.0)])
    assert held.derivatives(ctx, {**held.defaults(), **point}, held.names) is None
    assert held.derivatives(ctx, {**held.defaults(), **point}, some) is not None


def test_terms_without_derivatives_fall_back_to_finite_differences() -> None:
    """An effect term, or a K* term without derivatives, still fits (to the same values)."""
    rng = np.random.default_rng(5)
    table = {"M_s": 3.4, "K_s": 50194.0, "C_s": 5.05}
    z_disc = 2.0e5 + 1j * OMEGA * 120.0 - OMEGA**2 * 0.3
    z_table = table["K_s"] - OMEGA**2 * table["M_s"] + 1j * OMEGA * table["C_s"] + z_disc
    noise = 1 + 1e-3 * (rng.normal(size=(2, FREQUENCY.size)) + 1j * rng.normal(size=(2, 1)))
    data = FrfData(
        FREQUENCY,
        accelerance_of_stiffness(z_table) * noise[0],
        accelerance_of_stiffness(z_disc) * noise[1],
    )
    ctx = data.context()
    with_effect = parse_spec("voigt+frame")
    assert with_effect.derivatives(ctx, linear_start(with_effect, data, ("support",), table),
                                   with_effect.names) is None
    analytic = fit("voigt", data, fixed=table)

    class NoDerivatives(Voigt):
        def modulus_derivatives(self, ctx, p):
            return None

    plain = Model([NoDerivatives()])
    assert plain.derivatives(ctx, analytic.values, plain.names) is None
    numeric = fit(plain, data, fixed=table)
    for name in ("K_v", "C_v", "M_v"):
        assert numeric.values[name] == pytest.approx(analytic.values[name], rel=1e-6)
        assert numeric.stderr[name] == pytest.approx(analytic.stderr[name], rel=1e-3)
    framed = fit(with_effect, data, fixed=table)
    assert framed.values["K_v"] == pytest.approx(analytic.values["K_v"], rel=1e-3)


@pytest.mark.parametrize(("points", "said"), [(1, "1 point, a fit"), (3, "3 points, a fit")])
def test_too_few_points_are_counted_in_words(points: int, said: str) -> None:
    data = FrfData(np.linspace(20.0, 21.0, points), table=np.ones(points, complex), name="x")
    with pytest.raises(InputError, match=f"x: {said} needs at least 10"):
        data.checked(("table",), None)
