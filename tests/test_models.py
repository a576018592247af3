"""The model framework: spec strings, parameters, the evaluation pipeline, extension points."""

from __future__ import annotations

import re
from collections.abc import Iterator, Mapping

import numpy as np
import pytest

from viscorig.errors import InputError
from viscorig.models import (
    TERMS,
    Context,
    Fractional,
    Maxwell,
    Model,
    Parameter,
    Term,
    Voigt,
    parse_spec,
    register_term,
)

FREQUENCY = np.linspace(20.0, 120.0, 41)
TABLE = {"M_s": 3.4, "K_s": 50194.0, "C_s": 5.05}


@pytest.mark.parametrize(
    ("spec", "canonical"),
    [
        ("voigt", "voigt"),
        (" Voigt ", "voigt"),
        ("maxwell(3)", "maxwell(3)"),
        ("maxwell( 2.0 )", "maxwell(2)"),
        ("fractional", "fractional"),
        ("maxwell", "maxwell"),
        ("table", "table"),
    ],
)
def test_spec_round_trip(spec: str, canonical: str) -> None:
    model = parse_spec(spec)
    assert model.spec == canonical
    assert parse_spec(model.spec).spec == canonical


@pytest.mark.parametrize(
    ("spec", "names"),
    [
        ("voigt", ("M_s", "K_s", "C_s", "K_v", "C_v", "M_v")),
        ("maxwell(2)", ("M_s", "K_s", "C_s", "K_0", "K_1", "K_2", "C_1", "C_2", "M_v")),
        ("fractional", ("M_s", "K_s", "C_s", "K_0", "K_inf", "tau", "alpha", "M_v")),
        ("table", ("M_s", "K_s", "C_s")),
    ],
)
def test_parameter_names_follow_the_design(spec: str, names: tuple[str, ...]) -> None:
    assert parse_spec(spec).names == names


@pytest.mark.parametrize(
    ("spec", "words"),
    [
        ("voigt+nonsense", "unknown term 'nonsense'"),
        ("voigt+maxwell(2)", "exactly one K* term"),
        ("", "empty"),
        ("voigt++", "malformed term"),
        ("maxwell(2.5)", "whole number"),
        ("maxwell(x)", "needs a number"),
        ("voigt(3)", "takes no argument"),
        ("voigt+delay+delay", "'delay' is given more than once"),
        ("fractional+gain(x_v)+load_cell+gain(x_v)", "'gain(x_v)' is given more than once"),
        ("voigt+amplitude+amplitude", "'amplitude' is given more than once"),
        ("table+load_cell", "'load_cell' acts on the specimens"),
        ("table+drift", "'drift' acts on the specimens"),
        ("table+kraus", "'table' has none"),
        ("voigt+gain(F_e)+gain(x_s)", "through 1 combination only"),
        ("voigt+delay(F_v)+delay(x_v)", "through 1 combination only"),
        ("voigt+delay+delay(x_s)+delay(x_v)", "through 2 combinations only"),
        ("table+delay(x_v)", "'delay(x_v)' acts on no FRF the model predicts (x_s/F_e)"),
        # int(inf) and int(nan) ended in OverflowError and ValueError tracebacks
        ("maxwell(inf)", "whole number of arms 1..20, got inf"),
        ("maxwell(nan)", "whole number of arms 1..20, got nan"),
        ("maxwell(1e999)", "whole number of arms 1..20, got inf"),
        # a frame lighter than the table was fitted into K_v = 0 ± 2.6e18 N/m
        ("voigt+frame(1e-3)", "frame(M) needs the frame's mass in kg, 1 to 1e+07, got 0.001"),
        # 'needs a number in parentheses' for terms that take none
        ("voigt+load_cell(x)", "term 'load_cell' takes no argument, got '(x)'"),
        # a hundred local modes fitted for minutes
        ("voigt" + "+fixture" * 13, "'fixture' is given 13 times; a model holds at most 12"),
    ],
)
def test_bad_specs_name_what_is_wrong(spec: str, words: str) -> None:
    with pytest.raises(InputError, match=re.escape(words)):
        parse_spec(spec)


def test_the_bare_table_takes_the_terms_of_its_own_chain() -> None:
    """A K* modifier or a load cell on the bare table has nothing to act on: its parameters
    were fitted as 'rank deficient' values (K_c = 1e9 with no ±). A frame under the table, a
    local mode on it and its channels' terms act on the table itself."""
    for spec in ("table+frame(2000)", "table+fixture", "table+delay", "table+gain(x_s)"):
        parse_spec(spec)


