"""Helpers of the bench tests: a small sequence for the embedded simulated rig, a bench server
on loopback in this process, and waiting for its state."""

from __future__ import annotations

import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import httpx
import rigsim.server  # noqa: F401 (the simulated analyser's imports, once, at collection)

from viscorig.bench import BenchService
from viscorig.bench.app import BenchServer


def soft_sweep_sequence(name: str, stop_hz: float, segment_points: int = 8) -> str:
    """One prompt that mounts the soft specimens, then one sweep of run ``soft-0`` from 20 Hz to
    ``stop_hz`` every 0.25 Hz, in segments of ``segment_points``."""
    return f"""
name = "{name}"
[[steps]]
type = "prompt"
message = "Mount the soft specimens."
simulated_rig = "soft-0"
[[steps]]
type = "sweep"
run = "soft-0"
specimen = "soft"
hardness_shore_a = 25
band_hz = [20.0, {stop_hz}]
resolution_hz = 0.25
settle_cycles = 20
integrate_cycles = 20
level = "1 m/s^2"
segment_points = {segment_points}
"""


#: 81 points in segments of 8.
SMALL_SEQUENCE = soft_sweep_sequence("small", 40.0)

#: An adaptive plan of the bare table (12-28 Hz, K_s to 1e-4).
ADAPTIVE_TABLE_SEQUENCE = """
name = "adaptive-pause"
[[steps]]
type = "prompt"
message = "Remove the damper device."
simulated_rig = "table"
[[steps]]
type = "sweep"
run = "table"
specimen = "none"
band_hz = [12.0, 28.0]
level = "1 m/s^2"
plan = "adaptive"
model = "table"
target_uncertainty = { K_s = 1e-4 }
"""


def configure_soft_sweep(analyser: Any) -> None:
    """Set a driver's analyser up for a 20-30 Hz swept sine every 0.25 Hz (soft-0's wiring:
    forces on inputs 1 and 3, accelerations on 2 and 4, held at 1 m/s^2 on input 4)."""
    analyser.configure_swept_sine(
        inputs=[(1, "N", 0.01), (2, "M/S2", 0.01), (3, "N", 0.01), (4, "M/S2", 0.01)],
        reference_channel=4, reference_level_eu=1.0, source_limit_vpk=2.0,
        input_limit_eu=None, pairing="PAIR", resolution_hz=0.25, start_hz=20.0,
        stop_hz=30.0, settle_cycles=20, integrate_cycles=20, direction="UP",
        tolerance_db=1.0, start_level_vpk=0.1)


def small_sequence(folder: Path) -> Path:
    path = folder / "small.toml"
    path.write_text(SMALL_SEQUENCE)
    return path


def wait_until(condition: Callable[[], Any], timeout_s: float = 30.0, what: str = "",
               poll_s: float = 0.05) -> Any:
    """Poll ``condition`` until it is truthy; return its value."""
    deadline = time.monotonic() + timeout_s
    while True:
        value = condition()
        if value:
            return value
        if time.monotonic() > deadline:
            raise AssertionError(f"not within {timeout_s:g} s: {what}")
        time.sleep(poll_s)


class Client:
    """A script's client of the bench's JSON API (Bearer token, its own client name)."""

    def __init__(self, server: BenchServer, name: str = "script") -> None:
        self.http = httpx.Client(base_url=server.base, timeout=10.0, headers={
            "Authorization": f"Bearer {server.token}", "X-Bench-Client": name})

    def state(self) -> dict[str, Any]:
        answer = self.http.get("/api/state")
        assert answer.status_code == 200, answer.text
        return answer.json()

    def post(self, path: str, body: dict | None = None) -> httpx.Response:
        return self.http.post(path, json=body) if body is not None else self.http.post(path)

    def close(self) -> None:
        self.http.close()


def bench_server(folder: Path, **service: Any) -> BenchServer:
    """A bench server on a free loopback port, serving files of ``folder`` (started)."""
    return BenchServer(BenchService(root=folder, **service)).start()
