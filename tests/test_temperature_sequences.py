"""Temperature steps, repeats over temperatures and levels, the station's [chamber], and what
check and plan say about them."""

from __future__ import annotations

import json
import math
from pathlib import Path

import pytest
from stationfile import station_toml

from viscorig.cli import main
from viscorig.sequences import FileCheckError, TemperatureStep, parse_sequence, parse_station

ROOT = Path(__file__).resolve().parents[1]

HEAD = """\
name = "t"
[defaults]
band_hz = [20.0, 120.0]
resolution_hz = 20.0
settle_cycles = 10
integrate_cycles = 10
level = "1 m/s^2"
specimen = "medium"
hardness_shore_a = 33.0

[[steps]]
type = "prompt"
message = "Mount."
simulated_rig = "medium-chamber"
"""

STATION = station_toml("GPIB0::11::INSTR", force_v_per_n=0.01124,
                       acceleration_v_per_m_s2=0.0102)

CHAMBER = """\
[chamber]
address = "/dev/ttyUSB1"
specimen_unit = 2
low_limit_c = -30.0
high_limit_c = 60.0
safe_set_point_c = 25.0
"""


def test_repeat_over_temperatures_and_levels() -> None:
    sequence = parse_sequence(HEAD + """
[[steps]]
type = "repeat"
temperatures_c = [-20.0, 40.0]
levels = ["0.5 m/s^2", "2 m/s^2"]
ramp_c_per_min = 2.0
soak_band_k = 0.5
soak_minutes = 15

  [[steps.steps]]
  type = "sweep"
  run = "m_T{temperature_c}_L{level_index}"
""")
    kinds = [type(step).__name__ for step in sequence.steps[1:]]
    assert kinds == ["TemperatureStep", "SweepStep", "SweepStep"] * 2
    assert sequence.run_names == ("m_T-20_L1", "m_T-20_L2", "m_T40_L1", "m_T40_L2")
    assert [s.temperature_c for s in sequence.sweeps] == [-20.0, -20.0, 40.0, 40.0]
    assert [s.level_m_per_s2 for s in sequence.sweeps] == [0.5, 2.0, 0.5, 2.0]
    assert sequence.soaks == (
        TemperatureStep(-20.0, 2.0, 0.5, 15.0, 240.0), TemperatureStep(40.0, 2.0, 0.5, 15.0, 240.0))


@pytest.mark.parametrize(("body", "line", "message"), [
    ('[[steps]]\ntype = "repeat"\ntemperatures_c = [0.0]\n  [[steps.steps]]\n'
     '  type = "temperature"\n  set_point_c = 5.0\n', 19,
     "steps[1].steps[0].type: a temperature step cannot be repeated inside a repeat"),
    ('[[steps]]\ntype = "repeat"\nlevels = ["1 m/s^2"]\n  [[steps.steps]]\n  type = "sweep"\n'
     '  run = "a{level_index}"\n  level = "2 m/s^2"\n', 21,
     "steps[1].steps[0].level: set by the repeat for each round"),
    ('[[steps]]\ntype = "repeat"\n  [[steps.steps]]\n  type = "sweep"\n  run = "a"\n', 15,
     "steps[1]: repeats nothing"),
    ('[[steps]]\ntype = "repeat"\ntemperatures_c = [0.0, 10.0]\n  [[steps.steps]]\n'
     '  type = "sweep"\n  run = "same"\n', 20, "duplicate run name 'same'"),
    ('[[steps]]\ntype = "temperature"\nset_point_c = 20.0\nsoak_band_k = 0.0\n', 18,
     "steps[1].soak_band_k: 0.0 is outside (0, 20] K"),
    ('[[steps]]\ntype = "repeat"\ntemperatures_c = [0.0, 0.0]\n  [[steps.steps]]\n'
     '  type = "sweep"\n  run = "a{temperature_c}"\n', 17, "temperatures_c: names 0 twice"),
])
def test_repeat_and_temperature_problems_name_their_line(body: str, line: int,
                                                         message: str) -> None:
    with pytest.raises(FileCheckError) as caught:
        parse_sequence(HEAD + body, source="s.toml")
    problems = [str(problem) for problem in caught.value.problems]
    assert any(message in text and text.startswith(f"s.toml:{line}:") for text in problems), \
        problems


def test_station_chamber() -> None:
    station = parse_station(STATION + CHAMBER, source="lab.toml")
    chamber = station.chamber
    assert (chamber.address, chamber.unit, chamber.specimen_unit) == ("/dev/ttyUSB1", 1, 2)
    assert chamber.allows(60.0) and not chamber.allows(60.5)
    assert parse_station(STATION).chamber is None


