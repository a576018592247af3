"""Out of space, over ``ulimit -f``, read-only: one line naming the file and the cause, exit 2,
every committed segment kept, and ``resume`` continues once there is room again.

Before, a commit that hit ``ulimit -f`` made HDF5 report errors from object destructors and the
process die with SIGSEGV while closing the file. ``ulimit -f`` works without privileges; the
full disk (a 400 KiB tmpfs) and the read-only mount need a private mount namespace
(``unshare -rm``) and are skipped where the system does not allow one.
"""

from __future__ import annotations

import errno
import hashlib
import resource
import shutil
import subprocess
import sys
import textwrap
from pathlib import Path

import numpy as np
import pytest
import reliability_tally as tally
from reliability_campaign import check_prefix
from smallcampaign import GRIDS, SEQUENCE

from viscorig.storage import CampaignFile, room

VISCORIG = [sys.executable, "-m", "viscorig"]


def limited(kib: int):
    def preexec() -> None:
        resource.setrlimit(resource.RLIMIT_FSIZE, (kib * 1024, resource.RLIM_INFINITY))
    return preexec


def viscorig(*arguments: object, limit_kib: int | None = None) -> tuple[int, str, str]:
    done = subprocess.run([*VISCORIG, *map(str, arguments)], capture_output=True, text=True,
                          timeout=120, preexec_fn=limited(limit_kib) if limit_kib else None)
    return done.returncode, done.stdout, done.stderr


def one_line(err: str) -> str:
    lines = [line for line in err.splitlines() if line.strip()]
    assert len(lines) == 1 and "Traceback" not in err, err
    return lines[0]


