"""The 35670A driver against the simulated analyser, over loopback through pyvisa-py.

Both paths a lab uses: the raw SCPI socket and a Prologix GPIB-Ethernet adapter, and a long
paced sweep behind the adapter with a short adapter read time-out (the adapter's ``++read``
waits exactly ``++read_tmo_ms``), an auto-calibration in the middle, and a VISA time-out far
shorter than the sweep.
"""

from __future__ import annotations

import time

import numpy as np
import pytest
from agilent35670a import (
    Agilent35670A,
    InstrumentTimeout,
    MeasurementAborted,
    SCPIError,
)
from agilent35670a.connection import PROLOGIX_READ_TIMEOUT_MS
from agilent35670a.swept_sine import round_down

server_module = pytest.importorskip("rigsim.server")
rigfile = pytest.importorskip("rigsim.rigfile")
faults = pytest.importorskip("rigsim.faults")

#: The paper's station: forces (N) on inputs 1 and 3, accelerations (m/s²) on 2 and 4.
INPUTS = [(1, "N", 0.01124), (2, "M/S2", 0.0102), (3, "N", 0.01124), (4, "M/S2", 0.0102)]
LEVEL_M_PER_S2 = 2.0


@pytest.fixture(params=["socket", "prologix"])
def server(request: pytest.FixtureRequest):
    rig = rigfile.load_preset("soft-0")
    prologix = request.param == "prologix"
    with server_module.SimulatedAnalyserServer(rig, prologix=prologix, seed=7) as running:
        yield running


def connect(server, timeout_s: float = 2.0) -> Agilent35670A:
    if server.interface_resource and server.resource.startswith("GPIB"):
        return Agilent35670A.open(
            server.resource, adapter=server.interface_resource, timeout_s=timeout_s
        )
    return Agilent35670A.open(server.resource, timeout_s=timeout_s)


def configure(analyser: Agilent35670A, cycles: float = 20.0, **overrides) -> None:
    settings = dict(inputs=INPUTS, reference_channel=4, reference_level_eu=LEVEL_M_PER_S2,
                    source_limit_vpk=2.0, input_limit_eu=90.0, settle_cycles=cycles,
                    integrate_cycles=cycles)
    settings.update(overrides)
    analyser.configure_swept_sine(**settings)


def test_a_segment_is_measured_and_read_consistently(server) -> None:
    with connect(server) as analyser:
        configure(analyser)
        segment = analyser.measure(20.0, 25.0, poll_interval_s=0.01)
    assert len(segment) == 21
    np.testing.assert_allclose(segment.frequency_hz, 20.0 + 0.25 * np.arange(21), atol=1e-9)
    # the controller held the disc acceleration (channel 4) within its 2 dB tolerance
    level_db = 20 * np.log10(segment.amplitude_eu[4] / LEVEL_M_PER_S2)
    assert np.all(np.abs(level_db) <= 2.0)
    # each FRF agrees with the ratio of its channels' linear spectra, read through other feeds
    np.testing.assert_allclose(
        np.abs(segment.frf_21), segment.amplitude_eu[2] / segment.amplitude_eu[1], rtol=1e-6
    )
    np.testing.assert_allclose(
        np.abs(segment.frf_43), segment.amplitude_eu[4] / segment.amplitude_eu[3], rtol=1e-6
    )
    assert all(np.all(v >= 0) and np.all(v < 1e-2) for v in segment.variance.values())
    assert segment.eu_labels == {1: "N", 2: "M/S2", 3: "N", 4: "M/S2"}
    assert segment.finished_at_s >= segment.started_at_s
    assert segment.no_data is not None and not segment.no_data.any()


def test_every_setting_is_read_back_as_sent(server) -> None:
    with connect(server) as analyser:
        configure(analyser, start_hz=20.01, stop_hz=30.0)
        # the analyser holds the start rounded down to 15.625 mHz, as the manual says
        assert analyser.sweep.start_frequency_hz == round_down(20.01) == 20.0
        assert analyser.source.reference_eu == LEVEL_M_PER_S2
        assert analyser.ask("SOUR:VOLT:REF? UNIT") == '"EU"'
        assert analyser.ask("SOUR:VOLT:LIM:INP? UNIT") == '"EU"'
        assert analyser.channel(3).transducer_label == "N"
        # a setting changed behind the driver's back is named by the read-back
        analyser.write("SWE:DWEL 7 CYCLE")
        problems = analyser.sweep.mismatches()
    assert len(problems) == 1 and "integrate_cycles" in problems[0] and "7" in problems[0]


