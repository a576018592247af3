"""The diagnosis ladder on the benchmark's runs, as plain data to compare before and after a
change of the computation (``tests/data/ladder_reference.json``).

Each run is the paper's sweep (20-120 Hz at 0.25 Hz) of a rig preset measured on the
time-domain simulator with a fixed seed, as ``benchmarks/bench_diagnose.py`` measures it; the
ladder is climbed from Voigt with the table's values held. Recorded per run: every rung's model
and error, the significant findings of the first diagnosis, and the final fit's free
parameters with their standard errors.

Regenerate (only when a change of the diagnosis's *decisions* is intended)::

    python tests/ladder_reference.py tests/data/ladder_reference.json
"""

from __future__ import annotations

import json
import re
import sys
from pathlib import Path

import numpy as np
from rigsim.engine import RigSimulator
from rigsim.measurement import SourceControl, SweepRequest
from rigsim.rigfile import Rig, load_preset

from viscorig.fitting import FrfData

TABLE = {"M_s": 3.4, "K_s": 50194.0, "C_s": 5.05}
PRESETS = ("soft-0", "soft-10", "medium-0", "medium-10", "hard-0", "hard-10")
FIXTURE = Path(__file__).resolve().parent / "data" / "ladder_reference.json"


def measured_run(preset: str, seed: int = 1, rig: Rig | None = None) -> FrfData:
    """The paper's sweep of a preset (or of ``rig``, named ``preset``), as the analyser would
    give it (variance included)."""
    rig = load_preset(preset) if rig is None else rig
    frequency = np.arange(20.0, 120.125, 0.25)
    sensors = rig.sensors
    control = SourceControl(
        source_vpk=0.05, auto_level=True, reference_channel=4,
        reference_vpk=1.4 * sensors.acceleration_v_per_m_s2, tolerance_db=0.5,
        source_limit_vpk=rig.shaker.force_limit_n / rig.shaker.force_n_per_v,
    )
    record = RigSimulator(rig, seed=seed).sweep(
        SweepRequest(frequency, 100 / frequency, 100 / frequency, control)
    )
    v = record.channel_v
    force, accel = sensors.force_v_per_n, sensors.acceleration_v_per_m_s2
    variance = record.variance
    return FrfData(
        frequency,
        (v[:, 1] / accel) / (v[:, 0] / force),
        (v[:, 3] / accel) / (v[:, 2] / force),
        record.end_time_s,
        np.abs(v[:, 3] / accel),
        name=preset,
        variance_table=variance[:, 0] + variance[:, 1],
        variance_support=variance[:, 2] + variance[:, 3],
    )


def climb(preset: str) -> dict:
    """The ladder of one preset's run, as plain data."""
    from viscorig.diagnosis import diagnose

    with np.errstate(all="ignore"):
        first = diagnose(measured_run(preset), "voigt", table=TABLE)
        ladder = first.auto()
    last = ladder[-1]
    return {
        "run": preset,
        "rungs": [{"model": step.model, "rms_over_floor": step.rms_error / step.noise_floor}
                  for step in ladder],
        "first_findings": [{"effect": f.effect, "term": f.term} for f in first.significant],
        "final": {name: {"value": last.fit.values[name], "stderr": last.fit.stderr[name]}
                  for name in last.fit.free},
    }


_NUMBER = re.compile(r"\(([0-9.]+)\)")


def shape(spec: str) -> str:
    """A spec with every fixture's frequency left out (``fixture(58.23)`` -> ``fixture()``)."""
    return _NUMBER.sub(lambda m: "()", spec) if "fixture" in spec else spec


def frequencies(spec: str) -> list[float]:
    """The fixtures' frequencies in a spec, in order."""
    return [float(m) for m in re.findall(r"fixture\(([0-9.]+)\)", spec)]


def main(argv: list[str]) -> int:
    out = Path(argv[0]) if argv else FIXTURE
    presets = argv[1:] or PRESETS
    document = {"table": TABLE, "runs": [climb(preset) for preset in presets]}
    out.write_text(json.dumps(document, indent=1) + "\n")
    print(f"{out}: {len(document['runs'])} runs")
    return 0


if __name__ == "__main__":
    from viscorig.runtime import limit_blas_threads

    limit_blas_threads()
    raise SystemExit(main(sys.argv[1:]))
