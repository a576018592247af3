"""SDF import across the analyser family: FFT-mode H1, revision 3, channel roles from a station,
and what is refused; files written from the SDF guide by tests/sdfwrite.py."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from sdfstation import STATION
from sdfwrite import FOUR_CHANNELS, Channel, SdfLayout, Trace, sdf_bytes

from viscorig.cli import main
from viscorig.errors import InputError
from viscorig.exchange import read_sdf, read_sdf_frfs
from viscorig.sequences import parse_station
from viscorig.storage import CampaignFile

STATION_ROLES = parse_station(STATION, "station.toml")
S = STATION_ROLES.sensitivity
VOLT_CHANNELS = [Channel(f"Chan  {n}", "V", 1.0) for n in range(1, 5)]
#: An FFT measurement of 800 lines over 0-1600 Hz: 1025 lines stored, 0-800 alias-protected.
F_FFT = 2.0 * np.arange(1025)


def _table(f: np.ndarray) -> np.ndarray:
    """A table accelerance in m/s²/N (mass-spring-damper, 3.6 kg, 50 kN/m)."""
    w = 2 * np.pi * f
    return -(w**2) / (50e3 - w**2 * 3.6 + 1j * w * 120)


def _support(f: np.ndarray) -> np.ndarray:
    w = 2 * np.pi * f
    return -(w**2) / (150e3 - w**2 * 0.15 + 1j * w * 115)


def _fft_file(path: Path, traces: list[Trace]) -> Path:
    path.write_bytes(sdf_bytes(SdfLayout(F_FFT, VOLT_CHANNELS, traces, x_resolution=0,
                                         y_type=3, measurement=3, alias_protected=(0, 800))))
    return path


def _volts(h_si: np.ndarray, s_response: float, s_reference: float) -> np.ndarray:
    """What the analyser stores for a response in volts over volts."""
    return h_si * s_response / s_reference


def test_fft_mode_h1_of_both_frfs_in_one_file_goes_by_the_station_roles(tmp_path: Path):
    table_v = _volts(_table(F_FFT), S.table_acceleration_v_per_m_s2, S.excitation_force_v_per_n)
    support_v = _volts(_support(F_FFT), S.device_acceleration_v_per_m_s2, S.device_force_v_per_n)
    table_v[801:] = support_v[801:] = 1e30  # beyond the alias-protected lines: not data
    path = _fft_file(tmp_path / "H1.DAT", [Trace(3, 2, support_v), Trace(1, 0, table_v)])
    station = tmp_path / "station.toml"
    station.write_text(STATION)
    target = tmp_path / "c.h5"
    assert main(["import", str(target), "--run", "soft-0", "--specimen", "soft",
                 "--sdf", str(path), "--station", str(station)]) == 0
    run = CampaignFile.open(target).run("soft-0")
    f = F_FFT[1:801]  # the 0 Hz line and the lines past 1600 Hz are not kept
    assert np.array_equal(run.frequency_hz, f)
    assert np.allclose(run.accelerance_table, _table(f), rtol=2e-7, atol=0)  # float32 data
    assert np.allclose(run.accelerance_support, _support(f), rtol=2e-7, atol=0)


def test_without_a_station_the_file_order_decides_and_volts_are_refused(tmp_path: Path):
    path = _fft_file(tmp_path / "H1.DAT", [Trace(1, 0, _table(F_FFT))])
    with pytest.raises(InputError, match=r"input 2 over input 1.*--station STATION.toml"):
        read_sdf_frfs([path])


def test_a_pair_the_station_does_not_make_is_refused(tmp_path: Path):
    path = _fft_file(tmp_path / "H1.DAT", [Trace(3, 0, _table(F_FFT))])
    with pytest.raises(InputError, match=r"input 4 over input 1 is neither ẍ_s/F_e \(input 2 "
                                         r"over 1\) nor ẍ_v/F_v \(input 4 over 3\)"):
        read_sdf_frfs([path], STATION_ROLES)


def test_the_same_frf_twice_is_refused(tmp_path: Path):
    first = _fft_file(tmp_path / "A.DAT", [Trace(1, 0, _table(F_FFT))])
    second = _fft_file(tmp_path / "B.DAT", [Trace(1, 0, _table(F_FFT))])
    with pytest.raises(InputError, match="ẍ_s/F_e given twice"):
        read_sdf_frfs([first, second], STATION_ROLES)


@pytest.mark.parametrize(("revision", "sizes"), [(2, None), (3, None),
                                               (2, (80, 156, 148, 18, 212))])
def test_revisions_2_and_3_read_the_same_response(tmp_path: Path, revision: int, sizes):
    """Revision 2 and 3 layouts, and revision 3 records in a file marked revision 2."""
    f = np.geomspace(5.0, 2000.0, 300)
    path = tmp_path / f"rev{revision}.DAT"
    path.write_bytes(sdf_bytes(SdfLayout(f, FOUR_CHANNELS, [Trace(1, 0, _table(f))],
                                         revision=revision, sizes=sizes)))
    (frf,) = read_sdf(path)
    assert np.array_equal(frf.frequency_hz, f)
    assert np.allclose(frf.accelerance("t"), _table(f), rtol=1e-12, atol=0)


def test_a_sweep_stopped_early_keeps_the_points_measured(tmp_path: Path):
    f = np.linspace(10.0, 500.0, 200)
    path = tmp_path / "stopped.DAT"
    path.write_bytes(sdf_bytes(SdfLayout(f, FOUR_CHANNELS, [Trace(1, 0, _table(f))],
                                         last_valid=119)))
    (frf,) = read_sdf(path)
    assert np.array_equal(frf.frequency_hz, f[:120])


@pytest.mark.parametrize(
    ("changes", "message"),
    [
        ({"data_type": 0, "domain": 1, "powers": (48, 0)},
         "holds a time record \\(time domain\\) 'Freq Resp' \\(HP 35670A, swept sine\\)"),
        ({"data_type": 8, "powers": (0, 0), "application": 2},
         "holds an ordinary coherence 'Freq Resp' \\(HP 35665A, swept sine\\)"),
        ({"data_type": 1, "powers": (48, 0), "application": 4, "measurement": 3},
         "holds a linear spectrum .* \\(HP 89410A/89440A, FFT measurement\\)"),
        ({"scans": 12}, "holds a waterfall of 12 scans"),
        ({"revision": 1}, "SDF revision 1; this reader knows revisions 2 and 3"),
        ({"sizes": (64, 140, 150, 18, 192)},
         "data header 1 at byte 206 has size 150; SDF revisions 2 and 3 give 134 or 148"),
        ({"application": -99, "measurement": -99, "data_type": 2, "powers": (96, 0)},
         "holds an auto-power spectrum 'Freq Resp' \\(unknown instrument \\(application "
         "code -99\\), unknown measurement \\(type -99\\)\\)"),
    ],
)
def test_what_is_not_a_frequency_response_is_refused_saying_what_it_is(
        tmp_path: Path, changes: dict, message: str):
    f = np.linspace(10.0, 500.0, 50)
    layout = SdfLayout(f, FOUR_CHANNELS, [Trace(1, 0, _table(f))])
    for key, value in changes.items():
        setattr(layout, key, value)
    path = tmp_path / "x.DAT"
    path.write_bytes(sdf_bytes(layout))
    with pytest.raises(InputError, match=message) as error:
        read_sdf_frfs([path])
    assert "\n" not in str(error.value)


def test_an_absurd_revision_3_point_count_is_refused_before_anything_is_allocated(
        tmp_path: Path):
    f = np.linspace(10.0, 500.0, 50)
    raw = bytearray(sdf_bytes(SdfLayout(f, FOUR_CHANNELS, [Trace(1, 0, _table(f))],
                                        revision=3)))
    data_at = 2 + 80 + 156
    assert raw[data_at:data_at + 2] == b"\x00\x0c"
    raw[data_at + 134:data_at + 138] = (2**31 - 1).to_bytes(4, "big")
    path = tmp_path / "huge.DAT"
    path.write_bytes(bytes(raw))
    with pytest.raises(InputError, match="2147483647 points need 34359738352 bytes"):
        read_sdf(path)


def test_the_analysers_channel_labels_name_the_inputs_not_the_header_order(tmp_path: Path):
    """A file of the 3/4 pair may hold only the two channel headers of that trace."""
    f = F_FFT
    table_v = _volts(_table(f), S.table_acceleration_v_per_m_s2, S.excitation_force_v_per_n)
    support_v = _volts(_support(f), S.device_acceleration_v_per_m_s2, S.device_force_v_per_n)
    pair_34 = [Channel("Chan  3", "V", 1.0), Channel("Chan  4", "V", 1.0)]
    support = tmp_path / "SUPPORT.DAT"
    support.write_bytes(sdf_bytes(SdfLayout(f, pair_34, [Trace(1, 0, support_v)],
                                            x_resolution=0, measurement=3,
                                            alias_protected=(0, 800))))
    table = _fft_file(tmp_path / "TABLE.DAT", [Trace(1, 0, table_v)])
    frfs = read_sdf_frfs([support, table], STATION_ROLES)  # any order
    g = f[1:801]
    assert np.allclose(frfs.accelerance_table, _table(g), rtol=2e-7, atol=0)  # float32 file
    assert np.allclose(frfs.accelerance_support, _support(g), rtol=1e-12, atol=0)


def test_a_response_over_its_own_input_is_refused(tmp_path: Path):
    twice = [Channel("Chan  1", "V", 1.0), Channel("Chan  1", "V", 1.0)]
    path = tmp_path / "same.DAT"
    path.write_bytes(sdf_bytes(SdfLayout(F_FFT, twice, [Trace(1, 0, _table(F_FFT))],
                                         x_resolution=0, measurement=3)))
    with pytest.raises(InputError, match="response and reference are both input 1"):
        read_sdf(path)


def test_a_station_with_another_format_is_refused(tmp_path: Path, capsys):
    station = tmp_path / "station.toml"
    station.write_text(STATION)
    assert main(["import", str(tmp_path / "c.h5"), "--run", "r", "--csv", "x.csv",
                 "--station", str(station)]) == 2
    assert "--station: a station converts SDF files only" in capsys.readouterr().err
