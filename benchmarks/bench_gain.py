"""Rig time of an adaptive plan through the real path, on a station file with or without the
shaker's gain.

The virtual 35670A on the Voigt rig of ``tests/planning_rig.py`` (the model exact), reached
through the driver over pyvisa-py, runs an adaptive sequence whose targets are the paper plan's
noise-weighted stderr on this rig (``benchmarks/bench_plan.py``: K_v ± 2.09e-6, C_v ± 9.77e-6
in 1643 s of dwell), on a station file that gives ``[shaker] gain_n_per_v`` (the rig's true
50 N/V; ``--station-gain yes``) or leaves it out (``no``: the run measures the gain). Run it
with ``yes`` on a checkout from before the gain was measured and ``no`` on this one to compare
the two ways of knowing the gain.

Run: ``python benchmarks/bench_gain.py --station-gain yes|no [--seeds N]``.
"""

from __future__ import annotations

import argparse
import contextlib
import io
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))

from planning_rig import VOIGT_RIG
from reliability_campaign import station_text
from rigsim.rigfile import parse_rig
from rigsim.server import SimulatedAnalyserServer

from viscorig.cli import main
from viscorig.storage import CampaignFile

PAPER_S = 1643.1
TARGETS = {"K_v": 2.09e-6, "C_v": 9.77e-6}
SEQUENCE = f"""
name = "gain"
[defaults]
band_hz = [20.0, 120.0]
level = "1.4 m/s^2"
[[steps]]
type = "sweep"
run = "voigt"
specimen = "voigt damper"
plan = "adaptive"
model = "voigt"
target_uncertainty = {{ K_v = {TARGETS['K_v']}, C_v = {TARGETS['C_v']} }}
"""


def run_once(folder: Path, seed: int, gain_given: bool) -> dict:
    with SimulatedAnalyserServer(parse_rig(VOIGT_RIG, "voigt rig"), seed=seed) as server:
        text = station_text(server.resource, preset="soft-0")
        if not gain_given:
            text = "\n".join(line for line in text.splitlines()
                             if not line.startswith("gain_n_per_v"))
        tag = f"{seed}-{'given' if gain_given else 'measured'}"
        (folder / f"{tag}.toml").write_text(text)
        (folder / "sequence.toml").write_text(SEQUENCE)
        out = folder / f"{tag}.h5"
        with contextlib.redirect_stdout(io.StringIO()):
            status = main(["run", str(folder / "sequence.toml"), "--station",
                           str(folder / f"{tag}.toml"), "--out", str(out), "--yes"])
    attributes = CampaignFile.open(out).run_attributes("voigt")
    return {"status": status, "test_time_s": float(attributes["test_time_s"]),
            "reason": attributes["plan_reason"], "gain": attributes.get("shaker_gain_n_per_v"),
            "gain_stderr": attributes.get("shaker_gain_stderr_n_per_v"),
            "stderr": attributes["plan_relative_stderr"]}


def main_(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, default=2)
    parser.add_argument("--station-gain", choices=("yes", "no"), required=True)
    args = parser.parse_args(argv)
    given = args.station_gain == "yes"
    started = time.perf_counter()
    with tempfile.TemporaryDirectory() as folder:
        for seed in range(args.seeds):
            r = run_once(Path(folder), 100 + seed, given)
            gain = ("" if r["gain"] is None else
                    f"; gain stored {r['gain']:.4g} ± {r['gain_stderr']:.2g} N/V")
            print(f"seed {100 + seed} station gain {args.station_gain}: "
                  f"{r['test_time_s']:7.1f} s rig time = {r['test_time_s'] / PAPER_S:.3f} "
                  f"of the paper plan's {PAPER_S:g} s ({r['reason']}; {r['stderr']}){gain}")
    print(f"wall time {time.perf_counter() - started:.0f} s")


if __name__ == "__main__":
    main_()
