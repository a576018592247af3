"""Pauses of an adaptive plan and the source's ramp down, on the embedded simulated rig.

For each of ``--pauses`` pauses at a random moment of an adaptive run of the bare table (paced):
the points measured after the request, the time to ``paused``, and the source's output level
sampled every millisecond from the request until it is 0 (level before the fall, fall time, the
slope against the station's slew rate scaled by the pace). Prints one line per pause and a
summary. Bounded: each pause waits at most 10 s.

    nice python studies/pause_ramp.py --pauses 8 --pace 60
"""

from __future__ import annotations

import argparse
import random
import sys
import tempfile
import threading
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))

from benchrig import ADAPTIVE_TABLE_SEQUENCE

from viscorig.bench import BenchService

SEQUENCE = ADAPTIVE_TABLE_SEQUENCE
SLEW_V_PER_S = 1.0  # the embedded station's default


def _wait(condition, timeout_s: float = 10.0):
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        value = condition()
        if value:
            return value
        time.sleep(0.002)
    raise RuntimeError("timed out")


def one_pause(folder: Path, pace: float, delay_s: float) -> dict:
    (folder / "seq.toml").write_text(SEQUENCE)
    service = BenchService(root=folder, sim_pace=pace)
    service.add("seq.toml", "out.h5")
    service.start()
    try:
        prompt = _wait(lambda: service.state()["prompt"])
        analyser = service.opened.server.analyser
        revealed: list[float] = []
        analyser.on_point = lambda count: revealed.append(time.monotonic())
        service.answer(prompt["id"], "done")
        _wait(lambda: len(revealed) >= 5, 30.0)  # probe and gain points, then the first look
        time.sleep(delay_s)
        samples: list[tuple[float, float]] = []
        stop = threading.Event()

        def sample() -> None:
            end = time.monotonic() + 10.0
            while not stop.is_set() and time.monotonic() < end:
                samples.append((time.monotonic(), analyser.source_output_vpk))
                time.sleep(0.001)

        sampler = threading.Thread(target=sample, daemon=True)
        sampler.start()
        asked = time.monotonic()
        service.pause()
        _wait(lambda: service.state()["state"] == "paused")
        paused = time.monotonic()
        _wait(lambda: samples and samples[-1][1] == 0.0 and samples[-1][0] > paused)
        stop.set()
        sampler.join()
        after = sum(t > asked for t in revealed)
        times = np.array([t for t, _ in samples])
        levels = np.array([v for _, v in samples])
        zero = int(np.argmax(levels == 0.0))
        start = zero
        while start > 0 and levels[start - 1] > levels[start]:
            start -= 1
        level = float(levels[start])
        falling = (levels[start:zero] > 0.05 * level) & (levels[start:zero] < 0.95 * level)
        slope = (np.polyfit(times[start:zero][falling], levels[start:zero][falling], 1)[0]
                 if falling.sum() >= 3 else float("nan"))
        service.abort()
        _wait(lambda: not service.busy, 30.0)
        return {"after": after, "to_paused_s": paused - asked, "level_vpk": level,
                "fall_s": float(times[zero] - times[start]), "slope": -slope / pace}
    finally:
        service.shutdown()


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--pauses", type=int, default=8)
    parser.add_argument("--pace", type=float, default=60.0)
    parser.add_argument("--seed", type=int, default=1)
    args = parser.parse_args()
    rng = random.Random(args.seed)
    rows = []
    for number in range(args.pauses):
        with tempfile.TemporaryDirectory() as folder:
            row = one_pause(Path(folder), args.pace, rng.uniform(0.0, 0.5))
        rows.append(row)
        print(f"pause {number + 1}: {row['after']} point(s) after the request, paused in "
              f"{row['to_paused_s']:.3f} s; source {row['level_vpk']:.3f} Vpk down in "
              f"{row['fall_s'] * args.pace:.3f} s of rig time (expected "
              f"{row['level_vpk'] / SLEW_V_PER_S:.3f}), slope {row['slope']:.3f} V/s", flush=True)
    after = [r["after"] for r in rows]
    slopes = np.array([r["slope"] for r in rows])
    print(f"points after the request: {min(after)}..{max(after)}; to paused "
          f"{min(r['to_paused_s'] for r in rows):.3f}..{max(r['to_paused_s'] for r in rows):.3f}"
          f" s; ramp slope {np.nanmin(slopes):.3f}..{np.nanmax(slopes):.3f} V/s "
          f"(station {SLEW_V_PER_S:g} V/s)")


if __name__ == "__main__":
    main()