def test_the_same_effect_twice_is_refused_but_two_modes_or_two_channels_are_not() -> None:
    """Two copies of one delay, gain or amplitude term add into one value (τ₁ + τ₂): a fit of
    them is exactly degenerate. Two local modes, or delays of different channels, are not."""
    for spec in ("voigt+fixture+fixture", "voigt+fixture(58)+fixture(58)",
                 "voigt+delay+delay(x_v)", "voigt+gain(x_v)+gain(x_s)",
                 "voigt+delay(x_s)+delay(F_v)", "voigt+highpass(F_e)+highpass(x_s)"):
        parse_spec(spec)



def test_every_parameter_has_unit_bounds_and_a_feasible_default() -> None:
    for spec in ("voigt", "maxwell(3)", "fractional", "table"):
        for parameter in parse_spec(spec).parameters:
            assert parameter.lower < parameter.default < parameter.upper or (
                parameter.lower <= parameter.default <= parameter.upper
            )
            assert isinstance(parameter.unit, str)
    with pytest.raises(ValueError, match="positive lower bound"):
        Parameter("x", "m", 0.0, 1.0, 0.5)


def test_rigid_link_prediction_is_the_closed_form_of_physics_md() -> None:
    values = {**TABLE, "K_v": 1.5e5, "C_v": 114.59, "M_v": 0.25}
    ctx = Context(FREQUENCY)
    frfs = (Voigt() + Model([])).predict(ctx, values)
    w = 2 * np.pi * FREQUENCY
    kstar = 1.5e5 + 1j * w * 114.59
    table = 1 / (TABLE["K_s"] + kstar - w**2 * (TABLE["M_s"] + 0.25) + 1j * w * TABLE["C_s"])
    support = 1 / (kstar - w**2 * 0.25)
    np.testing.assert_allclose(frfs["table"], -(w**2) * table, rtol=1e-12)
    np.testing.assert_allclose(frfs["support"], -(w**2) * support, rtol=1e-12)


def test_bare_table_predicts_only_the_table_frf() -> None:
    model = parse_spec("table")
    frfs = model.predict(Context(FREQUENCY), TABLE)
    assert set(frfs) == {"table"}
    w = 2 * np.pi * FREQUENCY
    expected = -(w**2) / (TABLE["K_s"] - w**2 * TABLE["M_s"] + 1j * w * TABLE["C_s"])
    np.testing.assert_allclose(frfs["table"], expected, rtol=1e-12)


def test_maxwell_one_arm_is_eq_9_and_tends_to_its_limits() -> None:
    ctx = Context(np.array([1e-3, 50.0, 1e6]))
    kstar = Maxwell(1).modulus(ctx, {"K_0": 1e5, "K_1": 2e5, "C_1": 400.0})
    w = ctx.omega
    np.testing.assert_allclose(kstar, 1e5 + 1j * w * 2e5 * 400 / (2e5 + 1j * w * 400))
    assert kstar[0].real == pytest.approx(1e5, rel=1e-6)
    assert kstar[-1].real == pytest.approx(3e5, rel=1e-6)


def test_fractional_limits_are_k0_and_kinf() -> None:
    ctx = Context(np.array([1e-9, 1e9]))
    p = {"K_0": 1e5, "K_inf": 1e6, "tau": 1e-3, "alpha": 0.5}
    kstar = Fractional().modulus(ctx, p)
    assert kstar[0].real == pytest.approx(1e5, rel=1e-3)
    assert kstar[1].real == pytest.approx(1e6, rel=1e-3)


def test_open_maxwell_expands_into_concrete_orders_and_refuses_to_predict() -> None:
    model = parse_spec("maxwell")
    assert model.is_open
    assert [m.spec for m in model.candidates()] == [f"maxwell({n})" for n in range(1, 6)]
    with pytest.raises(InputError, match="fit it first"):
        model.predict(Context(FREQUENCY), TABLE)


# -- extension points: a term written and registered here, outside the package ---------------