def sha256(path: Path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


@pytest.mark.slow
def test_run_under_ulimit_f_stops_cleanly_and_resume_continues_once_allowed(tmp_path: Path):
    sequence, path = tmp_path / "s.toml", tmp_path / "c.h5"
    sequence.write_text(SEQUENCE)
    status, _, err = viscorig("run", sequence, "--yes", "--out", path, limit_kib=100)
    line = one_line(err)
    assert status == 2, err
    assert line.startswith(f"viscorig: {path}: file size limit reached: 100 KiB (ulimit -f)")
    assert "keeps every committed segment" in line
    kept = {name: check_prefix(path, name, grid) for name, grid in GRIDS.items()}
    assert kept["table"] == GRIDS["table"].size  # what was committed is whole
    assert not list(tmp_path.glob(".c.h5.*"))  # no staging or lock file left

    before = sha256(path)
    status, _, err = viscorig("resume", path, "--yes", limit_kib=100)
    assert status == 2 and "file size limit reached" in one_line(err)
    assert sha256(path) == before  # refused without touching the file

    status, _, err = viscorig("resume", path, "--yes")
    assert status == 0, err
    for name, grid in GRIDS.items():
        assert check_prefix(path, name, grid) == grid.size
    tally.add("storage faults")


CRASHER = textwrap.dedent(
    """
    import resource, signal, sys
    import numpy as np
    from viscorig.errors import InputError
    from viscorig.storage import CampaignFile, RunSettings, Segment, room
    signal.signal(signal.SIGXFSZ, signal.SIG_DFL)  # as an embedding program might leave it
    room.check_room = lambda path, needed: None    # so that the write itself hits the limit
    path = sys.argv[1]
    campaign = CampaignFile.create(path, sequence_text="")
    campaign.start_run("r", RunSettings(specimen="none", level_m_per_s2=1.0, direction="up",
                       settle_cycles=1, integrate_cycles=1, resolution_hz=0.25))
    resource.setrlimit(resource.RLIMIT_FSIZE, (60 * 1024, resource.RLIM_INFINITY))
    for index in range(1000):
        f = 1.0 + 1000.0 * index + np.arange(50)
        try:
            campaign.append_segment("r", Segment(f, f, f * 1j, f * 1j, f, f, f, np.zeros(50)))
        except InputError as error:
            print(index, error)
            break
    """
)


def test_a_write_past_the_file_size_limit_is_an_error_not_a_crash(tmp_path: Path) -> None:
    path = tmp_path / "c.h5"
    done = subprocess.run([sys.executable, "-c", CRASHER, str(path)], capture_output=True,
                          text=True, timeout=60)
    assert done.returncode == 0, (done.returncode, done.stderr[-2000:])
    assert "file size limit reached: 60 KiB (ulimit -f)" in done.stdout, done.stdout
    assert done.stderr == ""
    segments = int(done.stdout.split()[0])
    with CampaignFile.open(path) as campaign:
        assert campaign.run("r").points == 50 * segments
    assert not list(tmp_path.glob(".c.h5.*"))
    tally.add("storage faults")


@pytest.mark.parametrize(("number", "words"), [
    (errno.ENOSPC, "disk full: "), (errno.EDQUOT, "disk quota exceeded on /"),
    (errno.EFBIG, "file "), (errno.EROFS, "read-only file system: /"),
    (errno.EACCES, "permission denied: cannot write in"),
    (errno.EISDIR, "a folder has this name: "), (errno.EIO, "cannot write (x)"),
])
def test_each_write_failure_is_named(tmp_path: Path, number: int, words: str) -> None:
    error = room.write_failure(OSError(number, "x"), tmp_path / "c.h5")
    assert str(error).startswith(f"{tmp_path / 'c.h5'}: {words}")


def _unshare_works() -> bool:
    if shutil.which("unshare") is None:
        return False
    probe = subprocess.run(["unshare", "-rm", "sh", "-c", "mount -t tmpfs tmpfs /mnt"],
                           capture_output=True)
    return probe.returncode == 0


namespaces = pytest.mark.skipif(not _unshare_works(),
                                reason="needs a private mount namespace (unshare -rm)")

FULL_DISK = """
set -u
mount -t tmpfs -o size=400k tmpfs "$DISK"
cd "$DISK"
head -c 250000 /dev/zero > filler
run() {{ "$@" > out.txt 2> err.txt; echo "rc=$?"; cat err.txt; }}
run {viscorig} run "$SEQUENCE" --yes --out c.h5
sha256sum c.h5 > before.txt
run {viscorig} resume c.h5 --yes
sha256sum -c --quiet before.txt && echo "unchanged"
{python} -c "$CHECK" before
rm filler
run {viscorig} resume c.h5 --yes
{python} -c "$CHECK" after
"""
CHECK = """
import sys
from viscorig.storage import CampaignFile
with CampaignFile.open("c.h5") as c:
    print(sys.argv[1], *(f"{n}={c.run(n).points}/{len(set(c.run(n).frequency_hz))}"
                         for n in c.run_names))
"""


@pytest.mark.slow
@namespaces
def test_full_disk_stops_cleanly_and_resume_continues_once_space_returns(tmp_path: Path):
    sequence, disk = tmp_path / "s.toml", tmp_path / "disk"
    sequence.write_text(SEQUENCE)
    disk.mkdir()
    script = FULL_DISK.format(viscorig=" ".join(VISCORIG), python=sys.executable)
    done = subprocess.run(["unshare", "-rm", "sh", "-c", script], capture_output=True,
                          text=True, timeout=300,
                          env={"DISK": str(disk), "SEQUENCE": str(sequence), "CHECK": CHECK,
                               "PATH": "/usr/bin:/bin"})
    report = done.stdout.splitlines()
    assert report[0] == "rc=2", done.stdout + done.stderr
    assert report[1].startswith("viscorig: c.h5: disk full: ") and " free on " in report[1]
    assert report[2] == "rc=2" and "disk full" in report[3]
    assert report[4] == "unchanged"
    before = dict(item.split("=") for item in report[5].split()[1:])
    assert before["table"] == f"{GRIDS['table'].size}/{GRIDS['table'].size}"
    assert report[6] == "rc=0", done.stdout
    after = dict(item.split("=") for item in report[-1].split()[1:])
    assert after == {name: f"{grid.size}/{grid.size}" for name, grid in GRIDS.items()}
    tally.add("storage faults")


READ_ONLY = """
set -u
mount -t tmpfs tmpfs "$DISK"
cp "$CAMPAIGN" "$DISK/c.h5"
mount -o remount,ro "$DISK"
for command in "show" "summary" "diagnose --run soft-0" "identify --run soft-0 --no-store" \
        "export --run soft-0 --format csv --out $OUT/x.csv" \
        "identify --run soft-0" "resume --yes"; do
    {viscorig} $command "$DISK/c.h5" < /dev/null > /dev/null 2> "$OUT/err.txt"
    echo "$? $(tail -n 1 "$OUT/err.txt")"
done
"""


@pytest.mark.slow
@namespaces
def test_readers_work_on_a_read_only_mount_and_writers_say_why_they_cannot(tmp_path: Path):
    from campaigndata import paper_campaign

    campaign = paper_campaign(tmp_path / "c.h5", runs=("table", "soft-0"), step_hz=1.0)
    disk, out = tmp_path / "disk", tmp_path / "out"
    disk.mkdir()
    out.mkdir()
    script = READ_ONLY.format(viscorig=" ".join(VISCORIG))
    done = subprocess.run(["unshare", "-rm", "sh", "-c", script], capture_output=True,
                          text=True, timeout=300,
                          env={"DISK": str(disk), "OUT": str(out), "CAMPAIGN": str(campaign),
                               "PATH": "/usr/bin:/bin"})
    statuses = [line.split(" ", 1) for line in done.stdout.splitlines()]
    assert [int(status) for status, *_ in statuses] == [0, 0, 0, 0, 0, 2, 2], done.stdout
    for _, message in statuses[5:]:
        assert f"read-only file system: {disk}; nothing was written" in message, message
    tally.add("storage faults")
    exported = np.genfromtxt(out / "x.csv", delimiter=",", names=True)
    assert exported["frequency_hz"].size == 101
