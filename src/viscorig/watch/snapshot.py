"""What the live view shows, read from the committed state of a campaign file.

The file is opened read-only through :class:`viscorig.storage.CampaignFile`, only when it changed
(its size, time or inode), and never more than :data:`MIN_READ_INTERVAL_S` apart. A writer
commits by replacing the file whole, so every reading is one committed state, and a reader
never holds the file between readings: watching takes nothing from the measurement, whichever
process writes the file.

The planned points, the requested levels and the time left come from the sequence the campaign
runs (stored in the file); the force limit from the station file when there is one, else from
the run's own record of the limits it ran under.
"""

from __future__ import annotations

import contextlib
import math
import threading
import time
from collections.abc import Iterable
from pathlib import Path
from typing import Any

import h5py
import numpy as np
from numpy.typing import NDArray

from viscorig.errors import InputError
from viscorig.sequences import (
    Sequence,
    SweepStep,
    TemperatureStep,
    WaitStep,
    parse_sequence,
    parse_station,
    time_left_s,
)
from viscorig.storage import CampaignFile, RunRecord, writelock

#: Readings of a changing file are at least this far apart, s.
MIN_READ_INTERVAL_S = 0.5
#: A running run on a real rig with no commit for this many segments' worth of time is shown as
#: stalled (the page compares with the time of the last commit).
STALL_SEGMENTS = 3.0
#: Run attributes the runner writes that the live view shows (the limits a run ran under).
LIMIT_ATTRIBUTES = ("shaker_force_limit_n", "requested_level_m_per_s2", "tolerance_db",
                    "segment_s")


def _values(array: NDArray[Any], digits: int = 6) -> list[float | None]:
    """A JSON list: finite values rounded to ``digits`` significant digits, None elsewhere."""
    values = np.asarray(array, dtype=float)
    finite = np.isfinite(values)
    rounded = np.zeros_like(values)
    nonzero = finite & (values != 0)
    scale = 10.0 ** (digits - 1 - np.floor(np.log10(np.abs(values[nonzero]))))
    rounded[nonzero] = np.round(values[nonzero] * scale) / scale
    return [float(v) if ok else None for v, ok in zip(rounded, finite, strict=True)]


def _number(value: float) -> float | None:
    return float(value) if math.isfinite(value) else None


def _limits(path: Path, names: Iterable[str]) -> dict[str, dict[str, float]]:
    """The limits each run recorded when it started (read-only; empty when unreadable)."""
    found: dict[str, dict[str, float]] = {}
    try:
        with h5py.File(path, "r") as h5:
            runs = h5.get("runs")
            for name in names:
                group = runs.get(name) if isinstance(runs, h5py.Group) else None
                if not isinstance(group, h5py.Group):
                    continue
                found[name] = {
                    key: float(group.attrs[key]) for key in LIMIT_ATTRIBUTES
                    if key in group.attrs and np.ndim(group.attrs[key]) == 0
                    and np.asarray(group.attrs[key]).dtype.kind in "fi"
                }
    except (OSError, KeyError, ValueError, TypeError):
        return {}
    return found


def _run_state(run: RunRecord, step: SweepStep | None, limits: dict[str, float],
               station_limit_n: float | None) -> dict[str, Any]:
    metadata = run.metadata
    if step is not None and step.adaptive:  # its points in any order: drawn by frequency
        run = run.select(np.argsort(run.frequency_hz, kind="stable"))
    table = run.accelerance_table
    support = run.accelerance_support
    grid = step is not None and not step.adaptive  # an adaptive plan chooses its points
    planned = step.points if step is not None and grid else run.points
    left = (time_left_s(step.frequencies_hz(), run.points, *step.full_plan()[1:])
            if step is not None and grid and run.points <= planned else 0.0)
    force_limit = limits.get("shaker_force_limit_n", station_limit_n or math.nan)
    requested = limits.get("requested_level_m_per_s2",
                           step.level_m_per_s2 if step is not None else math.nan)
    tolerance = limits.get("tolerance_db", step.tolerance_db if step is not None else math.nan)
    with np.errstate(divide="ignore", invalid="ignore"):
        return {
            "name": run.name,
            "status": metadata.status,
            "specimen": metadata.specimen,
            "bare_table": metadata.specimen == "none",
            "points": run.points,
            "planned": planned,
            "flagged": int(np.count_nonzero(run.flags)),
            "level_m_per_s2": _number(metadata.level_m_per_s2),
            "requested_level_m_per_s2": _number(requested),
            "tolerance_db": _number(tolerance),
            "force_limit_n": _number(force_limit),
            "direction": metadata.direction,
            "simulated": bool(metadata.simulated),
            "segment_s": limits.get("segment_s", step.segment_s if step is not None else 60.0),
            "band_hz": list(step.band_hz) if step is not None else None,
            "left_s": left if metadata.status == "running" else 0.0,
            "frequency_hz": _values(run.frequency_hz, 9),
            "table_magnitude": _values(np.abs(table)),
            "table_phase_deg": _values(np.degrees(np.angle(table)), 5),
            "support_magnitude": _values(np.abs(support)),
            "support_phase_deg": _values(np.degrees(np.angle(support)), 5),
            "reference_m_per_s2": _values(run.reference_amplitude),
            "force_n": _values(run.force_amplitude),
            "flags": [int(flag) for flag in run.flags],
        }


