"""`viscorig import` against hand-made hostile FRF files: values that are not finite, rows from
high to low frequency, a frequency given twice.

The CSV files are written here with the standard library from a Voigt rig computed here (no
project code makes them); the UFF files are a valid export changed the way another tool could
write them. Each refusal must be one line naming the row (and the column) with exit status 2,
leaving no campaign file behind; a file in falling frequency order must be stored rising.
"""

from __future__ import annotations

import csv
from pathlib import Path

import numpy as np
import pytest
import pyuff
from campaigndata import paper_campaign
from reliability_campaign import cli, one_clear_line

from viscorig.exchange.uff import uff_records
from viscorig.storage import CampaignFile

HEADER = ["frequency_hz", "time_s", "accelerance_table_real_m_per_s2_per_n",
          "accelerance_table_imag_m_per_s2_per_n", "accelerance_support_real_m_per_s2_per_n",
          "accelerance_support_imag_m_per_s2_per_n", "flags"]
F = np.linspace(20.0, 120.0, 401)


def _voigt_rows(frequency_hz: np.ndarray) -> list[list[str]]:
    """Rows of a table on a Voigt damper (the paper's soft damper's order of magnitude)."""
    omega = 2 * np.pi * frequency_hz
    k, c, m_s, m_v = 150e3, 115.0, 3.4, 0.25
    support = -(omega**2) / (k + 1j * omega * c - omega**2 * m_v)
    table = -(omega**2) / (50e3 + k + 1j * omega * (5.0 + c) - omega**2 * (m_s + m_v))
    return [[repr(float(f)), "", *(repr(float(v)) for v in (t.real, t.imag, s.real, s.imag)),
             "0"]
            for f, t, s in zip(frequency_hz, table, support, strict=True)]


def _write(path: Path, rows: list[list[str]]) -> Path:
    with open(path, "w", newline="", encoding="utf-8") as handle:
        writer = csv.writer(handle)
        writer.writerow(HEADER)
        writer.writerows(rows)
    return path


def _import(tmp_path: Path, *source: object, run: str = "x"):
    return cli(["import", tmp_path / "c.h5", "--run", run, *source, "--specimen", "soft"])


def test_a_csv_of_nan_values_is_refused_naming_the_row_and_column(tmp_path: Path) -> None:
    rows = [[row[0], "", "nan", "nan", "nan", "nan", "0"] for row in _voigt_rows(F)]
    status, _, err = _import(tmp_path, "--csv", _write(tmp_path / "nan.csv", rows))
    line = one_clear_line(err)
    assert status == 2
    assert "nan.csv:2: accelerance_table_real_m_per_s2_per_n is 'nan'" in line, line
    assert not (tmp_path / "c.h5").exists()


@pytest.mark.parametrize(("column", "text"), [(3, "inf"), (4, "-inf"), (5, "NaN"), (1, "inf")])
def test_one_non_finite_cell_is_refused_naming_its_row(tmp_path: Path, column: int,
                                                       text: str) -> None:
    rows = _voigt_rows(F)
    rows[56][column] = text
    status, _, err = _import(tmp_path, "--csv", _write(tmp_path / "one.csv", rows))
    line = one_clear_line(err)
    assert status == 2
    assert f"one.csv:58: {HEADER[column]} is '{text}'" in line, line
    assert not (tmp_path / "c.h5").exists()


def test_rows_from_high_to_low_frequency_are_stored_rising(tmp_path: Path) -> None:
    rows = _voigt_rows(F)
    status, _, err = _import(tmp_path, "--csv", _write(tmp_path / "down.csv", rows[::-1]))
    assert status == 0, err
    run = CampaignFile.open(tmp_path / "c.h5").run("x")
    assert np.all(np.diff(run.frequency_hz) > 0)
    np.testing.assert_array_equal(run.frequency_hz, F)
    expected = np.array([complex(float(r[2]), float(r[3])) for r in rows])
    np.testing.assert_array_equal(run.accelerance_table, expected)
    assert run.metadata.direction == "down"  # the order the file listed them in


def test_rows_in_no_order_are_stored_rising(tmp_path: Path) -> None:
    rows = _voigt_rows(F)
    shuffled = [rows[i] for i in np.random.default_rng(1).permutation(len(rows))]
    status, _, err = _import(tmp_path, "--csv", _write(tmp_path / "mixed.csv", shuffled))
    assert status == 0, err
    run = CampaignFile.open(tmp_path / "c.h5").run("x")
    np.testing.assert_array_equal(run.frequency_hz, F)


