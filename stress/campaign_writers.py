"""Stress study of campaign files: writers killed at random instants while a second writer keeps
trying, and the memory of every reading command on hostile files.

Not part of the test run (it takes a few minutes). Run from the repository::

    python stress/campaign_writers.py [--kills 25] [--seed 1] [--folder DIR]

Part 1. Two writer loops start ``viscorig run`` (when the campaign file does not exist yet) or
``viscorig resume`` on the same campaign file, again and again, as two technicians might; a
killer sends SIGKILL at random instants to whichever process holds the file's writer lock (read
from its lock record). After every kill the file must open, every run must be a gap-free,
duplicate-free prefix of its frequency grid, and every point committed before the kill must
still be there bit for bit. When a campaign completes, a new one starts. At the end each
campaign is completed by ``resume`` and compared with two uninterrupted campaigns: the same
runs, the same frequency grids (no point missing, none twice), accelerances within the scatter
of the two uninterrupted campaigns.

Part 2. Every reading command (show, summary, diagnose, identify --no-store, export, report)
runs on every hostile file of ``tests/hostilefiles.py`` in a child process; its peak resident
memory is measured with ``wait4``.

It prints the figures quoted in the README's "Reliability" section.
"""

from __future__ import annotations

import argparse
import json
import random
import shutil
import signal
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO / "tests"))

import hostilefiles  # noqa: E402
from campaigndata import paper_campaign  # noqa: E402
from smallcampaign import GRIDS, SEQUENCE, peak_rss_mb  # noqa: E402

from viscorig.storage import Campaign, writelock  # noqa: E402

PACE = "150"  # simulated seconds per second: a campaign takes a few seconds of wall time


def viscorig(*arguments: object) -> subprocess.Popen:
    return subprocess.Popen([sys.executable, "-m", "viscorig", *map(str, arguments)],
                            stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)


def snapshot(path: Path) -> dict[str, dict[str, np.ndarray]]:
    if not path.exists():
        return {}
    with Campaign.open(path) as campaign:
        return {run.name: {"frequency_hz": run.frequency_hz, "accelerance_table":
                           run.accelerance_table, "flags": run.flags}
                for run in campaign.runs()}


def points_lost(before: dict, after: dict) -> int:
    lost = 0
    for name, columns in before.items():
        count = columns["frequency_hz"].size
        kept = after.get(name)
        if kept is None or kept["frequency_hz"].size < count:
            lost += count if kept is None else count - kept["frequency_hz"].size
            continue
        same = np.ones(count, dtype=bool)
        for key, values in columns.items():
            later = kept[key][:count]
            same &= (later == values) | (np.isnan(later) & np.isnan(values)) \
                if values.dtype.kind in "fc" else later == values
        lost += int(count - same.sum())
    return lost


def duplicated_and_off_grid(path: Path) -> tuple[int, int]:
    """(points stored twice, points not on the run's grid or not in order)."""
    duplicated = off = 0
    for name, columns in snapshot(path).items():
        frequency = columns["frequency_hz"]
        duplicated += frequency.size - np.unique(frequency).size
        grid = GRIDS[name][: frequency.size]
        off += int(np.count_nonzero(np.abs(frequency - grid) > 0.008)) if frequency.size <= \
            GRIDS[name].size else frequency.size
    return duplicated, off


def complete(path: Path, sequence: Path) -> None:
    command = ("resume", path, "--yes") if path.exists() else (
        "run", sequence, "--yes", "--out", path)
    process = viscorig(*command)
    _, err = process.communicate(timeout=300)
    if process.returncode != 0:
        raise SystemExit(f"{' '.join(map(str, command))} failed: {err}")


class Study:
    """The shared state of the writer loops and the killer."""

    def __init__(self, folder: Path, sequence: Path, kills: int, seed: int) -> None:
        self.folder, self.sequence, self.target = folder, sequence, kills
        self.rng = random.Random(seed)
        self.lock = threading.Lock()
        self.campaigns = [folder / "campaign-0.h5"]
        self.processes: dict[int, subprocess.Popen] = {}
        self.kills = self.lost = self.duplicated = self.off_grid = 0
        self.outcomes = {"refused: in use": 0, "refused: file exists": 0, "completed": 0,
                         "killed": 0, "other": 0}
        self.stop = threading.Event()

    @property
    def path(self) -> Path:
        return self.campaigns[-1]

    def writer_loop(self) -> None:
        while not self.stop.is_set():
            path = self.path
            process = viscorig("resume", path, "--yes", "--sim-pace", PACE) if path.exists() \
                else viscorig("run", self.sequence, "--yes", "--out", path, "--sim-pace", PACE)
            with self.lock:
                self.processes[process.pid] = process
            _, err = process.communicate()
            with self.lock:
                del self.processes[process.pid]
                if process.returncode == -signal.SIGKILL:
                    self.outcomes["killed"] += 1
                elif process.returncode == 2 and "in use by another writer" in err:
                    self.outcomes["refused: in use"] += 1
                elif process.returncode == 2 and "never overwritten" in err:
                    self.outcomes["refused: file exists"] += 1
                elif process.returncode == 0:
                    self.outcomes["completed"] += 1
                    if self._complete(path) and path == self.path:
                        self.campaigns.append(self.folder / f"campaign-{len(self.campaigns)}.h5")
                else:
                    self.outcomes["other"] += 1
                    print(f"unexpected exit {process.returncode}: {err.strip()}", flush=True)

    @staticmethod
    def _complete(path: Path) -> bool:
        with Campaign.open(path) as campaign:
            return set(campaign.run_names) == set(GRIDS) and all(
                run.metadata.status == "complete" for run in campaign.runs())

    def killer_loop(self) -> None:
        while self.kills < self.target:
            time.sleep(self.rng.uniform(0.5, 4.0))
            path = self.path
            holder = writelock.read_holder(path)
            with self.lock:
                process = self.processes.get(holder.pid) if holder else None
                if process is None or process.poll() is not None:
                    continue
                before = snapshot(path)
                process.send_signal(signal.SIGKILL)
                process.wait()
                self.kills += 1
            after = snapshot(path)
            self.lost += points_lost(before, after)
            duplicated, off = duplicated_and_off_grid(path)
            self.duplicated += duplicated
            self.off_grid += off
            print(f"kill {self.kills}: pid {holder.pid} ({holder.command.split()[1]}); "
                  f"{sum(c['frequency_hz'].size for c in after.values())} points kept, "
                  f"lost {points_lost(before, after)}, duplicated {duplicated}", flush=True)
        self.stop.set()


