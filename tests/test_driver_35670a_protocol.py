"""The 35670A driver against a scripted loopback SCPI endpoint, through pyvisa-py's sockets.

Pins each command the driver sends to the programming guide's syntax and checks the decoding,
validation, read-back, error and retry paths. The endpoint only records and answers canned
replies (and echoes settings back, as a compliant instrument does); the simulated analyser tests
are in ``test_driver_35670a_sim.py``.
"""

from __future__ import annotations

import numpy as np
import pytest
from agilent35670a import (
    Agilent35670A,
    InstrumentTimeout,
    MalformedReply,
    MeasurementAborted,
    MissingOption,
    SCPIError,
    SettingNotApplied,
    SettingOutOfRange,
    WrongInstrument,
)
from agilent35670a.blocks import (
    NO_DATA,
    check_values,
    decode_ascii,
    decode_real,
    interleaved_to_complex,
    split_definite_block,
)
from agilent35670a.connection import is_idempotent
from agilent35670a.scripted import ScriptedSCPIServer
from scpi_blocks import canned_trace, definite_block

IDN = "HEWLETT-PACKARD,35670A,3416A01234,A.02.01"
#: The paper's station: forces (N) on inputs 1 and 3, accelerations (m/s²) on 2 and 4.
INPUTS = [(1, "N", 0.01124), (2, "M/S2", 0.0102), (3, "N", 0.01124), (4, "M/S2", 0.0102)]
FREQUENCIES = np.array([10.0, 10.25, 10.5, 10.75, 11.0])
FRF_21 = np.array([1 + 2j, -0.5 + 0.25j, 3e-3 - 1e2j, 0.1 + 0.1j, -7.0 + 0j])


def trace_for(feed: str) -> np.ndarray:
    """Data of each feed: FRFs and linear spectra complex (interleaved), variances real."""
    return canned_trace(feed, FRF_21)


class Analyser(ScriptedSCPIServer):
    """A scripted 35670A: answers data queries from the last feed, in REAL,64 or ASCII."""

    def __init__(self, *, esr=("+0", "+0", "+1"), options='"1D2,AY6"', **kwargs) -> None:
        super().__init__(
            {
                "*IDN?": IDN,
                "*OPT?": options,
                "*ESR?": list(esr),
                "*STB?": "+32",
                "STAT:QUES:VOLT:EVEN?": ["+0", "+258"],
                "STAT:OPER:COND?": "+16",
                "TRAC:X? D1": lambda message: self.encode(FREQUENCIES),
                "TRAC:DATA? D1": lambda message: self.encode(trace_for(self.last_feed())),
            },
            defaults={"FREQ:STOP?": "+1.00000000E+002"},
            **kwargs,
        )

    def last_feed(self) -> str:
        feeds = [c for c in self.commands(0) if c.upper().startswith("CALC1:FEED")]
        return feeds[-1].split("'")[1]

    def encode(self, values: np.ndarray) -> bytes | str:
        formats = [c.upper() for c in self.commands(0) if c.upper().startswith("FORM ")]
        if formats and formats[-1].startswith("FORM ASC"):
            return ",".join(f"{v:+.12E}" for v in values)
        return definite_block(values)


def open_analyser(server: ScriptedSCPIServer, timeout_s: float = 1.0) -> Agilent35670A:
    resource = server.adapter or server.resource
    return Agilent35670A.open(resource, timeout_s=timeout_s)


def configured(server: Analyser, **overrides) -> Agilent35670A:
    analyser = open_analyser(server)
    arguments = dict(
        inputs=INPUTS,
        reference_channel=4,
        reference_level_eu=2.0,
        source_limit_vpk=1.5,
        input_limit_eu=40.0,
    )
    arguments.update(overrides)
    analyser.configure_swept_sine(**arguments)
    return analyser