@pytest.mark.parametrize("column", [4, 5])
def test_a_subnormal_part_a_damaged_double_reads_as_is_refused(tmp_path: Path,
                                                               column: int) -> None:
    rows = _voigt_rows(F)
    rows[56][column] = "6.77126833e-311"  # a UFF double of -4.76 with its top two bytes zeroed
    status, _, err = _import(tmp_path, "--csv", _write(tmp_path / "sub.csv", rows))
    line = one_clear_line(err)
    assert status == 2
    assert "1 of 401 values of ẍ_v/F_v have a part below 2.2e-308" in line, line
    assert f"point 57 of 401 ({F[56]:g} Hz)" in line, line
    assert not (tmp_path / "c.h5").exists()


def test_a_frequency_given_twice_is_refused_naming_both_rows(tmp_path: Path) -> None:
    rows = _voigt_rows(F)
    rows.insert(300, list(rows[10]))
    status, _, err = _import(tmp_path, "--csv", _write(tmp_path / "twice.csv", rows))
    line = one_clear_line(err)
    assert status == 2
    assert f"frequency {F[10]:g} Hz is given twice (lines 12 and 302)" in line, line
    assert not (tmp_path / "c.h5").exists()


@pytest.fixture(scope="module")
def campaign_file(tmp_path_factory) -> Path:
    path = tmp_path_factory.mktemp("campaign") / "paper.h5"
    paper_campaign(path, runs=("soft-0",))
    return path


def _uff(tmp_path: Path, campaign_file: Path, change) -> Path:
    run = CampaignFile.open(campaign_file).run("soft-0")
    records = uff_records(run)
    change(records)
    path = tmp_path / "changed.uff"
    pyuff.UFF(str(path)).write_sets(records, mode="overwrite")
    return path


def test_a_uff_frf_with_a_nan_point_is_refused_naming_the_point(tmp_path: Path,
                                                                  campaign_file: Path) -> None:
    # pyuff writes NaN as 0: the NaN is put in the ASCII text, as an editor or a tool could
    run = CampaignFile.open(campaign_file).run("soft-0")
    path = tmp_path / "nan.uff"
    pyuff.UFF(str(path)).write_sets(uff_records(run, binary=False), mode="overwrite")
    lines = path.read_text().splitlines()
    second = [i for i, line in enumerate(lines) if line.strip() == "58"][1]
    eighth = next(i for i in range(second, len(lines))
                  if lines[i].split()[:1] == [f"{run.frequency_hz[7]:.5e}"])
    lines[eighth] = f"{run.frequency_hz[7]:13.5e}{'NaN':>20}{'NaN':>20}"
    path.write_text("\n".join(lines) + "\n")
    status, _, err = _import(tmp_path, "--uff", path)
    line = one_clear_line(err)
    assert status == 2
    assert "1 of 401 values of ẍ_v/F_v are not finite, the first at point 8 of 401" in line, line


def test_a_uff_with_a_repeated_frequency_is_refused(tmp_path: Path, campaign_file: Path) -> None:
    def change(records):
        for record in records[1:]:
            x = np.array(record["x"], dtype=float)
            x[5] = x[4]
            record["x"] = x

    status, _, err = _import(tmp_path, "--uff", _uff(tmp_path, campaign_file, change))
    line = one_clear_line(err)
    assert status == 2 and "is given twice (points 5 and 6 of" in line, line


def test_a_uff_response_along_a_negative_axis_is_read_with_its_sign(
        tmp_path: Path, campaign_file: Path) -> None:
    """Record 6's response direction -3 (-Z) was ignored: the FRF stored 180° off."""
    def change(records):
        records[1]["rsp_dir"] = -3

    status, _, err = _import(tmp_path, "--uff", _uff(tmp_path, campaign_file, change))
    assert status == 0, err
    run = CampaignFile.open(campaign_file).run("soft-0")
    back = CampaignFile.open(tmp_path / "c.h5").run("x")
    np.testing.assert_allclose(back.accelerance_table, -run.accelerance_table, rtol=1e-6)
    np.testing.assert_allclose(back.accelerance_support, run.accelerance_support, rtol=1e-6)


