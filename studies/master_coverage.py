"""Coverage of the shift factors' standard errors over replicates with a known WLF (not a test).

Each replicate: a DMA-like sweep of a Havriliak-Negami material shifted by a WLF law
(``tests/materialdata.py``, an independent generator sharing no code with the core), 11
temperatures from -30 to 70 °C, 10 frequencies from 0.1 to 100 Hz, multiplicative noise of
1 % on E' and 2 % on E'' with its own seed. The shift factors are estimated as ``viscorig master``
does (``build_master``, reference 20 °C: spline master curve, then shifts refined together with
the Prony series) and WLF is fitted to them. It prints, per temperature and over all, the
fraction of replicates whose true log10 aT lies within 1 and 2 reported standard errors (68 %
and 95 % if the errors mean what they say) and the rms of error/stderr; then the same for the
WLF constants.

Run: ``python studies/master_coverage.py [REPLICATES] [--noise-scale X]`` (default 200).
"""

from __future__ import annotations

import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))

import materialdata as gen

from viscorig.materials.master import build_master
from viscorig.materials.table import ModulusTable

TEMPERATURES = np.arange(-30.0, 71.0, 10.0)
FREQUENCIES = np.logspace(-1, 2, 10)
REFERENCE = 20.0


def replicate(seed: int, noise_scale: float = 1.0) -> tuple[np.ndarray, np.ndarray, tuple]:
    """z = (estimate − truth)/stderr of every non-reference shift, and of C1, C2."""
    data = gen.dma_sweep(TEMPERATURES, FREQUENCIES, storage_noise=0.01 * noise_scale,
                         loss_noise=0.02 * noise_scale, seed=seed)
    table = ModulusTable(**data, source=f"replicate {seed}")
    master = build_master(table, (), REFERENCE)
    truth = gen.true_log10_at(master.temperature_c, REFERENCE)
    free = master.log10_at_stderr > 0
    z = np.full(TEMPERATURES.size, np.nan)
    z[free] = (master.log10_at[free] - truth[free]) / master.log10_at_stderr[free]
    wlf = next(f for f in master.shift_functions if f.kind == "wlf")
    zc = ((wlf.values[0] - gen.C1) / wlf.stderr[0], (wlf.values[1] - gen.C2_K) / wlf.stderr[1])
    return z, master.log10_at_stderr, zc


def main(replicates: int = 200, noise_scale: float = 1.0) -> None:
    started = time.perf_counter()
    zs, errors, zcs = [], [], []
    for seed in range(replicates):
        z, stderr, zc = replicate(seed, noise_scale)
        zs.append(z)
        errors.append(stderr)
        zcs.append(zc)
    z = np.array(zs)
    stderr = np.array(errors)
    print(f"{replicates} replicates, noise x{noise_scale} (1 % on E', 2 % on E''), "
          f"{time.perf_counter() - started:.1f} s\n")
    print("| temperature °C | true log10 aT | mean stderr | within 1 stderr | within 2 stderr "
          "| rms error/stderr |")
    print("|---|---|---|---|---|---|")
    truth = gen.true_log10_at(TEMPERATURES, REFERENCE)
    for k, temperature in enumerate(TEMPERATURES):
        if temperature == REFERENCE:
            continue
        column = z[:, k]
        print(f"| {temperature:.0f} | {truth[k]:+.3f} | {stderr[:, k].mean():.4f} | "
              f"{np.mean(np.abs(column) <= 1):.0%} | {np.mean(np.abs(column) <= 2):.0%} | "
              f"{np.sqrt(np.mean(column**2)):.2f} |")
    every = z[np.isfinite(z)]
    print(f"| all | | | {np.mean(np.abs(every) <= 1):.1%} | {np.mean(np.abs(every) <= 2):.1%} | "
          f"{np.sqrt(np.mean(every**2)):.2f} |")
    zc = np.array(zcs)
    for k, name in enumerate(("C1", "C2_K")):
        print(f"\nWLF {name}: within 1 stderr {np.mean(np.abs(zc[:, k]) <= 1):.1%}, within 2 "
              f"{np.mean(np.abs(zc[:, k]) <= 2):.1%}, rms error/stderr "
              f"{np.sqrt(np.mean(zc[:, k] ** 2)):.2f}")


if __name__ == "__main__":
    arguments = [a for a in sys.argv[1:] if not a.startswith("--")]
    scale = 1.0
    if "--noise-scale" in sys.argv:
        scale = float(sys.argv[sys.argv.index("--noise-scale") + 1])
        arguments = [a for a in arguments if a != str(sys.argv[sys.argv.index("--noise-scale")
                                                                + 1])]
    main(int(arguments[0]) if arguments else 200, scale)
