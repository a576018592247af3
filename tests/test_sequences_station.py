"""Station files: resource, channels, sensitivities, limits, table and specimen, validated."""

from __future__ import annotations

import re

import pytest
from tomlwrite import dumps

from viscorig.errors import InputError
from viscorig.sequences import parse_station
from viscorig.storage import CampaignFile


def document() -> dict:
    return {
        "resource": "GPIB0::11::INSTR",
        "adapter": "PRLGX-TCPIP::192.168.1.20::1234::INTFC",
        "channels": {"excitation_force": 1, "table_acceleration": 2, "device_force": 3,
                     "device_acceleration": 4},
        "sensitivity": {"excitation_force_v_per_n": 0.01124,
                        "table_acceleration_v_per_m_s2": 0.0102,
                        "device_force_v_per_n": 0.0112, "device_acceleration_v_per_m_s2": 0.0101},
        "shaker": {"force_limit_n": 100.0, "gain_n_per_v": 40},
        "source": {"limit_v": 2.0},
        "table": {"mass_kg": 3.4, "stiffness_n_per_m": 50194.0, "damping_ns_per_m": 5.05},
        "specimen": {"diameter_m": 0.02, "height_m": 0.012, "count": 2},
    }


def test_a_full_station_is_read_and_gives_the_rig_attributes(tmp_path) -> None:
    station = parse_station(dumps(document()), source="lab.toml")
    assert station.resource == "GPIB0::11::INSTR"
    assert station.channels.device_acceleration == 4
    assert station.sensitivity.device_force_v_per_n == 0.0112
    assert (station.shaker_force_limit_n, station.shaker_gain_n_per_v) == (100.0, 40.0)
    assert station.source_limit_v == 2.0
    rig = station.rig_attributes()
    assert rig == {
        "table_mass_kg": 3.4, "table_stiffness_n_per_m": 50194.0, "table_damping_ns_per_m": 5.05,
        "specimen_diameter_m": 0.02, "specimen_height_m": 0.012, "specimen_count": 2,
    }
    campaign = CampaignFile.create(tmp_path / "c.h5", sequence_text="", rig=rig, durable=False)
    assert campaign.rig == rig


def test_optional_tables_may_be_left_out() -> None:
    doc = document()
    for key in ("adapter", "table", "specimen"):
        del doc[key]
    del doc["shaker"]["gain_n_per_v"]
    station = parse_station(dumps(doc), source="lab.toml")
    assert station.table is None and station.specimen is None and station.adapter is None
    assert station.shaker_gain_n_per_v is None and station.rig_attributes() == {}


def edit(section: str | None, key: str, value: object) -> dict:
    doc = document()
    target = doc if section is None else doc[section]
    if value is ...:
        del target[key]
    else:
        target[key] = value
    return doc


@pytest.mark.parametrize(
    ("section", "key", "value", "where", "what"),
    [
        (None, "resource", "my analyser", "resource", "not a VISA resource"),
        (None, "resource", ..., "resource", "missing"),
        (None, "adapter", "GPIB0::11::INSTR", "adapter", "ends with ::INTFC"),
        (None, "colour", "red", "colour", "unknown key"),
        ("channels", "device_force", 1, "channels", "four different inputs"),
        ("channels", "device_force", 5, "channels.device_force", "outside [1, 4]"),
        ("sensitivity", "device_force_v_per_n", 0.0, "sensitivity.device_force_v_per_n",
         "outside"),
        ("sensitivity", "force_v_per_n", 0.01, "sensitivity.force_v_per_n", "unknown key"),
        ("shaker", "force_limit_n", -100.0, "shaker.force_limit_n", "outside (0, 100000] N"),
        ("shaker", "force_limit_n", "100 N", "shaker.force_limit_n", "expected a number"),
        ("source", "limit_v", 7.5, "source.limit_v", "outside (0, 5] V"),
        ("table", "mass_kg", ..., "table.mass_kg", "missing"),
        ("table", "damping_ns_per_m", -1.0, "table.damping_ns_per_m", "outside"),
        ("specimen", "count", 2.0, "specimen.count", "whole number"),
        ("specimen", "height_m", 12.0, "specimen.height_m", "outside (0, 1] m"),
    ],
)
def test_each_problem_names_file_and_field(
    section: str | None, key: str, value: object, where: str, what: str
) -> None:
    with pytest.raises(InputError) as caught:
        parse_station(dumps(edit(section, key, value)), source="lab.toml")
    message = str(caught.value)
    assert re.match(rf"lab\.toml(:\d+)?: {re.escape(where)}", message), message
    assert what in message, message


def test_force_and_acceleration_must_form_an_analyser_pair() -> None:
    doc = document()
    doc["channels"] = {"excitation_force": 2, "table_acceleration": 1, "device_force": 3,
                       "device_acceleration": 4}
    with pytest.raises(InputError, match="REF PAIR"):
        parse_station(dumps(doc), source="lab.toml")
    doc["channels"] = {"excitation_force": 3, "table_acceleration": 4, "device_force": 1,
                       "device_acceleration": 2}
    assert parse_station(dumps(doc), source="lab.toml").channels.excitation_force == 3
