"""Cost of a crash-safe commit per segment, and what an in-place writer risks when killed.

Baseline: appending a segment in place (h5py opens the file r+, resizes, writes, closes).
Measured: viscorig's atomic commit (change an in-memory copy, write it, os.replace), with and
without fsync.
The campaign is the paper's size: 7 runs, ~2500 points, 10 datasets per run.

Then both writers are killed with SIGKILL at random instants; the in-place writer's files are
checked for whether they still open with whole segments only.

Run: python benchmarks/bench_storage.py [--kills N]
"""

from __future__ import annotations

import argparse
import random
import signal
import subprocess
import sys
import tempfile
import textwrap
import time
from pathlib import Path

import h5py
import numpy as np

from viscorig.storage import CampaignFile, RunSettings, Segment

SETTINGS = RunSettings(specimen="soft", level_m_per_s2=1.4, direction="up", settle_cycles=100,
                       integrate_cycles=100, resolution_hz=0.25)
SEGMENT_POINTS = 16


def segment(start: int, count: int = SEGMENT_POINTS) -> Segment:
    values = np.arange(start, start + count, dtype=float)
    return Segment(values, values, values * 1j, values * 1j, values, values, values,
                   np.zeros(count), variance_table=values, variance_support=values)


def in_place_append(path: Path, run: str, part: Segment) -> None:
    with h5py.File(path, "r+") as h5:
        group = h5["runs"][run]
        for name, (values, _) in part.columns().items():
            dataset = group[name]
            old = dataset.shape[0]
            dataset.resize((old + len(values),))
            dataset[old:] = values


def time_commits(folder: Path, durable: bool | None, runs: int = 7, points: int = 400) -> float:
    """Mean seconds per segment appended over a whole campaign (None: in place)."""
    path = folder / f"bench-{durable}.h5"
    campaign = CampaignFile.create(path, sequence_text="", durable=bool(durable))
    elapsed, count = 0.0, 0
    for index in range(runs):
        name = f"run-{index}"
        campaign.start_run(name, SETTINGS)
        campaign.append_segment(name, segment(0))  # creates the optional datasets
        for start in range(SEGMENT_POINTS, points, SEGMENT_POINTS):
            begin = time.perf_counter()
            if durable is None:
                in_place_append(path, name, segment(start))
            else:
                campaign.append_segment(name, segment(start))
            elapsed += time.perf_counter() - begin
            count += 1
    return elapsed / count


IN_PLACE_WRITER = textwrap.dedent(
    """
    import sys
    import h5py, numpy as np
    path = sys.argv[1]
    with h5py.File(path, "w") as h5:
        group = h5.create_group("runs/kill")
        for name in range(10):
            group.create_dataset(str(name), shape=(0,), maxshape=(None,), chunks=(256,), dtype="f8")
    print("ready", flush=True)
    for index in range(100000):
        with h5py.File(path, "r+") as h5:
            for dataset in h5["runs/kill"].values():
                old = dataset.shape[0]
                dataset.resize((old + 16,))
                dataset[old:] = index
    """
)


def kill_in_place(folder: Path, kills: int) -> tuple[int, int]:
    """(files that no longer open, files with a partial segment) after SIGKILLs."""
    broken = partial = 0
    rng = random.Random(1)
    for kill in range(kills):
        path = folder / f"inplace-{kill}.h5"
        writer = subprocess.Popen([sys.executable, "-c", IN_PLACE_WRITER, str(path)],
                                  stdout=subprocess.PIPE, text=True)
        assert writer.stdout is not None
        writer.stdout.readline()
        time.sleep(rng.uniform(0.05, 0.4))
        writer.send_signal(signal.SIGKILL)
        writer.wait()
        try:
            with h5py.File(path, "r") as h5:
                lengths = {dataset.shape[0] for dataset in h5["runs/kill"].values()}
                partial += len(lengths) > 1 or any(length % 16 for length in lengths)
        except Exception:  # any failure to read counts as broken
            broken += 1
    return broken, partial


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--kills", type=int, default=20)
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as name:
        folder = Path(name)
        baseline = time_commits(folder, None)
        fast = time_commits(folder, False)
        safe = time_commits(folder, True)
        size = (folder / "bench-True.h5").stat().st_size
        print(f"campaign of 7 x 400 points, 10 datasets, {size / 1e6:.2f} MB at the end")
        print(f"in-place append (baseline): {baseline * 1e3:6.2f} ms per segment")
        print(f"atomic commit, no fsync:    {fast * 1e3:6.2f} ms per segment "
              f"({fast / baseline:.1f} x baseline)")
        print(f"atomic commit, fsync:       {safe * 1e3:6.2f} ms per segment "
              f"({safe / baseline:.1f} x baseline)")
        print(f"share of a 60 s segment spent committing: {safe / 60 * 100:.3f} %")
        if args.kills:
            broken, partial = kill_in_place(folder, args.kills)
            print(f"in-place writer killed {args.kills} times: {broken} files no longer open, "
                  f"{partial} hold a partial segment (atomic commits: see "
                  "tests/test_storage_crash.py, none)")


if __name__ == "__main__":
    main()
