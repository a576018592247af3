"""A small simulated campaign for tests that start, kill and resume ``viscorig`` processes, and
the peak memory of a ``viscorig`` child process.

The campaign: a bare-table run, the table's identification, and one specimen run, in segments
of 8 points (about 1.5 s of wall time at full speed on the embedded simulated rig).
"""

from __future__ import annotations

import os
import subprocess
import sys

import numpy as np

SEQUENCE = """
name = "crash"
[defaults]
resolution_hz = 0.25
settle_cycles = 20
integrate_cycles = 20
level = "1 m/s^2"
segment_points = 8
[[steps]]
type = "prompt"
message = "Remove the device."
simulated_rig = "table"
[[steps]]
type = "sweep"
run = "table"
specimen = "none"
band_hz = [15.0, 25.0]
[[steps]]
type = "identify_table"
run = "table"
[[steps]]
type = "prompt"
message = "Mount the soft specimens."
simulated_rig = "soft-0"
[[steps]]
type = "sweep"
run = "soft-0"
specimen = "soft"
band_hz = [20.0, 60.0]
"""
#: The frequency grid of each run of :data:`SEQUENCE`.
GRIDS = {"table": 15.0 + 0.25 * np.arange(41), "soft-0": 20.0 + 0.25 * np.arange(161)}


def peak_rss_mb(arguments: list[str]) -> tuple[int, float, str]:
    """Run ``viscorig ARGUMENTS`` in a child process: (exit status, peak resident memory in
    MB, stderr), the memory from ``wait4`` (``ru_maxrss``, KiB on Linux)."""
    process = subprocess.Popen([sys.executable, "-m", "viscorig", *arguments],
                               stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
    err = process.stderr.read() if process.stderr else ""
    _, status, usage = os.wait4(process.pid, 0)
    process.returncode = os.waitstatus_to_exitcode(status)
    return process.returncode, usage.ru_maxrss / 1024, err