def _soaks_left(campaign: CampaignFile, sequence: Sequence, after: int) -> float:
    """Predicted time of the soaks after step ``after`` (the last sweep started), s: the
    station's chamber where the file holds a station, else the forecast's defaults."""
    keywords: dict = {}
    if campaign.station_text is not None:
        with contextlib.suppress(InputError):
            chamber = parse_station(campaign.station_text, source="station").chamber
            keywords = {} if chamber is None else chamber.soak_forecast()
    temperature = keywords.pop("chamber_start_c", 25.0)
    left = 0.0
    for index, step in enumerate(sequence.steps):
        if isinstance(step, TemperatureStep):
            if index > after:
                left += step.duration_s(temperature, **{
                    "specimen_time_constant_s": 600.0, **keywords})
            temperature = step.set_point_c
    return left


def _station_limit(campaign: CampaignFile) -> float | None:
    text = campaign.station_text
    if text is None:
        return None
    try:
        return parse_station(text, source="station").shaker_force_limit_n
    except InputError:
        return None


def _sequence(campaign: CampaignFile) -> Sequence | None:
    text = campaign.sequence_text
    if text is None:
        return None
    try:
        return parse_sequence(text, source="sequence")
    except InputError:
        return None


def read_snapshot(path: Path) -> dict[str, Any]:
    """The live view's state of a campaign file, as JSON-ready data.

    Raises
    ------
    InputError
        The file cannot be read as a campaign (missing, damaged, not a campaign).
    """
    campaign = CampaignFile.open(path, "r")
    stat = path.stat()
    sequence = _sequence(campaign)
    steps = {step.run: step for step in sequence.sweeps} if sequence is not None else {}
    station_limit = _station_limit(campaign)
    names = campaign.run_names
    limits = _limits(path, names)
    runs = [_run_state(campaign.run(name), steps.get(name), limits.get(name, {}),
                       station_limit) for name in names]
    by_name = {run["name"]: run for run in runs}
    to_come = [step for step in (sequence.sweeps if sequence is not None else ())
               if step.run not in by_name]
    waits = [step for step in (sequence.steps if sequence is not None else ())
             if isinstance(step, WaitStep)]
    left = sum(run["left_s"] for run in runs) + sum(step.duration_s() for step in to_come
                                                    if not step.adaptive)
    if to_come and sequence is not None:
        first_to_come = sequence.steps.index(to_come[0])
        left += sum(step.seconds for step in waits if sequence.steps.index(step) > first_to_come)
        started = [sequence.steps.index(step) for step in sequence.sweeps
                   if step.run in by_name]
        left += _soaks_left(campaign, sequence, max(started, default=-1))
    simulated = bool(runs) and runs[-1]["simulated"]
    current = next((run for run in runs if run["status"] == "running"), None)
    state, detail = _campaign_state(runs, current, to_come)
    if current is not None and not writelock.writer_may_hold(path):
        # a run left "running" by a writer that is gone (killed, crashed, the power cut)
        state, detail = "stopped", (
            f"run '{current['name']}' was interrupted after {current['points']} of "
            f"{current['planned']} points and no writer holds the file: continue with "
            "viscorig resume")
    return {
        "file": path.name,
        "sequence": sequence.name if sequence is not None else "",
        "simulated": simulated,
        "clock": "test time" if simulated else "time",
        "state": state,
        "detail": detail,
        "current": current["name"] if current else (runs[-1]["name"] if runs else None),
        "time_left_s": left if sequence is not None else None,
        "committed": stat.st_mtime,
        "stall_after_s": (STALL_SEGMENTS * max(current["segment_s"], 20.0)
                          if current is not None and not simulated else None),
        "runs": runs,
        "to_come": [{"name": step.run, "specimen": step.specimen,
                     "planned": None if step.adaptive else step.points,
                     "band_hz": list(step.band_hz)} for step in to_come],
    }


def _campaign_state(runs: list[dict[str, Any]], current: dict[str, Any] | None,
                    to_come: list[SweepStep]) -> tuple[str, str]:
    """(state, one line for the operator). The page adds "stalled" when a running run has
    committed nothing for ``stall_after_s``."""
    if current is not None:
        return "measuring", (f"measuring run '{current['name']}': {current['points']} of "
                             f"{current['planned']} points")
    aborted = next((run for run in runs if run["status"] == "aborted"), None)
    if aborted is not None:
        return "stopped", (f"run '{aborted['name']}' stopped after {aborted['points']} points "
                           "(kept); continue with viscorig resume")
    if to_come:
        return "between runs", (f"next: run '{to_come[0].run}' (at a prompt, probing, or "
                                "identifying the table)")
    if not runs:
        return "complete", "the file holds no sweep run"
    return "complete", "every run of the sequence is complete"


class Snapshots:
    """The latest snapshot of a file, read again only when the file changed.

    Thread-safe: the web server's threads share it, and at most one of them reads at a time.
    """

    def __init__(self, path: str | Path) -> None:
        self.path = Path(path)
        self._lock = threading.Lock()
        self._key: tuple[int, int, int] | None = None
        self._snapshot: dict[str, Any] | None = None
        self._version = 0
        self._read_at = 0.0
        self.error: str | None = None

    def latest(self) -> tuple[int, dict[str, Any] | None]:
        """(version, snapshot); the version grows each time a changed file was read."""
        with self._lock:
            now = time.monotonic()
            if now - self._read_at < MIN_READ_INTERVAL_S and self._snapshot is not None:
                return self._version, self._snapshot
            try:
                stat = self.path.stat()
            except OSError as error:
                self.error = f"{self.path}: {error.strerror or error}"
                return self._version, self._snapshot
            key = (stat.st_mtime_ns, stat.st_size, stat.st_ino)
            if key != self._key:
                try:
                    self._snapshot = read_snapshot(self.path)
                except InputError as error:
                    self.error = str(error)  # a damaged file: keep what was shown, say why
                else:
                    self._key, self.error = key, None
                    self._version += 1
                self._read_at = now
            else:
                self._read_at = now
            return self._version, self._snapshot