# -- decoding ----------------------------------------------------------------------------------
def test_real64_and_ascii_decode_to_the_same_values() -> None:
    values = np.array([1.0, -2.5e-7, 3.25e4, 0.1, np.pi])
    from_block = decode_real(split_definite_block(definite_block(values)))
    from_ascii = decode_ascii(",".join(f"{v:+.15E}" for v in values))
    np.testing.assert_array_equal(from_block, values)
    np.testing.assert_allclose(from_ascii, values, rtol=1e-15)


@pytest.mark.parametrize(
    ("message", "complaint"),
    [
        (b"#15abc\n", "declares 5 bytes but holds 3"),
        (b"#213abc\n", "declares 13 bytes but holds 3"),
        (b"#0abc\n", "is not '#<1-9><length>'"),
        (b"+1.0,+2.0\n", "starting with '#'"),
        (b"#2x1abc\n", "is not 2 digits"),
        (b"#13abcdef\n", "unexpected bytes"),
    ],
)
def test_malformed_blocks_are_rejected_with_a_clear_message(message: bytes, complaint: str) -> None:
    with pytest.raises(MalformedReply, match=complaint):
        split_definite_block(message)


def test_bad_values_and_counts_are_rejected() -> None:
    with pytest.raises(MalformedReply, match="not a whole number of 8-byte values"):
        decode_real(b"\x00" * 12)
    with pytest.raises(MalformedReply, match="value 1 is nan"):
        check_values(np.array([1.0, np.nan, 2.0]), "TRAC:X? D1")
    with pytest.raises(MalformedReply, match=r"value 0 is 9.91e"):
        check_values(np.array([9.91e37]), "TRAC:X? D1")
    with pytest.raises(MalformedReply, match="expected 6 values, got 4"):
        interleaved_to_complex(np.ones(4), "TRAC:DATA? D1", points=3)
    with pytest.raises(MalformedReply, match="cannot be \\(real, imag\\) pairs"):
        interleaved_to_complex(np.ones(5), "TRAC:DATA? D1")
    with pytest.raises(MalformedReply, match=r"'1.0x' of an ASCII data reply"):
        decode_ascii("1.0,1.0x,3")


# -- identity, options, validation --------------------------------------------------------------
def test_identity_and_missing_option_are_named() -> None:
    with Analyser(options='"1D2"') as server, open_analyser(server) as analyser:
        assert analyser.identify() == IDN
        analyser.require_options(four_channels=False)
        with pytest.raises(MissingOption, match=r"option AY6 \(channels 3 and 4\)") as caught:
            analyser.require_options(four_channels=True)
        assert caught.value.missing == ("AY6",)
    with (
        ScriptedSCPIServer({"*IDN?": "KEYSIGHT,34401A,0,1"}) as server,
        pytest.raises(WrongInstrument, match=r"34401A.*not a 35670A"),
    ):
        open_analyser(server)


@pytest.mark.parametrize(
    ("target", "name", "value", "complaint"),
    [
        ("source", "level_vpk", 5.5, r"5.5 Vpk is outside \[0, 5\] Vpk"),
        ("source", "tolerance_db", 0.05, r"outside \[0.1, 20\] dB"),
        ("sweep", "points_per_sweep", 802, r"802 points is outside \[2, 801\]"),
        ("sweep", "start_frequency_hz", 30000.0, r"outside \[0.015625, 25600\] Hz"),
        ("sweep", "integrate_cycles", 300, r"outside \[1, 234\] cycles"),
        ("sweep", "direction", "SIDEWAYS", "not one of UP, DOWN"),
        ("source", "auto_level", 1, "not True or False"),
        ("channel", "range_dbvrms", -50.0, "in 2 dB steps"),
        ("channel", "range_dbvrms", 29.0, r"29 dBVrms is outside"),
        ("channel", "transducer_label", 'N;*RST', "not one of"),
    ],
)
def test_out_of_range_settings_are_refused_before_sending(target, name, value, complaint) -> None:
    with Analyser() as server, open_analyser(server) as analyser:
        analyser.require_options()
        owner = {"source": analyser.source, "sweep": analyser.sweep,
                 "channel": analyser.channel(2)}[target]
        before = list(server.received)
        with pytest.raises(SettingOutOfRange, match=complaint):
            setattr(owner, name, value)
        assert server.received == before


