"""The temperature loop's cost: a simulated campaign with soaks against the same campaign
without them, on the embedded rig paced at PACE simulated seconds per wall-clock second.

The soaks' own test time, paced, is what they must take; anything the loop adds (Modbus reads
of the controller and the specimen indicator every 10 s of test time, the chamber model, the
messages) should be absorbed in it. Prints both wall times, the soaks' paced time, and the
ratio (extra wall time) / (soaks' paced time): 1.00 means the loop adds nothing but the soaks.

    python benchmarks/bench_temperature.py [PACE]
"""

from __future__ import annotations

import subprocess
import sys
import tempfile
import time
from pathlib import Path

PACE = float(sys.argv[1]) if len(sys.argv) > 1 else 200.0
HEAD = """\
name = "bench"
[defaults]
band_hz = [20.0, 120.0]
resolution_hz = 5.0
settle_cycles = 20
integrate_cycles = 20
level = "0.5 m/s^2"
specimen = "medium"
hardness_shore_a = 33.0

[[steps]]
type = "prompt"
message = "Mount."
simulated_rig = "medium-chamber"
"""
SOAKS = """
[[steps]]
type = "temperature"
set_point_c = {t}
soak_band_k = 0.5
soak_minutes = 10
"""
SWEEP = """
[[steps]]
type = "sweep"
run = "m{i}"
"""


def wall(text: str, folder: Path, name: str) -> tuple[float, str]:
    sequence = folder / f"{name}.toml"
    sequence.write_text(text)
    started = time.perf_counter()
    done = subprocess.run([sys.executable, "-m", "viscorig", "run", str(sequence), "--yes",
                           "--out", str(folder / f"{name}.h5"), "--sim-pace", f"{PACE:g}"],
                          capture_output=True, text=True, timeout=1800, cwd=folder)
    if done.returncode != 0:
        raise SystemExit(done.stderr)
    return time.perf_counter() - started, done.stdout


def main() -> None:
    temperatures = (15.0, 35.0)
    with_soaks = HEAD + "".join(SOAKS.format(t=t) + SWEEP.format(i=i)
                                for i, t in enumerate(temperatures))
    without = HEAD + "".join(SWEEP.format(i=i) for i, _ in enumerate(temperatures))
    with tempfile.TemporaryDirectory() as folder:
        plain_s, _ = wall(without, Path(folder), "without")
        soaked_s, out = wall(with_soaks, Path(folder), "with")
    minutes = [float(line.split(" after ")[1].split(" min")[0])
               for line in out.splitlines() if line.startswith("soaked: specimen")]
    soak_s = 60.0 * sum(minutes)
    paced = soak_s / PACE
    extra = soaked_s - plain_s
    print(f"pace {PACE:g} simulated s per s; {len(minutes)} soaks, {soak_s:.0f} s of test time")
    print(f"wall time without soaks {plain_s:.2f} s, with soaks {soaked_s:.2f} s")
    print(f"soaks paced {paced:.2f} s; extra wall time {extra:.2f} s; ratio {extra / paced:.3f}"
          " (1.00: the loop adds nothing but the soaks)")


if __name__ == "__main__":
    main()
