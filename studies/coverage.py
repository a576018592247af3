"""Coverage of the reported standard errors over many simulated replicates (not part of the tests).

Each replicate: a noisy bare-table run and a noisy Voigt specimen run, both measured by the
time-domain simulator with their own noise (``tests/coverage.py``); the table identified from its
run, the specimen fitted with the table's covariance propagated, as ``viscorig identify`` does.
For white sensor noise and for noise correlated along the sweep (each transducer's sensitivity
drifting by 0.1 % rms with a 30 s correlation time), on both FRFs (identify's default) and on
X_s/F_e alone (the paper's Table 1), it prints the fraction of replicates whose truth lies within
1 and 2 reported standard errors, and the rms of error/stderr.

Then the change between two runs of one specimen, without and with preload (K_v +9.33 %,
C_v +9.00 %), on one table identified once from its own noisy run (``change_replicate``): with
an exact model, and with two fixture modes on the disc that the model leaves out (a misfit
both runs share), the change's ± from :mod:`viscorig.compare` against the true change, beside
the rms of error/stderr the two fits would give taken as independent.

Run: ``python studies/coverage.py [REPLICATES] [--changes] [--jobs N] [--scheduler
tcp://HOST:PORT]`` (default 200; about 40 ms of simulation and a few ms of fitting per run: a
minute or two per 200 on this machine; ``--changes`` prints only the table of changes). The
replicates run in ``N`` local processes (default 1), or on a Dask cluster's workers
(``pip install "viscorig[dask]"``; ``tests/coverage.py`` and ``tests/simdata.py`` are
uploaded to them).
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))

import coverage as helpers
from coverage import (
    FIXTURES,
    NOISES,
    change_coverage,
    change_replicate,
    coverage,
    replicate,
)

from viscorig.executor import DaskExecutor, LocalExecutor, executor

#: Where the replicates run (set by the command line; this process by default).
WORKERS: LocalExecutor | DaskExecutor = LocalExecutor(1)


def changes(replicates: int = 200) -> None:
    """Print the coverage table of a change between two runs in Markdown."""
    print(f"\n{replicates} replicates per row: the change from the specimen without to with "
          "preload, on one table\n")
    print("| rig | FRFs fitted | change | rms/floor | within 1 stderr | within 2 stderr "
          "| rms error/stderr | ± / ± as independent | rms error/stderr as independent |")
    print("|---|---|---|---|---|---|---|---|---|")
    for label, fixtures in (("exact model", None), ("fixture modes left out", FIXTURES)):
        for frfs, text in ((None, "both"), (("table",), "X_s/F_e")):
            start = time.perf_counter()
            table = change_coverage(WORKERS.map(
                change_replicate, [(NOISES["white"], seed, fixtures, frfs)
                                   for seed in range(replicates)]))
            for name, row in table.items():
                print(f"| {label} | {text} | {name} | {row['rms_over_floor']:.1f} | "
                      f"{row['within_1']:.0%} | {row['within_2']:.0%} | {row['rms']:.2f} | "
                      f"{row['stderr_ratio']:.2f} | {row['independent_rms']:.2f} |")
            print(f"<!-- {label}, {text}: {time.perf_counter() - start:.0f} s -->", flush=True)


def main(replicates: int = 200) -> None:
    """Print the coverage table in Markdown."""
    print(f"{replicates} replicates per row; goal: 68 % ± 12 % within 1, 95 % ± 5 % within 2\n")
    print("| noise | FRFs fitted | parameter | within 1 stderr | within 2 stderr "
          "| rms error/stderr |")
    print("|---|---|---|---|---|---|")
    for label, noise in NOISES.items():
        for frfs, text in ((None, "both"), (("table",), "X_s/F_e")):
            start = time.perf_counter()
            table = coverage(WORKERS.map(replicate, [(noise, seed, frfs)
                                                     for seed in range(replicates)]))
            for name, row in table.items():
                print(f"| {label} | {text} | {name} | {row['within_1']:.0%} | "
                      f"{row['within_2']:.0%} | {row['rms']:.2f} |")
            print(f"<!-- {label}, {text}: {time.perf_counter() - start:.0f} s -->", flush=True)


if __name__ == "__main__":
    parser = argparse.ArgumentParser(description=(__doc__ or "").split("\n")[0])
    parser.add_argument("replicates", type=int, nargs="?", default=200)
    parser.add_argument("--changes", action="store_true", help="only the table of changes")
    parser.add_argument("--jobs", type=int, default=1, help="local processes")
    parser.add_argument("--scheduler", default=None, metavar="tcp://HOST:PORT",
                        help="run the replicates on this Dask cluster's workers instead")
    args = parser.parse_args()
    with executor(args.jobs, args.scheduler) as WORKERS:
        if isinstance(WORKERS, DaskExecutor):
            for helper in ("simdata.py", "coverage.py"):  # what the replicates import
                WORKERS.upload(Path(helpers.__file__).with_name(helper))
        if not args.changes:
            main(args.replicates)
        changes(args.replicates)
