"""The 35670A driver against the simulated analyser, over loopback through pyvisa-py.

Both paths a lab uses: the raw SCPI socket and a Prologix GPIB-Ethernet adapter.
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

server_module = pytest.importorskip("rigsim.server")
rigfile = pytest.importorskip("rigsim.rigfile")

SENSITIVITIES = {1: 0.01124, 2: 0.0102, 3: 0.01124, 4: 0.0102}  # the soft-0 preset's sensors
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


def configure(analyser: Agilent35670A, cycles: float = 20.0) -> None:
    analyser.configure_swept_sine(
        sensitivities_v_per_eu=SENSITIVITIES,
        level_m_per_s2=LEVEL_M_PER_S2,
        source_limit_vpk=2.0,
        force_limit_n=90.0,
        settle_cycles=cycles,
        integrate_cycles=cycles,
    )


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


def test_real64_and_ascii_reads_of_the_same_trace_agree(server) -> None:
    with connect(server) as analyser:
        configure(analyser, cycles=5)
        analyser.measure(30.0, 31.0, poll_interval_s=0.01)
        axis, binary = analyser.read_trace("XFR:POW:RAT 2,1", with_axis=True)
        analyser.set_data_format("ASC,12")
        axis_text, text = analyser.read_trace("XFR:POW:RAT 2,1", with_axis=True)
    np.testing.assert_allclose(axis_text, axis, rtol=1e-11)
    np.testing.assert_allclose(text, binary, rtol=1e-10)


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
            analyser.spacing = "LIN"
    assert caught.value.code == -310
    assert "hardware fault" in caught.value.text
    assert caught.value.command == "SWE:SPAC LIN"


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
            analyser.spacing = "LIN"


@pytest.mark.parametrize("action", ["abort", "pause"])
def test_pause_resume_and_abort_a_running_sweep(action: str) -> None:
    rig = rigfile.load_preset("soft-0")
    with (
        server_module.SimulatedAnalyserServer(rig, pace=1.0, seed=3) as server,
        connect(server) as analyser,
    ):
        configure(analyser, cycles=3)  # 5 points of 6 cycles at 20 Hz: about 1.5 s paced
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
            with pytest.raises(MeasurementAborted):
                analyser.measure(20.0, 21.0, progress=steer, poll_interval_s=0.05)
            assert time.time() - started < 1.2
            # the analyser is idle again: the next segment runs
            assert len(analyser.measure(20.0, 20.5, poll_interval_s=0.05)) == 3
        else:
            segment = analyser.measure(20.0, 21.0, progress=steer, poll_interval_s=0.05)
            assert len(segment) == 5 and pauses
            # about 1.5 s of paced sweep plus the 0.5 s pause
            assert time.time() - started > 1.9


def test_a_single_point_in_manual_mode_matches_the_swept_value(server) -> None:
    with connect(server) as analyser:
        configure(analyser, cycles=10)
        point = analyser.measure_point(33.25, poll_interval_s=0.01)
        band = analyser.measure(33.0, 33.5, poll_interval_s=0.01)
        commands_ok = analyser.sweep_mode == "AUTO"
    np.testing.assert_array_equal(point.frequency_hz, [33.25])
    assert point.frf_21.shape == point.frf_43.shape == (1,)
    np.testing.assert_allclose(point.frf_21, band.frf_21[1:2], rtol=0.05)
    assert commands_ok
