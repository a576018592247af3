"""Rig files: presets load, bad files give one clear RigFileError naming file and key."""

from __future__ import annotations

import contextlib
import dataclasses
import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from rigsim.materials import complex_stiffness
from rigsim.rigfile import (
    FractionalMaterial,
    RigFileError,
    load_preset,
    load_rig,
    parse_rig,
    preset_names,
)

GOOD = """
name = "test"
[table]
mass_kg = 3.4
stiffness_n_per_m = 50194.0
damping_ns_per_m = 5.05

[device]
mass_kg = 0.15
model = "fractional"
static_stiffness_n_per_m = 1.2e5
high_stiffness_n_per_m = 4.0e5
tau_s = 8e-5
alpha = 0.5

[load_cell]
stiffness_n_per_m = 1.0e7

[[fixture]]
frequency_hz = 58.0
damping_ratio = 0.02
mass_kg = 0.005

[sensors]
force_v_per_n = 0.01124
acceleration_v_per_m_s2 = 0.0102

[sensors.device_force]
gain = 1.02
highpass_hz = 0.5
lowpass_hz = 5000.0

[noise]
device_force_n_per_sqrt_hz = 1e-4
seed = 4

[delays]
disc_acceleration_s = 1e-5

[amplitude]
softening_fraction = 0.2
reference_displacement_m = 1e-4

[drift]
modulus_change_per_hour = -0.02

[frame]
mass_kg = 2000.0
frequency_hz = 3.0
damping_ratio = 0.1
"""


def test_good_file_reads_every_section() -> None:
    rig = parse_rig(GOOD, source="good.toml")
    assert rig.device.material == FractionalMaterial(1.2e5, 4.0e5, 8e-5, 0.5)
    assert rig.load_cell.stiffness_n_per_m == 1.0e7
    assert rig.fixtures[0].frequency_hz == 58.0
    assert rig.noise.seed == 4 and rig.noise.adc_noise_db_re_range_per_sqrt_hz == -100.0
    assert rig.delays.as_tuple() == (0.0, 0.0, 0.0, 1e-5)
    assert rig.sensors.gains() == (1.0, 1.0, 1.02, 1.0)
    assert rig.sensors.conditioning[2].highpass_hz == 0.5
    assert rig.sensors.conditioning[2].lowpass_hz == 5000.0
    assert rig.drift.scale(1800.0) == pytest.approx(0.99)
    assert rig.amplitude.scale(1e-4) == pytest.approx(0.9)
    assert rig.frame.mass_kg == 2000.0
    assert rig.noiseless().noise is None


@pytest.mark.parametrize(
    ("old", "new", "expected"),
    [
        ("mass_kg = 3.4", "mass_kg = -3.4", "bad.toml: table.mass_kg: must be > 0, not -3.4"),
        ("alpha = 0.5", "alpha = 1.2", "bad.toml: device.alpha: must be < 1, not 1.2"),
        ("high_stiffness_n_per_m = 4.0e5", "high_stiffness_n_per_m = 1.0e5",
         "bad.toml: device.high_stiffness_n_per_m: must exceed static_stiffness_n_per_m"),
        ("damping_ratio = 0.02", "damping_ratio = \"low\"",
         "bad.toml: fixture[0].damping_ratio: must be a number, not str"),
        ("tau_s = 8e-5\n", "", "bad.toml: device.tau_s: missing value"),
        ("[drift]", "[drift]\ncolour = 3", "bad.toml: unknown key drift.colour"),
        ("model = \"fractional\"", "model = \"kelvin\"",
         "bad.toml: device.model: must be 'voigt', 'maxwell' or 'fractional'"),
        ("mass_kg = 3.4", "mass_kg = true", "bad.toml: table.mass_kg: must be a number, not bool"),
        ("[table]", "[tabel]\nx=1\n[table]", "bad.toml: unknown key tabel"),
        ("seed = 4", "seed = 4.5", "bad.toml: noise.seed: must be an integer"),
        ("mass_kg = 3.4", "mass_kg = nan", "bad.toml: table.mass_kg: must be finite"),
        ("[frame]", "[frame]\n[oops", "bad.toml: not valid TOML"),
    ],
)
def test_bad_values_name_file_and_key(old: str, new: str, expected: str) -> None:
    with pytest.raises(RigFileError) as info:
        parse_rig(GOOD.replace(old, new, 1), source="bad.toml")
    assert str(info.value).startswith(expected)


