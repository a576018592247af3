"""Start ``viscorig sim serve`` as a separate process and find its resources (for tests)."""

from __future__ import annotations

import re
import signal
import subprocess
import sys
from collections.abc import Iterator
from contextlib import contextmanager


@contextmanager
def sim_serve(*args: str) -> Iterator[tuple[subprocess.Popen, str, str, int]]:
    """The running server: (process, host, raw socket resource, raw socket port)."""
    code = "import sys; from viscorig.cli import main; sys.exit(main(sys.argv[1:]))"
    process = subprocess.Popen([sys.executable, "-c", code, "sim", "serve", *args],
                               stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        resource = ""
        for _ in range(20):
            line = process.stdout.readline()
            found = re.search(r"TCPIP::(\S+)::(\d+)::SOCKET", line)
            if found:
                resource = found.group(0)
                break
        assert resource, "sim serve printed no socket resource"
        yield process, found.group(1), resource, int(found.group(2))
    finally:
        process.send_signal(signal.SIGINT)
        try:
            process.wait(10)
        except subprocess.TimeoutExpired:
            process.kill()
            process.wait(5)


def rss_kib(pid: int) -> int:
    """Resident set size of a process, KiB (Linux)."""
    with open(f"/proc/{pid}/status", encoding="ascii") as status:
        for line in status:
            if line.startswith("VmRSS:"):
                return int(line.split()[1])
    raise RuntimeError("no VmRSS")