def test_a_uff_with_two_records_named_for_one_frf_is_refused(tmp_path: Path,
                                                              campaign_file: Path) -> None:
    """Both records named 'viscorig soft-0 accelerance_table': the second was stored as the
    support's FRF."""
    def change(records):
        records[2]["id1"] = records[1]["id1"]

    status, _, err = _import(tmp_path, "--uff", _uff(tmp_path, campaign_file, change))
    line = one_clear_line(err)
    assert status == 2 and "dataset 3 (58, 'viscorig soft-0 accelerance_table'): a second " \
        "record named accelerance_table, after dataset 2" in line, line


@pytest.mark.parametrize("factor", ["1.0D+400", "0.0D+00", "-3.048D-01"])
def test_a_uff_unit_factor_no_unit_system_has_is_refused(tmp_path: Path, campaign_file: Path,
                                                         factor: str) -> None:
    """A dataset 164 length factor that overflows to infinity divided every value to zero:
    the run was stored as an FRF of zeros."""
    run = CampaignFile.open(campaign_file).run("soft-0")
    path = tmp_path / "factor.uff"
    pyuff.UFF(str(path)).write_sets(uff_records(run, binary=False), mode="overwrite")
    lines = path.read_text().splitlines()
    at = next(i for i, line in enumerate(lines) if line.strip() == "164") + 2
    fields = lines[at].split()
    lines[at] = f"{factor:>25}{fields[1]:>25}{fields[2]:>25}"
    path.write_text("\n".join(lines) + "\n")
    status, _, err = _import(tmp_path, "--uff", path)
    line = one_clear_line(err)
    assert status == 2 and "dataset 164: length factor" in line and "is not a unit's factor to " \
        "SI" in line, line


def test_a_uff_from_high_to_low_frequency_is_stored_rising(tmp_path: Path,
                                                           campaign_file: Path) -> None:
    def change(records):
        for record in records[1:]:
            record["x"] = np.array(record["x"], dtype=float)[::-1]
            record["data"] = np.array(record["data"], dtype=complex)[::-1]
            record["abscissa_min"] = float(record["x"][0])

    status, _, err = _import(tmp_path, "--uff", _uff(tmp_path, campaign_file, change))
    assert status == 0, err
    stored = CampaignFile.open(tmp_path / "c.h5").run("x")
    original = CampaignFile.open(campaign_file).run("soft-0")
    assert np.all(np.diff(stored.frequency_hz) > 0)
    np.testing.assert_allclose(stored.frequency_hz, original.frequency_hz, rtol=1e-5)
    np.testing.assert_allclose(stored.accelerance_support, original.accelerance_support,
                               rtol=1e-10)


def _sdf(tmp_path: Path, frequency_hz: np.ndarray, table: np.ndarray) -> Path:
    from sdfwrite import FOUR_CHANNELS, SdfLayout, Trace, sdf_bytes

    path = tmp_path / "FRF.DAT"
    path.write_bytes(sdf_bytes(SdfLayout(frequency_hz, FOUR_CHANNELS, [Trace(1, 0, table)])))
    return path


def _table(frequency_hz: np.ndarray) -> np.ndarray:
    rows = _voigt_rows(frequency_hz)
    return np.array([complex(float(r[2]), float(r[3])) for r in rows])


def test_an_sdf_response_with_a_nan_point_is_refused_naming_the_point(tmp_path: Path) -> None:
    table = _table(F)
    table[12] = complex(np.nan, 0.0)
    status, _, err = _import(tmp_path, "--sdf", _sdf(tmp_path, F, table))
    line = one_clear_line(err)
    assert status == 2
    assert f"values of ẍ_s/F_e are not finite, the first at point 13 of 401 ({F[12]:g} Hz)" \
        in line, line
    assert not (tmp_path / "c.h5").exists()


@pytest.mark.parametrize("factor", [0.0, 1e-45, 1e-39])
def test_an_sdf_eu_factor_no_analyser_writes_is_refused(tmp_path: Path, factor: float) -> None:
    """A subnormal EU correction factor (damaged exponent bits) scaled every value by 1e43."""
    from sdfwrite import FOUR_CHANNELS, Channel, SdfLayout, Trace, sdf_bytes

    channels = list(FOUR_CHANNELS)
    channels[1] = Channel("xdd_s", "m/s2", factor)
    path = tmp_path / "FRF.DAT"
    path.write_bytes(sdf_bytes(SdfLayout(F, channels, [Trace(1, 0, _table(F))])))
    status, _, err = _import(tmp_path, "--sdf", path)
    line = one_clear_line(err)
    assert status == 2 and "channel header 2: EU correction factor" in line, line
    assert "is not usable" in line and not (tmp_path / "c.h5").exists()