def test_the_source_level_cannot_be_set_before_its_limit() -> None:
    with Analyser() as server, open_analyser(server) as analyser:
        with pytest.raises(SettingOutOfRange, match="source limit"):
            analyser.source.level_vpk = 0.5
        assert not any(c.startswith("SOUR") for c in server.received)
        analyser.source.limit_vpk = 1.0
        analyser.source.level_vpk = 0.5
        assert server.received[-4:] == ["SOUR:VOLT:LIM 1 VPK", "SYST:ERR?", "SOUR:VOLT 0.5 VPK",
                                        "SYST:ERR?"]


def test_valid_settings_send_the_manuals_syntax() -> None:
    with Analyser() as server, open_analyser(server) as analyser:
        analyser.channel(3).range_dbvrms = -51
        analyser.channel(2).coupling = "ac"
        analyser.sweep.settle_s = 0.5
        analyser.sweep.integrate_cycles = 12
        analyser.sweep.points_per_sweep = 401
        analyser.source.reference_vpk = 0.25
        analyser.sweep.manual_frequency_hz = 58.25
        analyser.fft_source.output = False
        sent = [c for c in server.received if c != "SYST:ERR?"]
        assert sent[-8:] == [
            "VOLT3:RANG -51 DBVRMS",
            "INP2:COUP AC",
            "SWE:STIM 0.5 S",
            "SWE:DWEL 12 CYCLE",
            "FREQ:RES 401 PNT/SWP",
            "SOUR:VOLT:REF 0.25 VPK",
            "FREQ:MAN 58.25 HZ",
            "OUTP OFF",
        ]
        # a fixed range turns autorange off in the analyser: the driver expects that
        assert analyser.channel(3).sent["autorange"] is False


# -- configuration ------------------------------------------------------------------------------
def test_configure_swept_sine_sends_the_papers_setup_in_a_safe_order() -> None:
    with Analyser() as server:
        configured(server).close()
        commands = server.received
        # every configuration step is followed by a check of the error queue
        steps = [c for c in commands if "?" not in c]
        for step in steps:
            index = commands.index(step)
            assert commands[index + 1] == "SYST:ERR?", step
        # in swept sine the sweep drives the source: no OUTP, the limit before the level
        assert steps == [
            "INST:SEL SINE",
            "FORM REAL,64",
            "INP2 ON",
            "INP3 ON",
            "INP4 ON",
            "REF PAIR",
            "VOLT1:RANG:UNIT:XDCR:LAB N",
            "VOLT1:RANG:UNIT:USER:SFAC 0.01124 V/EU",
            "VOLT1:RANG:UNIT:USER ON",
            "VOLT1:RANG:AUTO ON",
            "VOLT2:RANG:UNIT:XDCR:LAB M/S2",
            "VOLT2:RANG:UNIT:USER:SFAC 0.0102 V/EU",
            "VOLT2:RANG:UNIT:USER ON",
            "VOLT2:RANG:AUTO ON",
            "VOLT3:RANG:UNIT:XDCR:LAB N",
            "VOLT3:RANG:UNIT:USER:SFAC 0.01124 V/EU",
            "VOLT3:RANG:UNIT:USER ON",
            "VOLT3:RANG:AUTO ON",
            "VOLT4:RANG:UNIT:XDCR:LAB M/S2",
            "VOLT4:RANG:UNIT:USER:SFAC 0.0102 V/EU",
            "VOLT4:RANG:UNIT:USER ON",
            "VOLT4:RANG:AUTO ON",
            "SWE:MODE AUTO",
            "SWE:SPAC LIN",
            "SWE:DIR UP",
            "FREQ:RES:AUTO OFF",
            "FREQ:STAR 10 HZ",
            "FREQ:STOP 60 HZ",
            "FREQ:RES 0.25 HZ",
            "SWE:STIM 100 CYCLE",
            "SWE:DWEL 100 CYCLE",
            "SOUR:VOLT:LIM 1.5 VPK",
            "SOUR:VOLT:SLEW 1 V/S",
            "SOUR:VOLT 0.1 VPK",
            "SOUR:VOLT:REF:CHAN INP4",
            "SOUR:VOLT:REF 2 EU",
            "SOUR:VOLT:REF:TOL 2",
            "SOUR:VOLT:LIM:INP 40 EU",
            "SOUR:VOLT:AUTO ON",
        ]
        # then every setting is read back, with its unit where it has one
        readback = commands[commands.index("SOUR:VOLT:AUTO ON") + 2:]
        for query in ("INST:SEL?", "FORM?", "INP4?", "REF?", "VOLT2:RANG:UNIT:XDCR:LAB?",
                      "VOLT2:RANG:UNIT:USER:SFAC?", "FREQ:STAR?", "FREQ:STAR? UNIT",
                      "FREQ:RES? UNIT", "SWE:DWEL? UNIT", "SOUR:VOLT:LIM? UNIT",
                      "SOUR:VOLT:REF? UNIT", "SOUR:VOLT:LIM:INP?", "SOUR:VOLT:AUTO?"):
            assert query in readback, query