def test_a_rig_file_saved_with_a_byte_order_mark_reads_as_without() -> None:
    assert parse_rig("\ufeff" + GOOD, source="x") == parse_rig(GOOD, source="x")


def test_maxwell_arms_are_checked() -> None:
    text = """
[table]
mass_kg = 1.0
stiffness_n_per_m = 1.0e4
damping_ns_per_m = 1.0
[device]
mass_kg = 0.1
model = "maxwell"
static_stiffness_n_per_m = 1e5
arms = [[1e5, 10.0], [2e5]]
"""
    with pytest.raises(RigFileError, match=r"x.toml: device.arms\[1\]: must be a pair"):
        parse_rig(text, source="x.toml")
    with pytest.raises(RigFileError, match=r"device.arms\[0\]\[1\]: must be > 0"):
        parse_rig(text.replace("[[1e5, 10.0], [2e5]]", "[[1e5, -1.0]]"), source="x.toml")


def test_load_rig_reports_missing_and_binary_files(tmp_path) -> None:
    with pytest.raises(RigFileError, match=r"nothere\.toml: cannot read rig file"):
        load_rig(tmp_path / "nothere.toml")
    binary = tmp_path / "bin.toml"
    binary.write_bytes(b"\xff\xfe\x00")
    with pytest.raises(RigFileError, match=r"bin\.toml: not UTF-8"):
        load_rig(binary)
    good = tmp_path / "good.toml"
    good.write_text(GOOD)
    assert load_rig(good).source == str(good)


def test_presets() -> None:
    names = preset_names()
    assert names == sorted(
        ["table", "soft-0", "soft-10", "medium-0", "medium-10", "hard-0", "hard-10",
         "medium-chamber"]
    )
    for name in names:
        rig = load_preset(name)
        assert rig.name == name
        assert rig.table.mass_kg == 3.4 and rig.table.stiffness_n_per_m == 50194.0
        assert (rig.device is None) == (name == "table")
    with pytest.raises(RigFileError, match="no rig preset 'stone'"):
        load_preset("stone")


def test_preload_stiffens_every_rubber() -> None:
    f = np.array([20.0, 60.0, 120.0])
    for rubber in ("soft", "medium", "hard"):
        k0 = complex_stiffness(load_preset(f"{rubber}-0").device.material, f)
        k10 = complex_stiffness(load_preset(f"{rubber}-10").device.material, f)
        assert np.all(k10.real > k0.real)


@pytest.mark.slow
@settings(max_examples=300, deadline=None)
@given(st.text(max_size=400))
def test_fuzz_text_raises_only_rig_file_error(text: str) -> None:
    with contextlib.suppress(RigFileError):
        parse_rig(text)


VALUES = st.one_of(
    st.integers(-10**30, 10**30), st.floats(allow_nan=True), st.booleans(),
    st.text(max_size=5), st.just([]), st.just([[1.0, 2.0], [3.0]]), st.just({"a": 1}),
)


@settings(max_examples=300, deadline=None)
@given(st.data())
def test_fuzz_values_raise_only_rig_file_error(data) -> None:
    lines = GOOD.splitlines()
    keyed = [i for i, line in enumerate(lines) if " = " in line]
    index = data.draw(st.sampled_from(keyed))
    value = data.draw(VALUES)
    key = lines[index].split(" = ")[0]
    if isinstance(value, str):
        rendered = '"' + value.replace("\\", "\\\\").replace('"', '\\"') + '"'
    elif isinstance(value, bool):
        rendered = str(value).lower()
    elif isinstance(value, float):
        rendered = "nan" if value != value else ("inf" if value > 0 else "-inf") if abs(
            value) == float("inf") else repr(value)
    elif isinstance(value, dict):
        rendered = "{ a = 1 }"
    else:
        rendered = str(value)
    lines[index] = f"{key} = {rendered}"
    try:
        rig = parse_rig("\n".join(lines))
    except RigFileError:
        return
    # a value the file accepts reaches the simulator as a finite number, never NaN or inf
    assert all(math.isfinite(number) for number in _numbers(rig)), (key, rendered)


def _numbers(value: object) -> list[float]:
    """Every number inside a parsed rig (dataclasses, tuples), for the check above."""
    if dataclasses.is_dataclass(value):
        return [n for f in dataclasses.fields(value) for n in _numbers(getattr(value, f.name))]
    if isinstance(value, list | tuple):
        return [n for item in value for n in _numbers(item)]
    if isinstance(value, int | float) and not isinstance(value, bool):
        return [float(value)]
    return []
