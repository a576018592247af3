"""A fractional K* carried into a fit from a model that lacked a term can sit decades past the
band, where only ``(K_inf − K_0) τ^α`` shapes it: the likelihood fit starts such a K* from the
data instead, and reaches the optimum in a fraction of the solver steps."""

from __future__ import annotations

import numpy as np
from ladder_reference import TABLE, measured_run
from rigsim.rigfile import FractionalMaterial, load_preset

from viscorig.diagnosis.data import combine
from viscorig.diagnosis.weighted import ml_fit
from viscorig.models import Fractional, parse_spec

#: Far into the valley: the transition five decades above the band, K_inf twenty times K_0.
CORNER = {"K_0": 1.0e6, "K_inf": 3.0e7, "tau": 1e-9, "alpha": 0.38, "M_v": 0.14, "K_c": 1e7}


def test_resolved_says_where_the_band_pins_the_relaxation_time() -> None:
    omega = 2 * np.pi * np.array([20.0, 120.0])
    term = Fractional()
    truth = load_preset("hard-0").device.material
    assert isinstance(truth, FractionalMaterial)
    assert term.resolved(omega, {"tau": truth.tau_s})
    assert not term.resolved(omega, {"tau": 1e-9})  # transition 6 decades above the band
    assert not term.resolved(omega, {"tau": 1e3})  # 5 decades below it


def test_a_fit_started_in_the_valley_reaches_the_optimum_in_few_steps() -> None:
    data = combine([("hard-0", measured_run("hard-0"))], table=TABLE)
    model = parse_spec("fractional+load_cell+fixture(38)+fixture(58)+fixture(92)")
    start = {**model.defaults(), **CORNER}
    short = ml_fit(model, data, start, max_steps=60)
    full = ml_fit(model, data, {**start, "tau": 1e-4, "K_inf": 1.6e6})
    # carried from the corner, 60 steps left χ² 2.5 times higher and τ at 3e-8 s
    assert short.chi2 <= full.chi2 * (1 + 1e-6)
    truth = load_preset("hard-0").device.material
    assert isinstance(truth, FractionalMaterial)
    stderr = short.stderr()
    assert abs(short.values["tau"] - truth.tau_s) < 3 * stderr["tau"]
