"""Coverage of the reported standard errors over many simulated replicates (not part of the tests).

Each replicate: a noisy bare-table run and a noisy Voigt specimen run, both measured by the
time-domain simulator with their own noise (``tests/coverage.py``); the table identified from its
run, the specimen fitted with the table's covariance propagated, as ``viscorig identify`` does.
For white sensor noise and for noise correlated along the sweep (each transducer's sensitivity
drifting by 0.1 % rms with a 30 s correlation time), on both FRFs (identify's default) and on
X_s/F_e alone (the paper's Table 1), it prints the fraction of replicates whose truth lies within
1 and 2 reported standard errors, and the rms of error/stderr.

Run: ``python studies/coverage.py [REPLICATES]`` (default 200; about 40 ms of simulation and a
few ms of fitting per run: a minute or two per 200 on this machine).
"""

from __future__ import annotations

import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))

from coverage import NOISES, coverage, replicate


def main(replicates: int = 200) -> None:
    """Print the coverage table in Markdown."""
    print(f"{replicates} replicates per row; goal: 68 % ± 12 % within 1, 95 % ± 5 % within 2\n")
    print("| noise | FRFs fitted | parameter | within 1 stderr | within 2 stderr "
          "| rms error/stderr |")
    print("|---|---|---|---|---|---|")
    for label, noise in NOISES.items():
        for frfs, text in ((None, "both"), (("table",), "X_s/F_e")):
            start = time.perf_counter()
            table = coverage(replicate(noise, seed, frfs) for seed in range(replicates))
            for name, row in table.items():
                print(f"| {label} | {text} | {name} | {row['within_1']:.0%} | "
                      f"{row['within_2']:.0%} | {row['rms']:.2f} |")
            print(f"<!-- {label}, {text}: {time.perf_counter() - start:.0f} s -->", flush=True)


if __name__ == "__main__":
    main(int(sys.argv[1]) if len(sys.argv) > 1 else 200)
