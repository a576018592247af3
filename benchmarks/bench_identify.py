"""Identification speed and quality on simulated runs (401 points, 20-120 Hz), medians.

Baselines measured in the same process on the same data:
- a Nelder-Mead direct search from a generic start (the paper's method), same error measure;
- pyvisco's Prony fit (``pyvisco.prony``, frequency domain, optimised number of terms) of the
  same E' and E'' (K* from Eq. 5 with θ = 1 m), if pyvisco is installed (it is not a dependency).

Run: ``python benchmarks/bench_identify.py`` (needs the project installed; uses tests/simdata).
"""

from __future__ import annotations

import io
import statistics
import sys
import time
import warnings
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))

from simdata import DEFAULT_NOISE, rig_text, simulate_run

from viscorig.estimates import kstar_from_support
from viscorig.fitting import fit, nelder_mead_fit

TABLE = {"M_s": 3.4, "K_s": 50194.0, "C_s": 5.05}
RIGS = {
    "voigt": {"mass_kg": 0.25, "model": "voigt", "stiffness_n_per_m": 1.5e5,
              "damping_ns_per_m": 114.59},
    "maxwell": {"mass_kg": 0.25, "model": "maxwell", "static_stiffness_n_per_m": 1.2e5,
                "arms": [[5.0e4, 5.0e4 / (2 * np.pi * 150)], [8.0e4, 8.0e4 / (2 * np.pi * 30)]]},
    "fractional": {"mass_kg": 0.2, "model": "fractional", "static_stiffness_n_per_m": 1.5e5,
                   "high_stiffness_n_per_m": 6.0e5, "tau_s": 2.0e-3, "alpha": 0.45},
}  # fmt: skip
TARGETS_MS = {"voigt": 5.0, "maxwell": 100.0, "fractional": 50.0}
GENERIC_STARTS = {
    "voigt": {"K_v": 1.0e5, "C_v": 50.0, "M_v": 0.5},
    "maxwell": {"K_0": 1.0e5, "K_1": 1.0e5, "C_1": 100.0, "K_2": 1.0e5, "C_2": 1000.0,
                "M_v": 0.5},
    "fractional": {"K_0": 1.0e5, "K_inf": 1.0e6, "tau": 1.0e-3, "alpha": 0.5, "M_v": 0.5},
}  # fmt: skip
REPEATS = 15


def median_time(function, repeats: int = REPEATS) -> tuple[float, object]:
    """Median wall time in seconds, and the last result."""
    times, result = [], None
    for _ in range(repeats):
        start = time.perf_counter()
        result = function()
        times.append(time.perf_counter() - start)
    return statistics.median(times), result


def median_cpu_time(function, repeats: int = REPEATS) -> float:
    """Median processor time of this process in seconds (less sensitive to a busy machine than
    wall time, but it counts every BLAS thread's spinning)."""
    times = []
    for _ in range(repeats):
        start = time.process_time()
        function()
        times.append(time.process_time() - start)
    return statistics.median(times)


def pyvisco_prony(frequency_hz: np.ndarray, kstar: np.ndarray):
    """pyvisco's frequency-domain Prony fit of E' and E'' (MPa, θ = 1 m); None if missing."""
    try:
        from pyvisco import load, master, prony
    except ImportError:
        return None
    text = "f,E_stor,E_loss\nHz,MPa,MPa\n" + "\n".join(
        f"{f:.6g},{k.real / 1e6:.9g},{k.imag / 1e6:.9g}"
        for f, k in zip(frequency_hz, kstar, strict=True)
    )
    df_master, _ = load.user_master(text.encode(), "freq", 25, "E")
    df_master = master.smooth(df_master, 1)
    df_dis = prony.discretize(df_master, window="exact", nprony=4)
    with warnings.catch_warnings(), io.StringIO() as sink:
        warnings.simplefilter("ignore")
        stdout, sys.stdout = sys.stdout, sink
        try:
            result, _ = prony.fit(df_dis, df_master, opt=True)
        finally:
            sys.stdout = stdout
    terms = result["df_terms"]
    tau, alpha = terms["tau_i"].to_numpy(), terms["alpha_i"].to_numpy()
    a = 2 * np.pi * frequency_hz[:, None] * tau[None, :]
    e_0 = result["E_0"] * 1e6
    fitted = e_0 * (1 - alpha.sum() + (alpha * a**2 / (1 + a**2)).sum(axis=1)) + 1j * e_0 * (
        alpha * a / (1 + a**2)
    ).sum(axis=1)
    return fitted, len(tau)


