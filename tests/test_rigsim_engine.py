"""RigSimulator against closed forms written here, independently of the engine's code path."""

from __future__ import annotations

import numpy as np
import pytest
from rigsim.dynamics import build_state_space
from rigsim.engine import RigSimulator
from rigsim.measurement import INPUT_RANGES_VPK, SourceControl, SweepRequest
from rigsim.rigfile import parse_rig
from scipy.integrate import simpson, solve_ivp

FORCE_V_PER_N = 0.01124
ACCEL_V_PER_M_S2 = 0.0102
TABLE = """
[table]
mass_kg = 3.4
stiffness_n_per_m = 50194.0
damping_ns_per_m = 5.05
"""
DEVICES = {
    "voigt": """
[device]
mass_kg = 0.2
model = "voigt"
stiffness_n_per_m = 149986.61
damping_ns_per_m = 114.59
""",
    "maxwell": """
[device]
mass_kg = 0.2
model = "maxwell"
static_stiffness_n_per_m = 1.2e5
arms = [[5.0e4, 100.0], [2.0e5, 40.0], [1.0e6, 30.0]]
""",
    "fractional": """
[device]
mass_kg = 0.2
model = "fractional"
static_stiffness_n_per_m = 1.25e5
high_stiffness_n_per_m = 4.7e5
tau_s = 8.0e-5
alpha = 0.5
""",
}
LOAD_CELL = """
[load_cell]
stiffness_n_per_m = 3.0e6
"""
FIXTURES = """
[[fixture]]
frequency_hz = 58.0
damping_ratio = 0.02
mass_kg = 0.005

[[fixture]]
frequency_hz = 92.0
damping_ratio = 0.03
mass_kg = 0.003
"""


def k_star(text: str, w: np.ndarray) -> np.ndarray:
    """Closed-form K* of the device in a rig text (parsed here from the TOML itself)."""
    import tomllib

    device = tomllib.loads(text)["device"]
    if device["model"] == "voigt":
        return device["stiffness_n_per_m"] + 1j * w * device["damping_ns_per_m"]
    if device["model"] == "maxwell":
        total = device["static_stiffness_n_per_m"] + 0j * w
        for k, c in device["arms"]:
            total = total + 1j * w * k * c / (k + 1j * w * c)
        return total
    z = (1j * w * device["tau_s"]) ** device["alpha"]
    return (device["static_stiffness_n_per_m"] + device["high_stiffness_n_per_m"] * z) / (1 + z)


