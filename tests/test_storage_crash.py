"""A writer killed with SIGKILL at random instants leaves whole segments only.

Each kill starts a fresh writer process that creates a campaign, starts a run and appends
segments of known content as fast as it can, on a disk made slow (each ``fsync`` takes 8 ms
more). Half the kills are aimed at the instants while a commit's new file is on disk but not
yet renamed, half fall anywhere; after each, the test checks that the file is absent (killed
before the first commit) or opens with a whole number of segments, in order, none partial,
none twice.
"""

from __future__ import annotations

import random
import signal
import subprocess
import sys
import textwrap
import time
from pathlib import Path

import numpy as np
import pytest

from viscorig.storage import CampaignFile
from viscorig.storage.atomic import staging_path

KILLS = 24

WRITER = textwrap.dedent(
    """
    import os
    import sys
    import time
    import numpy as np
    from viscorig.storage import CampaignFile, RunSettings, Segment

    path = sys.argv[1]
    real_fsync = os.fsync

    def slow_fsync(descriptor):
        print("fsync", flush=True)
        time.sleep(0.008)
        real_fsync(descriptor)

    os.fsync = slow_fsync
    print("ready", flush=True)
    campaign = CampaignFile.create(path, sequence_text="name = 'kill'", durable=True)
    campaign.start_run("kill", RunSettings(specimen="none", level_m_per_s2=1.0, direction="up",
                       settle_cycles=1, integrate_cycles=1, resolution_hz=0.25))
    for index in range(10_000):
        size = 1 + (index * 7) % 23
        frequency = 1.0 + 50.0 * index + np.arange(size)
        campaign.append_segment("kill", Segment(
            frequency, frequency, frequency * (1 + 1j), frequency * 1j, frequency, frequency,
            frequency, np.full(size, index % 16)))
    """
)


def segment_size(index: int) -> int:
    return 1 + (index * 7) % 23


def check_whole_segments(path: Path) -> int:
    """Number of whole segments in the file; fails on a partial or repeated one."""
    with CampaignFile.open(path) as campaign:
        if campaign.run_names == []:
            return 0
        run = campaign.run("kill")
    expected = [1.0 + 50.0 * index + np.arange(segment_size(index)) for index in range(10_000)]
    count, total = 0, 0
    while total < run.points:
        total += segment_size(count)
        count += 1
    assert total == run.points, f"{run.points} points is not a whole number of segments"
    frequency = np.concatenate(expected[:count]) if count else np.empty(0)
    np.testing.assert_array_equal(run.frequency_hz, frequency)
    np.testing.assert_array_equal(run.accelerance_table, frequency * (1 + 1j))
    np.testing.assert_array_equal(run.force_amplitude, frequency)
    sizes = [segment_size(index) for index in range(count)]
    np.testing.assert_array_equal(run.flags, np.repeat(np.arange(count) % 16, sizes))
    assert run.metadata.status == "running"
    return count


@pytest.mark.slow
def test_sigkill_at_random_instants_keeps_whole_segments(tmp_path: Path) -> None:
    rng = random.Random(20240501)
    committed, during_commit, before_first = [], 0, 0
    for kill in range(KILLS):
        path = tmp_path / f"kill-{kill}.h5"
        writer = subprocess.Popen(
            [sys.executable, "-c", WRITER, str(path)], stdout=subprocess.PIPE, text=True
        )
        assert writer.stdout is not None and writer.stdout.readline().strip() == "ready"
        if kill % 2:
            # Half the kills land inside a commit: a commit syncs its new file, renames it over
            # the old one and syncs the folder, so odd-numbered fsyncs are of a new file still
            # waiting for its rename; kill during one of them.
            for _ in range(rng.randrange(1, 32, 2)):
                assert writer.stdout.readline().strip() == "fsync"
            time.sleep(rng.uniform(0.0, 0.006))
        else:
            time.sleep(rng.uniform(0.0, 0.5))  # the other half anywhere
        writer.send_signal(signal.SIGKILL)
        writer.wait(timeout=10)
        assert writer.returncode == -signal.SIGKILL, "the writer ended before it was killed"
        during_commit += staging_path(path).exists()
        if not path.exists():
            before_first += 1
            continue
        committed.append(check_whole_segments(path))
    print(
        f"\n{KILLS} kills: {before_first} before the file existed, {during_commit} inside a "
        f"commit; whole segments found per file: min {min(committed)}, max {max(committed)}"
    )
    assert during_commit >= KILLS // 4, "too few kills landed inside a commit to mean much"
    assert max(committed) > 5