def test_one_sdf_file_given_twice_is_refused(tmp_path: Path) -> None:
    """The same file as both FRFs made a run whose support FRF was the table's."""
    path = _sdf(tmp_path, F, _table(F))
    status, _, err = _import(tmp_path, "--sdf", path, "--sdf", tmp_path / "." / path.name)
    line = one_clear_line(err)
    assert status == 2 and "given twice; the two files hold the two FRFs" in line, line
    assert not (tmp_path / "c.h5").exists()


def test_an_sdf_word_that_is_a_signalling_nan_is_refused_without_a_warning(
        tmp_path: Path) -> None:
    table = _table(F)
    table[12] = complex(np.nan, 0.0)
    path = _sdf(tmp_path, F, table)
    quiet = np.array([np.nan], dtype=">f8").tobytes()
    assert quiet in path.read_bytes()  # the point's words (its scaling makes both NaN)
    path.write_bytes(path.read_bytes().replace(quiet, bytes.fromhex("7ff0000000000001")))
    status, _, err = _import(tmp_path, "--sdf", path)
    assert status == 2
    assert "point 13 of 401" in one_clear_line(err) and "warning" not in err


@pytest.mark.parametrize("damaged", [1.043e-309, 3.13e-134, 2.37e305])
def test_an_sdf_frequency_word_no_analyser_writes_is_refused_naming_the_point(
        tmp_path: Path, damaged: float) -> None:
    # a hit exponent of the X record's 87th frequency (41.5 Hz), as a byte-damaged file held
    path = _sdf(tmp_path, F, _table(F))
    word = np.array([F[86]], dtype=">f8").tobytes()
    assert path.read_bytes().count(word) == 1
    path.write_bytes(path.read_bytes().replace(word, np.array([damaged], ">f8").tobytes()))
    status, _, err = _import(tmp_path, "--sdf", path)
    line = one_clear_line(err)
    assert status == 2
    assert "1 of 401 frequencies lie outside 1e-06 to 1e+06 Hz, the first at point 87 of 401" \
        in line, line
    assert not (tmp_path / "c.h5").exists()


@pytest.mark.parametrize(("point", "value"), [(0, 0.0), (86, 0.0), (0, -20.0), (200, -41.5)])
def test_an_sdf_point_at_or_below_0_hz_is_refused_unless_an_fft_s_first_line(
        tmp_path: Path, point: int, value: float) -> None:
    """A damaged axis (a negative start, a log step of 0 or below) gave points at or below
    0 Hz, which were dropped as if DC lines: a run of 1 or 201 of its 401 points was stored
    without a word. A first point at 0 Hz is an FFT's DC line, dropped."""
    x = F.copy()
    x[point] = value
    path = _sdf(tmp_path, x, _table(F))
    status, _, err = _import(tmp_path, "--sdf", path)
    if point == 0 and value == 0.0:
        assert status == 0, err
        assert CampaignFile.open(tmp_path / "c.h5").run("x").points == F.size - 1
        return
    line = one_clear_line(err)
    assert status == 2 and f"1 valid point(s) at or below 0 Hz or not a number, the first " \
        f"point {point + 1} of 401 at {value:g} Hz" in line, line
    assert not (tmp_path / "c.h5").exists()


def test_an_sdf_from_high_to_low_frequency_is_stored_rising(tmp_path: Path) -> None:
    falling = F[::-1].copy()
    status, _, err = _import(tmp_path, "--sdf", _sdf(tmp_path, falling, _table(falling)))
    assert status == 0, err
    run = CampaignFile.open(tmp_path / "c.h5").run("x")
    np.testing.assert_allclose(run.frequency_hz, F, rtol=1e-12)
    np.testing.assert_allclose(run.accelerance_table, _table(F), rtol=1e-12)


@pytest.mark.parametrize("option", ["--csv", "--uff", "--sdf", "--dma"])
def test_a_folder_or_a_missing_path_to_import_is_named_alike(tmp_path: Path, option: str) -> None:
    """A folder given to --uff was 'no such file', to --csv 'cannot read the CSV file (Is a
    directory)': each reader said it in its own words."""
    folder = tmp_path / "exports"
    folder.mkdir()
    for path, said in ((folder, "not a file"), (tmp_path / "gone.dat", "no such file")):
        status, _, err = _import(tmp_path, option, path)
        assert status == 2 and one_clear_line(err) == f"viscorig: {path}: {said}", err
    assert not (tmp_path / "c.h5").exists()
