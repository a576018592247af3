"""Files other tools open as they are, and imports that are whole or nothing.

- The exported CSV opens with ``pandas.read_csv(path)`` and Python's default CSV dialect (what
  a spreadsheet reads) with no options; its metadata sits in a CSVW sidecar; it is written
  with the user's umask, as the UFF is.
- A campaign run opens in xarray (h5netcdf) with ``frequency_hz`` as its coordinate, through
  HDF5 dimension scales; files written before scales existed still read, and gain them when
  next written.
- A truncated UFF, a CSV with a 10 MB line or a partly missing column is refused in one line,
  and nothing is imported.
"""

from __future__ import annotations

import csv
import json
import os
import resource
import subprocess
import sys
from pathlib import Path

import h5py
import numpy as np
import pandas
import pytest
import reliability_tally as tally
import xarray
from campaigndata import paper_campaign
from reliability_campaign import cli, one_clear_line

from viscorig.errors import InputError
from viscorig.exchange import read_csv, read_uff, write_uff
from viscorig.exchange.csvfile import COLUMNS
from viscorig.storage import CampaignFile, RunSettings, Segment


@pytest.fixture(scope="module")
def campaign_file(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return paper_campaign(tmp_path_factory.mktemp("interop") / "c.h5",
                          runs=("table", "soft-0"), step_hz=1.0)


def export(campaign_file: Path, run: str, out: Path, *options: str) -> None:
    fmt = "csv" if out.suffix == ".csv" else "uff"
    status, _, err = cli(["export", campaign_file, "--run", run, "--format", fmt, "--out", out,
                          *options])
    assert status == 0, err


@pytest.mark.parametrize("run", ["soft-0", "table"])
def test_pandas_reads_the_csv_with_no_options(campaign_file: Path, tmp_path: Path, run: str):
    out = tmp_path / f"{run}.csv"
    export(campaign_file, run, out)
    frame = pandas.read_csv(out)
    stored = CampaignFile.open(campaign_file).run(run)
    assert tuple(frame.columns) == COLUMNS
    assert all(frame[name].dtype.kind in "fi" for name in COLUMNS)
    np.testing.assert_array_equal(frame["frequency_hz"], stored.frequency_hz)
    np.testing.assert_array_equal(frame["accelerance_table_real_m_per_s2_per_n"]
                                  + 1j * frame["accelerance_table_imag_m_per_s2_per_n"],
                                  stored.accelerance_table)
    support = frame["accelerance_support_real_m_per_s2_per_n"].to_numpy()
    assert np.isnan(support).all() == (run == "table")
    np.testing.assert_array_equal(frame["flags"], stored.flags)


def test_a_spreadsheet_reads_one_header_row_then_numbers(campaign_file: Path, tmp_path: Path):
    out = tmp_path / "table.csv"
    export(campaign_file, "table", out)
    raw = out.read_bytes()
    assert raw.count(b"\r\n") == raw.count(b"\n")  # RFC 4180 line ends
    with out.open(newline="", encoding="utf-8") as handle:
        rows = list(csv.reader(handle))  # the default dialect, as a spreadsheet imports
    assert rows[0] == list(COLUMNS)
    for row in rows[1:]:
        assert len(row) == len(COLUMNS)
        for cell in row:
            assert cell == "" or np.isfinite(float(cell))


def test_the_csv_metadata_is_a_csvw_sidecar(campaign_file: Path, tmp_path: Path) -> None:
    out = tmp_path / "soft.csv"
    export(campaign_file, "soft-0", out)
    document = json.loads((tmp_path / "soft.csv-metadata.json").read_text(encoding="utf-8"))
    assert document["@context"] == "http://www.w3.org/ns/csvw"
    assert document["url"] == "soft.csv"
    assert [column["name"] for column in document["tableSchema"]["columns"]] == list(COLUMNS)
    assert "m/s^2/N" in document["tableSchema"]["columns"][2]["dc:description"]
    metadata = document["notes"][0]["metadata"]
    assert metadata["specimen"] == "soft" and metadata["status"] == "complete"
    assert document["notes"][0]["points"] == 101


@pytest.mark.parametrize("umask", [0o022, 0o077, 0o002])
def test_exports_are_written_with_the_users_umask(campaign_file: Path, tmp_path: Path,
                                                  umask: int) -> None:
    previous = os.umask(umask)
    try:
        for name in ("soft.csv", "soft.uff"):
            export(campaign_file, "soft-0", tmp_path / name)
    finally:
        os.umask(previous)
    for name in ("soft.csv", "soft.csv-metadata.json", "soft.uff"):
        assert (tmp_path / name).stat().st_mode & 0o777 == 0o666 & ~umask, name


def test_xarray_sees_frequency_as_the_coordinate(campaign_file: Path) -> None:
    stored = CampaignFile.open(campaign_file).run("soft-0")
    with xarray.open_dataset(campaign_file, group="runs/soft-0", engine="h5netcdf") as dataset:
        assert "frequency_hz" in dataset.coords
        assert dataset["accelerance_table"].dims == ("frequency_hz",)
        assert not [dim for dim in dataset.dims if str(dim).startswith("phony_dim")]
        np.testing.assert_array_equal(dataset["frequency_hz"], stored.frequency_hz)
        np.testing.assert_array_equal(dataset["accelerance_table"], stored.accelerance_table)
        assert dataset["accelerance_table"].attrs["units"] == "m/s^2/N"
        assert dataset.attrs["specimen"] == "soft"


def _plain_file_without_scales(path: Path) -> None:
    """A campaign as a version without dimension scales wrote it."""
    campaign = CampaignFile.create(path, sequence_text="", durable=False)
    campaign.start_run("r", RunSettings(specimen="none", level_m_per_s2=1.0, direction="up",
                                        settle_cycles=1, integrate_cycles=1,
                                        resolution_hz=1.0))
    campaign.close()
    with h5py.File(path, "r+") as h5:
        group = h5["runs/r"]
        for name, item in list(group.items()):
            dtype, units = item.dtype, item.attrs["units"]
            del group[name]
            group.create_dataset(name, shape=(0,), maxshape=(None,), chunks=(256,),
                                 dtype=dtype).attrs["units"] = units
        assert not h5py.h5ds.is_scale(group["frequency_hz"].id)


def test_a_file_without_scales_reads_and_gains_them_when_written(tmp_path: Path) -> None:
    path = tmp_path / "old.h5"
    _plain_file_without_scales(path)
    with CampaignFile.open(path, "a") as campaign:
        assert campaign.run("r").points == 0
        f = np.array([10.0, 11.0])
        campaign.append_segment("r", Segment(f, f, f * 1j, f * 1j, f, f, f, np.zeros(2)))
    with xarray.open_dataset(path, group="runs/r", engine="h5netcdf") as dataset:
        assert dataset["flags"].dims == ("frequency_hz",)
    with h5py.File(path, "r") as h5:
        assert h5.attrs["format_version"] == 1  # scales are attributes: the format is the same


def test_a_truncated_uff_is_refused_and_nothing_imported(campaign_file: Path, tmp_path: Path):
    good = tmp_path / "good.uff"
    write_uff(CampaignFile.open(campaign_file).run("soft-0"), good)
    data = good.read_bytes()
    cut = tmp_path / "cut.uff"
    for keep in (0.3, 0.7, 0.99):
        cut.write_bytes(data[: int(len(data) * keep)])
        with pytest.raises(InputError, match="no closing '    -1' line: the file is truncated"):
            read_uff(cut)
        tally.add("hostile files")
    # cut inside the second FRF's values, then closed again: its points are short
    cut.write_bytes(data[: int(len(data) * 0.8)] + b"\n    -1\n")
    with pytest.raises(InputError, match="declares 101 points but holds"):
        read_uff(cut)
    target = tmp_path / "new.h5"
    status, _, err = cli(["import", target, "--run", "soft-0", "--uff", cut])
    assert status == 2 and "truncated or damaged" in one_clear_line(err)
    assert not target.exists()
    tally.add("hostile files")


def _csv_header() -> str:
    return ",".join(COLUMNS) + "\r\n"


def test_a_csv_with_a_10_mb_line_is_one_clear_line(tmp_path: Path) -> None:
    path = tmp_path / "long.csv"
    path.write_text(_csv_header() + "20.0," + "1" * 10_000_000 + "\r\n21,,1,2,,,0\r\n")
    before = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    status, _, err = cli(["import", tmp_path / "c.h5", "--run", "x", "--csv", path])
    assert status == 2
    assert one_clear_line(err) == (f"viscorig: {path}:2: line longer than 4096 characters; "
                                   "a row of this table has 7 numbers")
    grown_kib = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss - before
    assert grown_kib < 5_000  # the line is not read whole
    assert not (tmp_path / "c.h5").exists()
    tally.add("hostile files")


@pytest.mark.parametrize(("rows", "words"), [
    (["20,,1,2,3,4,0", "21,,1,2,,,0"], "1 of 2 values of ẍ_v/F_v are not finite"),
    (["20,,1,2,,,0", "21,,,2,,,0"],
     "bad.csv:3: accelerance_table_real_m_per_s2_per_n is empty"),
    (["20,,1,2,,,0", ",,1,2,,,0"], "bad.csv:3: frequency_hz is empty"),
    (["20,,1,2,,,0", '"21,,1,2,,,0'], "3:"),
])
def test_an_inconsistent_csv_is_refused_whole(tmp_path: Path, rows: list[str], words: str):
    path = tmp_path / "bad.csv"
    path.write_text(_csv_header() + "\r\n".join(rows) + "\r\n")
    status, _, err = cli(["import", tmp_path / "c.h5", "--run", "x", "--csv", path,
                          "--specimen", "soft"])
    assert status == 2 and words in one_clear_line(err), err
    assert not (tmp_path / "c.h5").exists()
    tally.add("hostile files")


def test_old_csv_with_comment_lines_still_imports(campaign_file: Path, tmp_path: Path) -> None:
    out = tmp_path / "soft.csv"
    export(campaign_file, "soft-0", out)
    old = tmp_path / "old.csv"
    old.write_text("# viscorig FRF export\n# run soft-0\n" + out.read_text().replace("\r\n", "\n")
                   .replace(",,", ",nan,"))
    np.testing.assert_array_equal(read_csv(old).accelerance_table, read_csv(out).accelerance_table)


IMPORTER = """
import resource, sys
from viscorig.cli import main
resource.setrlimit(resource.RLIMIT_FSIZE, (int(sys.argv[3]), resource.RLIM_INFINITY))
sys.exit(main(["import", sys.argv[1], "--run", "copy", "--uff", sys.argv[2]]))
"""


def test_an_import_that_cannot_be_written_leaves_no_partial_run(campaign_file: Path,
                                                                  tmp_path: Path) -> None:
    uff = tmp_path / "soft.uff"
    write_uff(CampaignFile.open(campaign_file).run("soft-0"), uff)
    target = tmp_path / "c.h5"
    target.write_bytes(campaign_file.read_bytes())
    before = target.read_bytes()
    limit = len(before) + 10_000  # room for the open, not for the run's chunks
    for path in (target, tmp_path / "new.h5"):
        size = limit if path == target else 12_000
        done = subprocess.run([sys.executable, "-c", IMPORTER, str(path), str(uff), str(size)],
                              capture_output=True, text=True, timeout=60)
        assert done.returncode == 2, done.stderr
        assert "file size limit reached" in one_clear_line(done.stderr)
    assert target.read_bytes() == before
    assert not (tmp_path / "new.h5").exists()
    assert sorted(p.name for p in tmp_path.iterdir()) == ["c.h5", "soft.uff"]
