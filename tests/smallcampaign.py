"""A small simulated campaign for tests that start, kill and resume ``viscorig`` processes, and
the peak memory of a ``viscorig`` child process.

The campaign: a bare-table run, the table's identification, and one specimen run, in segments
of 8 points (about 1.5 s of wall time at full speed on the embedded simulated rig).
"""

from __future__ import annotations

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


#: Runs the command and reports its peak memory from a small process of its own: a child's
#: ``ru_maxrss`` starts from the size of the process that forked it (its memory until ``exec``),
#: and a test runner can be larger than the bound itself.
_MEASURE = """
import os, subprocess, sys
process = subprocess.Popen(sys.argv[1:], stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
err = process.stderr.read()
_, status, usage = os.wait4(process.pid, 0)
sys.stderr.buffer.write(err)
print(os.waitstatus_to_exitcode(status), usage.ru_maxrss)
"""


def peak_rss_mb(arguments: list[str]) -> tuple[int, float, str]:
    """Run ``viscorig ARGUMENTS`` in a child process: (exit status, peak resident memory in
    MB, stderr), the memory from ``wait4`` (``ru_maxrss``, KiB on Linux)."""
    measured = subprocess.run([sys.executable, "-c", _MEASURE, sys.executable, "-m", "viscorig",
                               *arguments], capture_output=True, text=True, check=True)
    status, kib = measured.stdout.split()
    return int(status), int(kib) / 1024, measured.stderr
