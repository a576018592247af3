"""Master curve and Prony series of a real DMA sweep: viscorig against pyvisco, same file.

The file is pyvisco's own example sweep (``pyvisco_freq_user_raw.csv`` in ``shared/data/dma`` or
``$VISCORIG_REAL_DATA/dma``; tests/data/dma/README.md names it; 21
temperatures from -50 to 100 °C, 0.1-100 Hz; source and licence beside it). Each tool runs its
documented pipeline:

- viscorig: ``build_master`` (what ``viscorig master`` runs): shift factors of both moduli with
  standard errors, the Prony series with the fewest terms that reaches the data's scatter;
- pyvisco (2.1, if installed; it is not a dependency): ``load.user_raw`` → ``master.get_aT``
  (reference: the measured set nearest 25 °C, as it requires) → ``master.get_curve`` →
  ``master.smooth(win=5)`` → ``prony.discretize`` → ``prony.fit`` → ``opt.nprony(window="min")``,
  as its tutorial ``freq_raw.py`` does; both its initial series and the optimised one are scored.

Each is scored on every measured point, shifted by its own shift factors: the rms of
``ln(model/measured)`` for E' and E'', the number of terms, and the wall time (BLAS
single-threaded for both, as the ``viscorig`` command runs). With ``--figure
PATH`` it also draws viscorig's master curve (points with the ± of their shift, the series, and
pyvisco's optimised series) and the shift factors with WLF and Arrhenius.

Run: ``python benchmarks/bench_master_pyvisco.py [--figure docs/images/master-curve.png]``.
"""

from __future__ import annotations

from viscorig.runtime import limit_blas_threads

limit_blas_threads()  # before numpy loads, as the command line does, for both tools

import contextlib  # noqa: E402
import io  # noqa: E402
import os  # noqa: E402
import sys  # noqa: E402
import time  # noqa: E402
import warnings  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402

from viscorig.materials.dmafile import read_dma_csv  # noqa: E402
from viscorig.materials.master import build_master  # noqa: E402

#: pyvisco's example sweep, not held by the repository (tests/data/dma/README.md names it).
DATA = (Path(os.environ["VISCORIG_REAL_DATA"]) / "dma" if os.environ.get("VISCORIG_REAL_DATA")
        else Path(__file__).resolve().parents[2] / "shared" / "data" / "dma") \
    / "pyvisco_freq_user_raw.csv"


def rms_log(model: np.ndarray, measured: np.ndarray) -> float:
    """Rms of ln(model/measured)."""
    return float(np.sqrt(np.mean(np.log(model / measured) ** 2)))


def run_viscorig():
    started = time.perf_counter()
    master = build_master(read_dma_csv(DATA), ("pyvisco example",), 25.0)
    elapsed = time.perf_counter() - started
    return master, elapsed


def _pyvisco_series(prony: dict, df_master, modul: str = "E"):
    e0 = float(prony["E_0"])
    alpha = prony["df_terms"]["alpha_i"].to_numpy(dtype=float)
    tau = prony["df_terms"]["tau_i"].to_numpy(dtype=float)
    a = df_master["omega"].to_numpy(dtype=float)[:, None] * tau[None, :]
    storage = e0 * (1 - alpha.sum()) + (e0 * alpha * a**2 / (1 + a**2)).sum(axis=1)
    loss = (e0 * alpha * a / (1 + a**2)).sum(axis=1)
    return (rms_log(storage, df_master[f"{modul}_stor"].to_numpy(dtype=float)),
            rms_log(loss, df_master[f"{modul}_loss"].to_numpy(dtype=float)), alpha.size,
            e0, alpha, tau)


def run_pyvisco():
    """pyvisco's pipeline; None when it is not installed."""
    try:
        import matplotlib

        matplotlib.use("Agg")
        import pyvisco as visco
    except ImportError:
        return None
    started = time.perf_counter()
    with warnings.catch_warnings(), contextlib.redirect_stdout(io.StringIO()):
        warnings.simplefilter("ignore")
        data = visco.load.file(str(DATA))
        df_raw, arr_ref, _units = visco.load.user_raw(data, "freq", "E")
        temperatures = np.asarray(arr_ref, dtype=float)
        reference = float(temperatures[np.argmin(np.abs(temperatures - 25.0))])
        df_aT, _ = visco.master.get_aT(df_raw, reference)
        df_master = visco.master.get_curve(df_raw, df_aT, reference)
        df_master = visco.master.smooth(df_master, win=5)
        df_dis = visco.prony.discretize(df_master)
        initial, _ = visco.prony.fit(df_dis)
        first = time.perf_counter() - started
        series, n_opt, _ = visco.opt.nprony(df_master, initial, window="min")
    elapsed = time.perf_counter() - started
    return {"reference_c": reference, "initial": _pyvisco_series(initial, df_master),
            "optimised": _pyvisco_series(series[n_opt], df_master), "time_initial": first,
            "time": elapsed, "df_master": df_master, "df_aT": df_aT}


