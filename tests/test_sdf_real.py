"""SDF import on files saved by real analysers, checked against the analyser's own ASCII export
and against an independent parser (sdfascii); hostile variants of them.

The files are not part of the repository (tests/data/sdf/README.md names them, their source,
licence and SHA-256): :func:`realdata.real_data` finds them."""

from __future__ import annotations

import hashlib
import struct
from pathlib import Path

import numpy as np
import pytest
from realdata import real_data
from sdfstation import SENSITIVITY_A_V_PER_M_S2, SENSITIVITY_F_V_PER_N, STATION

from viscorig.cli import main
from viscorig.errors import InputError
from viscorig.exchange import read_sdf, read_sdf_file, read_sdf_frfs
from viscorig.sequences import parse_station
from viscorig.storage import CampaignFile

DATA = real_data("sdf", "HP35665A.DAT", "HP35670A.DAT", "ASCII3KH.TXT", "ASCII3KH.X")
FRF_35665A = DATA / "HP35665A.DAT"
SPECTRUM_35670A = DATA / "HP35670A.DAT"



@pytest.fixture
def station_file(tmp_path: Path) -> Path:
    path = tmp_path / "station.toml"
    path.write_text(STATION)
    return path


def _sdfascii_frf() -> np.ndarray:
    sdfascii = pytest.importorskip("sdfascii")
    _, data = sdfascii.read_sdf_file(str(FRF_35665A))
    return np.asarray(data)


def test_a_real_35665a_swept_sine_is_read_as_sdfascii_reads_it():
    file = read_sdf_file(FRF_35665A)
    assert (file.instrument, file.revision, file.measurement_name) == (
        "HP 35665A", 2, "swept sine")
    (trace,) = file.traces
    assert trace.kind == "frequency response" and trace.title == "Freq Resp"
    assert (trace.response.number, trace.reference.number) == (2, 1)
    assert trace.response.unit == trace.reference.unit == "V"
    # the header says a 20 Hz - 20 kHz logarithmic sweep of 401 points
    expected_axis = np.geomspace(20.0, 20000.0, 401)
    assert np.allclose(trace.x, expected_axis, rtol=1e-9, atol=0)
    independent = _sdfascii_frf()
    assert independent.shape == (401,)
    assert np.array_equal(trace.values, independent.astype(complex))


