"""False findings of diagnosis on independent clean rigs (:mod:`clean_rigs`), bare-table run noisy.

For each case: the bare-table run is identified with the ``table`` model as a campaign's is
(noise weighting), and the specimen run is diagnosed from ``voigt`` with the table's values and
the covariance of their fit (``--exact-table``: the values alone, as if exact). A case is a
false discovery when any finding is significant; the table also gives the share of cases
whose report lists a failure band.

Run (``--jobs``: processes; results are appended to ``--out`` and a rerun resumes)::

    nice python studies/diagnosis/false_findings.py --cases 2400 --jobs 2 \
        --out studies/diagnosis/false_findings.jsonl [--step-hz 0.5]

``--table-only FILE``: print the table of a results file without running anything.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import time
from collections import defaultdict
from pathlib import Path

for _variable in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_variable, "1")

sys.path.insert(0, str(Path(__file__).resolve().parent))

from clean_rigs import CleanCase, bare_table, cases, specimen  # noqa: E402

from viscorig.diagnosis import diagnose  # noqa: E402
from viscorig.fitting import FrfData, Known, fit  # noqa: E402

TABLE_NAMES = ("M_s", "K_s", "C_s")
EXACT_TABLE = False


def table_of(case: CleanCase) -> Known:
    """The table's values and covariance as identify gets them from the bare-table run."""
    run = bare_table(case)
    data = FrfData(run.frequency_hz, run.table, None, run.time_s, run.reference_amplitude,
                   name="table")
    result = fit("table", data, weighting="noise")
    return Known.from_fit(result, TABLE_NAMES, "run 'table'")


def run_case(case: CleanCase, exact_table: bool | None = None) -> dict:
    """Identify the table, diagnose the specimen run; what was significant and what failed."""
    exact = EXACT_TABLE if exact_table is None else exact_table
    known = table_of(case)
    run = specimen(case)
    data = FrfData(run.frequency_hz, run.table, run.support, run.time_s,
                   run.reference_amplitude, name="run")
    start = time.perf_counter()
    diagnosis = diagnose(data, "voigt", table=dict(known.values) if exact else known)
    elapsed = time.perf_counter() - start
    return {
        "case": case.name, "rig": case.rig, "noise_level": case.noise_level, "seed": case.seed,
        "disc_mass_kg": case.disc_mass_kg, "step_hz": case.step_hz, "exact_table": exact,
        "table_error": {n: known.values[n] / v - 1 for n, v in
                        {"M_s": 3.4, "K_s": 50194.0, "C_s": 5.05}.items()},
        "false": [f.term for f in diagnosis.significant],
        "failures": [band.what for band in diagnosis.failures],
        "at_noise_floor": bool(diagnosis.at_noise_floor),
        "rms_over_floor": float(diagnosis.rms_error / diagnosis.noise_floor),
        "seconds": elapsed,
    }


def _run_all(todo: list[CleanCase], jobs: int, log: Path | None) -> list[dict]:
    done: dict[str, dict] = {}
    if log is not None and log.exists():
        for line in log.read_text().splitlines():
            if line.strip():
                item = json.loads(line)
                if item["exact_table"] == EXACT_TABLE:
                    done[item["case"]] = item
    rest = [case for case in todo if case.name not in done]
    sink = None if log is None else log.open("a")
    try:
        if jobs <= 1:
            results = map(run_case, rest)
            pool = None
        else:
            from multiprocessing import get_context

            pool = get_context("spawn").Pool(jobs, initializer=_set_exact, initargs=(EXACT_TABLE,))
            results = pool.imap_unordered(run_case, rest, chunksize=4)
        for item in results:
            done[item["case"]] = item
            if sink is not None:
                sink.write(json.dumps(item) + "\n")
                sink.flush()
        if pool is not None:
            pool.close()
            pool.join()
    finally:
        if sink is not None:
            sink.close()
    return [done[case.name] for case in todo if case.name in done]


def _set_exact(value: bool) -> None:
    global EXACT_TABLE
    EXACT_TABLE = value


def table(results: list[dict]) -> str:
    """Markdown: cases, share with a significant finding, share with a failure band listed."""
    groups: dict[tuple, list[dict]] = defaultdict(list)
    for r in results:
        groups[(r["rig"], r["noise_level"])].append(r)
        groups[("all", r["noise_level"])].append(r)
        groups[(f"all, {r.get('step_hz', 0.25):g} Hz steps", r["noise_level"])].append(r)
        groups[("all", "all")].append(r)
    lines = ["| rig | noise | cases | any significant finding | failure band listed | "
             "findings named |", "|---|---|---|---|---|---|"]
    def order(key: tuple) -> tuple:
        rig, level = key
        return (rig.startswith("all"), rig == "all" and level == "all", rig, str(level))

    for (rig, level), items in sorted(groups.items(), key=lambda kv: order(kv[0])):
        n = len(items)
        false = sum(bool(i["false"]) for i in items)
        failed = sum(bool(i["failures"]) for i in items)
        names: dict[str, int] = defaultdict(int)
        for i in items:
            for term in i["false"]:
                names[term.split("(")[0]] += 1
        named = ", ".join(f"{k} {v}" for k, v in sorted(names.items(), key=lambda kv: -kv[1]))
        noise = "both" if level == "all" else f"{level * 100:g} %"
        lines.append(f"| {rig} | {noise} | {n} | {false} ({100 * false / n:.2f} %) | "
                     f"{failed} ({100 * failed / n:.2f} %) | {named} |")
    seconds = sorted(r["seconds"] for r in results)
    if seconds:
        lines.append("")
        lines.append(f"diagnose time per case: median {seconds[len(seconds) // 2]:.2f} s, "
                     f"max {seconds[-1]:.2f} s ({len(seconds)} cases)")
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    global EXACT_TABLE
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--cases", type=int, default=120)
    parser.add_argument("--first-seed", type=int, default=0)
    parser.add_argument("--step-hz", type=float, default=0.25,
                        help="frequency step of the specimen runs (the paper plan's 0.25 Hz)")
    parser.add_argument("--jobs", type=int, default=1)
    parser.add_argument("--exact-table", action="store_true",
                        help="hold the table's values as exact (the behaviour before the prior)")
    parser.add_argument("--out", type=Path, default=None)
    parser.add_argument("--table-only", type=Path, default=None,
                        help="print the table of a results file (JSON lines) and stop")
    args = parser.parse_args(argv)
    if args.table_only is not None:
        rows = [json.loads(line) for line in args.table_only.read_text().splitlines() if line]
        print(table([r for r in rows if r["exact_table"] == args.exact_table]))
        return 0
    EXACT_TABLE = args.exact_table
    start = time.perf_counter()
    todo = cases(args.cases, first_seed=args.first_seed, step_hz=args.step_hz)
    results = _run_all(todo, args.jobs, args.out)
    text = table(results)
    print(text)
    print(f"{len(results)} cases in {time.perf_counter() - start:.0f} s")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
