"""The settle rule against the time-domain simulator.

The simulator carries the rig's state from point to point, so a short settle leaves the
transient of the frequency change in the measured point. For each change, the point measured
with the rule's settle is compared with the same point after a settle of 5000 cycles on the
noiseless rig: the difference (the bias the settle left) must stay below a fraction of the
point's noise, and a point measured without settling must show far more (the transient is
there to be settled).
"""

from __future__ import annotations

import numpy as np
import pytest
from planning_rig import TABLE, VOIGT_RIG, VOIGT_TRUTH, SimulatedRig, load

from viscorig.fitting import fit
from viscorig.models import parse_spec
from viscorig.planning import (
    InformationModel,
    Mode,
    fit_noise_forecast,
    identified_modes,
    log_grid,
    point_noise_power,
)
from viscorig.planning.batch import point_context, settle_points


@pytest.fixture(scope="module")
def context():
    rig = SimulatedRig(VOIGT_RIG, 1.4, seed=1)
    look = rig.measure(log_grid((20.0, 120.0), 30), 300, 10)
    result = fit("voigt", look.frf_data(), fixed=TABLE)
    power, source = point_noise_power(look)
    info = InformationModel(result.model, result.values, result.free,
                            fit_noise_forecast(look, power, source), 1.4, 100.0)  # fmt: skip
    modes = identified_modes(result.model, result.values, (20.0, 120.0))
    return point_context(info, modes)


def _measured(previous_hz, frequency_hz, settle, cycles):
    rig = SimulatedRig(load(VOIGT_RIG).noiseless(), 1.4)
    if previous_hz is not None:
        rig.measure([previous_hz], 3000, 50)
    point = rig.measure([frequency_hz], settle, cycles)
    return np.array([point.accelerance_table[0], point.accelerance_support[0]])


@pytest.mark.parametrize(
    ("previous_hz", "frequency_hz", "cycles"),
    [(None, 20.0, 234), (30.0, 38.0, 200), (120.0, 20.0, 234), (20.0, 26.25, 234),
     (37.5, 37.75, 200)],
)  # fmt: skip
def test_the_rule_settles_below_a_third_of_the_noise(context, previous_hz, frequency_hz, cycles):
    planned, _ = settle_points([(frequency_hz, cycles, "refine")], previous_hz, context)
    settle = planned[0].settle_cycles  # on the lead-in, the long point follows unsettled
    assert planned[-1].integrate_cycles == cycles
    sigma = context.noise_sd(np.array([frequency_hz]), np.array([cycles / frequency_hz]))[0]
    steady = _measured(previous_hz, frequency_hz, 5000, cycles)
    with_rule = _measured(previous_hz, frequency_hz, settle, cycles)
    unsettled = _measured(previous_hz, frequency_hz, 0, cycles)
    assert np.max(np.abs(with_rule / steady - 1)) < 0.35 * sigma
    assert np.max(np.abs(unsettled / steady - 1)) > 5 * sigma


def test_modes_are_read_off_the_fitted_model():
    model = parse_spec("voigt")
    modes = identified_modes(model, VOIGT_TRUTH, (20.0, 120.0))
    stiffness = VOIGT_TRUTH["K_s"] + VOIGT_TRUTH["K_v"]
    mass = VOIGT_TRUTH["M_s"] + VOIGT_TRUTH["M_v"]
    f_n = np.sqrt(stiffness / mass) / (2 * np.pi)
    zeta = (VOIGT_TRUTH["C_s"] + VOIGT_TRUTH["C_v"]) / (2 * np.sqrt(stiffness * mass))
    assert modes[0].frequency_hz == pytest.approx(f_n, rel=0.02)
    assert modes[0].damping_ratio == pytest.approx(zeta, rel=0.05)


def test_a_fixture_term_brings_its_own_slower_mode_near_its_frequency():
    model = parse_spec("voigt+fixture(58)")
    values = {**VOIGT_TRUTH, "f_n_1": 58.0, "zeta_1": 0.02, "m_1": 0.003}
    values = {name: values.get(name, values.get(name + "_1", 0.0)) for name in model.names}
    modes = identified_modes(model, values, (20.0, 120.0))
    local = [m for m in modes if m.mass_ratio > 0]
    assert len(local) == 1 and local[0].frequency_hz == pytest.approx(58.0)
    assert local[0].weight(57.0, 58.0) > 10 * local[0].weight(20.0, 21.0)
    assert Mode(38.0, 0.07).weight(20.0) == 1.0
