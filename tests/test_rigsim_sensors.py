"""Per-channel sensor chains of the simulated rig: gain errors and conditioning filters.

Expected values are written here from the filters' textbook transfer functions and from a
brute-force ODE integration, not from the engine's code path.
"""

from __future__ import annotations

import numpy as np
import pytest
from rigsim.dynamics import build_state_space
from rigsim.engine import RigSimulator
from rigsim.measurement import SourceControl, SweepRequest
from rigsim.rigfile import RigFileError, parse_rig
from scipy.integrate import simpson, solve_ivp

RIG = """
[table]
mass_kg = 3.4
stiffness_n_per_m = 50194.0
damping_ns_per_m = 5.05

[device]
mass_kg = 0.2
model = "voigt"
stiffness_n_per_m = 149986.61
damping_ns_per_m = 114.59
"""
CHANNELS = ("excitation_force", "table_acceleration", "device_force", "disc_acceleration")


def sweep(text: str, frequency: np.ndarray, settle_cycles: float = 100.0, seed: int = 0):
    request = SweepRequest(
        frequency_hz=frequency,
        settle_s=settle_cycles / frequency,
        integrate_s=100.0 / frequency,
        control=SourceControl(source_vpk=0.05),
    )
    return RigSimulator(parse_rig(text), seed=seed).sweep(request)


@pytest.mark.parametrize("channel", range(4))
def test_gain_error_scales_one_channel(channel: int) -> None:
    frequency = np.array([25.0, 70.0, 110.0])
    plain = sweep(RIG, frequency).channel_v
    text = RIG + f"[sensors.{CHANNELS[channel]}]\ngain = 1.03\n"
    scaled = sweep(text, frequency).channel_v
    expected = np.ones(4)
    expected[channel] = 1.03
    np.testing.assert_allclose(scaled / plain, np.broadcast_to(expected, (3, 4)), rtol=1e-9)


@pytest.mark.parametrize("channel", [0, 3])
def test_highpass_and_lowpass_follow_first_order_filters(channel: int) -> None:
    frequency = np.array([20.0, 45.0, 90.0, 120.0])
    plain = sweep(RIG, frequency).channel_v
    text = RIG + f"[sensors.{CHANNELS[channel]}]\nhighpass_hz = 2.0\nlowpass_hz = 800.0\n"
    filtered = sweep(text, frequency).channel_v
    s = 2j * np.pi * frequency
    expected = s / (s + 2 * np.pi * 2.0) * (2 * np.pi * 800.0) / (s + 2 * np.pi * 800.0)
    np.testing.assert_allclose(filtered[:, channel] / plain[:, channel], expected, rtol=1e-6)
    others = [k for k in range(4) if k != channel]
    np.testing.assert_allclose(filtered[:, others], plain[:, others], rtol=1e-9)


def test_filter_transient_matches_brute_force_time_integration() -> None:
    """A short settle leaves the charge amplifier's transient in the reading, as an ODE says."""
    text = RIG + "[sensors.device_force]\nhighpass_hz = 5.0\nlowpass_hz = 300.0\n"
    rig = parse_rig(text)
    frequency = np.array([30.0, 31.5])
    settle, integrate = np.array([0.02, 0.01]), np.array([0.1, 0.12])
    record = RigSimulator(rig).sweep(
        SweepRequest(frequency, settle, integrate, SourceControl(source_vpk=0.1))
    )
    # Brute force: the mechanical rig (no filters) and the two filters as explicit ODEs.
    space = build_state_space(parse_rig(RIG))
    n = space.a.shape[0]
    force = 0.1 * rig.shaker.force_n_per_v
    w_h, w_l = 2 * np.pi * 5.0, 2 * np.pi * 300.0
    state = np.zeros(n + 2)
    phase = 0.0
    for k, f in enumerate(frequency):
        w, end = 2 * np.pi * f, settle[k] + integrate[k]

        def rhs(t, z, w=w, phase=phase):
            u = force * np.cos(w * t + phase)
            y = space.c[2] @ z[:n] + space.d[2] * u
            high = y - z[n]
            return np.concatenate([space.a @ z[:n] + space.b * u,
                                   [w_h * (y - z[n]), w_l * (high - z[n + 1])]])

        solution = solve_ivp(rhs, (0, end), state, method="DOP853", rtol=1e-11, atol=1e-14,
                             dense_output=True)
        t = np.linspace(settle[k], end, 20001)
        reading = solution.sol(t)[n + 1]
        expected = 2 / integrate[k] * simpson(reading * np.exp(-1j * (w * t + phase)), x=t)
        assert record.channel_v[k, 2] == pytest.approx(expected * 0.01124, rel=1e-6)
        state = solution.y[:, -1]
        phase += w * end
    # and the transient is really there: a long settle reads another value
    settled = sweep(text, frequency, settle_cycles=200).channel_v[:, 2]
    assert abs(record.channel_v[0, 2] / settled[0] - 1) > 1e-3


def test_sensor_sections_are_read_and_checked() -> None:
    text = RIG + "[sensors]\nforce_v_per_n = 0.01\n[sensors.disc_acceleration]\ngain = 0.98\n"
    rig = parse_rig(text)
    assert rig.sensors.force_v_per_n == 0.01 and rig.sensors.acceleration_v_per_m_s2 == 0.0102
    assert rig.sensors.gains() == (1.0, 1.0, 1.0, 0.98)
    assert rig.sensors.conditioning[3].highpass_hz is None
    for bad, message in [
        ("[sensors.disc_acceleration]\ngain = 0\n", "sensors.disc_acceleration.gain: must be >="),
        ("[sensors.disc_acceleration]\nhighpass_hz = -1\n", "highpass_hz: must be >="),
        ("[sensors.disc_acceleration]\ndelay_s = 1e-5\n", "unknown key sensors.disc_acceleration"),
        ("[sensors.disc]\ngain = 1.0\n", "unknown key sensors.disc"),
    ]:
        with pytest.raises(RigFileError, match=message):
            parse_rig(RIG + bad, "x.toml")