def test_a_setting_the_analyser_does_not_hold_is_named() -> None:
    with Analyser() as server:
        server.replies["SWE:DWEL?"] = "+5.00000000000E+000"  # as if the command were lost
        with pytest.raises(SettingNotApplied, match=r"integrate_cycles: sent 100.*SWE:DWEL\?"):
            configured(server)


def test_a_refused_setting_raises_with_code_text_and_command() -> None:
    with Analyser() as server, open_analyser(server) as analyser:
        server.errors[:] = ['-222,"Data out of range; value not changed"', '-350,"Queue overflow"']
        with pytest.raises(SCPIError) as caught:
            analyser.sweep.stop_frequency_hz = 20000.0
        error = caught.value
        assert (error.code, error.text, error.command) == (
            -222, "Data out of range; value not changed", "FREQ:STOP 20000 HZ"
        )
        assert error.others == ((-350, "Queue overflow"),)
        assert server.received[-3:] == ["SYST:ERR?"] * 3


def test_real64_refused_falls_back_to_ascii() -> None:
    with Analyser() as server, open_analyser(server) as analyser:
        server.errors[:] = ['-224,"Illegal parameter value"']
        assert analyser.set_data_format("REAL,64") == "ASC,12"
        assert "FORM ASC,12" in server.received


# -- measuring ----------------------------------------------------------------------------------
def check_segment(segment) -> None:
    np.testing.assert_array_equal(segment.frequency_hz, FREQUENCIES)
    np.testing.assert_allclose(segment.frf_21, FRF_21, rtol=1e-12)
    np.testing.assert_allclose(segment.frf_43, 2 * FRF_21, rtol=1e-12)
    for channel in (1, 2, 3, 4):
        np.testing.assert_allclose(segment.amplitude_eu[channel], 5.0 * channel)
        np.testing.assert_allclose(segment.variance[channel], 1e-4 * channel)
    np.testing.assert_allclose(segment.variance_21, 3e-4)
    assert segment.eu_labels == {1: "N", 2: "M/S2", 3: "N", 4: "M/S2"}
    assert segment.overload_channels == (2,)
    assert segment.half_range_channels == (1,)


