"""``viscorig bench check``: the station self-test names each injected fault correctly.

Faults are injected into a ``viscorig sim serve`` process (its wiring: an unplugged input, two
swapped inputs, a sensitivity off by ten, an inverted accelerometer, a range stuck too small);
the check reaches it through a station file, as it reaches a lab's analyser. The judging logic
is also checked on readings built from the table's equation of motion directly.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from reliability_campaign import cli, one_clear_line, station_text
from simserve import sim_serve

from viscorig.acquisition.sweep import Wiring
from viscorig.benchcheck.checks import Readings, RigFacts, assess

#: The judging needs only which input carries which transducer, not their sensitivities.
ROLES = Wiring(1, 2, 3, 4, sensitivities_v_per_eu={})


def fails(out: str) -> list[str]:
    return [line for line in out.splitlines() if line.startswith("FAIL")]


def test_the_embedded_simulated_rig_passes_every_check() -> None:
    status, out, err = cli(["bench", "check"])
    assert status == 0, out + err
    passes = [line for line in out.splitlines() if line.startswith("PASS")]
    assert len(passes) == 8 and not fails(out)
    for needed in ("analyser: ", "input 1 noise", "input 4 noise", "transducer roles",
                   "overload", "level loop"):
        assert any(needed in line for line in passes), needed
    assert out.strip().splitlines()[-1] == "bench check: 8 of 8 checks passed"


@pytest.mark.slow
@pytest.mark.parametrize(("fault", "named"), [
    ("unplug=3", "FAIL  input 3 (device force): reads nothing at 10, 25, 45 Hz (no signal "
                 "above its own noise); check the cable or the ICP supply"),
    ("swap=1,2", "FAIL  transducer roles: inputs 1 and 2 read each other's transducer "
                 "(excitation force and table accelerometer); swap the cables of inputs 1 "
                 "and 2"),
    ("swap=2,3", "FAIL  transducer roles: inputs 2 and 3 read each other's transducer"),
    ("gain=3:10", "FAIL  input 3 (device force): reads 10 times what its role implies; its "
                  "sensitivity in the station file (or the amplifier's gain) is off by 10"),
    ("gain=2:0.1", "FAIL  input 2 (table accelerometer): reads 0.1 times what its role"),
    ("invert=4", "FAIL  input 4 (disc accelerometer): reads with the wrong sign; the "
                 "transducer is mounted upside down or its cable's polarity is reversed"),
    ("range=3:-51", "FAIL  overload: input 3 (device force) during the fixed-drive sine"),
    ("hum=3:0.005", "FAIL  input 3 noise: noise "),
])
def test_an_injected_fault_is_named(tmp_path: Path, fault: str, named: str) -> None:
    with sim_serve("--preset", "soft-0", "--seed", "2", "--fault", fault) as (_, _, resource, _):
        station = tmp_path / "station.toml"
        station.write_text(station_text(resource))
        status, out, err = cli(["bench", "check", "--station", station])
    assert status == 1, out + err
    assert any(line.startswith(named) for line in fails(out)), out
    if fault.startswith("hum"):  # 5 mV peak over 0.01124 V/N
        assert "mains lines at 50 Hz (0.31 N rms); mains hum" in out, out
    # the culprit is named, no healthy input is blamed
    culprit = {"unplug=3": "3", "gain=3:10": "3", "gain=2:0.1": "2", "invert=4": "4",
               "range=3:-51": "3", "hum=3:0.005": "3"}.get(fault)
    if culprit is not None:
        blamed = {line.split()[2].rstrip(":") for line in fails(out)
                  if line.startswith("FAIL  input ")}
        assert blamed <= {culprit}, out


@pytest.mark.slow
def test_a_station_without_table_parameters_skips_the_role_check(tmp_path: Path) -> None:
    with sim_serve("--preset", "soft-0", "--seed", "2") as (_, _, resource, _):
        station = tmp_path / "station.toml"
        station.write_text(station_text(resource, table=False))
        status, out, _ = cli(["bench", "check", "--station", station])
    assert status == 0
    assert "PASS  transducer roles: not checked: the station file gives no [table]" in out


@pytest.mark.parametrize(("arguments", "status", "message"), [
    (["bench", "check", "--station", "/no/such/station.toml"], 2, "station.toml"),
    (["bench", "check", "--preset", "nonesuch"], 2, "not a simulated rig preset"),
])
def test_bad_input_is_one_line(arguments, status: int, message: str) -> None:
    code, _, err = cli(arguments)
    assert code == status
    assert message in one_clear_line(err)


def test_an_unreachable_analyser_is_exit_3(tmp_path: Path) -> None:
    station = tmp_path / "station.toml"
    station.write_text(station_text("TCPIP::127.0.0.1::1::SOCKET"))
    code, _, err = cli(["bench", "check", "--station", station])
    assert code == 3 and "cannot reach the analyser" in one_clear_line(err)


# -- the judgement on readings built from the rig's equations alone -------------------------------

TABLE = (3.4, 50194.0, 5.05)
GAIN = 50.0


def physical_readings(gains: dict[int, complex] | None = None,
                      swap: tuple[int, int] | None = None) -> Readings:
    """Four inputs obeying the table's equation at 10, 25, 45 Hz: a made-up specimen
    (stiffness 1.5e5 N/m, damping 100 N s/m) between the table and a fixed frame."""
    f = np.array([10.0, 25.0, 45.0])
    w = 2 * np.pi * f
    mass, stiffness, damping = TABLE
    specimen = 1.5e5 + 1j * w * 100.0
    force = GAIN * 0.05 * np.exp(1j * 0.3)  # the shaker's force, any phase
    displacement = force / (stiffness + specimen - w**2 * mass + 1j * w * damping)
    table = -(w**2) * displacement
    device = specimen * displacement
    true = {1: np.full(3, force), 2: table, 3: device, 4: table * 0.97}
    sensitivity = {1: 0.01124, 2: 0.0102, 3: 0.01124, 4: 0.0102}
    measured = {k: v * (gains or {}).get(k, 1.0) for k, v in true.items()}
    if swap is not None:
        a, b = swap
        measured[a], measured[b] = (true[b] * sensitivity[b] / sensitivity[a],
                                    true[a] * sensitivity[a] / sensitivity[b])
    phase = np.exp(-1j * np.angle(measured[1]))  # input 1 is the phase reference
    return Readings(
        identity="Agilent Technologies,35670A,0,0", options=frozenset({"1D2", "AY6"}),
        noise_density=dict.fromkeys((1, 2, 3, 4), 1e-4),
        noise_range_dbvrms=dict.fromkeys((1, 2, 3, 4), -51.0), frequency_hz=f,
        amplitude={k: v * phase for k, v in measured.items()},
        variance={k: np.full(3, 1e-6) for k in (1, 2, 3, 4)}, source_vpk=0.05,
        sensitivity=sensitivity, level_reached_m_per_s2=0.5, level_m_per_s2=0.5,
        tolerance_db=2.0, level_input=4)


@pytest.mark.parametrize(("gains", "swap", "expected"), [
    ({}, None, []),
    ({3: 10.0}, None, ["input 3 (device force): reads 10 times"]),
    ({4: -1.0}, None, ["input 4 (disc accelerometer): reads with the wrong sign"]),
    ({2: 0.1}, None, ["input 2 (table accelerometer): reads 0.1 times"]),
    ({1: 2.0}, None, ["input 1 (excitation force): reads 2 times"]),
    ({1: -1.0}, None, ["input 1 (excitation force): reads with the wrong sign"]),
    ({}, (1, 3), ["transducer roles: inputs 1 and 3 read each other's transducer"]),
    ({}, (3, 4), ["transducer roles: inputs 3 and 4 read each other's transducer"]),
])
def test_the_judgement_names_the_fault(gains, swap, expected) -> None:
    verdicts = assess(physical_readings(gains, swap), ROLES, RigFacts(TABLE, GAIN))
    failed = [f"{v.name}: {v.found}" for v in verdicts if not v.passed]
    assert len(failed) == len(expected), failed
    for found, wanted in zip(failed, expected, strict=True):
        assert found.startswith(wanted), failed


def test_a_noisy_input_and_a_loop_that_does_not_close_are_named() -> None:
    readings = physical_readings()
    readings.noise_density = {**readings.noise_density, 2: 0.5}
    readings.noise_range_dbvrms = {**readings.noise_range_dbvrms, 3: 7.0}
    readings.level_reached_m_per_s2 = 0.2
    failed = {v.name: v for v in assess(readings, ROLES, RigFacts(TABLE, GAIN)) if not v.passed}
    assert set(failed) == {"input 2 noise", "input 3 noise", "level loop"}
    assert "above 0.01 m/s²/√Hz" in failed["input 2 noise"].found
    assert "hum" in failed["input 3 noise"].advice
    assert math.isclose(float(failed["level loop"].found.split("(")[1].split()[0]),
                        20 * math.log10(0.2 / 0.5), abs_tol=0.05)


def test_mains_lines_are_read_off_a_hann_power_spectrum() -> None:
    """A spectrum made here with scipy (Hann window, scaled so that a sine's peak line holds
    its power): 0.2 N rms at 50 Hz and 0.05 N rms at 150 Hz over white noise of 1e-3 N/√Hz are
    found with their rms; the noise alone gives no line."""
    from scipy.signal import periodogram

    from viscorig.benchcheck.checks import mains_lines

    rng = np.random.default_rng(5)
    fs, seconds = 1024.0, 8.0
    t = np.arange(int(fs * seconds)) / fs
    noise = 1e-3 * np.sqrt(fs / 2) * rng.standard_normal(t.size)
    hum = 0.2 * np.sqrt(2) * np.sin(2 * np.pi * 50 * t) + 0.05 * np.sqrt(2) * np.sin(
        2 * np.pi * 150 * t + 1.0)
    for signal, expected in ((noise + hum, [(50.0, 0.2), (150.0, 0.05)]), (noise, [])):
        frequency, power = periodogram(signal, fs, window="hann", scaling="spectrum")
        keep = (frequency >= 5) & (frequency <= 400)
        found = mains_lines(frequency[keep], power[keep], frequency[1])
        assert [hz for hz, _ in found] == [hz for hz, _ in expected]
        for (_, rms), (_, truth) in zip(found, expected, strict=True):
            assert rms == pytest.approx(truth, rel=0.02)