def relative_rms(a: np.ndarray, b: np.ndarray) -> float:
    return float(np.sqrt(np.nanmean(np.abs(a / b - 1.0) ** 2)))


def writers(folder: Path, kills: int, seed: int) -> dict[str, object]:
    sequence = folder / "stress.toml"
    sequence.write_text(SEQUENCE)
    references = [folder / "reference-1.h5", folder / "reference-2.h5"]
    for reference in references:
        complete(reference, sequence)
    study = Study(folder, sequence, kills, seed)
    started = time.monotonic()
    loops = [threading.Thread(target=study.writer_loop, daemon=True) for _ in range(2)]
    for loop in loops:
        loop.start()
    study.killer_loop()
    for loop in loops:
        loop.join(timeout=300)
    for path in study.campaigns:
        complete(path, sequence)
    with Campaign.open(references[0]) as one, Campaign.open(references[1]) as two:
        noise = {name: relative_rms(two.run(name).accelerance_table,
                                    one.run(name).accelerance_table) for name in GRIDS}
        base = {name: one.run(name) for name in GRIDS}
    missing = duplicated = 0
    worst = 0.0
    for path in study.campaigns:
        with Campaign.open(path) as campaign:
            assert campaign.run_names == list(GRIDS), (path, campaign.run_names)
            assert any(fit.model == "table" for fit in campaign.fits("table"))
            for name, grid in GRIDS.items():
                run = campaign.run(name)
                assert run.metadata.status == "complete"
                found = np.round(run.frequency_hz / 0.25).astype(int)
                wanted = np.round(grid / 0.25).astype(int)
                missing += len(set(wanted) - set(found))
                duplicated += found.size - np.unique(found).size
                assert np.array_equal(found, wanted), (path, name)
                scatter = relative_rms(run.accelerance_table, base[name].accelerance_table)
                worst = max(worst, scatter / (noise[name] + 1e-12))
                assert scatter <= 3.0 * noise[name] + 1e-4, (path, name, scatter, noise)
    return {
        "kills": study.kills, "campaigns": len(study.campaigns),
        "writer processes": dict(study.outcomes),
        "points lost after a kill": study.lost,
        "points duplicated after a kill": study.duplicated,
        "points off the grid after a kill": study.off_grid,
        "points missing at the end": missing, "points duplicated at the end": duplicated,
        "worst scatter against an uninterrupted campaign / scatter of two uninterrupted":
            round(worst, 2),
        "seconds": round(time.monotonic() - started, 1),
    }


READERS = {
    "show": [], "summary": [], "diagnose": ["--run", "soft-0"],
    "identify": ["--run", "soft-0", "--no-store"],
    "export": ["--run", "soft-0", "--format", "csv", "--out", "{folder}/out.csv"],
    "report": ["--out", "{folder}/report"],
}


def hostile_memory(folder: Path) -> dict[str, object]:
    good = paper_campaign(folder / "good.h5", runs=("table", "soft-0"), step_hz=1.0)
    worst: tuple[float, str] = (0.0, "")
    baseline = 0.0
    refused = 0
    for command, options in READERS.items():
        arguments = [part.format(folder=folder) for part in options]
        status, peak, err = peak_rss_mb([command, str(good), *arguments])
        assert status == 0, err
        baseline = max(baseline, peak)
    for name, maker in hostilefiles.REFUSED.items():
        case = folder / "case"
        shutil.rmtree(case, ignore_errors=True)
        case.mkdir()
        path = case / "campaign.h5"
        shutil.copyfile(good, path)
        words = maker(path)
        for command, options in READERS.items():
            arguments = [part.format(folder=case) for part in options]
            status, peak, err = peak_rss_mb([command, str(path), *arguments])
            lines = [line for line in err.splitlines() if line.strip()]
            assert status == 2 and len(lines) == 1 and words in lines[0], (name, command, err)
            refused += 1
            worst = max(worst, (peak, f"{command} on '{name}'"))
    return {"hostile files": len(hostilefiles.REFUSED), "commands refused in one line": refused,
            "peak memory on a hostile file (MB)": round(worst[0]), "worst case": worst[1],
            "peak memory of the same commands on a good file (MB)": round(baseline)}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--kills", type=int, default=25)
    parser.add_argument("--seed", type=int, default=1)
    parser.add_argument("--folder", type=Path, default=None)
    args = parser.parse_args()
    folder = args.folder or Path(tempfile.mkdtemp(prefix="viscorig-stress-"))
    folder.mkdir(parents=True, exist_ok=True)
    figures = {"writers": writers(folder / "writers", args.kills, args.seed)
               if (folder / "writers").mkdir(exist_ok=True) is None else {}}
    (folder / "memory").mkdir(exist_ok=True)
    figures["memory"] = hostile_memory(folder / "memory")
    print(json.dumps(figures, indent=1))


if __name__ == "__main__":
    main()