@pytest.mark.parametrize("data_format", ["REAL,64", "ASC,12"])
def test_measure_runs_a_segment_and_reads_everything(data_format: str) -> None:
    seen = []
    with Analyser() as server, configured(server, data_format=data_format) as analyser:
        segment = analyser.measure(10.0, 11.0, progress=seen.append, poll_interval_s=0.01)
        check_segment(segment)
        assert len(seen) == 1 and seen[0].measuring and not seen[0].paused
        # settle + integration of 200 cycles and the analyser's own time at each point
        assert seen[0].expected_s == pytest.approx(sum(200 / FREQUENCIES) + 5 * 0.45)
        commands = server.commands()
        run = commands.index("ABOR")
        assert commands[run : run + 3] == ["ABOR", ":INIT:IMM", "*OPC"]
        # the event registers are cleared and their summary enabled before the start
        assert commands[run - 5 : run] == ["*ESR?", "STAT:QUES:VOLT:EVEN?", "*ESE 61",
                                           "SYST:ERR?", ] or commands[run - 4: run] == [
            "*ESR?", "STAT:QUES:VOLT:EVEN?", "*ESE 61", "SYST:ERR?"]
        assert "FREQ:STAR 10 HZ" in commands and "FREQ:STOP 11 HZ" in commands
        assert "*STB?" in commands[run:]  # status is polled, never waited on
        assert commands[-1] == "ABOR" and not any(c.startswith("OUTP") for c in commands)
        for feed in ("XFR:POW:RAT 2,1", "XFR:POW:RAT 4,3", "XFR:POW:LIN 4", "XFR:POW:VAR 1"):
            assert f"CALC1:FEED '{feed}'" in commands
        assert commands.count("TRAC:X? D1") == 1


def test_band_order_keeps_start_below_stop() -> None:
    with Analyser() as server, configured(server) as analyser:
        analyser.sweep.stop_frequency_hz = 20.0
        analyser.sweep.set_band(50.0, 60.0)
        bands = [c for c in server.received if c.startswith(("FREQ:STAR", "FREQ:STOP"))]
        assert bands[-2:] == ["FREQ:STOP 60 HZ", "FREQ:STAR 50 HZ"]


def test_a_band_of_more_than_801_points_is_refused_before_sending() -> None:
    with Analyser() as server, configured(server) as analyser:
        before = len(server.received)
        with pytest.raises(SettingOutOfRange, match="is 802 points; at most 801"):
            analyser.measure(10.0, 210.25)
        assert len(server.received) == before


def test_wrong_point_count_in_a_trace_is_malformed() -> None:
    with Analyser() as server, configured(server) as analyser:
        server.replies["TRAC:DATA? D1"] = lambda message: definite_block(np.ones(8))
        with pytest.raises(MalformedReply, match=r"XFR:POW:RAT 2,1\): expected 5 values, got 4"):
            analyser.measure(10.0, 11.0, poll_interval_s=0.01)
        assert server.commands()[-1] == "ABOR"


def test_no_data_markers_become_nan_and_empty_slots_are_left_out() -> None:
    """A 401-point trace: 5 measured points, the rest the no-data marker (X too); inside the
    measured points a marker is a point without data: NaN, flagged."""
    slots = np.full(401, NO_DATA)
    slots[:5] = FREQUENCIES

    def data(message: str) -> bytes:
        trace = trace_for(server.last_feed())
        values = np.full(401 if trace.size == 5 else 802, NO_DATA)
        values[: trace.size] = trace
        if server.last_feed() == "XFR:POW:RAT 4,3":
            values[4:6] = NO_DATA  # point 2 of the support FRF has no data
        return definite_block(values)

    with Analyser() as server, configured(server) as analyser:
        server.replies["TRAC:X? D1"] = lambda message: definite_block(slots)
        server.replies["TRAC:DATA? D1"] = data
        segment = analyser.measure(10.0, 11.0, poll_interval_s=0.01)
        np.testing.assert_array_equal(segment.frequency_hz, FREQUENCIES)
        assert np.isnan(segment.frf_43[2]) and np.all(np.isfinite(np.delete(segment.frf_43, 2)))
        np.testing.assert_array_equal(segment.no_data, [False, False, True, False, False])
        # a value where only no data may be is malformed
        values = np.full(802, NO_DATA)
        values[:12] = 1.0
        server.replies["TRAC:DATA? D1"] = lambda message: definite_block(values)
        with pytest.raises(MalformedReply, match="should hold no data"):
            analyser.measure(10.0, 11.0, poll_interval_s=0.01)


