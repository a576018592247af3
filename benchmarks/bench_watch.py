"""Does watching slow the measurement? The paper campaign with and without a live view.

Runs ``viscorig run sequences/paper.toml --yes`` on the embedded simulated rig (as fast as the
computer allows, so any competition for the processor shows) three ways, in turn, several times:

- alone (the baseline);
- with ``viscorig watch`` serving the file to a client that asks for its state ten times a
  second (ten times more often than the page does);
- with ``run --live`` (its own live view) and the same client.

Prints the median wall time of each, its ratio to the baseline, the time to read a snapshot of
the whole campaign, and the size of what the page receives. Usage::

    python benchmarks/bench_watch.py [--repeats N]
"""

from __future__ import annotations

import argparse
import json
import re
import statistics
import subprocess
import sys
import tempfile
import threading
import time
import urllib.request
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
PAPER = ROOT / "sequences" / "paper.toml"


def hammer(url: str, stop: threading.Event, counts: list[int]) -> None:
    """Ask for the state ten times a second until ``stop``."""
    while not stop.is_set():
        try:
            with urllib.request.urlopen(url + "state.json", timeout=5) as answer:
                answer.read()
            counts[0] += 1
        except OSError:
            pass
        stop.wait(0.1)


def run_campaign(folder: Path, mode: str) -> tuple[float, int]:
    out = folder / f"{mode}-{time.monotonic_ns()}.h5"
    command = [sys.executable, "-m", "viscorig", "run", str(PAPER), "--yes", "--out", str(out)]
    watcher = None
    if mode == "live":
        command += ["--live", "--no-browser"]
    stop, counts, client = threading.Event(), [0], None
    start = time.perf_counter()
    if mode == "watch":
        watcher = subprocess.Popen([sys.executable, "-m", "viscorig", "watch", str(out),
                                    "--port", "0", "--no-browser"], stdout=subprocess.PIPE,
                                   text=True)
        url = re.search(r"http://\S+/", watcher.stdout.readline()).group(0)
        client = threading.Thread(target=hammer, args=(url, stop, counts), daemon=True)
        client.start()
        start = time.perf_counter()
    process = subprocess.Popen(command, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                               text=True)
    if mode == "live":
        line = ""
        while "live view:" not in line:
            line = process.stdout.readline()
        url = re.search(r"http://\S+/", line).group(0)
        client = threading.Thread(target=hammer, args=(url, stop, counts), daemon=True)
        client.start()
    _, err = process.communicate()
    elapsed = time.perf_counter() - start
    stop.set()
    if watcher is not None:
        watcher.terminate()
        watcher.wait()
    if process.returncode != 0:
        raise SystemExit(f"{mode}: run failed: {err}")
    if mode == "live":  # its live view serves the end for a moment before it stops
        from viscorig.cli.watch import FINAL_STATE_S

        elapsed -= FINAL_STATE_S
    return elapsed, counts[0]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=3)
    repeats = parser.parse_args().repeats
    times: dict[str, list[float]] = {"alone": [], "watch": [], "live": []}
    requests: dict[str, int] = {"watch": 0, "live": 0}
    with tempfile.TemporaryDirectory() as folder:
        for _ in range(repeats):
            for mode in times:
                elapsed, count = run_campaign(Path(folder), mode)
                times[mode].append(elapsed)
                requests[mode] = requests.get(mode, 0) + count
        from viscorig.watch import read_snapshot

        path = next(Path(folder).glob("alone-*.h5"))
        reads = []
        for _ in range(5):
            start = time.perf_counter()
            snapshot = read_snapshot(path)
            reads.append(time.perf_counter() - start)
        size = len(json.dumps(snapshot, allow_nan=False, separators=(",", ":")))
    base = statistics.median(times["alone"])
    print(f"paper campaign, {repeats} runs each (median wall time):")
    for mode, values in times.items():
        median = statistics.median(values)
        extra = f", {requests.get(mode, 0)} state requests served" if mode != "alone" else ""
        print(f"  {mode:6s} {median:6.2f} s   ratio {median / base:5.2f}{extra}")
    print(f"snapshot of the whole campaign: read in {1000 * statistics.median(reads):.0f} ms, "
          f"{size / 1024:.0f} KiB of JSON")


if __name__ == "__main__":
    main()
