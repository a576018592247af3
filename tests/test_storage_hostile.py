"""Untrusted campaign files: links are not followed, declared sizes are checked before anything
is read, memory stays bounded, and texts reach the terminal without control characters.

The hostile files are made by ``tests/hostilefiles.py`` with plain h5py from a valid campaign.
Before these checks, a run declaring 3·10^8 points made ``show`` allocate 4.9 GB, one declaring
10^12 points a traceback, and an external link was followed into another file.
"""

from __future__ import annotations

import hashlib
import shutil
from pathlib import Path

import hostilefiles
import pytest
import reliability_tally as tally
from campaigndata import paper_campaign
from reliability_campaign import cli, one_clear_line
from smallcampaign import peak_rss_mb

from viscorig.errors import InputError
from viscorig.storage import CampaignFile

#: Commands that read a campaign, with their arguments after the file.
READERS = {
    "show": [],
    "summary": [],
    "diagnose": ["--run", "soft-0"],
    "identify": ["--run", "soft-0", "--no-store"],
    "export": ["--run", "soft-0", "--format", "csv", "--out", "{out}"],
    "report": ["--no-diagnosis", "--out", "{out}"],
}
#: The bound asserted on a reading command's peak resident memory, whatever the file declares.
MEMORY_BOUND_MB = 500


@pytest.fixture(scope="module")
def good(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return paper_campaign(tmp_path_factory.mktemp("hostile") / "good.h5",
                          runs=("table", "soft-0"), step_hz=1.0)


def hostile(good: Path, folder: Path, maker) -> tuple[Path, str | None]:
    path = folder / "campaign.h5"
    shutil.copyfile(good, path)
    return path, maker(path)


def sha256(path: Path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


@pytest.mark.parametrize("name", list(hostilefiles.REFUSED))
@pytest.mark.parametrize("command", list(READERS))
def test_hostile_file_is_one_line_exit_2_and_unchanged(good: Path, tmp_path: Path, name: str,
                                                       command: str) -> None:
    path, words = hostile(good, tmp_path, hostilefiles.REFUSED[name])
    before = sha256(path) if path.stat().st_size < 10**7 else None
    arguments = [part.format(out=tmp_path / "out.csv") for part in READERS[command]]
    status, _, err = cli([command, path, *arguments])
    line = one_clear_line(err)
    assert status == 2, err
    assert words in line, line
    assert "\x1b" not in line and "\x07" not in line
    assert before is None or sha256(path) == before
    assert not (tmp_path / "out.csv").exists()
    tally.add("hostile files")


@pytest.mark.parametrize("name", ["external link", "soft link to a run", "1e12 points"])
def test_writers_refuse_hostile_files_too(good: Path, tmp_path: Path, name: str) -> None:
    path, words = hostile(good, tmp_path, hostilefiles.REFUSED[name])
    before = sha256(path)
    with pytest.raises(InputError, match=words):
        CampaignFile.open(path, "a")
    assert sha256(path) == before
    assert not list(tmp_path.glob(".campaign.h5.*"))  # no lock or staging file left


@pytest.mark.slow
@pytest.mark.parametrize("name", ["3e8 points", "1e12 points"])
def test_memory_stays_bounded_whatever_the_file_declares(good: Path, tmp_path: Path,
                                                         name: str) -> None:
    path, words = hostile(good, tmp_path, hostilefiles.REFUSED[name])
    baseline_status, baseline_mb, _ = peak_rss_mb(["show", str(good)])
    assert baseline_status == 0
    peaks = []
    for command in ("show", "diagnose"):
        status, peak_mb, err = peak_rss_mb([command, str(path), *READERS[command]])
        assert status == 2 and words in err, err
        assert peak_mb < MEMORY_BOUND_MB, f"{command}: {peak_mb:.0f} MB"
        peaks.append(peak_mb)
    print(f"\n{name}: peak resident memory {max(peaks):.0f} MB "
          f"(show of a good file: {baseline_mb:.0f} MB)")


def test_the_bound_on_points_is_the_one_a_sequence_accepts() -> None:
    from viscorig.sequences import sequence
    from viscorig.storage import layout

    assert layout.MAX_RUN_POINTS == sequence.MAX_RUN_POINTS


def test_escape_sequences_never_reach_the_terminal(good: Path, tmp_path: Path) -> None:
    path, _ = hostile(good, tmp_path, hostilefiles.escapes_in_texts)
    for command in ("show", "summary"):
        status, out, err = cli([command, path, *READERS[command]])
        assert status == 0, err
        printed = out + err
        assert "soft[2J]0;owned31m" in printed or command == "summary"
        for char in printed:
            assert char.isprintable() or char in "\n\t", (command, repr(char))
    with CampaignFile.open(path) as campaign:
        run = campaign.run("soft-0")
        fit = campaign.fits("soft-0")[0]
        assert run.metadata.specimen == "soft[2J]0;owned31m"
        assert fit.model == "voigt[2J]0;owned31m"
        assert fit.parameters["K_v"].unit == "N/m[2J]0;owned31m"
        assert campaign.setup_files["sequence_file"] == "paper[2J]0;owned31m.toml"


def test_a_refused_report_leaves_the_last_one_as_it_was(good: Path, tmp_path: Path) -> None:
    out = tmp_path / "report"
    status, _, err = cli(["report", good, "--no-diagnosis", "--out", out])
    assert status == 0, err
    before = {p.name: p.read_bytes() for p in out.iterdir()}
    assert "index.html" in before and any(name.endswith(".png") for name in before)
    for name in ("text for numbers", "compound with text"):  # refused once the runs are read
        path, words = hostile(good, tmp_path, hostilefiles.REFUSED[name])
        status, _, err = cli(["report", path, "--no-diagnosis", "--out", out])
        assert status == 2 and words in one_clear_line(err), err
        assert {p.name: p.read_bytes() for p in out.iterdir()} == before
    assert sorted(p.name for p in tmp_path.iterdir() if p.name.startswith(".")) == []


def test_a_report_that_cannot_replace_a_figure_says_so_in_one_line(good: Path,
                                                                     tmp_path: Path) -> None:
    out = tmp_path / "report"
    (out / "frf-soft-0.png").mkdir(parents=True)  # a folder where a figure goes
    status, _, err = cli(["report", good, "--no-diagnosis", "--out", out])
    assert status == 2 and "cannot write the report" in one_clear_line(err), err
    assert not (out / "index.html").exists()  # the page goes last: none beside half a report
    assert sorted(p.name for p in tmp_path.iterdir() if p.name.startswith(".")) == []