def test_manual_points_send_one_manual_frequency_each() -> None:
    with Analyser(esr=("+0", "+1")) as server, configured(server) as analyser:
        server.replies["TRAC:X? D1"] = lambda message: definite_block(
            np.array([float(server.settings["FREQ:MAN"].split()[0])]))
        server.replies["TRAC:DATA? D1"] = lambda message: definite_block(
            trace_for(server.last_feed())[:2 if "VAR" not in server.last_feed() else 1])
        segment = analyser.measure_points([30.0, 12.5], settle_cycles=10, integrate_cycles=20,
                                          poll_interval_s=0.01)
        commands = server.commands()
    np.testing.assert_array_equal(segment.frequency_hz, [30.0, 12.5])
    assert "SWE:MODE MAN" in commands and "SWE:DWEL 20 CYCLE" in commands
    manual = [c for c in commands if c.startswith("FREQ:MAN ")]
    assert manual == ["FREQ:MAN 30 HZ", "FREQ:MAN 30 HZ", "FREQ:MAN 12.5 HZ"]
    assert commands.count(":INIT:IMM") == 2


def test_abort_and_pause_from_the_progress_callback() -> None:
    with Analyser(esr=("+0",)) as server, configured(server) as analyser:
        def steer(progress) -> None:
            if progress.elapsed_s < 0.05 and not progress.paused:
                analyser.pause()
            elif progress.paused:
                analyser.resume()
            else:
                analyser.abort()

        with pytest.raises(MeasurementAborted):
            analyser.measure(10.0, 11.0, progress=steer, poll_interval_s=0.03)
        tail = server.commands()[server.commands().index(":INIT:IMM") :]
        assert tail.index("INIT:CONT OFF") < tail.index("INIT:CONT ON") < tail.index("ABOR")
        assert tail[-1] == "ABOR"


def test_a_sweep_past_its_deadline_is_aborted_with_a_clear_message() -> None:
    with Analyser(esr=("+0",)) as server, configured(server) as analyser:
        with pytest.raises(InstrumentTimeout, match=r"did not complete within 0.2 s.*aborted"):
            analyser.measure(10.0, 11.0, timeout_s=0.2, poll_interval_s=0.02)
        assert server.commands()[-2:] == ["ABOR", "ABOR"]


def test_an_error_during_the_sweep_is_raised_from_the_queue() -> None:
    with Analyser(esr=("+0", "+16")) as server, configured(server) as analyser:
        server.errors[:] = ['-221,"SOURCE LEVEL is 0 Volts, measurement paused"']
        with pytest.raises(SCPIError, match="SOURCE LEVEL is 0 Volts") as caught:
            analyser.measure(10.0, 11.0, poll_interval_s=0.01)
        assert caught.value.code == -221


# -- timeouts and retries -----------------------------------------------------------------------
def test_a_timeout_names_resource_command_and_timeout() -> None:
    with Analyser() as server, open_analyser(server, timeout_s=0.3) as analyser:
        with pytest.raises(InstrumentTimeout) as caught:
            analyser.ask("SYST:ERR? NOPE")
        message = str(caught.value)
        assert server.resource in message and "'SYST:ERR? NOPE'" in message and "0.3 s" in message
        assert server.received.count("SYST:ERR? NOPE") == 1


