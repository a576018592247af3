"""The source is ramped down, not cut, when a sweep stops: the driver sets the 35670A's source
ramp rate (``SOUR:VOLT:SLEW``) with the swept sine, and the simulated analyser's source output
falls at that rate to 0 after ``ABOR`` (a pause at a point, an abort) and at a sweep's end, the
rig being driven through the ramp."""

from __future__ import annotations

import threading
import time

import numpy as np
import pytest
from agilent35670a import Agilent35670A, MeasurementAborted, SettingOutOfRange
from rigsim.rigfile import load_preset
from rigsim.server import SimulatedAnalyserServer
from test_driver_35670a_protocol import Analyser, configured

INPUTS = [(1, "N", 0.01), (2, "M/S2", 0.01), (3, "N", 0.01), (4, "M/S2", 0.01)]
#: Simulated seconds per wall second: a point of 20 + 20 cycles near 20 Hz takes about 35 ms.
PACE = 60.0
#: Slow enough that the ramp of a few tenths of a volt lasts over a hundred milliseconds of wall
#: time: a sampler held off for 50 ms by a loaded machine still sees it fall.
SLEW_V_PER_S = 0.02


def test_the_slew_rate_is_sent_after_the_limit_and_before_the_level() -> None:
    with Analyser() as server:
        analyser = configured(server, source_slew_v_per_s=20.0)
        steps = [c for c in server.received if "?" not in c]
        sent = steps.index("SOUR:VOLT:SLEW 20 V/S")
        assert steps[sent - 1] == "SOUR:VOLT:LIM 1.5 VPK" and steps[sent + 1] == "SOUR:VOLT 0.1 VPK"
        assert "SOUR:VOLT:SLEW?" in server.received[server.received.index("SOUR:VOLT:AUTO ON"):]
        assert analyser.source_ramp_down_s() == pytest.approx(1.5 / 20.0)
        analyser.close()


@pytest.mark.parametrize("slew", [-1.0, 10001.0])
def test_a_slew_rate_out_of_range_is_refused_before_anything_is_sent(slew: float) -> None:
    with Analyser() as server:
        with pytest.raises(SettingOutOfRange, match="V/s"):
            configured(server, source_slew_v_per_s=slew)
        assert not any(c.startswith(("INST:SEL ", "SOUR")) for c in server.received)


def test_without_a_slew_rate_there_is_no_ramp_to_wait_for() -> None:
    with Analyser() as server:
        analyser = configured(server, source_slew_v_per_s=0.0)
        assert "SOUR:VOLT:SLEW 0 V/S" in server.received
        assert analyser.source_ramp_down_s() == 0.0
        analyser.close()


class Sampler:
    """Reads the simulated source's output level every millisecond in a thread (bounded to
    ``limit_s``)."""

    def __init__(self, server: SimulatedAnalyserServer, limit_s: float = 4.0) -> None:
        self.server = server
        self.samples: list[tuple[float, float]] = []
        self.stop = threading.Event()
        self.limit_s = limit_s
        self.thread = threading.Thread(target=self._run, daemon=True)

    def _run(self) -> None:
        end = time.monotonic() + self.limit_s
        while not self.stop.is_set() and time.monotonic() < end:
            self.samples.append((time.monotonic(), self.server.analyser.source_output_vpk))
            time.sleep(0.001)

    def __enter__(self) -> Sampler:
        self.thread.start()
        return self

    def __exit__(self, *exc: object) -> None:
        self.stop.set()
        self.thread.join()

    def ramp(self) -> tuple[float, np.ndarray, np.ndarray]:
        """The first fall to 0 after the source drove: (level it fell from, times and levels
        from the last sample at that level to the first at 0)."""
        levels = np.array([v for _, v in self.samples])
        times = np.array([t for t, _ in self.samples])
        driving = int(np.argmax(levels > 0.0))
        assert levels[driving] > 0.0, "the source never drove"
        zero = driving + int(np.argmax(levels[driving:] == 0.0))
        assert levels[zero] == 0.0, "the source never came back to 0"
        start = zero
        while start > 0 and levels[start - 1] > levels[start]:  # strictly falling: the ramp
            start -= 1
        return float(levels[start]), times[start:zero + 1], levels[start:zero + 1]


