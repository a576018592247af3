"""Several parameter sets evaluated at once (``predict_many``, every finite-difference Jacobian
of the fitters) give each set's own prediction, for every kind of term, and a term written for
scalars only is evaluated set by set."""

from __future__ import annotations

from collections.abc import Iterator, Mapping

import numpy as np
import pytest

from viscorig.fitting.jacobian import predict_many
from viscorig.models import TERMS, Context, Parameter, Term, parse_spec, register_term

FREQUENCY = np.linspace(20.0, 120.0, 57)
CONTEXT = Context(FREQUENCY, time_s=np.linspace(0.0, 3600.0, 57),
                  reference_amplitude=np.full(57, 9.81),
                  temperature_c=np.linspace(20.0, 24.0, 57))
TABLE = {"M_s": 3.4, "K_s": 2.0e5, "C_s": 60.0}
SPECS = (
    "fractional+load_cell+fixture(58)+fixture(92)+delay(x_v)+gain(x_s)+drift",
    "maxwell(2)+amplitude+highpass(F_e)+lowpass(x_s)+temperature(20)",
    "voigt+frame+kraus+delay",
)


def _rows(model, values: Mapping[str, float], rng) -> tuple[list[str], np.ndarray]:
    """A forward-difference step of every parameter, one set each, and one set moving all."""
    names = [n for n in model.names if n not in TABLE]
    base = np.array([values[n] for n in names])
    steps = base * 1e-3 + 1e-9
    rows = base[None, :] + np.diag(steps)
    return names, np.vstack([rows, base * (1 + 0.01 * rng.standard_normal(base.size))])


def _values(model) -> dict[str, float]:
    values = {**model.defaults(), **TABLE}
    values.update({n: v for n, v in {"M_v": 0.15, "K_c": 5e6, "f_n_1": 58.0,
                                      "f_n_2": 92.0}.items() if n in values})
    return values


@pytest.mark.parametrize("spec", SPECS)
def test_every_set_is_its_own_prediction(spec: str) -> None:
    model = parse_spec(spec)
    values = _values(model)
    names, rows = _rows(model, values, np.random.default_rng(1))
    together = predict_many(model, CONTEXT, values, names, rows)
    for index, row in enumerate(rows):
        alone = model.predict(CONTEXT, {**values, **dict(zip(names, row, strict=True))})
        for frf, h in alone.items():
            np.testing.assert_allclose(together[frf][index], h, rtol=1e-12, atol=0.0)


@pytest.fixture
def scalar_term() -> Iterator[None]:
    class Softened(Term):
        """Scales K* by a factor read as a Python float: scalars only."""

        keyword = "test_softened"

        def __init__(self, argument: float | None = None) -> None:
            self.argument = argument

        def parameters(self) -> tuple[Parameter, ...]:
            return (Parameter("s", "", 0.5, 2.0, 1.0, log=False),)

        def modify_modulus(self, ctx: Context, p: Mapping[str, float], kstar):  # type: ignore[no-untyped-def]
            return kstar * float(p["s"])

    register_term(Softened)
    try:
        yield
    finally:
        del TERMS["test_softened"]


@pytest.mark.usefixtures("scalar_term")
def test_a_term_for_scalars_only_is_evaluated_set_by_set() -> None:
    model = parse_spec("voigt+test_softened")
    values = {**_values(model), "s": 0.9}
    names, rows = _rows(model, values, np.random.default_rng(2))
    together = predict_many(model, CONTEXT, values, names, rows)
    column = names.index("s")
    for index, row in enumerate(rows):
        alone = model.predict(CONTEXT, {**values, **dict(zip(names, row, strict=True))})
        np.testing.assert_allclose(together["support"][index], alone["support"], rtol=1e-12)
    # the factor really moved with its row: the batch did not hold one value for all sets
    assert not np.allclose(together["support"][column], together["support"][0], rtol=1e-6)
