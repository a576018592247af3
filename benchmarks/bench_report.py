"""How long ``viscorig report`` takes on the paper's campaign, against the time the simulated rig
took to make the campaign (target: the report with the full ladder in one process, ``--jobs 1``,
at most 1.0x the simulation; the report without the ladder under 20 s).

The campaign is made first with ``viscorig run sequences/paper.toml --yes`` on the simulated rig
(7 runs, 2,535 points). Then, in this process:

- baseline: ``viscorig summary`` (the table fit and the six Voigt fits of Tables 1 and 2), the
  least any report of the campaign must do;
- the report's phases with each run diagnosed once: analysis, figures (PNG, the default; and
  PNG and SVG, as ``--svg`` draws them), page;
- the whole ``viscorig report`` command: without diagnosis, with each run diagnosed once
  (``--no-ladder``), and as by default, climbing the diagnosis ladder of every run in parallel
  processes, and in one process (``--jobs 1``, the target's case).

Each command is also printed as a ratio to the campaign's simulation, measured in this process
just before (wall to wall, CPU to CPU: CPU is steadier on a shared machine).

Wall and CPU time are both printed: the machine may be shared, and CPU time is what the code
costs. BLAS runs single-threaded, as in the ``viscorig`` command (set before numpy loads).
Run: ``python benchmarks/bench_report.py``. CPU time counts the worker processes too
(``os.times``, children included).
"""

from __future__ import annotations

from viscorig.runtime import limit_blas_threads

limit_blas_threads()  # before numpy loads, as the command line does

import contextlib  # noqa: E402
import io  # noqa: E402
import os  # noqa: E402
import sys  # noqa: E402
import tempfile  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402

from viscorig.cli import main  # noqa: E402
from viscorig.fitting.noise_estimation import forget_estimates  # noqa: E402
from viscorig.identify import PAPER_BAND_HZ, summarize  # noqa: E402
from viscorig.report.analysis import analyse_campaign  # noqa: E402
from viscorig.report.figures import campaign_figures  # noqa: E402
from viscorig.report.page import build_page  # noqa: E402
from viscorig.storage import CampaignFile  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
#: The rig noise of the simulated campaign, fixed so that runs of the benchmark compare.
SEED = "2026"
TARGET_S = 20.0  # for the report without the ladder; the ladder's cost is the diagnosis's


def _cpu() -> float:
    # this process's own at the clock's resolution, finished children's from os.times
    times = os.times()
    return time.process_time() + times.children_user + times.children_system


def timed(function):
    """(result, wall seconds, CPU seconds of this process and its finished children), with no
    noise estimate kept from before (as in a new process)."""
    forget_estimates()
    wall, cpu = time.perf_counter(), _cpu()
    result = function()
    return result, time.perf_counter() - wall, _cpu() - cpu


def main_quiet(arguments: list[str]) -> int:
    with contextlib.redirect_stdout(io.StringIO()):
        return main(arguments)


def run(ladder: bool) -> None:
    folder = Path(tempfile.mkdtemp(prefix="bench-report-"))
    campaign_path = folder / "paper.h5"
    _, sim_wall, sim_cpu = timed(lambda: main_quiet(
        ["run", str(ROOT / "sequences" / "paper.toml"), "--yes", "--sim-seed", SEED,
         "--out", str(campaign_path)]))
    campaign = CampaignFile.open(campaign_path)
    points = sum(campaign.run(name).points for name in campaign.run_names)
    print(f"campaign: {len(campaign.run_names)} runs, {points} points (simulated in "
          f"{sim_wall:.1f} s wall, {sim_cpu:.1f} s CPU; load {os.getloadavg()[0]:.1f})")

    _, base_wall, base_cpu = timed(lambda: summarize(campaign, PAPER_BAND_HZ))
    print(f"baseline  summary (Tables 1, 2)     wall {base_wall:6.2f} s   cpu {base_cpu:6.2f} s")
    with np.errstate(all="ignore"):
        analysis, a_wall, a_cpu = timed(lambda: analyse_campaign(campaign, ladder=False,
                                                                 jobs=1))
    (folder / "phases").mkdir()
    figures, f_wall, f_cpu = timed(lambda: campaign_figures(analysis, folder / "phases"))
    _, v_wall, v_cpu = timed(lambda: campaign_figures(analysis, folder / "phases", svg=True))
    _, p_wall, p_cpu = timed(lambda: build_page(analysis, figures, "bench"))
    print(f"phase     analysis + diagnosis      wall {a_wall:6.2f} s   cpu {a_cpu:6.2f} s")
    print(f"phase     {len(figures)} figures, PNG           wall {f_wall:6.2f} s   "
          f"cpu {f_cpu:6.2f} s   {f_wall / sim_wall:4.2f}x the simulation")
    print(f"phase     {len(figures)} figures, PNG + SVG     wall {v_wall:6.2f} s   "
          f"cpu {v_cpu:6.2f} s   (--svg)")
    print(f"phase     page                      wall {p_wall:6.2f} s   cpu {p_cpu:6.2f} s")
    cases = [("report --no-diagnosis", ["--no-diagnosis"]), ("report --no-ladder", ["--no-ladder"]),
             ("report (ladder)", [])]
    cases.append(("report --jobs 1", ["--jobs", "1"]))
    for label, options in cases:
        out = folder / label.replace(" ", "_")
        status, wall, cpu = timed(lambda out=out, options=options: main_quiet(
            ["report", str(campaign_path), "--out", str(out), *options]))
        assert status == 0
        verdict = "within" if wall < TARGET_S else "OVER"
        print(f"command   {label:<24}  wall {wall:6.2f} s   cpu {cpu:6.2f} s   "
              f"{wall / base_wall:5.1f}x summary, {verdict} the {TARGET_S:g} s target;  "
              f"{wall / sim_wall:4.2f}x the simulation (CPU {cpu / sim_cpu:4.2f}x)")
    print(f"files in {folder}")


if __name__ == "__main__":
    run(ladder="--ladder" in sys.argv[1:])