def _open(server: SimulatedAnalyserServer) -> Agilent35670A:
    analyser = Agilent35670A.open(server.socket_resource, timeout_s=5.0)
    analyser.configure_swept_sine(
        inputs=INPUTS, reference_channel=4, reference_level_eu=1.0, source_limit_vpk=2.0,
        input_limit_eu=None, pairing="PAIR", resolution_hz=0.25, start_hz=20.0, stop_hz=30.0,
        settle_cycles=20, integrate_cycles=20, direction="UP", tolerance_db=1.0,
        start_level_vpk=0.1, source_slew_v_per_s=SLEW_V_PER_S)
    return analyser


def _check_ramp(level: float, times: np.ndarray, levels: np.ndarray) -> None:
    """The level falls linearly at the slew rate (on the paced clock) from ``level`` to 0."""
    assert level > 0.05
    rate = SLEW_V_PER_S * PACE  # volts per wall second
    falling = (levels > 0.05 * level) & (levels < 0.95 * level)
    assert falling.sum() >= 10  # seen on the way down: not a jump
    slope = np.polyfit(times[falling], levels[falling], 1)[0]
    assert slope == pytest.approx(-rate, rel=0.15)
    assert levels[-1] == 0.0
    assert times[-1] - times[0] == pytest.approx(level / rate, rel=0.25, abs=0.005)


def test_on_a_pause_at_a_point_the_source_falls_at_the_slew_rate(monkeypatch) -> None:
    with SimulatedAnalyserServer(load_preset("soft-0"), pace=PACE) as server:
        simulator = server.analyser.simulator
        requests: list = []
        sweep = simulator.sweep
        monkeypatch.setattr(simulator, "sweep", lambda r: (requests.append(r), sweep(r))[1])
        analyser = _open(server)
        try:
            asked: list[float] = []

            def progress(report) -> None:
                if report.elapsed_s > 0.12 and not asked:
                    asked.append(time.monotonic())
                    analyser.end_after_point()

            with Sampler(server) as sampler:
                cut = analyser.measure(20.0, 24.0, progress=progress)
                time.sleep(0.02 + analyser.source_ramp_down_s() / PACE)
            assert cut.ended_early and 0 < len(cut) < 17
            level, times, levels = sampler.ramp()
            _check_ramp(level, times, levels)
            # the rig was driven through the ramp: falling fixed levels at the last frequency
            ramp = [r for r in requests if not r.control.auto_level]
            assert len(ramp) == 8
            steps = np.array([r.control.source_vpk for r in ramp])
            assert np.all(np.diff(steps) < 0) and steps[0] < level < steps[0] * 1.1
            assert all(r.frequency_hz[0] == cut.frequency_hz[-1] or
                       r.frequency_hz[0] == cut.frequency_hz[-1] + 0.25 for r in ramp)
            total_s = sum(float(r.integrate_s[0] + r.settle_s[0]) for r in ramp)
            assert total_s == pytest.approx(level / SLEW_V_PER_S, rel=1e-6)
        finally:
            analyser.close()


def test_at_the_end_of_a_sweep_and_on_an_abort_the_source_ramps_down_too() -> None:
    with SimulatedAnalyserServer(load_preset("soft-0"), pace=PACE) as server:
        analyser = _open(server)
        try:
            with Sampler(server) as sampler:
                analyser.measure(20.0, 21.0)  # five points, ended by the sweep itself
                time.sleep(0.02 + analyser.source_ramp_down_s() / PACE)
            _check_ramp(*sampler.ramp())

            def abort(report) -> None:
                if report.elapsed_s > 0.1:
                    analyser.abort()

            with Sampler(server) as sampler:
                with pytest.raises(MeasurementAborted):
                    analyser.measure(20.0, 24.0, progress=abort)
                time.sleep(0.02 + analyser.source_ramp_down_s() / PACE)
            _check_ramp(*sampler.ramp())
        finally:
            analyser.close()
