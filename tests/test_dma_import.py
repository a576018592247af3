"""DMA tables in: the CSV layouts DMA users exchange, the /dma run of a campaign file, and one
clear line for bad input."""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pytest
from materialdata import dma_sweep
from realdata import real_data

from viscorig.cli import main
from viscorig.errors import InputError
from viscorig.materials.dmafile import read_dma_csv
from viscorig.materials.dmastore import dma_run_names, import_dma, read_dma
from viscorig.materials.table import MAX_MASTER_POINTS, ModulusTable
from viscorig.storage import CampaignFile

SWEEP = "pyvisco_freq_user_raw.csv"


@pytest.fixture
def sweep_csv(tmp_path) -> Path:
    """A sweep in pyvisco's layout (names row, units row) made by the test's own generator:
    21 temperatures from -50 to 100 °C, 10 frequencies from 0.1 to 100 Hz."""
    data = dma_sweep(np.linspace(-50.0, 100.0, 21), np.logspace(-1, 2, 10))
    rows = ["f,E_stor,E_loss,T,Set", "Hz,MPa,MPa,C,-"]
    rows += [f"{f:.17g},{e1 / 1e6:.17g},{e2 / 1e6:.17g},{t:.17g},{k}" for f, e1, e2, t, k in zip(
        data["frequency_hz"], data["storage_pa"], data["loss_pa"], data["temperature_c"],
        data["set_index"], strict=True)]
    path = tmp_path / "sweep.csv"
    path.write_text("\n".join(rows) + "\n")
    return path


def real_sweep() -> Path:
    """pyvisco's example DMA sweep (tests/data/dma/README.md); skips the test without it."""
    return real_data("dma", SWEEP) / SWEEP


def test_pyvisco_layout_names_then_units_row():
    table = read_dma_csv(real_sweep())
    assert table.points == 210 and table.sets.size == 21 and table.modulus == "E"
    assert table.frequency_hz[0] == 0.1 and table.storage_pa[0] == pytest.approx(8097.175545e6)
    assert table.loss_pa[0] == pytest.approx(93.07449045e6)
    assert table.set_temperatures_c()[0] == pytest.approx(-49.91, abs=0.01)


def test_units_in_names_semicolons_decimal_comma_and_bom(tmp_path):
    path = tmp_path / "eplexor.csv"
    text = ("Temperature (°C);Frequency (Hz);G' [kPa];G'' [kPa]\n"
            "20,0;1,0;1500,5;300,25\n20,1;10,0;1700,0;350,0\n"
            "30,0;1,0;1200,0;260,0\n30,1;10,0;1400,0;290,0\n")
    path.write_bytes("\ufeff".encode() + text.encode("utf-8"))
    table = read_dma_csv(path)
    assert table.modulus == "G"
    assert table.storage_pa.tolist() == [1500.5e3, 1700e3, 1200e3, 1400e3]
    assert table.loss_pa[0] == pytest.approx(300.25e3)
    assert table.set_index.tolist() == [0, 0, 1, 1]  # grouped by temperature


@pytest.mark.parametrize("end", ["\r", "\r\n"])
def test_lines_ended_by_a_carriage_return_read_as_any(tmp_path, end):
    """A table saved with CR line ends (classic Mac OS) was 'not a readable table (new-line
    character seen in unquoted field...)'."""
    path = tmp_path / "cr.csv"
    path.write_bytes("f,E_stor,E_loss,T\nHz,MPa,MPa,C\n1,10,1,20\n2,11,x,20\n"
                     .replace("\n", end).encode())
    with pytest.raises(InputError, match="row 4, column 'E_loss'"):
        read_dma_csv(path)
    path.write_bytes(path.read_bytes().replace(b",x,", b",1,"))
    assert read_dma_csv(path).frequency_hz == pytest.approx([1.0, 2.0])


def test_a_quantity_logged_twice_alike_or_once_reads(tmp_path):
    """A rheometer that logs the temperature twice (the second column often left empty)."""
    path = tmp_path / "twice.csv"
    path.write_text("f,E_stor,E_loss,T,T\nHz,MPa,MPa,C,C\n1,10,1,20,20\n2,11,1,30,\n")
    table = read_dma_csv(path)
    assert table.temperature_c == pytest.approx([20.0, 30.0])


def test_complex_modulus_and_tan_delta_with_kelvin_and_rad_per_s(tmp_path):
    path = tmp_path / "trios.txt"
    path.write_text("omega (rad/s)\tT (K)\t|E*| (MPa)\ttan delta\n"
                    "6.283185307\t293.15\t5.0\t0.75\n62.83185307\t293.15\t6.0\t0.5\n")
    table = read_dma_csv(path)
    assert table.frequency_hz == pytest.approx([1.0, 10.0])
    assert table.temperature_c == pytest.approx([20.0, 20.0])
    assert table.storage_pa[0] == pytest.approx(5e6 * 0.8) and table.loss_pa[0] == \
        pytest.approx(5e6 * 0.6)


