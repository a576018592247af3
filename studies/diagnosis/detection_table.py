"""Detection table of diagnosis on the held-out cases (:mod:`heldout`): rerun it to check it.

For each planted effect (on each channel where it applies), noise type and noise level, the
share of seeds in which ``diagnose`` names it significant, at each strength, from the strongest
down until a strength is found in fewer than 90 % of the seeds (weaker ones are not run); the
smallest strength found in at least 90 % of the seeds; and, on the clean cases (nothing
planted), the share with any significant finding (false discoveries) and the share not at the
noise floor.

A planted effect is *found* when a significant finding has its effect name and, for a sensor
effect, its channel (a gain error only to its FRF: one FRF cannot tell which of its two
channels reads high), and for a local mode its frequency within 3 %. Any other significant
finding is a false discovery.

Run (about an hour on two cores for the full set)::

    python studies/diagnosis/detection_table.py --presets --out studies/diagnosis/results.jsonl
    python studies/diagnosis/detection_table.py --quick          # a few minutes

``--jobs N`` runs N local processes, ``--scheduler tcp://HOST:PORT`` the workers of a Dask
cluster instead (``pip install "viscorig[dask]"``; this folder's ``heldout.py`` is uploaded to
them); the table is printed as Markdown and written beside ``--out``.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import sys
import time
from collections import defaultdict
from collections.abc import Iterable
from pathlib import Path

for _variable in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_variable, "1")

sys.path.insert(0, str(Path(__file__).resolve().parent))

import heldout  # noqa: E402
from heldout import EFFECTS, TABLE, Case, clean_cases, detection_cases, measure  # noqa: E402

from viscorig.diagnosis import diagnose  # noqa: E402
from viscorig.executor import DaskExecutor, executor  # noqa: E402
from viscorig.fitting import FrfData  # noqa: E402

#: Share of seeds a strength must be found in to count as detected.
DETECTED_SHARE = 0.9


def _channel_of(term: str) -> str | None:
    return term[term.index("(") + 1 : term.index(")")] if "(" in term else None


def found(case: Case, effect: str, term: str, parameters: dict) -> bool:
    """The significant finding ``(effect, term)`` is the effect planted in ``case``."""
    if effect != case.vocabulary:
        return False
    channel = _channel_of(term)
    if case.effect in ("delay", "lowpass", "highpass"):
        return channel == case.channel
    if case.effect == "gain":
        frf = {"F_e": "table", "x_s": "table", "F_v": "support", "x_v": "support"}
        return channel is not None and frf[channel] == frf[case.channel]
    if case.effect == "fixture":
        f_n = next((p["value"] for name, p in parameters.items() if name.startswith("f_n")), 0.0)
        return abs(f_n / case.fixture_hz - 1) < 0.03
    return True


#: Give diagnosis the analyser's normalized variance of each point, as a 35670A campaign file
#: holds it (``--no-variance``: the FRFs alone, as some other tools export them).
WITH_VARIANCE = True


def run_case(case: Case, with_variance: bool | None = None) -> dict:
    """Measure and diagnose one case; what was found, and how long it took."""
    runs = measure(case)
    variance = WITH_VARIANCE if with_variance is None else with_variance
    pieces = [
        (run.name, FrfData(run.frequency_hz, run.table, run.support, run.time_s,
                           run.reference_amplitude, name=run.name,
                           variance_table=run.variance_table if variance else None,
                           variance_support=run.variance_support if variance else None))
        for run in runs
    ]
    start = time.perf_counter()
    diagnosis = diagnose(pieces, case.model, table=TABLE)
    elapsed = time.perf_counter() - start
    significant = [
        {"effect": f.effect, "term": f.term, "parameters": f.parameters(),
         "planted": found(case, f.effect, f.term, f.parameters())}
        for f in diagnosis.significant
    ]
    return {
        "case": case.name, "effect": case.effect, "channel": case.channel,
        "strength": case.strength, "noise_type": case.noise_type,
        "noise_level": case.noise_level, "seed": case.seed, "base": case.base,
        "found": any(item["planted"] for item in significant),
        "false": [item["term"] for item in significant if not item["planted"]],
        "at_noise_floor": bool(diagnosis.at_noise_floor),
        "rms_over_floor": float(diagnosis.rms_error / diagnosis.noise_floor),
        "floor_over_true_noise": float(diagnosis.noise_floor / runs[0].true_noise),
        "seconds": elapsed,
    }


def _run_adaptive(planted: list[Case], jobs, log: Path | None) -> list[dict]:
    """Planted cases strongest first, one strength of every group (effect, channel, noise) per
    round; a group stops below the first strength found in fewer than 90 % of its seeds (the
    weaker ones are then not run: the table needs only where detection ends)."""
    groups: dict[tuple, dict[float, list[Case]]] = defaultdict(lambda: defaultdict(list))
    for case in planted:
        key = (case.effect, case.channel, case.noise_type, case.noise_level)
        groups[key][case.strength].append(case)
    order = {key: sorted(per, reverse=True) for key, per in groups.items()}
    alive = set(groups)
    results: list[dict] = []
    for depth in range(max(len(strengths) for strengths in order.values())):
        batch = [case for key in sorted(alive, key=str) if depth < len(order[key])
                 for case in groups[key][order[key][depth]]]
        if not batch:
            break
        found = _run_all(batch, jobs, log)
        results += found
        for key in list(alive):
            if depth >= len(order[key]):
                alive.discard(key)
                continue
            strength = order[key][depth]
            rows = [r for r in found if (r["effect"], r["channel"], r["noise_type"],
                                         r["noise_level"], r["strength"]) == (*key, strength)]
            if rows and sum(r["found"] for r in rows) < DETECTED_SHARE * len(rows):
                alive.discard(key)
    return results


def _run_all(cases: list[Case], jobs, log: Path | None = None) -> list[dict]:
    """Every case's result; with ``log`` (JSON lines), results already there are read back and
    each new one is appended as it comes, so a stopped study resumes where it was. ``jobs``:
    a number of local processes, or an executor of :mod:`viscorig.executor`."""
    done: dict[str, dict] = {}
    if log is not None and log.exists():
        for line in log.read_text().splitlines():
            if line.strip():
                item = json.loads(line)
                done[item["case"]] = item
    todo = [case for case in cases if case.name not in done]
    sink = None if log is None else log.open("a")
    try:
        own = isinstance(jobs, int)
        workers = executor(jobs) if own else jobs
        try:
            for item in workers.unordered(run_case, todo):
                done[item["case"]] = item
                if sink is not None:
                    sink.write(json.dumps(item) + "\n")
                    sink.flush()
        finally:
            if own:
                workers.close()
    finally:
        if sink is not None:
            sink.close()
    return [done[case.name] for case in cases]


def _smallest(rates: dict[float, float]) -> float | None:
    """Smallest strength found at least :data:`DETECTED_SHARE` of the time, from which on every
    stronger one is found too."""
    best = None
    for strength in sorted(rates, reverse=True):
        if rates[strength] >= DETECTED_SHARE:
            best = strength
        else:
            break
    return best


def _format(effect: str, strength: float | None) -> str:
    if strength is None:
        return "not found"
    unit = EFFECTS[effect][3]
    if effect in ("delay", "lowpass"):
        return f"{strength * 1e6:g} µs"
    if effect == "highpass":
        return f"{strength:g} Hz"
    if effect == "fixture":
        return f"{strength * 1e3:g} g"
    if effect == "drift":
        return f"{strength * 100:g} %/h"
    if unit in ("relative", "K*/K_c"):
        return f"{strength * 100:g} %"
    return f"{strength:g} {unit}"


def table(results: Iterable[dict]) -> str:
    """The Markdown tables: smallest strength found 90 % of the time, and the clean cases."""
    results = list(results)
    rates: dict[tuple, dict[float, list[bool]]] = defaultdict(lambda: defaultdict(list))
    false_in_detection: dict[tuple, list[bool]] = defaultdict(list)
    clean: dict[tuple, list[dict]] = defaultdict(list)
    for r in results:
        if r["effect"] == "clean":
            clean[(r["base"], r["noise_type"], r["noise_level"])].append(r)
            continue
        key = (r["effect"], r["channel"], r["noise_type"], r["noise_level"])
        rates[key][r["strength"]].append(r["found"])
        false_in_detection[(r["noise_type"], r["noise_level"])].append(bool(r["false"]))
    kinds = list(heldout.NOISE_TYPES)
    noises = sorted({(k[2], k[3]) for k in rates}, key=lambda n: (kinds.index(n[0]), n[1]))
    lines = []
    if rates:
        header = "| effect | channel | " + " | ".join(
            f"{kind} {level * 100:g} %" for kind, level in noises) + " |"
        lines += [header, "|" + "---|" * (2 + len(noises))]
        for effect, (_, channels, _, _) in EFFECTS.items():
            for channel in channels:
                cells = []
                for kind, level in noises:
                    per = rates.get((effect, channel, kind, level))
                    if not per:
                        cells.append("")
                        continue
                    share = {s: sum(v) / len(v) for s, v in per.items()}
                    smallest = _smallest(share)
                    text = _format(effect, smallest)
                    if smallest is not None and smallest == min(EFFECTS[effect][2]):
                        text = "≤ " + text  # the weakest strength tried: the limit is lower
                    cells.append(text)
                if any(cells):
                    lines.append(f"| {effect} | {channel or ''} | " + " | ".join(cells) + " |")
        lines.append("")
        cells = []
        for kind, level in noises:
            values = false_in_detection[(kind, level)]
            cells.append(f"{100 * sum(values) / max(len(values), 1):.1f} %")
        lines.append("| other effect named (planted cases) | | " + " | ".join(cells) + " |")
        lines.append("")
    if clean:
        lines += ["| clean cases | noise | cases | false discoveries | not at the floor | "
                  "floor / true noise |", "|---|---|---|---|---|---|"]
        for (base, kind, level), items in sorted(clean.items()):
            n = len(items)
            false = sum(bool(i["false"]) for i in items)
            above = sum(not i["at_noise_floor"] for i in items)
            ratio = sorted(i["floor_over_true_noise"] for i in items)
            lines.append(
                f"| {base} | {kind} {level * 100:g} % | {n} | {100 * false / n:.1f} % | "
                f"{100 * above / n:.1f} % | {ratio[n // 2]:.2f} (median) |"
            )
    seconds = [r["seconds"] for r in results]
    if seconds:
        seconds.sort()
        lines.append("")
        lines.append(f"diagnose time per case: median {seconds[len(seconds) // 2]:.2f} s, "
                     f"max {seconds[-1]:.2f} s ({len(seconds)} cases)")
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--quick", action="store_true", help="2 seeds, white noise, 1 %% only")
    parser.add_argument("--seeds", type=int, default=10, help="seeds per planted case")
    parser.add_argument("--clean-seeds", type=int, default=50, help="clean cases per noise")
    parser.add_argument("--noise", nargs="*", default=list(heldout.NOISE_TYPES))
    parser.add_argument("--effects", nargs="*", default=list(EFFECTS))
    parser.add_argument("--levels", nargs="*", type=float, default=list(heldout.NOISE_LEVELS),
                        help="relative rms noise levels (0.01 is 1 %%)")
    parser.add_argument("--presets", action="store_true", help="also the paper-like presets")
    parser.add_argument("--jobs", type=int, default=max(1, (os.cpu_count() or 1)))
    parser.add_argument("--scheduler", default=None, metavar="tcp://HOST:PORT",
                        help="run the cases on this Dask cluster's workers instead")
    parser.add_argument("--cases", type=int, default=None,
                        help="run only the first N clean and N planted cases (a timing sample)")
    parser.add_argument("--out", type=Path, default=None,
                        help="results (JSON lines, one case each; a rerun resumes from it)")
    args = parser.parse_args(argv)
    levels = tuple(args.levels)
    seeds, clean_seeds, noise = args.seeds, args.clean_seeds, args.noise
    if args.quick:
        seeds, clean_seeds, noise, levels = 2, 4, ["white"], (0.01,)
    cases = list(clean_cases(noise, levels, range(clean_seeds)))
    if args.presets:
        presets = tuple(heldout.PRESET_MODELS)
        cases += list(clean_cases(noise, levels, range(math.ceil(clean_seeds / 6)), presets))
    planted = list(detection_cases(noise, levels, range(seeds), args.effects))
    if args.cases is not None:
        cases, planted = cases[: args.cases], planted[: args.cases]
    start = time.perf_counter()
    with executor(args.jobs, args.scheduler) as workers:
        if isinstance(workers, DaskExecutor):
            workers.upload(Path(heldout.__file__))
        results = _run_all(cases, workers, args.out)
        results += _run_adaptive(planted, workers, args.out)
    text = table(results)
    print(text)
    print(f"{len(results)} cases in {time.perf_counter() - start:.0f} s")
    if args.out is not None:
        args.out.with_suffix(".md").write_text(text + "\n")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
