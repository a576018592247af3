"""``viscorig show``: runs with status, points, band, level, specimen, preload, flags; fits."""

from __future__ import annotations

import json
import re
import subprocess
import sys
from pathlib import Path

import h5py
import numpy as np
import pytest
from test_storage import SETTINGS, make_segment

from viscorig.cli import main
from viscorig.storage import CampaignFile, RunSettings
from viscorig.storage.atomic import staging_path


@pytest.fixture()
def campaign_path(tmp_path: Path) -> Path:
    path = tmp_path / "paper.h5"
    campaign = CampaignFile.create(path, sequence_text="name = 'paper'", sequence_file="paper.toml",
                               rig={"table_mass_kg": 3.4}, durable=False)
    table = RunSettings(specimen="none", level_m_per_s2=1.4, direction="up", settle_cycles=200,
                        integrate_cycles=100, resolution_hz=0.125, simulated=True)
    campaign.start_run("table", table)
    campaign.append_segment("table", make_segment(12.0, 20))  # flags 0..15, 0..3
    campaign.finish_run("table")
    campaign.add_fit("table", model="table", band_hz=(12.0, 16.75), rms_error=0.0021,
                     noise_floor=0.0019, parameters={"M_s": (3.41, 0.02, "kg")})
    campaign.start_run("soft-10", SETTINGS)
    campaign.append_segment("soft-10", make_segment(20.0, 6))
    return path


def test_lists_runs_flags_and_fits(campaign_path: Path, capsys: pytest.CaptureFixture) -> None:
    assert main(["show", str(campaign_path)]) == 0
    out = capsys.readouterr().out
    assert "sequence: paper.toml; station: none (simulated rig)" in out
    assert "rig: table_mass_kg 3.4" in out
    lines = {line.split()[0]: line for line in out.splitlines() if line}
    table = lines["table"].split()
    assert table[:4] == ["table", "complete", "20", "12.00-16.75"]
    assert table[4:6] == ["1.4", "none"]
    # flags 0..15 then 0..3: 18 flagged; bits 1 and 2 on 8 + 2 points, bits 4 and 8 on 8 + 0
    assert lines["table"].endswith(
        "18 (level not reached 10, input overload 10, source at limit 8, "
        "force above shaker limit 8)"
    )
    soft = lines["soft-10"]
    assert soft.split()[:4] == ["soft-10", "running", "6", "20.00-21.25"]
    assert "soft 25 Shore A (25 Shore A)" in soft and "0.104" in soft
    assert "table/0001  table  12-16.75 Hz  rms_error 0.0021  noise_floor 0.0019" in out
    assert "M_s = 3.410 ± 0.020 kg" in out


def test_crashed_writer_leaves_a_file_show_reads(campaign_path: Path,
                                                 capsys: pytest.CaptureFixture) -> None:
    campaign = CampaignFile.open(campaign_path, mode="a", durable=False)
    campaign.start_run("hard-0", SETTINGS)  # started, no segment yet
    staging_path(campaign_path).write_bytes(b"half a commit")  # a writer killed mid-commit
    assert main(["show", str(campaign_path)]) == 0
    out = capsys.readouterr().out
    assert [line.split()[:3] for line in out.splitlines() if line.startswith("hard-0")] == [
        ["hard-0", "running", "0"]
    ]


def test_a_damaged_run_is_reported_and_the_others_still_listed(
    campaign_path: Path, capsys: pytest.CaptureFixture
) -> None:
    with h5py.File(campaign_path, "r+") as h5:
        del h5["runs/soft-10/flags"]
    assert main(["show", str(campaign_path)]) == 2
    captured = capsys.readouterr()
    assert any(line.split()[:2] == ["table", "complete"] for line in captured.out.splitlines())
    assert "soft-10  cannot be read: dataset missing" in captured.out
    assert captured.err.strip() == (
        f"viscorig: {campaign_path}: /runs/soft-10/flags: dataset missing"
    )