def test_only_idempotent_queries_are_retried_after_a_lost_connection() -> None:
    assert is_idempotent("TRAC:DATA? D1") and is_idempotent("*IDN?")
    assert not is_idempotent("SYST:ERR?") and not is_idempotent("*ESR?")
    assert not is_idempotent("STAT:QUES:VOLT:EVEN?") and not is_idempotent("*OPC?")
    with Analyser() as server, open_analyser(server, timeout_s=0.3) as analyser:
        server.drop_next_connection_on = "*IDN?"
        assert analyser.identify() == IDN
        assert server.received.count("*IDN?") == 3  # open, dropped, retried
        server.drop_next_connection_on = "*ESR?"
        with pytest.raises(InstrumentTimeout, match="'\\*ESR\\?'"):
            analyser.ask("*ESR?")
        assert server.received.count("*ESR?") == 1


# -- Prologix ----------------------------------------------------------------------------------
def test_the_prologix_path_configures_the_adapter_and_carries_binary_blocks() -> None:
    with Analyser(prologix=True, board=3) as server, configured(server) as analyser:
        assert analyser.resource == "GPIB3::11::INSTR"
        # a block whose payload holds line feeds and '+' survives the adapter's framing
        tricky = np.frombuffer(b"\n+\x1b\r" * 4, dtype=">f8").astype(float)
        server.replies["TRAC:X? D1"] = lambda message: definite_block(tricky)
        np.testing.assert_array_equal(analyser.read_values("TRAC:X? D1"), tricky)
        segment_server = server
        segment_server.replies["TRAC:X? D1"] = lambda message: definite_block(FREQUENCIES)
        check_segment(analyser.measure(10.0, 11.0, poll_interval_s=0.01))
    assert server.adapter_commands[:7] == [
        "++mode 1", "++auto 0", "++read_tmo_ms 50", "++eos 3", "++eoi 1", "++eot_enable 0",
        "++read_tmo_ms 500",
    ]
    assert "++addr 11" in server.adapter_commands
    assert "SOUR:VOLT:REF 2 EU" in server.received


def test_every_dwell_and_settle_time_sent_carries_its_unit() -> None:
    """A bare number on ``SWE:DWEL``/``SWE:STIM`` is read in a unit the guide does not name
    (docs/virtual-analyser.md): the driver never sends one."""
    with Analyser(esr=("+0", "+1")) as server, configured(
            server, settle_cycles=3, integrate_cycles=4) as analyser:
        server.replies["TRAC:X? D1"] = lambda message: definite_block(
            np.array([float(server.settings["FREQ:MAN"].split()[0])]))
        server.replies["TRAC:DATA? D1"] = lambda message: definite_block(
            trace_for(server.last_feed())[:2 if "VAR" not in server.last_feed() else 1])
        analyser.measure_points([30.0], settle_cycles=10, integrate_cycles=20,
                                poll_interval_s=0.01)
        analyser.sweep.settle_s = 0.5
        analyser.sweep.integrate_s = 0.02
        commands = server.commands()
    timing = [c for c in commands if c.upper().startswith(("SWE:DWEL", "SWE:STIM"))
              and not c.endswith("?") and "? " not in c]
    assert len(timing) >= 5
    for command in timing:
        assert command.split()[-1] in ("CYCLE", "S"), command
    assert "SWE:STIM 0.5 S" in timing and "SWE:DWEL 0.02 S" in timing


