"""The paper campaign on the embedded simulated rig: wall time against real dwell time.

Runs ``viscorig run sequences/paper.toml --yes`` twice: as a user does (a subprocess, so
interpreter start-up and imports count), then in process with the driver's connection counted,
to give messages per segment and the time spent where. Prints the wall time, the campaign's
settle-plus-integration time (what the real rig would take), their ratio, and the target
(under 15 s).
"""

from __future__ import annotations

import subprocess
import sys
import tempfile
import time
from collections import Counter
from pathlib import Path

from agilent35670a import connection

from viscorig.cli import main
from viscorig.sequences import load_sequence
from viscorig.storage import CampaignFile

ROOT = Path(__file__).resolve().parents[1]
PAPER = ROOT / "sequences" / "paper.toml"
TARGET_S = 15.0


def counted(counts: Counter) -> None:
    """Count every message the driver sends (writes, queries, block queries)."""
    for name in ("write", "query", "query_block"):
        original = getattr(connection.Connection, name)

        def wrapper(self, command, _original=original, _name=name):
            counts[_name] += 1
            counts[command.split(" ")[0].split(";")[0]] += 1
            return _original(self, command)

        setattr(connection.Connection, name, wrapper)


def main_benchmark() -> None:
    sequence = load_sequence(PAPER)
    dwell_s = sequence.duration_s()
    segments = sum(len(step.segments()) for step in sequence.sweeps)
    points = sum(step.points for step in sequence.sweeps)
    with tempfile.TemporaryDirectory() as folder:
        started = time.perf_counter()
        result = subprocess.run(
            [sys.executable, "-m", "viscorig", "run", str(PAPER), "--yes", "--out", "a.h5"],
            cwd=folder, capture_output=True, text=True, check=False,
        )
        subprocess_s = time.perf_counter() - started
        if result.returncode != 0:
            raise SystemExit(result.stderr)

        counts: Counter = Counter()
        counted(counts)
        out = Path(folder) / "b.h5"
        started = time.perf_counter()
        with open(Path(folder) / "log.txt", "w") as log:
            stdout, sys.stdout = sys.stdout, log
            try:
                status = main(["run", str(PAPER), "--yes", "--out", str(out)])
            finally:
                sys.stdout = stdout
        in_process_s = time.perf_counter() - started
        if status != 0:
            raise SystemExit(f"in-process run failed with status {status}")
        stored = sum(run.points for run in CampaignFile.open(out).runs())
        size_kb = out.stat().st_size / 1024

    messages = counts["write"] + counts["query"] + counts["query_block"]
    print(f"paper campaign: {len(sequence.sweeps)} runs, {points} points, {segments} segments; "
          f"real dwell {dwell_s:.0f} s ({dwell_s / 3600:.2f} h)")
    print(f"viscorig run (subprocess):   {subprocess_s:6.2f} s   "
          f"dwell / wall = {dwell_s / subprocess_s:,.0f}x   target < {TARGET_S:g} s: "
          f"{'met' if subprocess_s < TARGET_S else 'MISSED'}")
    print(f"viscorig run (in process):   {in_process_s:6.2f} s   "
          f"dwell / wall = {dwell_s / in_process_s:,.0f}x")
    print(f"stored {stored} points, file {size_kb:.0f} KiB")
    print(f"driver messages: {messages} ({messages / segments:.1f} per segment): "
          f"{counts['write']} writes, {counts['query']} queries, "
          f"{counts['query_block']} block reads")
    per_segment = {key: value / segments for key, value in counts.most_common()
                   if key not in ("write", "query", "query_block")}
    print("per segment: " + ", ".join(f"{key} {value:.1f}"
                                      for key, value in list(per_segment.items())[:10]))


if __name__ == "__main__":
    main_benchmark()