@pytest.mark.parametrize(("text", "expected"), [
    ("f,E_stor,E_loss,T\nHz,MPa,MPa,C\n1,10,1,20\n2,x,1,20\n", "row 4, column 'E_stor'"),
    ("f,E_stor,E_loss,T\nHz,MPa,MPa,C\n1,10,1,20\n2,-3,1,20\n",
     "1 data row(s) with a storage and loss modulus in range"),
    ("f,E_stor,T\nHz,MPa,C\n1,10,20\n2,11,20\n", "no storage and loss modulus columns"),
    ("f,E_stor,E_loss,T\n1,10,1,20\n2,11,1,20\n", "no unit for modulus"),
    ("f,E_stor,E_loss,T\nHz,furlong,MPa,C\n1,10,1,20\n2,11,1,20\n", "furlong"),
    # a row with a cell too many was read shifted: E'' as the temperature, without a word
    ("f,E_stor,E_loss,T\nHz,MPa,MPa,C\n1,10,1,20\n2,5,11,1,20\n",
     "row 4: 5 cells where the header names 4"),
    # a viscosity named eta was taken for the loss factor: E' 0.63 Pa where it is 8.1 GPa
    ("f,E*,Eta,T\nHz,MPa,Pa.s,C\n1,10,0.5,20\n2,11,0.4,20\n",
     "row 2, column 'Eta': unit 'Pa.s' for a loss factor"),
    ("f,E*,tan delta,T\nHz,MPa,°,C\n1,10,5,20\n2,11,4,20\n",
     "row 2, column 'tan delta': unit '°' for a loss factor"),
    # millipascal was read as megapascal, case folded away: every modulus 1e9 times too large
    ("f,E_stor,E_loss,T\nHz,mPa,mPa,C\n1,10,1,20\n2,11,1,20\n",
     "row 2, column 'E_stor': unit 'mPa' is not a unit of modulus"),
    # a temperature no specimen is measured at was taken (1e6 °C shifted like any other)
    ("f,E_stor,E_loss,T\nHz,MPa,MPa,C\n1,10,1,20\n2,11,1,1e6\n", "row 4, column 'T'"),
    # a denormal frequency (a damaged cell) stretched the shifts' knots over 320 decades: the
    # master curve ran for hours
    ("f,E_stor,E_loss,T\nHz,MPa,MPa,C\n1,10,1,20\n1e-320,11,1,20\n",
     "row 4, column 'f': frequency must be a number from 1e-09 to 1e+09 Hz"),
    # a denormal modulus made the Prony fit's residuals NaN: left out, so too few remain
    ("f,E_stor,E_loss,T\nHz,MPa,MPa,C\n1,10,1,20\n2,1e-320,1,20\n",
     "1 data row(s) with a storage and loss modulus in range"),
    # the first of two storage columns was read, the second ignored without a word
    ("f,E_stor,E_loss,T,E'\nHz,MPa,MPa,C,MPa\n1,10,1,20,10\n2,11,1,20,12\n",
     "row 4: columns 'E_stor' and \"E'\" give the same quantity and differ (11 and 12)"),
    ("f,E_stor,E_loss,T,E'\nHz,MPa,MPa,C,GPa\n1,10,1,20,10\n2,11,1,20,11\n",
     "row 2, column \"E'\": columns 'E_stor' (MPa) and \"E'\" (GPa) give the same quantity"),
    # a unit in the name was overridden by the units row's
    ("f,E_stor [Pa],E_loss,T\nHz,MPa,MPa,C\n1,10,1,20\n2,11,1,20\n",
     "row 1, column 'E_stor [Pa]': unit 'Pa' in the name and 'MPa' in the units row"),
])
def test_bad_tables_name_file_row_and_column(tmp_path, text, expected):
    path = tmp_path / "bad.csv"
    path.write_text(text)
    with pytest.raises(InputError) as error:
        read_dma_csv(path)
    assert expected in str(error.value) and "bad.csv" in str(error.value)


def test_import_stores_a_dma_run_beside_the_rig_runs(tmp_path, capsys, sweep_csv):
    path = tmp_path / "c.h5"
    assert main(["import", str(path), "--run", "eca", "--dma", str(sweep_csv)]) == 0
    assert "210 points, 21 temperatures" in capsys.readouterr().out
    campaign = CampaignFile.open(path)
    assert dma_run_names(campaign) == ["eca"] and campaign.run_names == []
    table = read_dma(campaign, "eca")
    assert np.array_equal(table.storage_pa, read_dma_csv(sweep_csv).storage_pa)
    # the rest of the tool still reads the file; a second import never overwrites
    assert main(["show", str(path)]) == 0
    listing = capsys.readouterr().out
    assert "DMA run" in listing and "eca" in listing and "-50.0..100.0" in listing
    assert main(["import", str(path), "--run", "eca", "--dma", str(sweep_csv)]) == 2
    assert "DMA run exists" in capsys.readouterr().err


