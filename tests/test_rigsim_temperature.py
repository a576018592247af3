"""The simulated chamber and the simulated rubber's temperature and strain amplitude, checked
against closed forms written here (the simulator integrates the rig in the time domain)."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest
from rigsim.chamber import Chamber, ChamberParameters
from rigsim.engine import RigSimulator
from rigsim.measurement import SourceControl, SweepRequest
from rigsim.rigfile import RigFileError, load_preset, parse_rig


def test_chamber_rates_and_lag() -> None:
    chamber = Chamber(ChamberParameters(heating_rate_k_per_min=6.0, cooling_rate_k_per_min=3.0,
                                        air_time_constant_s=1.0, specimen_time_constant_s=300.0,
                                        start_temperature_c=20.0))
    chamber.set_target(80.0)
    chamber.advance(60.0)
    assert chamber.air_c == pytest.approx(26.0, abs=0.01)  # clipped at 6 K/min
    assert chamber.output_percent == pytest.approx(100.0)
    chamber.advance(3000.0)
    assert chamber.air_c == pytest.approx(80.0, abs=0.01)
    specimen = chamber.specimen_c
    chamber.advance(300.0)  # one time constant: 63 % of the way
    assert 80.0 - chamber.specimen_c == pytest.approx((80.0 - specimen) * math.exp(-1), rel=0.01)
    chamber.set_rate(2.0)
    chamber.set_target(70.0)
    chamber.advance(60.0)
    assert chamber.working_c == pytest.approx(78.0)


def _kstar(rig, frequency_hz: float, temperature_c: float | None, force_v: float) -> complex:
    """K* = F_v/X_v + ω² M_v (Eq. 5) of the simulated rig, steady, noiseless."""
    simulator = RigSimulator(rig.noiseless(), seed=1)
    if temperature_c is not None:
        chamber = Chamber(ChamberParameters(start_temperature_c=temperature_c))
        simulator.attach_chamber(chamber, advance=False)
    f = np.array([frequency_hz])
    record = simulator.sweep(SweepRequest(f, np.array([20.0]), np.array([2.0]),
                                          SourceControl(force_v)))
    volts = record.channel_v[0]
    acceleration = volts[3] / rig.sensors.acceleration_v_per_m_s2
    force = volts[2] / rig.sensors.force_v_per_n
    omega = 2 * math.pi * frequency_hz
    return complex(force / (acceleration / -(omega**2)) + omega**2 * rig.device.mass_kg)


def test_wlf_shift_on_the_specimen_temperature() -> None:
    """At the temperature where a_T = 2, K* at 30 Hz is K* at 60 Hz at the reference."""
    rig = dataclasses.replace(load_preset("medium-chamber"), payne=None)
    shift = rig.temperature
    # log10 aT = log10 2: -c1 d / (c2 + d) = L  ->  d = -L c2 / (c1 + L)
    target = math.log10(2.0)
    temperature = shift.reference_temperature_c - target * shift.c2_k / (shift.c1 + target)
    cold = _kstar(rig, 30.0, temperature, 0.05)
    reference = _kstar(rig, 60.0, shift.reference_temperature_c, 0.05)
    assert abs(cold / reference - 1) < 2e-3
    assert abs(_kstar(rig, 30.0, shift.reference_temperature_c, 0.05) / reference - 1) > 0.02


def test_payne_difference_between_two_levels_is_kraus() -> None:
    """Between two drive levels the stiffness differs by the Kraus law at each amplitude,
    computed here from the rig file's parameters."""
    rig = load_preset("medium-chamber")
    payne = rig.payne
    f = 25.0
    omega = 2 * math.pi * f

    def kraus(x: float) -> complex:
        r = (x / payne.critical_displacement_m) ** payne.exponent
        return (payne.storage_drop_n_per_m + 2j * payne.loss_peak_n_per_m * r) / (1 + r * r)

    results = []
    for volts in (0.02, 1.0):
        simulator = RigSimulator(rig.noiseless(), seed=1)
        record = simulator.sweep(SweepRequest(np.array([f]), np.array([30.0]), np.array([2.0]),
                                              SourceControl(volts)))
        channel = record.channel_v[0]
        acceleration = channel[3] / rig.sensors.acceleration_v_per_m_s2
        force = channel[2] / rig.sensors.force_v_per_n
        kstar = force / (acceleration / -(omega**2))
        results.append((kstar, record.extras["specimen_displacement_m"][0]))
    (k_small, x_small), (k_large, x_large) = results
    assert x_large > 20 * x_small
    expected = kraus(x_large) - kraus(x_small)
    assert abs((k_large - k_small) - expected) < 0.01 * abs(expected)


@pytest.mark.parametrize(("section", "message"), [
    ("[temperature]\nreference_temperature_c = 25.0\nc1 = 6.6\nc2_k = 0.0\n", "c2_k: must be >"),
    ("[payne]\nstorage_drop_n_per_m = 1.0\nloss_peak_n_per_m = 1.0\n", "critical_displacement_m"),
    ("[chamber]\nheating_rate_k_per_min = -1.0\n", "heating_rate_k_per_min: must be >"),
    ("[chamber]\nfan = 1\n", "unknown key chamber.fan"),
])
def test_rig_file_sections(section: str, message: str) -> None:
    text = "[table]\nmass_kg = 3.4\nstiffness_n_per_m = 5e4\ndamping_ns_per_m = 5.0\n" + section
    with pytest.raises(RigFileError, match=message):
        parse_rig(text, source="rig.toml")