def test_real64_and_ascii_reads_of_the_same_trace_agree(server) -> None:
    with connect(server) as analyser:
        configure(analyser, cycles=5)
        analyser.measure(30.0, 31.0, poll_interval_s=0.01)
        axis, binary = analyser.read_trace("XFR:POW:RAT 2,1", with_axis=True)
        analyser.set_data_format("ASC,12")
        axis_text, text = analyser.read_trace("XFR:POW:RAT 2,1", with_axis=True)
    assert axis.size == 5
    np.testing.assert_allclose(axis_text, axis, rtol=1e-11)
    np.testing.assert_allclose(text, binary, rtol=1e-10)


def test_an_801_point_sweep_fills_the_long_trace(server) -> None:
    with connect(server) as analyser:
        configure(analyser, cycles=1)
        segment = analyser.measure(20.0, 220.0, poll_interval_s=0.01)
    assert len(segment) == 801
    np.testing.assert_allclose(segment.frequency_hz, 20.0 + 0.25 * np.arange(801))
    assert np.all(np.isfinite(segment.frf_43))


def test_overload_is_reported_for_its_segment_only(server) -> None:
    with connect(server) as analyser:
        configure(analyser, cycles=5)
        server.faults.overload(3, points=2)
        flagged = analyser.measure(40.0, 41.0, poll_interval_s=0.01)
        clean = analyser.measure(41.0, 42.0, poll_interval_s=0.01)
    assert 3 in flagged.overload_channels
    assert 3 not in clean.overload_channels


def test_an_instrument_error_carries_code_and_text(server) -> None:
    with connect(server) as analyser:
        server.faults.error(-310, "System error; hardware fault")
        with pytest.raises(SCPIError) as caught:
            analyser.sweep.spacing = "LIN"
    assert caught.value.code == -310
    assert "hardware fault" in caught.value.text
    assert caught.value.command == "SWE:SPAC LIN"


def test_a_full_error_queue_says_errors_were_lost(server) -> None:
    with connect(server) as analyser:
        for code in range(7):  # the queue holds 5: the last entry becomes "Queue overflow"
            server.faults.error(-200 - code, f"error {code}")
        with pytest.raises(SCPIError) as caught:
            analyser.check_errors("a burst of faults")
        assert analyser.read_errors() == []
    assert caught.value.code == -200
    assert len(caught.value.others) == 4 and caught.value.others[-1][0] == -350
    assert "overflowed" in str(caught.value)


def test_a_lost_reply_to_an_idempotent_query_is_retried_once(server) -> None:
    with connect(server, timeout_s=0.5) as analyser:
        configure(analyser, cycles=5)
        server.faults.no_reply("TRAC:X?")
        segment = analyser.measure(20.0, 21.0, poll_interval_s=0.01)
    assert len(segment) == 5 and np.all(np.isfinite(segment.frf_21))


def test_a_lost_reply_to_a_clearing_query_is_not_repeated(server) -> None:
    with connect(server, timeout_s=0.5) as analyser:
        server.faults.no_reply("SYST:ERR?")
        with pytest.raises(InstrumentTimeout, match=r"'SYST:ERR\?'.*0.5 s"):
            analyser.sweep.spacing = "LIN"


def test_arbitrary_frequencies_with_their_own_timing(server) -> None:
    """The adaptive sweep's path: chosen frequencies, settle and integration per call."""
    wanted = [33.3, 20.1, 47.0, 20.1]
    with connect(server) as analyser:
        configure(analyser, cycles=10)
        points = analyser.measure_points(wanted, settle_cycles=30, integrate_cycles=40,
                                         poll_interval_s=0.01)
        assert analyser.sweep.sweep_mode == "MAN"
        assert analyser.sweep.integrate_cycles == 40.0
        band = analyser.measure(20.0, 48.0, resolution_hz=0.25, settle_cycles=30,
                                integrate_cycles=40, poll_interval_s=0.01)
    # the analyser's own axis: each frequency rounded down to 15.625 mHz, in the order asked
    np.testing.assert_allclose(points.frequency_hz, [round_down(f) for f in wanted])
    assert points.frf_21.shape == points.frf_43.shape == (4,)
    # the manual points agree with the swept values at the nearest grid frequencies
    for k, frequency in enumerate(points.frequency_hz):
        nearest = int(np.argmin(np.abs(band.frequency_hz - frequency)))
        if abs(band.frequency_hz[nearest] - frequency) < 1e-9:
            np.testing.assert_allclose(points.frf_43[k], band.frf_43[nearest], rtol=0.02)