def test_a_volt_over_volt_response_is_refused_without_a_station_naming_the_fix(
        tmp_path: Path, capsys):
    target = tmp_path / "c.h5"
    assert main(["import", str(target), "--run", "table", "--specimen", "none",
                 "--sdf", str(FRF_35665A)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1
    assert "volt-over-volt" in err and "--station STATION.toml" in err
    assert not target.exists()


def test_a_real_35665a_response_imports_with_a_station_as_one_frf_run(
        tmp_path: Path, station_file: Path, capsys):
    target = tmp_path / "c.h5"
    assert main(["import", str(target), "--run", "table", "--specimen", "none",
                 "--sdf", str(FRF_35665A), "--station", str(station_file)]) == 0
    assert "ẍ_s/F_e only" in capsys.readouterr().out
    run = CampaignFile.open(target).run("table")
    independent = _sdfascii_frf().astype(complex)
    # m/s² per N = (V/V) · (V/N) / (V/(m/s²))
    expected = independent * SENSITIVITY_F_V_PER_N / SENSITIVITY_A_V_PER_M_S2
    assert run.frequency_hz.size == 401
    assert np.allclose(run.frequency_hz, np.geomspace(20.0, 20000.0, 401), rtol=1e-9)
    assert np.allclose(run.accelerance_table, expected, rtol=1e-12, atol=0)
    assert np.all(np.isnan(run.accelerance_support))


def test_a_lone_device_frf_by_the_station_roles_is_refused_a_run_needs_the_table_one():
    swapped = (STATION.replace("excitation_force = 1", "excitation_force = 3")
               .replace("table_acceleration = 2", "table_acceleration = 4")
               .replace("device_force = 3", "device_force = 1")
               .replace("device_acceleration = 4", "device_acceleration = 2"))
    with pytest.raises(InputError, match="holds ẍ_v/F_v only; a run needs ẍ_s/F_e "
                                         r"\(input 4 over input 3\)"):
        read_sdf_frfs([FRF_35665A], parse_station(swapped, "swapped.toml"))


def test_a_real_power_spectrum_is_refused_in_one_line_saying_what_it_is(
        tmp_path: Path, capsys):
    target = tmp_path / "c.h5"
    assert main(["import", str(target), "--run", "soft-0",
                 "--sdf", str(SPECTRUM_35670A)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1
    assert "holds an auto-power spectrum 'Pwr Spec' (HP 35670A, FFT measurement)" in err


def test_a_real_35670a_trace_matches_the_analysers_own_ascii_export():
    file = read_sdf_file(SPECTRUM_35670A)
    (trace,) = file.traces
    assert trace.kind == "auto-power spectrum" and trace.values.size == 2049
    shown_y = np.loadtxt(DATA / "ASCII3KH.TXT")
    shown_x = np.loadtxt(DATA / "ASCII3KH.X")
    # the analyser shows the 1601 alias-protected lines, in Vrms with the flat-top window's
    # amplitude correction: sqrt(P / 2) · narrowBandCorr for a power spectrum P in Vpk²
    assert int(trace.valid.sum()) == shown_y.size == 1601
    assert np.array_equal(trace.x[trace.valid], shown_x)
    ours = np.sqrt(trace.values[trace.valid] / 2) * trace.response.narrow_band_correction
    assert np.allclose(ours, shown_y, rtol=1e-6, atol=1e-12)  # the export has 7 digits
    tone = np.argmax(shown_y)
    assert shown_x[tone] == 3000.0 and abs(ours[tone] - 0.0101) < 1e-4  # 10 mVrms source


def _patched(raw: bytes, offset: int, layout: str, value: int | float) -> bytes:
    out = bytearray(raw)
    struct.pack_into(">" + layout, out, offset, value)
    return bytes(out)


RAW = FRF_35665A.read_bytes()
DATA_AT, CHANNEL_AT, YDATA_AT = 206, 358, 1304  # from the file header of HP35665A.DAT
HOSTILE = {
    "truncated in the data header": RAW[:250],
    "truncated in the Y data": RAW[:2000],
    "one byte short": RAW[:-1],
    "data header record size 150": _patched(RAW, DATA_AT + 2, "l", 150),
    "channel record size 1e9": _patched(RAW, CHANNEL_AT + 2, "l", 10**9),
    "32767 points": _patched(RAW, DATA_AT + 30, "h", 32767),
    "-5 points": _patched(RAW, DATA_AT + 30, "h", -5),
    "30000 rows": _patched(RAW, DATA_AT + 64, "h", 30000),
    "Y data at a negative offset": _patched(RAW, 2 + 60, "l", -7),
    "Y data offset past the end": _patched(RAW, 2 + 60, "l", 10**8),
    "32767 data headers": _patched(RAW, 2 + 24, "h", 32767),
    "vector number 99": _patched(RAW, DATA_AT + 60, "l", 99),
    "channel record 40": _patched(RAW, 340 + 10, "h", 40),
    "Y data type 9": _patched(RAW, DATA_AT + 48, "h", 9),
    "infinite X step": _patched(RAW, DATA_AT + 122, "d", float("inf")),
    "revision 7": _patched(RAW, 2 + 6, "h", 7),
    "waterfall of 50 scans": _patched(RAW, 1264 + 6, "h", 50),
    "empty": b"",
    "not SDF": b"MZ" + RAW[2:],
}


def _digest(path: Path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


@pytest.mark.parametrize("name", sorted(HOSTILE))
def test_a_hostile_variant_of_a_real_file_is_one_line_exit_2_campaign_unchanged(
        tmp_path: Path, station_file: Path, capsys, name: str):
    bad = tmp_path / "bad.dat"
    bad.write_bytes(HOSTILE[name])
    target = tmp_path / "c.h5"
    assert main(["import", str(target), "--run", "first", "--specimen", "none",
                 "--sdf", str(FRF_35665A), "--station", str(station_file)]) == 0
    before = _digest(target)
    capsys.readouterr()
    assert main(["import", str(target), "--run", "second", "--specimen", "none",
                 "--sdf", str(bad), "--station", str(station_file)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.startswith("viscorig: ") and "bad.dat" in err
    assert _digest(target) == before


def test_random_damage_to_the_headers_gives_an_input_error_or_a_clean_read(tmp_path: Path):
    rng = np.random.default_rng(28)
    path = tmp_path / "damaged.dat"
    outcomes = {"read": 0, "refused": 0}
    for _ in range(300):
        raw = bytearray(RAW)
        for at in rng.integers(0, YDATA_AT + 6, size=3):
            raw[at] = int(rng.integers(0, 256))
        path.write_bytes(bytes(raw))
        try:
            frfs = read_sdf(path)
        except InputError as error:
            assert "\n" not in str(error)
            outcomes["refused"] += 1
        else:
            assert all(frf.values.size == frf.frequency_hz.size for frf in frfs)
            outcomes["read"] += 1
    assert outcomes["refused"] > 0 and outcomes["read"] > 0
