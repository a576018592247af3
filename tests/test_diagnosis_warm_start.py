"""A ladder tries a fractional K* at its first rung and again at the next, once the Maxwell K*
it chose has an arm more: the second try starts from the first's optimum (the same model, under
a prior weighed a little differently) and reaches as low a ``χ²`` in a fraction of the solver's
evaluations, where ``identify``'s fit from the linear start followed the relaxation time's
valley again."""

from __future__ import annotations

import numpy as np
import pytest
from ladder_reference import TABLE, measured_run
from scipy.optimize import least_squares

from viscorig.diagnosis import diagnose
from viscorig.diagnosis import weighted as weighted_module
from viscorig.diagnosis.data import combine
from viscorig.diagnosis.findings import fit_term
from viscorig.diagnosis.significance import dispersion
from viscorig.diagnosis.weighted import ml_fit
from viscorig.fitting import nonlinear as nonlinear_module
from viscorig.models import parse_spec


@pytest.fixture(scope="module")
def data():
    return combine([("medium-10", measured_run("medium-10"))], table=TABLE)


def counted(monkeypatch: pytest.MonkeyPatch) -> list[int]:
    """The objective evaluations of every least-squares solve from here on (both solvers)."""
    evaluations: list[int] = []

    def solve(*arguments, **options):
        solution = least_squares(*arguments, **options)
        evaluations.append(int(solution.nfev))
        return solution

    monkeypatch.setattr(weighted_module, "least_squares", solve)
    monkeypatch.setattr(nonlinear_module, "least_squares", solve)
    return evaluations


def test_each_rung_hands_on_the_models_it_fitted(data) -> None:
    first = diagnose(data, "voigt")
    assert {"voigt", "fractional", "maxwell(2)"} <= set(first.optima)
    before = {spec: dict(values) for spec, values in first.optima.items()}
    second = first.with_significant()
    assert second.model == "maxwell(2)"
    assert set(first.optima) < set(second.optima)
    # a rung's record is its own: the one before it is unchanged, so that climbing again
    # from it gives the same rungs
    assert first.optima == before


def test_a_fractional_tried_again_starts_from_its_optimum(data, monkeypatch) -> None:
    earlier = ml_fit(parse_spec("fractional"), data, {}).values
    current = ml_fit(parse_spec("maxwell(2)"), data, {})
    evaluations = counted(monkeypatch)
    again = fit_term(current, data, "fractional", {}, earlier=earlier)
    warm = sum(evaluations)
    evaluations.clear()
    afresh = fit_term(current, data, "fractional", {})
    cold = sum(evaluations)
    phi = dispersion(afresh.chi2, data.residual_count, len(afresh.free))
    assert again.chi2 <= afresh.chi2 + 0.05 * phi
    print(f"evaluations: {warm} from the earlier optimum, {cold} afresh")
    assert warm < 0.5 * cold
    assert np.isclose(again.values["alpha"], afresh.values["alpha"], rtol=0.02)