def test_points_far_apart_and_at_the_top_frequency_keep_the_sweep_s_resolution(server) -> None:
    """A run's probe measures the band's two ends one by one. Moving the band from 20 Hz to
    2 kHz passed through 20 Hz-2 kHz, over 801 points at 1 Hz: the analyser grew its
    resolution and the driver's read-back refused the sweep as an instrument fault. At the
    top frequency the band's second point lay above the analyser's range, and 25599.984375 Hz
    was sent rounded up past it."""
    with connect(server) as analyser:
        configure(analyser, cycles=10, resolution_hz=1.0, start_hz=20.0, stop_hz=820.0)
        for frequency in (20.0, 2000.0, 25600.0, 20.0):
            point = analyser.measure_point(frequency, poll_interval_s=0.01)
            assert point.frequency_hz[0] == pytest.approx(frequency)
        assert analyser.sweep.resolution_hz == 1.0


def test_no_data_in_a_trace_becomes_nan_and_is_flagged() -> None:
    """An input that reads exactly nothing (unplugged, no noise) makes the response it divides
    by hold the analyser's no-data marker: NaN points, flagged."""
    rig = rigfile.load_preset("soft-0").noiseless()
    with server_module.SimulatedAnalyserServer(rig, seed=1) as server:
        server.faults.add(faults.parse_fault_spec("unplug=1"))
        with connect(server) as analyser:
            configure(analyser, cycles=5, reference_channel=4)
            segment = analyser.measure(30.0, 31.0, poll_interval_s=0.01)
    assert np.all(np.isnan(segment.frf_21)) and segment.no_data.all()
    assert np.all(np.isfinite(segment.frf_43))


@pytest.mark.parametrize("action", ["abort", "pause"])
def test_pause_resume_and_abort_a_running_sweep(action: str) -> None:
    rig = rigfile.load_preset("soft-0")
    with (
        server_module.SimulatedAnalyserServer(rig, pace=4.0, seed=3) as server,
        connect(server) as analyser,
    ):
        # 5 points of 6 cycles at 20 Hz plus the analyser's 0.45 s per point: 0.94 s paced
        configure(analyser, cycles=3)
        pauses: list[float] = []

        def steer(progress) -> None:
            if action == "abort" and progress.elapsed_s > 0.2:
                analyser.abort()
            elif action == "pause" and not pauses and progress.elapsed_s > 0.2:
                analyser.pause()
                pauses.append(time.time())
            elif action == "pause" and progress.paused and time.time() - pauses[0] > 0.5:
                analyser.resume()

        started = time.time()
        if action == "abort":
            with pytest.raises(MeasurementAborted):  # 41 points: about 7 s paced
                analyser.measure(20.0, 30.0, progress=steer, poll_interval_s=0.05)
            assert time.time() - started < 1.5
            assert server.analyser.wait_until_idle(1.0)  # ABOR reached the analyser
            # the analyser is idle again: the next segment runs
            assert len(analyser.measure(20.0, 20.5, poll_interval_s=0.05)) == 3
        else:
            segment = analyser.measure(20.0, 21.0, progress=steer, poll_interval_s=0.05)
            assert len(segment) == 5 and pauses
            assert time.time() - started > 1.35  # the paced sweep (0.94 s) plus the 0.5 s pause


@pytest.mark.slow
def test_a_long_sweep_behind_the_prologix_adapter_with_a_short_read_timeout() -> None:
    """About 18 minutes of instrument time (201 points of the paper's 100 + 100 cycles at
    20-70 Hz, the analyser's own time per point, an auto-calibration) paced 400 times faster,
    through the
    Prologix endpoint whose ``++read`` waits exactly its 500 ms, with a 2 s VISA time-out:
    the driver polls status and never waits on the sweep."""
    rig = rigfile.load_preset("soft-0")
    with server_module.SimulatedAnalyserServer(rig, prologix=True, pace=400.0, seed=4,
                                               read_timeout_floor_s=0.0) as server:
        with connect(server, timeout_s=2.0) as analyser:
            configure(analyser, cycles=100, start_hz=20.0, stop_hz=70.0)
            grid = 20.0 + 0.25 * np.arange(201)
            expected_s = analyser.expected_duration_s(grid)
            assert 900 < expected_s < 1200
            seen: list = []
            server.faults.autocal(":INIT:IMM")
            started = time.monotonic()
            segment = analyser.measure(20.0, 70.0, progress=seen.append, poll_interval_s=0.01)
            wall_s = time.monotonic() - started
            calibrating_s = analyser.runner.calibrating_s
        read_timeouts = [c for c in server.adapter_log if c.startswith("read_tmo_ms")]
    assert len(segment) == 201 and np.all(np.isfinite(segment.frf_43))
    assert expected_s / 400 * 0.8 < wall_s < expected_s / 400 + 20.0
    assert len(seen) > 20 and any(p.settling for p in seen) and any(p.calibrating for p in seen)
    assert calibrating_s > 0
    # pyvisa-py opens with 50 ms; the driver then sets its own short read time-out
    assert read_timeouts and int(read_timeouts[-1].split()[1]) == PROLOGIX_READ_TIMEOUT_MS