@pytest.mark.parametrize(("change", "message"), [
    (('address = "/dev/ttyUSB1"', 'address = "udp://x"'), "neither tcp://HOST:PORT nor a serial"),
    (("safe_set_point_c = 25.0", "safe_set_point_c = 70.0"), "70 °C is outside the limits"),
    (("high_limit_c = 60.0", "high_limit_c = -40.0"), "is not above low_limit_c"),
    (("specimen_unit = 2", "specimen_unit = 1"), "the same unit as the controller"),
])
def test_station_chamber_problems(change: tuple[str, str], message: str) -> None:
    with pytest.raises(FileCheckError, match=message):
        parse_station(STATION + CHAMBER.replace(*change), source="lab.toml")


SOAKS = HEAD + """
[[steps]]
type = "temperature"
set_point_c = 50.0

[[steps]]
type = "sweep"
run = "hot"

[[steps]]
type = "repeat"
temperatures_c = [-35.0, 0.0, 70.0]
  [[steps.steps]]
  type = "sweep"
  run = "m{temperature_c}"
"""


def test_check_refuses_set_points_outside_the_station_limits(tmp_path: Path, capsys) -> None:
    sequence = tmp_path / "soaks.toml"
    sequence.write_text(SOAKS)
    station = tmp_path / "lab.toml"
    station.write_text(STATION + CHAMBER)
    assert main(["check", str(sequence), "--station", str(station)]) == 2
    out = capsys.readouterr().out.splitlines()
    assert len(out) == 2  # -35 and 70, both written in temperatures_c, each said once
    assert all(":26: steps[3].temperatures_c: set point" in line for line in out), out
    assert "-35 °C is outside" in out[0] and "70 °C is outside" in out[1]
    assert "chamber limits [-30, 60] °C" in out[0]
    station.write_text(STATION)
    assert main(["check", str(sequence), "--station", str(station)]) == 2
    assert "a temperature step needs a chamber" in capsys.readouterr().out


def test_check_refuses_set_points_beyond_the_embedded_chamber(tmp_path: Path, capsys) -> None:
    sequence = tmp_path / "cold.toml"
    sequence.write_text(HEAD + '[[steps]]\ntype = "temperature"\nset_point_c = -60.0\n')
    assert main(["check", str(sequence)]) == 2
    assert "outside the embedded rig's chamber limits [-40, 100] °C" in capsys.readouterr().out


def test_plan_counts_the_soaks(tmp_path: Path, capsys) -> None:
    sequence = tmp_path / "soaks.toml"
    sequence.write_text(SOAKS.replace("-35.0", "-25.0").replace("70.0", "55.0"))
    assert main(["plan", str(sequence), "--json"]) == 0
    document = json.loads(capsys.readouterr().out)
    assert document["soaks"] == 4
    soaks = [step for step in document["steps"] if step["kind"] == "soak"]
    # from the safe set point 25 °C to 50 °C, no ramp: the air heats at 5 K/min (300 s), the
    # specimens trail it (420 s of the medium-chamber preset) into the 1 K band, a 10 min soak
    assert soaks[0]["low_s"] == pytest.approx(300.0 + 420.0 * math.log(25.0) + 600.0)
    assert main(["plan", str(sequence)]) == 0
    assert "4 soaks:" in capsys.readouterr().out


def test_example_sequence_checks_and_plans(capsys) -> None:
    example = ROOT / "sequences" / "temperature-strain.toml"
    assert main(["check", str(example)]) == 0
    assert main(["plan", str(example), "--json"]) == 0
    document = json.loads(capsys.readouterr().out.split("\n", 1)[1])
    assert document["soaks"] == 14
    temperatures = [step["name"] for step in document["steps"] if step["kind"] == "soak"]
    assert temperatures[0] == "-20 °C" and temperatures[12] == "80 °C"


def test_several_runs_are_fitted_together_only_for_the_payne_effect(tmp_path: Path,
                                                                    capsys) -> None:
    assert main(["identify", str(tmp_path / "c.h5"), "--run", "a", "--run", "b"]) == 2
    assert "add --model kraus" in capsys.readouterr().err



@pytest.mark.parametrize(("recorded", "says"), [
    ({"r": (21.3, 24.6)}, "recorded temperature moved from 21.3 to 24.6 °C"),
    ({"r": (25.0, 25.05)}, "so it is not the rubber's temperature"),
    ({}, "record the temperature"),
])
def test_a_drift_is_explained_by_the_recorded_temperature_first(recorded, says) -> None:
    from types import SimpleNamespace

    from viscorig.diagnosis.explain import explain

    finding = SimpleNamespace(
        effect="thermal_drift", evidence="K* falls along the run", significant=True,
        parameters=lambda: {"kappa": {"value": -5.6e-6, "stderr": 1e-7}}, likelihood=None)
    # nothing inherited with an uncertainty: the table's error is not a candidate explanation
    data = SimpleNamespace(run="r", temperature_range_c=recorded, nuisance=())
    text = explain(finding, data)
    assert text.startswith("The modulus drifts by") and says in text
