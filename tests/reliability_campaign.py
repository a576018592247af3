"""Helpers of the campaign-level reliability tests: a station file for a simulated analyser on
loopback, small sequences, the command line run in-process, and checks of a campaign file.
"""

from __future__ import annotations

import io
from contextlib import redirect_stderr, redirect_stdout
from pathlib import Path

import numpy as np
from rigsim.faults import Fault, FaultInjector
from rigsim.rigfile import load_preset
from stationfile import station_toml

from viscorig.cli import main
from viscorig.storage import CampaignFile


def station_text(resource: str, *, preset: str = "soft-0", source_limit_v: float = 5.0,
                 force_limit_n: float | None = None, table: bool = True) -> str:
    """A station file for the simulated analyser at ``resource`` measuring ``preset``."""
    rig = load_preset(preset)
    sensors, shaker = rig.sensors, rig.shaker
    text = station_toml(resource, force_v_per_n=sensors.force_v_per_n,
                        acceleration_v_per_m_s2=sensors.acceleration_v_per_m_s2,
                        force_limit_n=force_limit_n or shaker.force_limit_n,
                        gain_n_per_v=shaker.force_n_per_v, source_limit_v=source_limit_v)
    if table:
        text += "[table]\nmass_kg = 3.4\nstiffness_n_per_m = 50194.0\ndamping_ns_per_m = 5.05\n"
    return text


def sweep_sequence(run: str = "soft-0", specimen: str = "soft", band: tuple = (20.0, 30.0),
                   level: str = "1 m/s^2", segment_points: int = 8, cycles: int = 20) -> str:
    """A sequence of one prompt and one sweep run."""
    return f"""
name = "faults"
[[steps]]
type = "prompt"
message = "Mount the specimens."
[[steps]]
type = "sweep"
run = "{run}"
specimen = "{specimen}"
band_hz = [{band[0]}, {band[1]}]
resolution_hz = 0.25
settle_cycles = {cycles}
integrate_cycles = {cycles}
level = "{level}"
segment_points = {segment_points}
"""


def cli(arguments: list[str]) -> tuple[int, str, str]:
    """The command line in-process: (exit status, stdout, stderr); nothing may escape it."""
    out, err = io.StringIO(), io.StringIO()
    with redirect_stdout(out), redirect_stderr(err):
        try:
            status = main([str(part) for part in arguments])
        except SystemExit as exit_:
            status = int(exit_.code or 0)
    return status, out.getvalue(), err.getvalue()


def one_clear_line(err: str) -> str:
    """The single stderr line of a failed command (no traceback)."""
    assert "Traceback" not in err, err
    lines = [line for line in err.strip().splitlines() if line.strip()]
    assert len(lines) == 1, err
    assert lines[0].startswith(("viscorig: ", "viscorig ")), err  # "viscorig run: error: ..."
    return lines[0]


def check_prefix(path: Path, run: str, grid_hz: np.ndarray) -> int:
    """The run holds the first N points of ``grid_hz``, no gap, no duplicate; return N."""
    with CampaignFile.open(path) as campaign:
        if run not in campaign.run_names:
            return 0
        stored = campaign.run(run)
    count = stored.points
    assert count <= grid_hz.size
    np.testing.assert_allclose(stored.frequency_hz, grid_hz[:count], rtol=0, atol=0.008)
    assert np.unique(stored.frequency_hz).size == count, "a frequency is stored twice"
    assert np.all(np.isfinite(stored.accelerance_table)), "a stored point is not finite"
    return count


def snapshot(path: Path) -> dict[str, dict[str, np.ndarray]]:
    """Every run's arrays, to check later that they are kept exactly."""
    if not path.exists():
        return {}
    with CampaignFile.open(path) as campaign:
        return {
            run.name: {"frequency_hz": run.frequency_hz, "time_s": run.time_s,
                       "accelerance_table": run.accelerance_table,
                       "accelerance_support": run.accelerance_support, "flags": run.flags}
            for run in campaign.runs()
        }


def points_lost(before: dict, after: dict) -> int:
    """Points present ``before`` that are missing or changed ``after`` (must be 0)."""
    lost = 0
    for name, columns in before.items():
        count = columns["frequency_hz"].size
        if name not in after:
            lost += count
            continue
        kept = after[name]
        same = np.ones(count, dtype=bool)
        for key, values in columns.items():
            later = kept[key][:count]
            if later.size < count:
                same[later.size:] = False
                later = np.resize(later, count)
            same &= (later == values) | (np.isnan(later) & np.isnan(values)) \
                if values.dtype.kind in "fc" else later == values
        lost += int(count - same.sum())
    return lost


class DelayedFaults(FaultInjector):
    """Fault injection armed only when the analyser starts its ``after_sweeps + 1``-th sweep,
    so that ``after_sweeps`` segments are committed before the fault.

    Only segment sweeps count: the runner's force probe before a newly mounted run measures
    single points in manual sweep mode (``SWE:MODE MAN``), which are not segments."""

    def __init__(self, analyser, fault: Fault, after_sweeps: int) -> None:
        super().__init__(analyser)
        self.delayed = fault
        self.after_sweeps = after_sweeps
        self.sweeps = 0
        self.manual = False

    def take(self, message: str) -> set[str]:
        upper = message.upper()
        if "SWE:MODE MAN" in upper or "SWE:MODE AUTO" in upper:
            self.manual = "SWE:MODE MAN" in upper
        if "INIT" in upper and ":IMM" in upper and not self.manual:
            self.sweeps += 1
            if self.sweeps == self.after_sweeps + 1 and self.delayed is not None:
                fault, self.delayed = self.delayed, None
                self.add(fault)
        return super().take(message)