def figure(master, pyvisco, path: Path) -> None:
    """Master curve with the ± of the shifts, and the shift factors with WLF and Arrhenius."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    table = master.table
    fig, (left, right) = plt.subplots(1, 2, figsize=(11, 4.2))
    lookup = dict(zip(master.shifts.sets.tolist(), master.log10_at_stderr, strict=True))
    xerr = np.array([lookup[s] for s in table.set_index.tolist()])
    fr = master.reduced_frequency_hz
    band = np.vstack([fr * (1 - 10 ** -xerr), fr * (10 ** xerr - 1)])
    left.errorbar(fr, table.storage_pa / 1e6, xerr=band, fmt="o", ms=3, color="tab:blue",
                  alpha=0.6, label="E' measured (± shift)")
    left.errorbar(fr, table.loss_pa / 1e6, xerr=band, fmt="s", ms=3, color="tab:red",
                  alpha=0.6, label="E'' measured (± shift)")
    grid = np.logspace(np.log10(fr.min()) - 0.5, np.log10(fr.max()) + 0.5, 400)
    model = master.prony.complex_modulus(2 * np.pi * grid) / 1e6
    left.plot(grid, model.real, "-", color="navy",
              label=f"viscorig Prony, {master.prony.terms} terms")
    left.plot(grid, model.imag, "-", color="darkred")
    if pyvisco is not None:
        n = pyvisco["optimised"][2]
        # pyvisco's series lives on its own reduced-frequency axis (its own shifts): not drawn
        left.plot([], [], " ", label=f"(pyvisco: {n} terms on its own shifts, not drawn)")
    left.set_xscale("log")
    left.set_yscale("log")
    left.set_xlabel("reduced frequency f·aT (Hz), reference "
                    f"{master.reference_temperature_c:.1f} °C")
    left.set_ylabel("modulus (MPa)")
    left.legend(fontsize=8)
    left.set_title("master curve of pyvisco's example DMA sweep")
    right.errorbar(master.temperature_c, master.log10_at, yerr=master.log10_at_stderr, fmt="o",
                   color="k", capsize=3, label="log10 aT ± stderr")
    t = np.linspace(master.temperature_c.min(), master.temperature_c.max(), 200)
    for function in master.shift_functions:
        right.plot(t, function(t), label=f"{function.kind} (χ²/dof {function.reduced_chi2:.0f})")
    if pyvisco is not None:
        right.plot(pyvisco["df_aT"]["T"], pyvisco["df_aT"]["log_aT"], "x", color="tab:green",
                   label="pyvisco's shift factors")
    right.set_xlabel("temperature (°C)")
    right.set_ylabel("log10 aT")
    right.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=110)


def main() -> None:
    master, elapsed = run_viscorig()
    fit = master.prony_fit
    print(f"file: {DATA.name}, {master.table.points} points, {master.temperature_c.size} "
          "temperatures\n")
    print("| tool | reference °C | terms | rms ln error E' | rms ln error E'' | time (s) |")
    print("|---|---|---|---|---|---|")
    print(f"| viscorig master | {master.reference_temperature_c:.1f} | {master.prony.terms} | "
          f"{fit.storage_rms_log_error:.3f} | {fit.loss_rms_log_error:.3f} | {elapsed:.2f} |")
    pyvisco = run_pyvisco()
    if pyvisco is None:
        print("pyvisco is not installed: its rows are skipped (pip install pyvisco)")
    else:
        for label, key, seconds in (("pyvisco, initial series", "initial", "time_initial"),
                                    ("pyvisco, optimised (opt.nprony)", "optimised", "time")):
            storage, loss, terms, *_ = pyvisco[key]
            print(f"| {label} | {pyvisco['reference_c']:.1f} | {terms} | {storage:.3f} | "
                  f"{loss:.3f} | {pyvisco[seconds]:.2f} |")
    flagged = master.flagged_points()
    print(f"\nviscorig: data scatter about one smooth master curve: E' "
          f"{master.shifts.storage_scatter:.3f}, E'' {master.shifts.loss_scatter:.3f}; "
          f"{len(flagged)} point(s) fail the Kramers-Kronig check; "
          f"{master.superposition.verdict}")
    if "--figure" in sys.argv:
        path = Path(sys.argv[sys.argv.index("--figure") + 1])
        figure(master, pyvisco, path)
        print(f"figure: {path}")


if __name__ == "__main__":
    main()
