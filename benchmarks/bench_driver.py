"""Reading an 801-point complex trace: REAL,64 against ASCII, and the cost of one query.

Runs the driver against the simulated analyser over loopback (raw socket and Prologix), or, if
the simulator is not installed, against the scripted endpoint. Prints time and bytes per read and
the ratios ASCII / REAL,64 measured in the same process.
"""

from __future__ import annotations

import contextlib
import statistics
import time

import numpy as np
from agilent35670a import Agilent35670A

REPEATS = 30
INPUTS = [(1, "N", 0.01124), (2, "M/S2", 0.0102), (3, "N", 0.01124), (4, "M/S2", 0.0102)]


def timed(action, repeats: int = REPEATS) -> float:
    """Median wall time of ``action`` in seconds."""
    samples = []
    for _ in range(repeats):
        started = time.perf_counter()
        action()
        samples.append(time.perf_counter() - started)
    return statistics.median(samples)


def bench(analyser: Agilent35670A, label: str) -> None:
    rows = {}
    for data_format in ("REAL,64", "ASC,12"):
        analyser.set_data_format(data_format)
        analyser.configure("CALC1:FEED 'XFR:POW:RAT 2,1';*WAI")
        analyser.configure("TRAC:DATA D1,TRAC1")
        values = analyser.read_values("TRAC:DATA? D1")
        assert values.size == 2 * 801, values.size
        before = analyser.connection.bytes_read
        seconds = timed(lambda: analyser.read_values("TRAC:DATA? D1"))
        size = (analyser.connection.bytes_read - before) / REPEATS
        rows[data_format] = (seconds, size)
        print(f"{label:9s} {data_format:8s} {seconds * 1e3:8.2f} ms  {size:9.0f} bytes")
    query = timed(lambda: analyser.ask("*IDN?"), 200)
    print(f"{label:9s} one query (*IDN?) {query * 1e3:8.3f} ms")
    (t_bin, b_bin), (t_asc, b_asc) = rows["REAL,64"], rows["ASC,12"]
    print(
        f"{label:9s} ASCII / REAL,64: time x{t_asc / t_bin:.2f}, bytes x{b_asc / b_bin:.2f}; "
        f"REAL,64 read = {t_bin / query:.1f} queries"
    )


def with_simulator() -> bool:
    try:
        from rigsim.rigfile import load_preset
        from rigsim.server import SimulatedAnalyserServer
    except ImportError:
        return False
    for prologix in (False, True):
        with SimulatedAnalyserServer(load_preset("soft-0"), prologix=prologix, seed=1) as server:
            adapter = server.interface_resource if prologix else None
            with Agilent35670A.open(server.resource, adapter=adapter) as analyser:
                analyser.configure_swept_sine(
                    inputs=INPUTS, reference_channel=4, reference_level_eu=2.0,
                    source_limit_vpk=2.0, settle_cycles=1, integrate_cycles=1,
                )
                analyser.measure(10.0, 210.0, poll_interval_s=0.01)
                bench(analyser, "prologix" if prologix else "socket")
    return True


def with_scripted_endpoint() -> None:
    from agilent35670a.scripted import ScriptedSCPIServer

    values = np.linspace(-1.0, 1.0, 2 * 801) * np.pi
    payload = values.astype(">f8").tobytes()
    block = b"#" + str(len(str(len(payload)))).encode() + str(len(payload)).encode() + payload
    text = ",".join(f"{v:+.12E}" for v in values)
    for prologix in (False, True):
        server = ScriptedSCPIServer({"*IDN?": "HP,35670A,0,A"}, prologix=prologix)

        def trace(message: str, server: ScriptedSCPIServer = server) -> str | bytes:
            formats = [c for c in server.received if c.startswith("FORM ")]
            return text if formats[-1].startswith("FORM ASC") else block + b"\n"

        server.replies["TRAC:DATA? D1"] = trace
        with server, contextlib.closing(
            Agilent35670A.open(server.adapter or server.resource)
        ) as analyser:
            bench(analyser, "scripted-prologix" if prologix else "scripted")


if __name__ == "__main__":
    import sys

    if "--scripted" in sys.argv or not with_simulator():
        with_scripted_endpoint()