def main() -> None:
    print("identification of simulated runs, 401 points 20-120 Hz, both FRFs, table fixed")
    print(f"{'model':<11} {'ours [ms]':>9} {'target':>7} {'cpu [ms]':>8} {'rms':>9} {'floor':>9} "
          f"{'NM [ms]':>9} {'NM rms':>9} {'NM/ours time':>12}")  # fmt: skip
    runs = {}
    for name, device in RIGS.items():
        runs[name] = simulate_run(rig_text(device, noise=DEFAULT_NOISE), seed=5).frf_data(name)
    for name, data in runs.items():
        spec = name
        ours_s, ours = median_time(lambda data=data, spec=spec: fit(spec, data, fixed=TABLE))
        ours_cpu = median_cpu_time(lambda data=data, spec=spec: fit(spec, data, fixed=TABLE))
        nm_spec = "maxwell(2)" if name == "maxwell" else spec
        nm_s, (_, nm_rms) = median_time(
            lambda data=data, nm_spec=nm_spec, name=name: nelder_mead_fit(
                nm_spec, data, GENERIC_STARTS[name], frfs=("table", "support"), fixed=TABLE
            ),
            repeats=3,
        )
        flag = "ok" if ours_s * 1e3 <= TARGETS_MS[name] else "SLOW"  # on wall time
        print(
            f"{ours.spec:<11} {ours_s * 1e3:>9.2f} {TARGETS_MS[name]:>5.0f}{flag:>2} "
            f"{ours_cpu * 1e3:>8.2f} {ours.rms_error:>9.2e} {ours.noise_floor:>9.2e} "
            f"{nm_s * 1e3:>9.1f} {nm_rms:>9.2e} {nm_s / ours_s:>11.0f}x"
        )
    # pyvisco on the Maxwell run's E' and E'' (Eq. 5), against our Maxwell fit of the same K*.
    data = runs["maxwell"]
    ours = fit("maxwell", data, fixed=TABLE, frfs=("support",))
    measured = kstar_from_support(data.frequency_hz, data.support, ours.values["M_v"])
    ours_error = np.sqrt(np.mean(np.abs(ours.kstar(data.frequency_hz) / measured - 1) ** 2))
    ours_s, _ = median_time(lambda: fit("maxwell", data, fixed=TABLE, frfs=("support",)))
    try:
        available = pyvisco_prony(data.frequency_hz, measured) is not None
    except Exception as error:  # a baseline failing must not hide our figures
        print(f"pyvisco failed on these data ({type(error).__name__}: {error}); column skipped")
        return
    if not available:
        print("pyvisco is not installed: its column is skipped (pip install pyvisco)")
        return
    pv_s, (pv_fit, terms) = median_time(
        lambda: pyvisco_prony(data.frequency_hz, measured), repeats=5
    )
    pv_error = np.sqrt(np.mean(np.abs(pv_fit / measured - 1) ** 2))
    print("\nProny fit of K* = E'+iE'' from Eq. (5), same points; error rms|K*_fit/K*_meas - 1|")
    print(f"  ours    maxwell, order by BIC ({ours.spec}): {ours_s * 1e3:8.2f} ms  "
          f"error {ours_error:.2e}")  # fmt: skip
    print(f"  pyvisco prony.fit(opt=True), {terms} terms:      {pv_s * 1e3:8.2f} ms  "
          f"error {pv_error:.2e}  ({pv_s / ours_s:.0f}x our time)")  # fmt: skip


if __name__ == "__main__":
    main()