@pytest.mark.slow
def test_a_modulus_below_zero_is_stored_named_and_left_out_of_the_master_curve(
        tmp_path, capsys, sweep_csv):
    lines = sweep_csv.read_text().splitlines()
    cells = lines[13].split(",")  # row 14 of the file: set 1's second point
    cells[2] = "-0.02"
    lines[13] = ",".join(cells)
    sweep_csv.write_text("\n".join(lines) + "\n")
    path = tmp_path / "c.h5"
    assert main(["import", str(path), "--run", "eca", "--dma", str(sweep_csv)]) == 0
    said = capsys.readouterr()  # the command's warnings go to stderr, not to the root logger
    warned = [line for line in said.err.splitlines() if "warning" in line]
    assert len(warned) == 1 and "row 14, column 'E_loss'" in warned[0], said.err
    assert "210 points" in said.out
    stored = read_dma(CampaignFile.open(path), "eca")
    assert stored.loss_pa[11] == pytest.approx(-0.02e6)  # kept as measured
    assert main(["master", str(path), "--run", "eca", "--json"]) == 0
    import json

    document = json.loads(capsys.readouterr().out)
    # the -50 °C sweep, whose glassy moduli meet no other sweep's, is left out as well
    assert document["points"] == 199 and len(document["shift_factors"]) == 20
    (left,) = [point for point in document["left_out"] if point["temperature_c"] != -50.0]
    assert left["point"] == 12 and left["loss_pa"] == pytest.approx(-0.02e6)
    assert "loss modulus" in left["why"]
    assert len(document["left_out"]) == 11