def test_a_fixed_source_measurement_turns_auto_level_off_and_on_again() -> None:
    """``measure_at_source``: auto level off, the source held at the level asked (within the
    limit), the points measured, auto level on again, also after a failed measurement."""
    with Analyser(esr=("+0", "+1")) as server, configured(server) as analyser:
        server.replies["TRAC:X? D1"] = lambda message: definite_block(
            np.array([float(server.settings["FREQ:MAN"].split()[0])]))
        server.replies["TRAC:DATA? D1"] = lambda message: definite_block(
            trace_for(server.last_feed())[:2 if "VAR" not in server.last_feed() else 1])
        before = len(server.commands())
        segment = analyser.measure_at_source([30.0], 0.01, poll_interval_s=0.01)
        commands = server.commands()[before:]
        with pytest.raises(SettingOutOfRange):
            analyser.measure_at_source([30.0], 2.0)  # above the 1.5 Vpk source limit
        server.replies["TRAC:X? D1"] = lambda message: definite_block(np.array([99.0]))
        before = len(server.commands())
        with pytest.raises(MalformedReply):
            analyser.measure_at_source([30.0], 0.01, poll_interval_s=0.01)
        after_error = server.commands()[before:]
    np.testing.assert_array_equal(segment.frequency_hz, [30.0])
    off, level = commands.index("SOUR:VOLT:AUTO OFF"), commands.index("SOUR:VOLT 0.01 VPK")
    start = commands.index(":INIT:IMM")
    assert off < level < start < commands.index("SOUR:VOLT:AUTO ON")
    assert after_error[0] == "SOUR:VOLT:AUTO OFF" and "SOUR:VOLT:AUTO ON" in after_error


# -- the wiring is the caller's ------------------------------------------------------------------
def test_configure_inputs_sends_the_labels_and_pairing_the_caller_gives() -> None:
    """Forces on 2 and 4 here: the labels follow the argument, not a wiring built in."""
    with Analyser() as server, open_analyser(server) as analyser:
        analyser.configure_inputs([(1, "m/s2", 0.0102), (2, "N", 0.01124), (3, "M/S2", 0.0102),
                                   (4, "N", 0.01124)], pairing="SING")
        sent = [c for c in server.received if "?" not in c]
        assert sent[:4] == ["INP2 ON", "INP3 ON", "INP4 ON", "REF SING"]
        labels = [c for c in sent if ":XDCR:LAB " in c]
        assert labels == ["VOLT1:RANG:UNIT:XDCR:LAB M/S2", "VOLT2:RANG:UNIT:XDCR:LAB N",
                          "VOLT3:RANG:UNIT:XDCR:LAB M/S2", "VOLT4:RANG:UNIT:XDCR:LAB N"]
        assert analyser.channels_in_use == (1, 2, 3, 4)


@pytest.mark.parametrize(
    ("inputs", "complaint"),
    [
        ([(1, "N", 0.01), (2, "N;*RST", 0.01)], "label"),
        ([(1, "N", 0.01), (1, "M/S2", 0.01)], "given twice"),
        ([(2, "M/S2", 0.01)], "input 1"),
        ([(1, "N", 0.01), (5, "N", 0.01)], "not 1..4"),
        ([(1, "N", 0.0)], "V/EU"),
        ([(1, "N")], "not \\(number, label"),
    ],
)
def test_bad_input_settings_are_refused_before_anything_is_sent(inputs, complaint) -> None:
    with Analyser() as server, open_analyser(server) as analyser:
        before = list(server.received)
        with pytest.raises(SettingOutOfRange, match=complaint):
            analyser.configure_inputs(inputs, pairing="PAIR")
        with pytest.raises(SettingOutOfRange, match=complaint):
            analyser.configure_swept_sine(inputs=inputs, reference_channel=1,
                                          reference_level_eu=1.0, source_limit_vpk=1.0)
        assert server.received == before


def test_a_reference_outside_the_inputs_is_refused_before_anything_is_sent() -> None:
    with Analyser() as server, open_analyser(server) as analyser:
        before = list(server.received)
        with pytest.raises(SettingOutOfRange, match="reference channel 4 is not in use"):
            analyser.configure_swept_sine(inputs=INPUTS[:2], reference_channel=4,
                                          reference_level_eu=2.0, source_limit_vpk=1.0)
        with pytest.raises(SettingOutOfRange, match="PAIR"):
            analyser.configure_swept_sine(inputs=INPUTS, reference_channel=4,
                                          reference_level_eu=2.0, source_limit_vpk=1.0,
                                          pairing="BOTH")
        assert server.received == before
