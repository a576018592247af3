"""Exchange: UFF 58 and CSV round trips, 35670A SDF import, and bad input left untouched."""

from __future__ import annotations

import hashlib
import struct
from pathlib import Path

import numpy as np
import pytest
from campaigndata import paper_campaign
from sdfwrite import FOUR_CHANNELS, Channel, SdfLayout, Trace, sdf_bytes

from viscorig.cli import main
from viscorig.errors import InputError
from viscorig.exchange import (
    read_csv,
    read_sdf,
    read_sdf_frfs,
    read_uff,
    uff_records,
    write_csv,
    write_uff,
)
from viscorig.exchange.cells import parse_number
from viscorig.exchange.units import ACCELERATION_UNITS, FREQUENCY_UNITS, MODULUS_UNITS, lookup
from viscorig.storage import CampaignFile


@pytest.fixture(scope="module")
def campaign_file(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return paper_campaign(tmp_path_factory.mktemp("exchange") / "c.h5",
                          runs=("table", "soft-0"))


def _digest(path: Path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


def test_uff_round_trip_is_exact_and_declares_accelerance(campaign_file: Path, tmp_path: Path):
    run = CampaignFile.open(campaign_file).run("soft-0")
    out = tmp_path / "soft.uff"
    assert main(["export", str(campaign_file), "--run", "soft-0", "--format", "uff",
                 "--out", str(out)]) == 0
    back = read_uff(out)
    assert np.array_equal(back.frequency_hz, run.frequency_hz)
    assert np.array_equal(back.accelerance_table, run.accelerance_table)
    assert np.array_equal(back.accelerance_support, run.accelerance_support)
    frfs = [r for r in uff_records(run) if r["type"] == 58]
    assert len(frfs) == 2
    for record in frfs:
        assert record["func_type"] == 4
        assert record["abscissa_spec_data_type"] == 18
        assert record["abscissa_axis_units_lab"] == "Hz"
        assert (record["ordinate_spec_data_type"], record["ordinate_len_unit_exp"]) == (12, 1)
        assert record["ordinate_axis_units_lab"] == "m/s^2"
        assert (record["orddenom_spec_data_type"], record["orddenom_force_unit_exp"]) == (13, 1)
        assert record["orddenom_axis_units_lab"] == "N"
    assert [r["rsp_node"] for r in frfs] == [1, 2]


def test_uff_import_makes_a_run_equal_to_the_original(campaign_file: Path, tmp_path: Path):
    run = CampaignFile.open(campaign_file).run("soft-0")
    uff = tmp_path / "soft.uff"
    write_uff(run, uff)
    target = tmp_path / "imported.h5"
    assert main(["import", str(target), "--run", "soft-0", "--uff", str(uff),
                 "--specimen", "soft", "--hardness", "25"]) == 0
    imported = CampaignFile.open(target).run("soft-0")
    assert np.array_equal(imported.frequency_hz, run.frequency_hz)
    assert np.array_equal(imported.accelerance_table, run.accelerance_table)
    assert np.array_equal(imported.accelerance_support, run.accelerance_support)
    assert imported.metadata.status == "complete"
    assert imported.metadata.specimen == "soft" and imported.metadata.hardness_shore_a == 25


def test_ascii_uff_keeps_twelve_digits_and_bare_table_has_one_record(campaign_file, tmp_path):
    table = CampaignFile.open(campaign_file).run("table")
    out = tmp_path / "table.uff"
    assert write_uff(table, out, binary=False) == 1
    back = read_uff(out)
    assert np.all(np.isnan(back.accelerance_support))
    assert np.max(np.abs(back.accelerance_table / table.accelerance_table - 1)) < 1e-10
    assert np.max(np.abs(back.frequency_hz / table.frequency_hz - 1)) < 1e-5


def test_uff_receptance_in_mm_is_converted_to_accelerance(campaign_file, tmp_path):
    run = CampaignFile.open(campaign_file).run("soft-0")
    records = uff_records(run)[:2]  # units (164), then the table FRF
    omega = 2 * np.pi * run.frequency_hz
    records[1].update(ordinate_spec_data_type=8, ordinate_axis_units_lab="mm",
                      data=run.accelerance_table / -(omega**2) * 1e3, id1="other tool")
    import pyuff

    pyuff.UFF(str(tmp_path / "r.uff")).write_sets(records, mode="overwrite")
    back = read_uff(tmp_path / "r.uff")
    assert np.allclose(back.accelerance_table, run.accelerance_table, rtol=1e-12, atol=0)


@pytest.mark.parametrize(
    ("change", "message"),
    [
        ({"ordinate_axis_units_lab": "V"}, "not a unit of acceleration"),
        ({"orddenom_spec_data_type": 8}, "not a force"),
        ({"abscissa_spec_data_type": 17}, "not frequency"),
        ({"func_type": 1}, "holds no frequency response"),
    ],
)
def test_uff_with_wrong_units_is_refused(campaign_file, tmp_path, change, message):
    import pyuff

    run = CampaignFile.open(campaign_file).run("soft-0")
    records = uff_records(run)[:2]
    records[1].update(change)
    pyuff.UFF(str(tmp_path / "bad.uff")).write_sets(records, mode="overwrite")
    with pytest.raises(InputError, match=message):
        read_uff(tmp_path / "bad.uff")


def test_csv_round_trip_keeps_values_flags_and_units(campaign_file: Path, tmp_path: Path):
    run = CampaignFile.open(campaign_file).run("soft-0")
    out = tmp_path / "soft.csv"
    assert main(["export", str(campaign_file), "--run", "soft-0", "--format", "csv",
                 "--out", str(out)]) == 0
    header = out.read_text().splitlines()[0]
    assert header.split(",") == [
        "frequency_hz", "time_s", "accelerance_table_real_m_per_s2_per_n",
        "accelerance_table_imag_m_per_s2_per_n", "accelerance_support_real_m_per_s2_per_n",
        "accelerance_support_imag_m_per_s2_per_n", "flags"]
    assert "m/s^2/N" in (tmp_path / "soft.csv-metadata.json").read_text()
    back = read_csv(out)
    for name in ("frequency_hz", "accelerance_table", "accelerance_support", "flags", "time_s"):
        assert np.array_equal(getattr(back, name), getattr(run, name)), name


def test_csv_with_flags_survives_and_bad_cell_is_named(tmp_path: Path, campaign_file: Path):
    run = CampaignFile.open(campaign_file).run("table")
    out = tmp_path / "t.csv"
    write_csv(run, out)
    back = read_csv(out)
    assert np.all(np.isnan(back.accelerance_support))
    lines = out.read_text().splitlines()
    lines[-1] = lines[-1].replace(",0", ",zero")
    out.write_text("\n".join(lines))
    with pytest.raises(InputError, match=rf"t.csv:{len(lines)}: a cell is not a number"):
        read_csv(out)


def test_a_csv_column_given_twice_is_refused(tmp_path: Path, campaign_file: Path) -> None:
    """The second of two ẍ_s/F_e real-part columns was ignored without a word."""
    out = tmp_path / "t.csv"
    write_csv(CampaignFile.open(campaign_file).run("soft-0"), out)
    lines = out.read_text().splitlines()
    column = "accelerance_table_real_m_per_s2_per_n"
    lines = [f"{lines[0]},{column}"] + [f"{line},1.0" for line in lines[1:]]
    out.write_text("\n".join(lines) + "\n")
    with pytest.raises(InputError, match=f"t.csv:1: column {column} given twice"):
        read_csv(out)


@pytest.mark.parametrize("cell", ["1_0", "１２", "٣", "0x10", "1e"])
def test_a_cell_only_python_reads_as_a_number_is_refused(cell: str) -> None:
    """float() reads '1_0' as 10 and full-width or Arabic-Indic digits as numbers: a typo or
    a stray character became a value."""
    from viscorig.exchange.cells import parse_number

    for decimal_comma in (False, True):
        with pytest.raises(ValueError, match="could not convert"):
            parse_number(cell, decimal_comma)
    assert parse_number(" -1.5e3 ", False) == -1500.0 and parse_number("2,5", True) == 2.5


@pytest.mark.parametrize("delimiter", [";", "\t"])
def test_csv_saved_by_a_spreadsheet_with_a_decimal_comma_reads_the_same(
        tmp_path: Path, campaign_file: Path, delimiter: str):
    # a spreadsheet under a regional setting saves the table with ';' (or tabs) between cells
    # and decimal commas; it was refused as "unknown columns frequency_hz;time_s;..."
    run = CampaignFile.open(campaign_file).run("soft-0")
    out = tmp_path / "soft.csv"
    write_csv(run, out)
    lines = out.read_text(encoding="utf-8").splitlines()
    regional = tmp_path / "regional.csv"
    regional.write_text("\r\n".join([lines[0].replace(",", delimiter)] + [
        delimiter.join(cell.replace(".", ",") for cell in line.split(","))
        for line in lines[1:]]) + "\r\n", encoding="utf-8-sig")
    assert "0,0" in regional.read_text(encoding="utf-8-sig")
    back = read_csv(regional)
    for name in ("frequency_hz", "accelerance_table", "accelerance_support", "flags", "time_s"):
        assert np.array_equal(getattr(back, name), getattr(run, name)), name


@pytest.mark.parametrize(("cell", "value"), [
    ("-1,234.25", -1234.25), ("1.234,5", 1234.5), ("-0,0997", -0.0997), ("12,345,678.9",
    12345678.9), ("1.234.567,8", 1234567.8), ("-1,5e-3", -1.5e-3), ("1,23.4", None),
    ("1.2,3", None), ("1,2,3", None)])
def test_a_cell_with_both_marks_groups_thousands_by_the_one_before_the_decimal(cell, value):
    """A tab-separated export with thousands grouped the English way ('-1,234.25') was read
    as -1.23425: every value 1000 times too small, without a word."""
    if value is None:
        with pytest.raises(ValueError):
            parse_number(cell, decimal_comma=True)
    else:
        assert parse_number(cell, decimal_comma=True) == pytest.approx(value, rel=1e-15)


F = np.arange(20.0, 120.0 + 1e-9, 0.25)
H_TABLE = -0.1 * F**2 / (50e3 + 150e3 - (2 * np.pi * F) ** 2 * 3.6 + 2j * np.pi * F * 120)
H_SUPPORT = -(2 * np.pi * F) ** 2 / (150e3 - (2 * np.pi * F) ** 2 * 0.15 + 2j * np.pi * F * 115)


def test_sdf_with_both_frfs_reads_back_the_same_data(tmp_path: Path):
    path = tmp_path / "FRF.DAT"
    path.write_bytes(sdf_bytes(SdfLayout(F, FOUR_CHANNELS,
                                         [Trace(1, 0, H_TABLE), Trace(3, 2, H_SUPPORT)])))
    frfs = read_sdf(path)
    assert [frf.response_unit for frf in frfs] == ["m/s2", "m/s2"]
    assert [frf.reference_unit for frf in frfs] == ["N", "N"]
    assert np.array_equal(frfs[0].frequency_hz, F)
    assert np.allclose(frfs[0].values, H_TABLE, rtol=1e-14, atol=0)
    assert np.allclose(frfs[1].values, H_SUPPORT, rtol=1e-14, atol=0)


def test_sdf_import_of_two_files_with_linear_axis_and_g_units(tmp_path: Path):
    channels = [Channel("F_e", "N", 0.01), Channel("acc", "g", 0.1),
                Channel("F_v", "lbf", 0.04), Channel("acc", "m/s2", 0.01)]
    first, second = tmp_path / "TABLE.DAT", tmp_path / "SUPPORT.DAT"
    first.write_bytes(sdf_bytes(SdfLayout(F, channels, [Trace(1, 0, H_TABLE)],
                                          x_resolution=0, y_type=3)))
    second.write_bytes(sdf_bytes(SdfLayout(F, channels, [Trace(3, 2, H_SUPPORT)],
                                           x_resolution=0, y_type=3)))
    target = tmp_path / "c.h5"
    assert main(["import", str(target), "--run", "soft-0", "--sdf", str(first),
                 "--sdf", str(second), "--specimen", "soft"]) == 0
    run = CampaignFile.open(target).run("soft-0")
    assert np.allclose(run.frequency_hz, F, rtol=1e-12)
    assert np.allclose(run.accelerance_table, H_TABLE * 9.80665, rtol=1e-6, atol=0)
    assert np.allclose(run.accelerance_support, H_SUPPORT / 4.4482216152605, rtol=1e-6, atol=0)


def test_sdfascii_cannot_read_a_swept_sine_frequency_response(tmp_path: Path):
    """Why viscorig has its own SDF reader: sdfascii mangles FRF data (see exchange/sdf.py)."""
    sdfascii = pytest.importorskip("sdfascii")
    path = tmp_path / "FRF.DAT"
    path.write_bytes(sdf_bytes(SdfLayout(F, FOUR_CHANNELS, [Trace(1, 0, H_TABLE)])))
    with np.errstate(all="ignore"):
        header, data = sdfascii.read_sdf_file(str(path))
    assert header["data_hdr"][0]["data_type"] == "Frequency response"  # headers agree
    assert np.asarray(data).shape != H_TABLE.shape or not np.allclose(data, H_TABLE)


def _sdf(tmp_path: Path, **changes) -> Path:
    path = tmp_path / "bad.dat"
    layout = SdfLayout(F, FOUR_CHANNELS, [Trace(1, 0, H_TABLE)])
    for key, value in changes.items():
        setattr(layout, key, value)
    path.write_bytes(sdf_bytes(layout))
    return path


@pytest.mark.parametrize(
    ("changes", "message"),
    [
        ({"revision": 1}, "SDF revision 1"),
        ({"data_type": 2, "powers": (96, 0)},
         r"holds an auto-power spectrum .* \(HP 35670A, swept sine\)"),
        ({"x_unit": "s"}, "not a unit of frequency"),
        ({"channels": [Channel("F", "N", 0.01), Channel("a", "N", 1.0)]},
         "not a unit of acceleration"),
        ({"channels": [Channel("F", "N", 0.01), Channel("a", "V", 1.0)]},
         "volt-over-volt .* give --station"),
        ({"powers": (48, 0)}, "not those of a frequency response"),
    ],
)
def test_bad_sdf_is_refused_with_the_reason(tmp_path: Path, changes, message):
    with pytest.raises(InputError, match=message):
        read_sdf_frfs([_sdf(tmp_path, **changes)])


@pytest.mark.parametrize("cut", [1, 40, 300, 2000, -8])
def test_truncated_or_corrupt_sdf_is_one_input_error(tmp_path: Path, cut: int):
    path = _sdf(tmp_path)
    raw = path.read_bytes()
    path.write_bytes(raw[:cut])
    with pytest.raises(InputError):
        read_sdf(path)
    path.write_bytes(raw[:64] + struct.pack(">h", 99) + raw[66:])  # a wrong record type
    with pytest.raises(InputError):
        read_sdf(path)


@pytest.mark.parametrize(
    "arguments",
    [
        ["--uff", "{bad}"],
        ["--sdf", "{bad}"],
        ["--csv", "{bad}"],
        ["--uff", "{missing}"],
        ["--uff", "{good}", "--run", "soft-0"],  # the run exists
        ["--uff", "{good}", "--run", "bad name"],
    ],
)
def test_bad_import_is_one_line_exit_2_and_leaves_the_campaign_unchanged(
    campaign_file: Path, tmp_path: Path, capsys, arguments
):
    target = tmp_path / "c.h5"
    target.write_bytes(campaign_file.read_bytes())
    before = _digest(target)
    bad = tmp_path / "bad.bin"
    bad.write_bytes(b"    -1\n    58\n garbage\n    -1\n")
    good = tmp_path / "good.uff"
    write_uff(CampaignFile.open(campaign_file).run("soft-0"), good)
    values = {"bad": bad, "missing": tmp_path / "nothing.uff", "good": good}
    arguments = [a.format(**values) for a in arguments]
    if "--run" not in arguments:
        arguments += ["--run", "new"]
    capsys.readouterr()
    assert main(["import", str(target), *arguments]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.startswith("viscorig: ")
    assert _digest(target) == before


@pytest.mark.parametrize(("option", "value", "message"), [
    ("--hardness", "500", "--hardness: 500 is outside 0..100 Shore A"),
    ("--temperature", "-300", "--temperature: -300 is outside -100..300 °C"),
    ("--temperature", "1e9", "--temperature: 1e+09 is outside -100..300 °C"),
    ("--preload-strain", "0.6", "--preload-strain: 0.6 is outside 0..0.5"),
    ("--preload-strain", "nan", "--preload-strain: nan is not a number"),
    ("--level", "-1", "--level: -1.0 must be a positive number"),
    # read past the option's check, then refused by the writer under its attribute's name
    ("--level", "1e5", "--level: 100000.0 must be a positive number, at most 10000 m/s^2"),
])
def test_an_imported_run_s_options_are_held_to_a_sequence_s_bounds(
    campaign_file: Path, tmp_path: Path, capsys, option: str, value: str, message: str
):
    # a hardness of 500 Shore A, or a run at -300 °C, was stored as given
    good = tmp_path / "good.uff"
    write_uff(CampaignFile.open(campaign_file).run("soft-0"), good)
    target = tmp_path / "c.h5"
    assert main(["import", str(target), "--run", "r", "--uff", str(good), option, value]) == 2
    assert capsys.readouterr().err == f"viscorig: {message}\n"
    assert not target.exists()
    assert main(["import", str(target), "--run", "r", "--uff", str(good), "--temperature",
                 "-70", "--hardness", "0"]) == 0  # a chamber run's temperature; the scale's end


def test_export_of_a_missing_run_is_one_line_and_writes_nothing(campaign_file, tmp_path, capsys):
    out = tmp_path / "x.uff"
    assert main(["export", str(campaign_file), "--run", "nope", "--format", "uff",
                 "--out", str(out)]) == 2
    assert "no such run" in capsys.readouterr().err
    assert not out.exists() and not list(tmp_path.iterdir())


@pytest.mark.parametrize(("out", "words"), [
    ("folder", "a folder has this name: "), ("missing/x.csv", "folder does not exist: "),
])
def test_an_export_that_cannot_be_written_says_why_once(campaign_file, tmp_path, capsys, out,
                                                        words):
    (tmp_path / "folder").mkdir()
    assert main(["export", str(campaign_file), "--run", "soft-0", "--format", "csv",
                 "--out", str(tmp_path / out)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and words in err and "cannot write (" not in err, err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["folder"]


@pytest.mark.parametrize(("label", "factor"), [
    ("MPa", 1e6), ("MPA", 1e6), ("mpa", 1e6), ("M Pa", 1e6), ("kPa", 1e3), ("mPa", None),
    ("Mpa", None), ("GPa", 1e9), ("pa", 1.0)])
def test_a_unit_in_mixed_case_is_read_as_written(label, factor):
    """Labels were compared in lower case: mPa (millipascal) read as MPa, 1e9 times off. A
    label in one case (as instruments write them) still matches any spelling."""
    assert lookup(label, MODULUS_UNITS) == factor
    assert lookup("Mm/s^2", ACCELERATION_UNITS) is None
    assert lookup("M/S2", ACCELERATION_UNITS) == 1.0 and lookup("HZ", FREQUENCY_UNITS) == 1.0


def test_a_run_of_one_point_is_not_written_to_a_uff_file(campaign_file: Path, tmp_path: Path):
    """A run stopped after its first point ended in pyuff's 'Error writing data-set #58'."""
    run = CampaignFile.open(campaign_file).run("soft-0")
    one = run.select(np.arange(run.points) == 0)
    with pytest.raises(InputError, match="run 'soft-0': 1 point\\(s\\); a universal file's "):
        write_uff(one, tmp_path / "one.uff")
    assert not (tmp_path / "one.uff").exists()


@pytest.mark.parametrize("kind", ["fifo", "folder", "empty"])
def test_export_never_replaces_what_is_not_a_file(tmp_path: Path, campaign_file: Path,
                                                  kind: str) -> None:
    """--out /dev/null was replaced by a regular file (the rename of the finished export),
    and its metadata written beside it in /dev; --out '' ended in a ValueError traceback."""
    import os

    target = tmp_path / "target"
    if kind == "fifo":
        os.mkfifo(target)
    elif kind == "folder":
        target.mkdir()
    out = "" if kind == "empty" else str(target)
    for format_ in ("csv", "uff"):
        assert main(["export", str(campaign_file), "--run", "soft-0", "--format", format_,
                     "--out", out]) == 2
    if kind == "fifo":
        assert target.is_fifo()
    assert sorted(p.name for p in tmp_path.iterdir()) == (["target"] if kind != "empty" else [])