def test_import_refuses_a_bad_file_in_one_line_and_creates_nothing(tmp_path, capsys):
    bad = tmp_path / "bad.csv"
    bad.write_text("f;E';E'';T\nHz;MPa;MPa;C\n1;10;1;20\n2;11;oops;20\n")
    path = tmp_path / "c.h5"
    assert main(["import", str(path), "--run", "x", "--dma", str(bad)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "row 4" in err and "Traceback" not in err
    assert not path.exists()


@pytest.mark.parametrize("content", [
    b"\x00\x01\x02binary\xff\xfe" * 100,
    b"f,E_stor,E_loss,T\nHz,MPa,MPa,C\n1,10,1," + b"9" * 200_000 + b"\n",
    b"f;E';E'';T\r\nHz;MPa;MPa;C\r\n1;10;1;20\r\n2;11;1\r\n",
    b"",
])
def test_hostile_dma_files_are_refused_in_one_line(tmp_path, capsys, content):
    bad = tmp_path / "hostile.csv"
    bad.write_bytes(content)
    path = tmp_path / "c.h5"
    assert main(["import", str(path), "--run", "x", "--dma", str(bad)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "hostile.csv" in err and "Traceback" not in err
    assert not path.exists()


def test_excel_workbook_in_the_eplexor_layout(tmp_path, capsys, sweep_csv):
    openpyxl = pytest.importorskip("openpyxl")
    csv_table = read_dma_csv(sweep_csv)
    book = openpyxl.Workbook()
    book.active.title = "Data header"
    book.active.append(["Measurement type:", "Temp. Freq. Sweep"])
    sheet = book.create_sheet("Exported Data")
    sheet.append(["Nr", "F stat.", "Time", "f", "T", "E'", "E''", "|E*|", "tan delta", "T2"])
    sheet.append([None, "N", "s", "Hz", "°C", "MPa", "MPa", "MPa", None, "°C"])
    for i in range(csv_table.points):
        sheet.append([i + 1, -1.0, 10.0 * i, csv_table.frequency_hz[i],
                      csv_table.temperature_c[i], csv_table.storage_pa[i] / 1e6,
                      csv_table.loss_pa[i] / 1e6, 0.0, 0.0, 0.0])
    path = tmp_path / "eplexor.xlsx"
    book.save(path)
    path_h5 = tmp_path / "c.h5"
    assert main(["import", str(path_h5), "--run", "epl", "--dma", str(path)]) == 0
    table = read_dma(CampaignFile.open(path_h5), "epl")
    assert table.sets.size == 21  # no set column: grouped by temperature
    assert np.allclose(table.storage_pa, csv_table.storage_pa, rtol=1e-12)
    assert np.allclose(table.loss_pa, csv_table.loss_pa, rtol=1e-12)
    capsys.readouterr()
    sheet.cell(row=7, column=6, value="n/a")
    book.save(path)
    assert main(["import", str(tmp_path / "d.h5"), "--run", "x", "--dma", str(path)]) == 2
    err = capsys.readouterr().err
    assert "sheet 'Exported Data'" in err and "row 7" in err and "column \"E'\"" in err


def test_modulus_option_names_the_kind_and_belongs_to_dma_only(tmp_path, capsys, sweep_csv):
    path = tmp_path / "c.h5"
    assert main(["import", str(path), "--run", "g", "--dma", str(sweep_csv), "--modulus", "G"]) == 0
    assert "modulus G" in capsys.readouterr().out
    assert read_dma(CampaignFile.open(path), "g").modulus == "G"
    assert main(["import", str(path), "--run", "h", "--uff", str(sweep_csv), "--modulus", "E"]) == 2
    assert "--modulus: only with --dma" in capsys.readouterr().err


#: The TRIOS "Export to LIMS" text layout (docs/materials.md names the public exports it was
#: taken from): header sections of name<TAB>value, then one [Step] per isothermal frequency
#: sweep with Variables, Units (aligned) and "Data point" lines.
TRIOS_VARIABLES = ["Run time", "Temperature", "Angular frequency", "Oscillation strain",
                   "Complex viscosity", "Step time", "Phase angle", "Date and time", "Frequency",
                   "Tan(delta)", "Complex modulus", "Storage modulus", "Loss modulus"]
TRIOS_UNITS = ["s", "°C", "rad/s", "%", "Pa.s", "s", "°", "", "Hz", "", "Pa", "MPa", "MPa"]


def _trios_text(data, temperatures, frequencies, drift_k=0.03) -> str:
    lines = ["[Version]", "TA Instruments LIMS export format version\t0", "[Header]",
             "Instrument name\tRSA-G2", "Run date\t6/26/2023", "[Sample]", "Name\tgenerated",
             "[Procedure]", "Procedure name\tTTS", "[Procedure: Steps]",
             "Step 1\tConditioning-Sample : Temperature 150 °C", "[Parameters]",
             "[Parameters: File Parameters]", "Trios version\t5.1.1.46572"]
    size = len(frequencies)
    for k, temperature in enumerate(temperatures):
        lines += ["[Step]", f"Step name\tFrequency sweep ({temperature:.1f} °C)",
                  f"Number of points\t{size}", "Variables\t" + "\t".join(TRIOS_VARIABLES),
                  "Units\t" + "\t".join(TRIOS_UNITS)]
        for i in range(k * size, (k + 1) * size):
            f, e1, e2 = data["frequency_hz"][i], data["storage_pa"][i], data["loss_pa"][i]
            t = data["temperature_c"][i] + drift_k * ((i % 3) - 1)
            cells = [f"{10.0 * i:.6g}", f"{t:.17g}", f"{2 * np.pi * f:.17g}", "1.0", "12.5",
                     "3.0", f"{np.degrees(np.arctan2(e2, e1)):.17g}", "6/26/2023 1:43:31 PM",
                     f"{f:.17g}", f"{e2 / e1:.17g}", f"{np.hypot(e1, e2):.17g}",
                     f"{e1 / 1e6:.17g}", f"{e2 / 1e6:.17g}"]
            lines.append("Data point\t" + "\t".join(cells))
    return "\r\n".join(lines) + "\r\n"


@pytest.fixture
def trios_file(tmp_path):
    temperatures, frequencies = np.linspace(-20.0, 60.0, 5), np.logspace(-1, 1.3, 7)
    data = dma_sweep(temperatures, frequencies, seed=5)
    path = tmp_path / "sweep.txt"
    path.write_text(_trios_text(data, temperatures, frequencies), encoding="utf-8")
    return path, data


def test_trios_text_export_is_read_by_content_each_step_one_set(trios_file, tmp_path, capsys):
    path, data = trios_file
    table = read_dma_csv(path)
    assert table.points == 35 and table.sets.size == 5
    assert table.set_index.tolist() == np.repeat(np.arange(5), 7).tolist()
    assert np.allclose(table.frequency_hz, data["frequency_hz"], rtol=1e-12)
    assert np.allclose(table.storage_pa, data["storage_pa"], rtol=1e-12)
    assert np.allclose(table.loss_pa, data["loss_pa"], rtol=1e-12)
    assert np.allclose(table.temperature_c, data["temperature_c"], atol=0.031)
    # TRIOS names shear and tensile moduli alike: the kind is --modulus's, E by default
    assert table.modulus == "E"
    h5 = tmp_path / "c.h5"
    assert main(["import", str(h5), "--run", "trios", "--dma", str(path), "--modulus", "G"]) == 0
    assert "35 points, 5 temperatures" in capsys.readouterr().out
    assert read_dma(CampaignFile.open(h5), "trios").modulus == "G"


def _spoil_frequency(lines: list[str], row: int) -> list[str]:
    """The Frequency cell of line ``row`` (1-based) made not a number."""
    cells = lines[row - 1].split("\t")
    cells[1 + TRIOS_VARIABLES.index("Frequency")] = "oops"
    return [*lines[:row - 1], "\t".join(cells), *lines[row:]]


@pytest.mark.parametrize(("edit", "expected"), [
    (lambda lines: _spoil_frequency(lines, 20), "row 20, column 'Frequency'"),
    (lambda lines: [line for line in lines if not line.startswith("Units")],
     "row 19: a data point before the step's Variables and Units"),
    (lambda lines: lines[:-1], "declares 7 points but holds 6"),
])
def test_bad_trios_exports_name_file_row_and_column(trios_file, tmp_path, capsys, edit,
                                                    expected):
    path, _ = trios_file
    lines = edit(path.read_text(encoding="utf-8").splitlines())
    bad = tmp_path / "bad.txt"
    bad.write_text("\n".join(lines) + "\n", encoding="utf-8")
    h5 = tmp_path / "c.h5"
    assert main(["import", str(h5), "--run", "x", "--dma", str(bad)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "bad.txt" in err and "row " in err and expected in err, err
    assert "Traceback" not in err and not h5.exists()


# --- the units row told from every named column; typographic primes; unitless kelvin; xlrd


def _read(tmp_path, text: str, name: str = "t.csv"):
    path = tmp_path / name
    path.write_text(text, encoding="utf-8")
    return read_dma_csv(path)


@pytest.mark.parametrize("text", [
    # a leading text column: its first data cell is a sample name, not a unit
    "Sample,f [Hz],E' [MPa],E'' [MPa],T [°C]\nA1,0.1,10,1,20\nA1,1,11,1.5,20\nA1,10,12,2,20\n",
    # a units row whose first cell is empty, then one whose first cell is the sample's name
    "Sample,f,E',E'',T\n,Hz,MPa,MPa,C\nA1,0.1,10,1,20\nA1,1,11,1.5,20\nA1,10,12,2,20\n",
    "Sample,f,E',E'',T\nA1,Hz,MPa,MPa,C\nA1,0.1,10,1,20\nA1,1,11,1.5,20\nA1,10,12,2,20\n",
])
def test_units_row_is_told_from_the_named_columns_not_the_first_cell(tmp_path, text):
    table = _read(tmp_path, text)
    assert table.points == 3 and table.frequency_hz.tolist() == [0.1, 1.0, 10.0]
    assert table.storage_pa.tolist() == [10e6, 11e6, 12e6]


@pytest.mark.parametrize(("text", "expected"), [
    # a first data row with one bad cell is a data row: its row and column are named
    ("f [Hz],E' [MPa],E'' [MPa],T [°C]\nabc,10,1,20\n1,11,1,20\n", "row 2, column 'f [Hz]'"),
    ("Sample,f,E',E'',T\n,Hz,MPa,MPa,C\nA1,0.1,x,1,20\nA1,1,11,1,20\n", "row 3, column \"E'\""),
    # a unit the units row gives wrongly is named with the units row's number
    ("Sample,f,E',E'',T\nA1,Hz,furlong,MPa,C\nA1,0.1,10,1,20\nA1,1,11,1,20\n",
     "row 2, column \"E'\": unit 'furlong'"),
    ("f,E_stor,E_loss,T\nHz,MPa,MPa,F\n1,10,1,20\n2,11,1,20\n", "row 2, column 'T': unit 'F'"),
    # a unit missing altogether: the header row and the column
    ("f,E_stor,E_loss,T\n1,10,1,20\n2,11,1,20\n", "row 1, column 'E_stor': no unit"),
])
def test_unit_and_cell_errors_name_file_row_and_column(tmp_path, text, expected):
    with pytest.raises(InputError) as error:
        _read(tmp_path, text, "bad.csv")
    message = str(error.value)
    assert "bad.csv" in message and expected in message, message


@pytest.mark.parametrize(("storage", "loss", "modulus"), [
    ("E\u2019", "E\u2019\u2019", "E"),  # right single quotation mark (Word, Excel)
    ("E\u2032", "E\u2033", "E"),  # prime and double prime
    ("E\u2019", "E\u201d", "E"),  # right double quotation mark for the loss
    ("G\u2019", "G\u201d", "G"),
    ("G\u2032", "G\u2032\u2032", "G"),
])
def test_typographic_primes_name_storage_and_loss(tmp_path, storage, loss, modulus):
    table = _read(tmp_path, f"f [Hz];{storage} [MPa];{loss} [MPa];T [°C]\n"
                            "1;10;1;20\n10;11;1.5;20\n")
    assert table.modulus == modulus and table.storage_pa.tolist() == [10e6, 11e6]
    assert table.loss_pa.tolist() == [1e6, 1.5e6]


def test_typographic_primes_in_a_windows_1252_file(tmp_path):
    path = tmp_path / "cp.csv"
    path.write_bytes("f [Hz];E\u2019 [MPa];E\u2019\u2019 [MPa];T [°C]\n1;10;1;20\n10;11;1;20\n"
                     .encode("cp1252"))
    assert read_dma_csv(path).storage_pa.tolist() == [10e6, 11e6]


@pytest.mark.parametrize("units", ["f [Hz],E' [MPa],E'' [MPa],T\n",
                                   "f,E',E'',T\nHz,MPa,MPa,-\n"])
def test_temperatures_without_a_unit_that_look_like_kelvin_are_refused(tmp_path, units):
    with pytest.raises(InputError) as error:
        _read(tmp_path, units + "1,10,1,283.15\n10,11,1,283.2\n1,9,1,293.15\n", "k.csv")
    message = str(error.value)
    assert "k.csv: row 1, column 'T'" in message, message
    assert "[K]" in message and "kelvin" in message and "\n" not in message, message


def test_temperatures_without_a_unit_are_celsius_otherwise_and_kelvin_when_told(tmp_path):
    assert _read(tmp_path, "f [Hz],E' [MPa],E'' [MPa],T\n1,10,1,20\n1,11,1,160\n") \
        .temperature_c.tolist() == [20.0, 160.0]
    table = _read(tmp_path, "f [Hz],E' [MPa],E'' [MPa],T [K]\n1,10,1,283.15\n1,11,1,293.15\n")
    assert table.temperature_c == pytest.approx([10.0, 20.0])


def test_xls_without_xlrd_names_the_fix_in_one_line(tmp_path, capsys, monkeypatch):
    import sys

    monkeypatch.setitem(sys.modules, "xlrd", None)  # import xlrd raises ImportError
    book = tmp_path / "eplexor.xls"
    book.write_bytes(b"\xd0\xcf\x11\xe0\xa1\xb1\x1a\xe1" + b"\x00" * 504)
    assert main(["import", str(tmp_path / "c.h5"), "--run", "x", "--dma", str(book)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "eplexor.xls" in err and "xlrd" in err, err
    assert 'pip install "viscorig[excel]"' in err, err


def test_the_excel_extra_lists_the_packages_the_workbook_readers_import():
    import tomllib

    root = Path(__file__).resolve().parents[1]
    extra = tomllib.loads((root / "pyproject.toml").read_text())["project"][
        "optional-dependencies"]["excel"]
    names = {re.split(r"[<>=!~\[; ]", requirement)[0].lower() for requirement in extra}
    source = (root / "src/viscorig/materials/dmafile.py").read_text()
    assert {"xlrd", "openpyxl"} <= names
    assert {"xlrd", "openpyxl"} <= set(re.findall(r"^\s*import (\w+)", source, re.MULTILINE))


def test_a_curve_at_one_temperature_imports_but_is_no_master_curve(tmp_path, capsys):
    # a DMA program's master export: one curve already shifted to its reference temperature
    frequency = np.geomspace(1e-6, 1e6, 25)
    storage = 1.0 + 50.0 * (frequency / (1.0 + frequency))
    rows = [f"{f:.6g},{e:.6g},{0.1 * e:.6g},25.0" for f, e in zip(frequency, storage, strict=True)]
    source = tmp_path / "master.csv"
    source.write_text("f,E_stor,E_loss,T\nHz,MPa,MPa,C\n" + "\n".join(rows) + "\n")
    path = tmp_path / "c.h5"
    assert main(["import", str(path), "--run", "m", "--dma", str(source)]) == 0
    assert "25 points, 1 temperature, modulus E" in capsys.readouterr().out
    assert main(["master", str(path), "--run", "m"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "one temperature only" in err and "raw sweeps" in err


def test_a_dma_sweep_named_where_a_rig_run_is_needed_is_said_to_be_one(tmp_path, capsys):
    # it read "no such run (runs: none)", as if the name were wrong
    path = tmp_path / "c.h5"
    data = dma_sweep([0.0, 20.0], np.geomspace(1.0, 100.0, 8), seed=1)
    import_dma(path, "sweep", ModulusTable(**data, source="generated"))
    for command in (["identify", str(path), "--run", "sweep"],
                    ["diagnose", str(path), "--run", "sweep"]):
        assert main(command) == 2
        err = capsys.readouterr().err
        assert err.count("\n") == 1 and "'sweep' is a DMA sweep" in err, err
    assert main(["identify", str(path), "--run", "other"]) == 2
    assert "DMA" not in capsys.readouterr().err


def test_summary_of_a_file_without_rig_runs_says_so_and_where_its_dma_sweeps_go(
        tmp_path, capsys, sweep_csv):
    # it printed two empty tables and exited 0
    empty = tmp_path / "empty.h5"
    CampaignFile.create(empty, sequence_text="", durable=False).close()
    assert main(["summary", str(empty)]) == 2
    assert capsys.readouterr().err == (f"viscorig: {empty}: holds no sweep run with points: "
                                       "Tables 1 and 2 are of the rig's runs\n")
    path = tmp_path / "c.h5"
    assert main(["import", str(path), "--run", "eca", "--dma", str(sweep_csv)]) == 0
    capsys.readouterr()
    assert main(["summary", str(path)]) == 2
    assert "(its DMA sweeps, eca, make a master curve: see viscorig master)" in \
        capsys.readouterr().err


#: RepTate's oscillatory-shear layout: a parameter line, names and units separated by tabs
#: (``Temp`` twice, a blank unit), numbers aligned with spaces and fewer than the names.
RHEOMETER_OSC = (
    "T=40;Mw=100;chem=PI;label=sample 1;\n"
    "Freq\tG'\tG\"\tTemp\tStrain\tTemp\ttan_delta\n"
    "rad/s\tPa\tPa\t°C\t%\t°C\t \n"
    "       31.623       2.9E5          77000         40.02        0.99\n"
    "           10       2.2E5          92000         40.00        0.99\n"
    "       3.1623       1.5E5       1.09E5         39.99        1.00\n")


def test_rheometer_sweep_with_a_parameter_line_and_aligned_numbers(tmp_path):
    path = tmp_path / "sample_40C.osc"
    path.write_bytes(RHEOMETER_OSC.encode("cp1252"))
    table = read_dma_csv(path)
    assert table.modulus == "G" and table.points == 3
    assert table.frequency_hz[1] == pytest.approx(10 / (2 * np.pi))
    assert table.storage_pa.tolist() == [2.9e5, 2.2e5, 1.5e5]
    assert table.loss_pa[2] == pytest.approx(1.09e5)
    assert table.temperature_c.tolist() == [40.02, 40.0, 39.99]


def test_the_parameter_lines_temperature_stands_for_a_missing_column(tmp_path):
    path = tmp_path / "sample.osc"
    path.write_text("T=-12.5;Mw=100;\nw\tG'\tG''\nrad/s\tkPa\tkPa\n1 10 2\n10 20 5\n")
    table = read_dma_csv(path)
    assert table.temperature_c.tolist() == [-12.5, -12.5]
    assert table.storage_pa.tolist() == [10e3, 20e3]
    path.write_text("T=warm;Mw=100;\nw\tG'\tG''\nrad/s\tkPa\tkPa\n1 10 2\n10 20 5\n")
    with pytest.raises(InputError, match=r"sample.osc: parameter line: T='warm' is not a number"):
        read_dma_csv(path)
    path.write_text("Mw=100;\nw\tG'\tG''\nrad/s\tkPa\tkPa\n1 10 2\n10 20 5\n")
    with pytest.raises(InputError, match=r"row 2: no temperature column"):
        read_dma_csv(path)


def test_real_rheometer_sweeps_of_a_polymer_melt():
    """RepTate's polyisoprene sweeps (tests/data/dma/README.md): 14 names over 11 numbers a row,
    ``G"`` for the loss modulus, frequencies in rad/s, Windows-1252 degree signs."""
    name = "PI223k-14_40C_FS_PP10.osc"
    table = read_dma_csv(real_data("dma", name) / name)
    assert table.modulus == "G" and table.points == 20
    assert table.frequency_hz[0] == pytest.approx(31.623 / (2 * np.pi))
    assert table.storage_pa[0] == pytest.approx(2.9008e5) and table.loss_pa[0] == 77694
    assert table.temperature_c[0] == pytest.approx(40.021)


def test_sweeps_saved_one_file_per_temperature_make_one_material_by_their_specimen(
        tmp_path, capsys):
    from viscorig.report.materials import candidate_groups

    data = dma_sweep(np.array([0.0, 20.0, 40.0]), np.logspace(-1, 2, 6))
    path = tmp_path / "lab.h5"
    for k, temperature in enumerate((0, 20, 40)):
        rows = ["f,E_stor,E_loss,T", "Hz,MPa,MPa,C"]
        rows += [f"{f:.17g},{e1 / 1e6:.17g},{e2 / 1e6:.17g},{t:.17g}" for f, e1, e2, t, s in zip(
            data["frequency_hz"], data["storage_pa"], data["loss_pa"], data["temperature_c"],
            data["set_index"], strict=True) if s == k]
        sweep = tmp_path / f"sweep_{temperature}.csv"
        sweep.write_text("\n".join(rows) + "\n")
        options = [] if temperature == 40 else ["--specimen", "eca-1"]
        assert main(["import", str(path), "--run", f"t{temperature}", "--dma", str(sweep),
                     *options]) == 0
    capsys.readouterr()
    campaign = CampaignFile.open(path)
    assert sorted(candidate_groups(campaign)) == [("t0", "t20"), ("t40",)]
    assert main(["show", str(path)]) == 0
    shown = capsys.readouterr().out
    assert re.search(r"t0 .* G?E?\s+eca-1 ", shown) and re.search(r"t40 .* -\s+sweep_40", shown)
    assert main(["master", str(path), "--run", "t40"]) == 2
    assert "--run A --run B" in capsys.readouterr().err


def _trios_step_export(data, temperatures, frequencies, separator: str) -> str:
    """TRIOS's export of every step to text (tabs) or CSV (commas), as public exports show it:
    name/value header lines, then per step ``[step]``, its name, a names row, a units row and
    the points, a blank line after each. A peak hold and an amplitude sweep at one frequency
    stand between the frequency sweeps, as a procedure's other steps do."""
    j = separator.join
    lines = [j(["Filename", "generated"]), j(["Instrument name", "RSA-G2"]), "[File Parameters]",
             j(["Trios version", "5.1.0.46403"]), "[step]", "Peak hold - 1",
             j(["Stress", "Shear rate", "Temperature"]), j(["Pa", "1/s", "°C"]),
             j(["0.0", "1e-3", "20.0"]), j(["0.1", "2e-3", "20.0"]), ""]
    size = len(frequencies)
    for k, temperature in enumerate(temperatures):
        lines += ["[step]", f"Frequency sweep - {k + 2}",
                  j(["Storage modulus", "Loss modulus", "Tan(delta)", "Angular frequency",
                     "Temperature", "Step time"]), j(["MPa", "MPa", "", "rad/s", "°C", "s"])]
        for i in range(k * size, (k + 1) * size):
            f, e1, e2 = data["frequency_hz"][i], data["storage_pa"][i], data["loss_pa"][i]
            lines.append(j([f"{e1 / 1e6:.17g}", f"{e2 / 1e6:.17g}", f"{e2 / e1:.17g}",
                            f"{2 * np.pi * f:.17g}", f"{temperature:.2f}", f"{i:.1f}"]))
        lines.append("")
        if k == 1:
            lines += ["[step]", "Amplitude sweep - 9", j(["Storage modulus", "Loss modulus",
                      "Frequency", "Temperature"]), j(["Pa", "Pa", "Hz", "°C"]),
                      j(["13.9", "10.2", "1.0", "20.0"]), j(["14.5", "7.6", "1.0", "20.0"]), ""]
    return "\n".join(lines)


@pytest.mark.parametrize(("separator", "suffix"), [("\t", ".txt"), (",", ".csv")])
def test_trios_export_of_every_step_reads_its_frequency_sweeps(tmp_path, separator, suffix):
    temperatures, frequencies = np.array([-10.0, 10.0, 30.0]), np.logspace(-1, 1, 5)
    data = dma_sweep(temperatures, frequencies, seed=9)
    path = tmp_path / f"export{suffix}"
    path.write_text(_trios_step_export(data, temperatures, frequencies, separator),
                    encoding="utf-8")
    table = read_dma_csv(path)
    assert table.points == 15 and table.sets.size == 3
    assert np.allclose(table.frequency_hz, data["frequency_hz"])
    assert np.allclose(table.storage_pa, data["storage_pa"])
    assert table.set_temperatures_c().tolist() == [-10.0, 10.0, 30.0]


def test_trios_export_without_a_frequency_sweep_names_its_steps(tmp_path):
    path = tmp_path / "export.txt"
    text = _trios_step_export(dma_sweep([20.0], [1.0, 2.0]), [20.0], [1.0, 2.0], "\t")
    path.write_text(text.replace("Angular frequency", "Oscillation strain"), encoding="utf-8")
    with pytest.raises(InputError, match=r"no frequency sweep among the export's steps "
                       r"\(Peak hold - 1, Frequency sweep - 2\)"):
        read_dma_csv(path)
    path.write_text("Filename\tx\n[step]\nPeak hold - 1\n\n1\t2\n", encoding="utf-8")
    with pytest.raises(InputError, match=r"row 4: a \[step\] without its name, column names"):
        read_dma_csv(path)


REAL_TRIOS_STEPS = ("sample_Trios_1.txt", "sample_Trios_2.csv")


@pytest.mark.parametrize("name", REAL_TRIOS_STEPS)
def test_real_trios_exports_of_flow_and_amplitude_steps_are_told_apart(name):
    """Two real TRIOS exports of every step (tests/data/dma/README.md): flow curves, peak holds,
    time and amplitude sweeps of a Carbopol gel, no frequency sweep among them."""
    path = real_data("dma", name) / name
    with pytest.raises(InputError, match=r"no frequency sweep among the export's steps "
                       r"\(Peak hold - 1, .*(Time|Peak) .* and \d+ more\)"):
        read_dma_csv(path)


def test_a_specimen_attribute_that_is_not_text_leaves_its_run_alone(tmp_path, capsys, caplog):
    import h5py

    from viscorig.report.materials import candidate_groups

    path = tmp_path / "lab.h5"
    data = dma_sweep(np.array([0.0, 20.0]), np.logspace(-1, 2, 6))
    for name in ("a", "b", "c"):
        import_dma(path, name, ModulusTable(**data, source=f"{name}.csv"), specimen="eca-1")
    with h5py.File(path, "a") as h5:
        h5["dma/b"].attrs["specimen"] = np.array([1, 2])
    assert sorted(candidate_groups(CampaignFile.open(path))) == [("a", "c"), ("b",)]
    assert "/dma/b.specimen: attribute not text" in caplog.text


def test_real_trios_exports_of_a_time_temperature_sweep_and_of_a_mixed_procedure():
    """3M's hermes-rheo files (tests/data/dma/README.md): a LIMS export of 20 isothermal
    frequency sweeps (ARES-G2), and a DHR export of every step whose amplitude sweep and flow
    ramp are left out, its one frequency sweep read."""
    ares = "test_frequency_sweep_tts_ARES.txt"
    mixed = "multi_technique.txt"
    folder = real_data("dma", ares, mixed)
    table = read_dma_csv(folder / ares)
    assert table.points == 340 and table.sets.size == 20
    table = read_dma_csv(folder / mixed)
    assert table.points == 29 and table.sets.size == 1
    assert table.frequency_hz.max() == pytest.approx(100.0, rel=1e-6)  # 628.3 rad/s
    assert table.temperature_c.mean() == pytest.approx(25.0, abs=0.05)


def test_a_table_larger_than_a_master_curve_is_fitted_on_is_refused(tmp_path, capsys):
    """100,000 rows (a hostile or mistaken file): the master curve would run for an hour."""
    rows = "".join(f"{1 + i % 1000},10,1,{20 + i // 1000}\n" for i in range(MAX_MASTER_POINTS + 1))
    path = tmp_path / "big.csv"
    path.write_text("f,E_stor,E_loss,T\nHz,MPa,MPa,C\n" + rows)
    assert main(["import", str(tmp_path / "c.h5"), "--run", "big", "--dma", str(path)]) == 2
    assert (f"big.csv: {MAX_MASTER_POINTS + 1} points; a master curve is fitted on at most "
            f"{MAX_MASTER_POINTS}") in capsys.readouterr().err
    assert not (tmp_path / "c.h5").exists()


def test_a_trios_step_in_other_units_than_the_first_is_refused(tmp_path):
    """Each [step] has its own units row, and only the first's was read: a later sweep in
    Pa where the first is in MPa was stored a million times too stiff."""
    temperatures, frequencies = np.array([-10.0, 10.0, 30.0]), np.logspace(-1, 1, 5)
    text = _trios_step_export(dma_sweep(temperatures, frequencies, seed=9), temperatures,
                              frequencies, "\t")
    lines = text.splitlines()
    third = [i for i, line in enumerate(lines) if line.startswith("Frequency sweep")][2]
    lines[third + 2] = lines[third + 2].replace("MPa", "Pa")
    path = tmp_path / "export.txt"
    path.write_text("\n".join(lines), encoding="utf-8")
    with pytest.raises(InputError, match=rf"export.txt: row {third + 3}: column 'Storage "
                       r"modulus' in 'Pa', where the first frequency sweep gives 'MPa'"):
        read_dma_csv(path)