@pytest.mark.parametrize("value", [np.nan, -20.0, 0.0, 1e308])
def test_a_frequency_no_analyser_measures_is_named_with_its_point(
    campaign_path: Path, capsys: pytest.CaptureFixture, value: float
) -> None:
    with h5py.File(campaign_path, "r+") as h5:
        h5["runs/soft-10/frequency_hz"][3] = value
    assert main(["show", str(campaign_path)]) == 2
    captured = capsys.readouterr()
    assert any(line.split()[:2] == ["table", "complete"] for line in captured.out.splitlines())
    assert captured.err.strip() == (
        f"viscorig: {campaign_path}: /runs/soft-10/frequency_hz: 1 of 6 frequencies are not "
        f"numbers from 1e-06 to 1e+06 Hz (the first, point 4, is {value:g})")


@pytest.mark.parametrize(("damage", "message"), [
    (lambda fit: fit.attrs.__setitem__("band_hz", [np.nan, np.nan]),
     "0001.band_hz: band_hz [nan, nan] is not a band from 0 to 1e+06 Hz, low end first"),
    (lambda fit: fit.attrs.__setitem__("band_hz", [16.75, 12.0]),
     "0001.band_hz: band_hz [16.75, 12] is not a band from 0 to 1e+06 Hz, low end first"),
    (lambda fit: (fit.__delitem__("M_s"), fit.create_dataset("M_s", data="3.41")),
     "0001/M_s: a parameter's value is a real number, not text"),
    (lambda fit: fit["M_s"].write_direct(np.array(np.inf)),
     "0001/M_s: value inf is not a finite number"),
])
def test_a_damaged_fit_is_named_and_its_run_still_listed(
    campaign_path: Path, capsys: pytest.CaptureFixture, damage, message: str
) -> None:
    with h5py.File(campaign_path, "r+") as h5:
        damage(h5["runs/table/fits/0001"])
    assert main(["show", str(campaign_path)]) == 2
    captured = capsys.readouterr()
    assert any(line.split()[:3] == ["table", "complete", "20"]
               for line in captured.out.splitlines())
    assert "table: fits cannot be read:" in captured.out
    assert captured.err.strip() == f"viscorig: {campaign_path}: /runs/table/fits/{message}"


def test_not_a_campaign_is_one_line_and_status_2(tmp_path: Path) -> None:
    path = tmp_path / "notes.h5"
    path.write_bytes(np.arange(100, dtype=np.uint8).tobytes())
    result = subprocess.run([sys.executable, "-m", "viscorig", "show", str(path)],
                            capture_output=True, text=True, check=False)
    assert result.returncode == 2
    assert result.stderr.count("\n") == 1 and "Traceback" not in result.stderr
    assert "notes.h5: not a readable HDF5 file" in result.stderr


def test_json_holds_what_the_listing_shows(campaign_path: Path, capsys) -> None:
    import json

    assert main(["show", str(campaign_path), "--json"]) == 0
    document = json.loads(capsys.readouterr().out)
    assert document["format_version"] == 1 and document["sequence_file"] == "paper.toml"
    assert document["simulated_rig"] is True and document["rig"] == {"table_mass_kg": 3.4}
    runs = {run["name"]: run for run in document["runs"]}
    table = runs["table"]
    assert (table["status"], table["points"], table["band_hz"]) == ("complete", 20, [12.0, 16.75])
    assert table["hardness_shore_a"] is None  # NaN in the file: unknown, valid JSON
    assert table["flagged_points"] == 18
    assert table["flags"] == {"level not reached": 10, "input overload": 10,
                              "source at limit": 8, "force above shaker limit": 8,
                              "outside the soak band": 0}
    (fit,) = table["fits"]
    assert fit["id"] == "0001" and fit["model"] == "table"
    assert fit["parameters"]["M_s"] == {"value": 3.41, "stderr": 0.02, "unit": "kg"}
    soft = runs["soft-10"]
    assert (soft["status"], soft["points"], soft["preload_strain"]) == ("running", 6, 0.104)
    assert soft["fits"] == []


