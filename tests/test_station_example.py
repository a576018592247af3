"""The example station file shipped for labs is valid and says what the paper's rig has."""

from __future__ import annotations

from pathlib import Path

from viscorig.sequences import load_station

EXAMPLE = Path(__file__).resolve().parents[1] / "sequences" / "station-example.toml"


def test_example_station_parses_to_the_papers_rig() -> None:
    station = load_station(EXAMPLE)
    assert station.resource == "GPIB0::11::INSTR"
    assert station.adapter is None
    assert (station.channels.excitation_force, station.channels.device_acceleration) == (1, 4)
    assert station.shaker_force_limit_n == 100.0
    assert station.source_limit_v == 2.0
    assert station.table is not None and station.table.stiffness_n_per_m == 50194.0
    assert station.specimen is not None and station.specimen.count == 2


def test_example_station_with_a_prologix_adapter_parses(tmp_path: Path) -> None:
    usb = 'adapter = "PRLGX-ASRL::/dev/ttyUSB0::INTFC"'
    text = EXAMPLE.read_text(encoding="utf-8").replace(f"# {usb}", usb)
    path = tmp_path / "usb.toml"
    path.write_text(text, encoding="utf-8")
    assert load_station(path).adapter == "PRLGX-ASRL::/dev/ttyUSB0::INTFC"