def closed_form(text: str, w: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Accelerances ẍ_s/F_e and ẍ_v/F_v of physics.md, with fixture modes on the disc."""
    import tomllib

    data = tomllib.loads(text)
    m_s = data["table"]["mass_kg"]
    d_s = data["table"]["stiffness_n_per_m"] - w**2 * m_s + 1j * w * data["table"][
        "damping_ns_per_m"
    ]
    m_v = data["device"]["mass_kg"]
    z_v = k_star(text, w) - w**2 * m_v
    for mode in data.get("fixture", []):
        wn = 2 * np.pi * mode["frequency_hz"]
        k_f = mode["mass_kg"] * wn**2 + 2j * mode["damping_ratio"] * mode["mass_kg"] * wn * w
        z_v = z_v - w**2 * mode["mass_kg"] * k_f / (k_f - w**2 * mode["mass_kg"])
    if "load_cell" in data:
        k_c = data["load_cell"]["stiffness_n_per_m"]
        det = (d_s + k_c) * (z_v + k_c) - k_c**2
        x_s = (z_v + k_c) / det
    else:
        x_s = 1.0 / (d_s + z_v)
    x_v_over_f_v = 1.0 / z_v
    return -(w**2) * x_s, -(w**2) * x_v_over_f_v


def measured_accelerances(record) -> tuple[np.ndarray, np.ndarray]:
    ch = record.channel_v
    scale = FORCE_V_PER_N / ACCEL_V_PER_M_S2
    with np.errstate(invalid="ignore", divide="ignore"):  # bare table: no device channels
        return ch[:, 1] / ch[:, 0] * scale, ch[:, 3] / ch[:, 2] * scale


def cycles_request(frequency, settle_cycles, integrate_cycles, control=None, ranges=None):
    frequency = np.asarray(frequency, dtype=float)
    return SweepRequest(
        frequency_hz=frequency,
        settle_s=settle_cycles / frequency,
        integrate_s=integrate_cycles / frequency,
        control=control or SourceControl(source_vpk=0.05),
        input_range_vpk=ranges or (None,) * 4,
    )


@pytest.mark.parametrize("model", sorted(DEVICES))
@pytest.mark.parametrize("extras", ["", LOAD_CELL, LOAD_CELL + FIXTURES, FIXTURES])
def test_noiseless_long_settle_matches_closed_form(model: str, extras: str) -> None:
    text = TABLE + DEVICES[model] + extras
    sim = RigSimulator(parse_rig(text))
    frequency = np.linspace(20.0, 120.0, 41)
    record = sim.sweep(cycles_request(frequency, 100, 100))
    table, support = measured_accelerances(record)
    exp_table, exp_support = closed_form(text, 2 * np.pi * frequency)
    assert np.max(np.abs(table / exp_table - 1)) < 1e-3
    assert np.max(np.abs(support / exp_support - 1)) < 1e-3


def test_transient_matches_brute_force_time_integration() -> None:
    """Short settle: the exact modal solution equals an ODE integration of the same rig."""
    rig = parse_rig(TABLE + DEVICES["maxwell"] + LOAD_CELL)
    sim = RigSimulator(rig)
    frequency = np.array([40.0, 41.3])
    settle = np.array([0.05, 0.02])
    integrate = np.array([0.1, 0.13])
    control = SourceControl(source_vpk=0.1)
    record = sim.sweep(SweepRequest(frequency, settle, integrate, control))
    space = build_state_space(rig)
    sensitivity = np.array([FORCE_V_PER_N, ACCEL_V_PER_M_S2] * 2)
    state = np.zeros(space.a.shape[0])
    phase = 0.0
    force = 0.1 * rig.shaker.force_n_per_v
    for n, f in enumerate(frequency):
        w, end = 2 * np.pi * f, settle[n] + integrate[n]

        def rhs(t, z, w=w, phase=phase):
            return space.a @ z + space.b * force * np.cos(w * t + phase)

        solution = solve_ivp(rhs, (0, end), state, method="DOP853", rtol=1e-11, atol=1e-14,
                             dense_output=True)
        t = np.linspace(settle[n], end, 20001)
        y = space.c @ solution.sol(t) + np.outer(space.d, force * np.cos(w * t + phase))
        expected = 2 / integrate[n] * simpson(y * np.exp(-1j * (w * t + phase)), x=t, axis=1)
        np.testing.assert_allclose(record.channel_v[n], expected * sensitivity, rtol=1e-7)
        state = solution.y[:, -1]
        phase += w * end


def test_short_settle_biases_near_lightly_damped_resonance() -> None:
    text = TABLE  # bare table: 19.3 Hz, damping ratio 0.0024, time constant 1.35 s
    frequency = np.arange(17.0, 22.0, 0.25)
    exp_table = -((2 * np.pi * frequency) ** 2) / (
        50194.0 - (2 * np.pi * frequency) ** 2 * 3.4 + 2j * np.pi * frequency * 5.05
    )

    def worst_error(settle_cycles: float) -> float:
        record = RigSimulator(parse_rig(text)).sweep(cycles_request(frequency, settle_cycles, 5))
        table, _ = measured_accelerances(record)
        return float(np.max(np.abs(table / exp_table - 1)))

    assert worst_error(2) > 0.05
    assert worst_error(400) < 1e-3


def test_frf_noise_falls_as_one_over_sqrt_integration_cycles() -> None:
    text = TABLE + DEVICES["voigt"] + """
[noise]
excitation_force_n_per_sqrt_hz = 2e-3
table_acceleration_m_per_s2_per_sqrt_hz = 2e-4
device_force_n_per_sqrt_hz = 2e-3
disc_acceleration_m_per_s2_per_sqrt_hz = 2e-4
"""
    frequency = np.full(400, 60.0)
    _, exact = closed_form(text, 2 * np.pi * frequency)
    scatter = {}
    for cycles in (10, 160):
        sim = RigSimulator(parse_rig(text), seed=3)
        record = sim.sweep(cycles_request(frequency, 50, cycles))
        _, support = measured_accelerances(record)
        scatter[cycles] = np.std(support / exact - 1)
        predicted = np.sqrt(record.variance[:, 2] + record.variance[:, 3])
        assert 0.8 < scatter[cycles] / np.mean(predicted) < 1.25
    assert 3.2 < scatter[10] / scatter[160] < 4.8  # sqrt(16) = 4


def test_auto_level_holds_reference_within_tolerance() -> None:
    rig = parse_rig(TABLE + DEVICES["fractional"] + LOAD_CELL + FIXTURES)
    target = 1.0 * ACCEL_V_PER_M_S2
    control = SourceControl(source_vpk=0.01, auto_level=True, reference_channel=4,
                            reference_vpk=target, tolerance_db=0.5, source_limit_vpk=2.0)
    record = RigSimulator(rig).sweep(cycles_request(np.arange(20, 120.01, 1.0), 20, 20, control))
    error_db = 20 * np.log10(np.abs(record.channel_v[:, 3]) / target)
    assert record.level_reached.all()
    assert np.max(np.abs(error_db)) <= 0.5
    assert record.extras["iterations"][0] > 1  # the first point starts far below the target
    # each controller iteration costs a settle and an integration window
    dwell = np.sum(record.extras["iterations"] * 40 / np.arange(20, 120.01, 1.0))
    assert record.end_time_s[-1] == pytest.approx(dwell)


def test_shaker_force_limit_flags_points() -> None:
    shaker = "[shaker]\nforce_n_per_v = 50.0\nforce_limit_n = 10.0\n"
    rig = parse_rig(TABLE + DEVICES["voigt"] + shaker)
    target = 5.0 * ACCEL_V_PER_M_S2  # 5 m/s² at 20 Hz needs about 25 N on this rig
    control = SourceControl(source_vpk=0.05, auto_level=True, reference_channel=4,
                            reference_vpk=target, source_limit_vpk=2.0)
    record = RigSimulator(rig).sweep(cycles_request([20.0, 38.0, 40.0], 30, 30, control))
    assert record.extras["force_limited"][0]
    assert not record.level_reached[0] and record.source_limited[0]
    assert abs(record.channel_v[0, 0]) == pytest.approx(10.0 * FORCE_V_PER_N, rel=1e-3)
    assert record.level_reached[1] and not record.extras["force_limited"][1]


def test_input_limit_holds_the_force_channel() -> None:
    rig = parse_rig(TABLE + DEVICES["voigt"])
    control = SourceControl(source_vpk=0.05, auto_level=True, reference_channel=4,
                            reference_vpk=5.0 * ACCEL_V_PER_M_S2, source_limit_vpk=2.0,
                            input_limit_channel=1, input_limit_vpk=8.0 * FORCE_V_PER_N)
    record = RigSimulator(rig).sweep(cycles_request([20.0], 30, 30, control))
    assert record.input_limited[0] and not record.level_reached[0]
    assert abs(record.channel_v[0, 0]) <= 8.0 * FORCE_V_PER_N * 1.001


def test_fixed_range_overloads_and_autorange_does_not() -> None:
    rig = parse_rig(TABLE + DEVICES["voigt"])
    frequency = [40.0, 60.0]
    auto = RigSimulator(rig).sweep(cycles_request(frequency, 50, 50))
    assert not auto.overload.any()
    peak = np.abs(auto.channel_v)
    assert np.all(auto.range_vpk >= peak) and np.all(auto.range_vpk <= 1.6 * peak * 1.25)
    small = float(INPUT_RANGES_VPK[0.4 * peak[0, 1] > INPUT_RANGES_VPK][0])
    fixed = RigSimulator(rig).sweep(cycles_request(frequency, 50, 50, ranges=(None, small, None,
                                                                             None)))
    assert fixed.overload[0, 1] and fixed.half_range[0, 1]
    assert not fixed.overload[:, [0, 2, 3]].any()
    assert np.all(fixed.range_vpk[:, 1] == small)
    assert abs(fixed.channel_v[0, 1]) < abs(auto.channel_v[0, 1])  # clipped


def test_sensor_delay_is_a_phase() -> None:
    text = TABLE + DEVICES["voigt"] + "[delays]\ndisc_acceleration_s = 2.0e-4\n"
    frequency = np.array([30.0, 90.0])
    plain = RigSimulator(parse_rig(TABLE + DEVICES["voigt"])).sweep(
        cycles_request(frequency, 100, 100))
    delayed = RigSimulator(parse_rig(text)).sweep(cycles_request(frequency, 100, 100))
    ratio = delayed.channel_v[:, 3] / plain.channel_v[:, 3]
    np.testing.assert_allclose(ratio, np.exp(-2j * np.pi * frequency * 2.0e-4), atol=1e-6)
    np.testing.assert_allclose(delayed.channel_v[:, :3], plain.channel_v[:, :3])


def test_thermal_drift_softens_with_clock() -> None:
    text = TABLE + DEVICES["voigt"] + "[drift]\nmodulus_change_per_hour = -0.1\n"
    sim = RigSimulator(parse_rig(text))
    frequency = np.full(30, 60.0)
    record = sim.sweep(cycles_request(frequency, 3000, 3000))  # 100 s per point
    scale = record.extras["modulus_scale"]
    start = np.concatenate([[0.0], record.end_time_s[:-1]])
    np.testing.assert_allclose(scale, 1 - 0.1 * start / 3600)
    _, support = measured_accelerances(record)
    k_eff = -((2 * np.pi * 60.0) ** 2) / support + (2 * np.pi * 60.0) ** 2 * 0.2
    np.testing.assert_allclose(k_eff.real / 149986.61, scale, rtol=1e-4)


def test_amplitude_dependence_softens_at_high_level() -> None:
    text = TABLE + DEVICES["voigt"] + """
[amplitude]
softening_fraction = 0.3
reference_displacement_m = 1.0e-4
"""
    frequency = np.array([30.0])
    results = {}
    for level in (0.001, 1.0):
        sim = RigSimulator(parse_rig(text))
        record = sim.sweep(cycles_request(frequency, 200, 100, SourceControl(source_vpk=level)))
        x = record.extras["specimen_displacement_m"][0]
        expected = 1 - 0.3 * (x / 1e-4) / (1 + x / 1e-4)
        assert record.extras["modulus_scale"][0] == pytest.approx(expected, rel=1e-6)
        _, support = measured_accelerances(record)
        w = 2 * np.pi * 30.0
        results[level] = (-(w**2) / support[0] + w**2 * 0.2).real
    assert results[1.0] < 0.95 * results[0.001]


def test_clock_mount_and_idle() -> None:
    sim = RigSimulator(parse_rig(TABLE + DEVICES["voigt"]))
    record = sim.sweep(cycles_request([25.0, 50.0], 10, 10))
    assert record.end_time_s.tolist() == pytest.approx([0.8, 1.2])
    assert sim.clock_s == pytest.approx(1.2)
    assert np.any(sim.state() != 0)
    sim.idle(100.0)
    assert sim.clock_s == pytest.approx(101.2)
    assert np.max(np.abs(sim.state())) < 1e-12
    sim.mount(parse_rig(TABLE))
    assert sim.clock_s == 0.0 and not np.any(sim.state())
    assert sim.rig.device is None