def test_json_of_a_damaged_run_names_it_and_exits_2(campaign_path: Path, capsys) -> None:
    import json

    with h5py.File(campaign_path, "r+") as h5:
        del h5["runs/soft-10/flags"]
    assert main(["show", str(campaign_path), "--json"]) == 2
    captured = capsys.readouterr()
    runs = {run["name"]: run for run in json.loads(captured.out)["runs"]}
    assert runs["soft-10"] == {"name": "soft-10", "error": "dataset missing"}
    assert runs["table"]["status"] == "complete"
    assert captured.err.count("\n") == 1


def test_the_journal_is_listed_in_order_without_control_characters(
        campaign_path: Path, capsys) -> None:
    # the bench's notes and the run engine's events were stored and shown nowhere after the run
    with CampaignFile.open(campaign_path, "a", durable=False) as campaign:
        campaign.add_journal_entry("note", "bolt re-tightened\nafter the table run")
        campaign.add_journal_entry("pause", "paused at the bench", run="soft-10")
        campaign.add_journal_entry("note", "soft\x1b[2J <b>rubber</b>")
    assert main(["show", str(campaign_path)]) == 0
    out = capsys.readouterr().out
    journal = out.split("\njournal\n")[1].splitlines()
    assert [re.split(r"\s{2,}", line)[1:3] for line in journal] == [
        ["-", "note"], ["soft-10", "pause"], ["-", "note"]]
    assert journal[0].endswith("bolt re-tightened / after the table run")
    assert journal[2].endswith("soft[2J <b>rubber</b>") and "\x1b" not in out
    assert main(["show", str(campaign_path), "--json"]) == 0
    entries = json.loads(capsys.readouterr().out)["journal"]
    assert entries[1] == {"time_utc": entries[1]["time_utc"], "kind": "pause", "run": "soft-10",
                          "text": "paused at the bench"}
    assert entries[0]["text"] == "bolt re-tightened\nafter the table run"


def test_a_damaged_journal_is_named_and_the_runs_still_listed(campaign_path: Path,
                                                              capsys) -> None:
    with CampaignFile.open(campaign_path, "a", durable=False) as campaign:
        campaign.add_journal_entry("note", "first")
    with h5py.File(campaign_path, "r+") as h5:
        h5["journal/text"].resize((2,))
    assert main(["show", str(campaign_path)]) == 2
    captured = capsys.readouterr()
    assert "soft-10" in captured.out and "\njournal\n" not in captured.out
    assert "/journal: columns of different lengths" in captured.err


@pytest.mark.parametrize(("damage", "said"), [
    (lambda h5: h5.__delitem__("journal/kind"), "/journal/kind: missing or not a 1-D string"),
    (lambda h5: (h5.__delitem__("journal"), h5.create_dataset("journal", data=[1, 2])),
     "/journal: not a group"),
    (lambda h5: (h5.__delitem__("journal/text"),
                 h5.create_dataset("journal/text", data=["first"], dtype=h5py.string_dtype())),
     "/journal/text: a column of fixed length"),
])
def test_a_note_is_refused_by_a_damaged_journal_and_writes_nothing(
        campaign_path: Path, capsys, damage, said: str) -> None:
    """A note added to a journal missing a column made that column anew, one entry long beside
    the others' (a journal no reader takes); one of the wrong kind ended in h5py's traceback."""
    with CampaignFile.open(campaign_path, "a", durable=False) as campaign:
        campaign.add_journal_entry("note", "first")
    with h5py.File(campaign_path, "r+") as h5:
        damage(h5)
    before = campaign_path.read_bytes()
    assert main(["note", str(campaign_path), "bolt re-tightened"]) == 2
    assert said in capsys.readouterr().err
    assert campaign_path.read_bytes() == before