@pytest.fixture
def probe_terms() -> Iterator[None]:
    """Register two test terms for one test and take them out again."""

    class Stiffen(Term):
        """Multiplies K* by (1 + g): a stage-2 modifier."""

        keyword = "test_stiffen"

        def parameters(self) -> tuple[Parameter, ...]:
            return (Parameter("g", "", -0.5, 0.5, 0.0, log=False),)

        def modify_modulus(self, ctx: Context, p: Mapping[str, float], kstar):  # type: ignore[no-untyped-def]
            return kstar * (1 + p["g"])

    class Mass(Term):
        """A rigid mass added to the disc: stage 3, and takes an argument (its count)."""

        keyword = "test_mass"

        def __init__(self, argument: float | None = None) -> None:
            self.argument = argument

        def parameters(self) -> tuple[Parameter, ...]:
            return (Parameter("m", "kg", 1e-6, 1.0, 0.01),)

        def disc_stiffness(self, ctx: Context, p: Mapping[str, float]):  # type: ignore[no-untyped-def]
            return -(ctx.omega**2) * p["m"]

    register_term(Stiffen)
    register_term(Mass)
    try:
        yield
    finally:
        del TERMS["test_stiffen"], TERMS["test_mass"]


@pytest.mark.usefixtures("probe_terms")
def test_registered_terms_compose_and_get_suffixes() -> None:
    model = parse_spec("test_mass(2)+voigt+test_stiffen+test_mass(1)")
    assert model.spec == "voigt+test_stiffen+test_mass(1)+test_mass(2)"
    assert model.names[-4:] == ("M_v", "g", "m_1", "m_2")
    assert parse_spec(model.spec).spec == model.spec
    values = {**TABLE, "K_v": 1e5, "C_v": 100.0, "M_v": 0.2, "g": 0.1, "m_1": 0.01, "m_2": 0.02}
    frfs = model.predict(Context(FREQUENCY), values)
    w = 2 * np.pi * FREQUENCY
    d_disc = (1e5 + 1j * w * 100.0) * 1.1 - w**2 * (0.2 + 0.03)
    np.testing.assert_allclose(frfs["support"], -(w**2) / d_disc, rtol=1e-12)


def test_registering_a_clashing_keyword_is_refused() -> None:
    class Other(Term):
        keyword = "voigt"

    with pytest.raises(ValueError, match="already registered"):
        register_term(Other)


def test_a_channel_term_sent_to_a_worker_process_keeps_its_channel():
    """Diagnosis renames a channel delay fitted negative to the other channel of its FRF, by
    the channel's identity; a term that came back from a worker process must still be on one
    of the four channels, not on a copy that matches none."""
    import pickle

    from viscorig.models.sensors import CHANNELS, Delay

    for name, channel in CHANNELS.items():
        assert pickle.loads(pickle.dumps(channel)) is channel
        term = pickle.loads(pickle.dumps(Delay(name)))
        assert term.channel is channel
        others = [c for c in CHANNELS.values() if c.frf == term.channel.frf
                  and c is not term.channel]
        assert len(others) == 1 and others[0].name != name


def test_modifiers_give_kstar_at_their_reference_without_their_covariate() -> None:
    """K* on a grid or at one frequency (a plot, the report's headline) has no test time,
    amplitude or temperature: each modifier then gives K* at its reference, never an error."""
    f = np.array([20.0, 60.0, 120.0])
    base = {"K_v": 2e5, "C_v": 100.0, "M_v": 0.15}
    voigt = parse_spec("voigt").kstar(Context(f), base)
    spec = "voigt+drift+amplitude+temperature(25)"
    values = {**base, "kappa": -1e-5, "beta": 0.1, "gamma": -0.02}
    np.testing.assert_allclose(parse_spec(spec).kstar(Context(f), values), voigt)
    kraus = {**base, "K_f": 5e4, "L_f": 1.5e3, "x_c": 2.5e-4, "m_k": 1.5}
    np.testing.assert_allclose(parse_spec("voigt+kraus").kstar(Context(f), kraus), voigt + 5e4)
    # with the covariates the modifiers act
    moved = parse_spec(spec).kstar(Context(f, np.full(3, 3600.0), np.full(3, 1.0),
                                           np.full(3, 35.0)), values)
    assert np.all(np.abs(moved / voigt - 1) > 0.05)


def test_a_plus_inside_parentheses_is_the_number_s_not_a_join() -> None:
    """'fixture(1e+2)' was split at its exponent's sign: 'malformed term'."""
    assert parse_spec("voigt+fixture(1e+2)+load_cell").spec == "voigt+load_cell+fixture(100)"
