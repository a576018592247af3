"""Channel terms (``delay(x_v)``, ``gain(F_v)``, ``highpass(F_e)``, ``lowpass(x_s)``) recover
the sensor chain the time-domain simulator planted on one channel."""

from __future__ import annotations

import pytest
from simdata import DEFAULT_NOISE, rig_text, simulate_run

from viscorig.errors import InputError
from viscorig.fitting import fit
from viscorig.models import parse_spec

TABLE = {"M_s": 3.4, "K_s": 50194.0, "C_s": 5.05}
VOIGT = {"mass_kg": 0.25, "model": "voigt", "stiffness_n_per_m": 1.5e5, "damping_ns_per_m": 114.59}
QUIET = {key: value / 10 for key, value in DEFAULT_NOISE.items()}


@pytest.mark.parametrize(
    ("rig_lines", "spec", "name", "expected", "tolerance"),
    [
        ("[delays]\ndisc_acceleration_s = 3.5e-5\n", "delay(x_v)", "tau_x_v", 3.5e-5, 1e-6),
        # the load cell lagging reads as the disc accelerometer leading
        ("[delays]\ndevice_force_s = 3.5e-5\n", "delay(x_v)", "tau_x_v", -3.5e-5, 1e-6),
        ("[delays]\ndevice_force_s = 3.5e-5\n", "delay(F_v)", "tau_F_v", 3.5e-5, 1e-6),
        ("[sensors.device_force]\ngain = 1.02\n", "gain(F_v)", "gain_F_v", 1.02, 1e-3),
        ("[sensors.table_acceleration]\ngain = 0.97\n", "gain(x_s)", "gain_x_s", 0.97, 1e-3),
        ("[sensors.excitation_force]\nhighpass_hz = 1.0\n", "highpass(F_e)", "f_hp_F_e", 1.0,
         0.02),
        ("[sensors.disc_acceleration]\nhighpass_hz = 2.0\n", "highpass(x_v)", "f_hp_x_v", 2.0,
         0.02),
        ("[sensors.table_acceleration]\nlowpass_hz = 1500.0\n", "lowpass(x_s)", "f_lp_x_s",
         1500.0, 15.0),
    ],
)
def test_channel_term_recovers_the_planted_chain(
    rig_lines: str, spec: str, name: str, expected: float, tolerance: float
) -> None:
    run = simulate_run(rig_text(VOIGT, noise=QUIET, extra=rig_lines), seed=2, step_hz=0.5)
    result = fit(f"voigt+{spec}", run.frf_data(), fixed=TABLE)
    assert result.values[name] == pytest.approx(expected, abs=tolerance)
    assert result.values["K_v"] == pytest.approx(1.5e5, rel=1e-3)
    assert result.rms_error <= 1.3 * result.noise_floor
    plain = fit("voigt", run.frf_data(), fixed=TABLE)
    assert plain.rms_error > 3 * result.rms_error  # the term is what was missing


def test_shared_delay_of_both_accelerometers_keeps_its_meaning() -> None:
    lines = "[delays]\ntable_acceleration_s = 5e-5\ndisc_acceleration_s = 5e-5\n"
    run = simulate_run(rig_text(VOIGT, noise=QUIET, extra=lines), seed=2, step_hz=0.5)
    result = fit("voigt+delay", run.frf_data(), fixed=TABLE)
    assert result.values["tau_d"] == pytest.approx(5e-5, abs=1e-6)
    assert result.rms_error <= 1.3 * result.noise_floor


def test_channel_terms_in_spec_strings() -> None:
    model = parse_spec("voigt+gain(f_v)+delay(x_v)+highpass(F_e)+lowpass(X_S)")
    assert model.spec == "voigt+delay(x_v)+gain(F_v)+highpass(F_e)+lowpass(x_s)"
    assert {"tau_x_v", "gain_F_v", "f_hp_F_e", "f_lp_x_s"} <= set(model.names)
    assert parse_spec(model.spec).spec == model.spec
    two = parse_spec("voigt+delay(x_v)+delay(F_e)")
    assert two.spec == "voigt+delay(F_e)+delay(x_v)"
    for bad, message in [("voigt+gain", "needs a channel"), ("voigt+delay(y)", "unknown channel"),
                         ("voigt+highpass(58)", "unknown channel")]:  # fmt: skip
        with pytest.raises(InputError, match=message):
            parse_spec(bad)
