"""The virtual 35670A through pyvisa-py over a loopback raw SCPI socket, as a client sees it.

Commands and codes follow ``shared/docs/35670a.md``; every test talks SCPI to the simulated
analyser (``rigsim.server``) measuring the simulated rig, nothing is mocked.
"""

from __future__ import annotations

import time

import numpy as np
import pytest
import pyvisa
from rigsim.server import SimulatedAnalyserServer

SETUP_4CH = "*RST;*CLS;:INST:SEL SINE;:INP2 ON;:INP3 ON;:INP4 ON;:REF PAIR"


@pytest.fixture(scope="module")
def server():
    with SimulatedAnalyserServer("soft-0", seed=3) as srv:
        yield srv


@pytest.fixture(scope="module")
def rm():
    manager = pyvisa.ResourceManager("@py")
    yield manager
    manager.close()


def open_socket(rm, server, timeout_ms: int = 5000):
    inst = rm.open_resource(server.socket_resource, read_termination="\n",
                            write_termination="\n", timeout=timeout_ms)
    return inst


@pytest.fixture
def inst(rm, server):
    resource = open_socket(rm, server)
    resource.write("ABOR;*RST;*CLS")
    yield resource
    resource.close()


def errors(inst) -> list[tuple[int, str]]:
    """Drain the error queue."""
    found = []
    for _ in range(10):
        code, _, text = inst.query("SYST:ERR?").partition(",")
        if int(code) == 0:
            return found
        found.append((int(code), text.strip('"')))
    raise AssertionError(f"error queue does not empty: {found}")


def codes(inst) -> list[int]:
    return [code for code, _ in errors(inst)]


def start_sweep(inst, *, points: int = 21, start: float = 20.0, stop: float = 120.0,
                cycles: int = 20, extra: str = "") -> None:
    inst.write(SETUP_4CH)
    inst.write(f"FREQ:STAR {start} HZ;STOP {stop} HZ;:FREQ:RES:AUTO OFF;:FREQ:RES {points} PNT/SWP")
    inst.write(f"SWE:STIM {cycles} CYCLE;DWEL {cycles} CYCLE")
    inst.write("OUTP ON;:SOUR:VOLT 0.2 VPK")
    inst.write("CALC1:FEED 'XFR:POW:RAT 2,1';*WAI")
    if extra:
        inst.write(extra)
    inst.write("ABOR;:INIT:IMM")


def run_sweep(inst, **kwargs) -> None:
    start_sweep(inst, **kwargs)
    assert inst.query("*OPC?") == "+1"


# --------------------------------------------------------------------------------------------
# identity and common commands


def test_identity_and_common_commands(inst) -> None:
    assert "35670A" in inst.query("*IDN?")
    assert inst.query("*OPT?").split(",") == ["1D2", "AY6"]
    assert inst.query("*TST?") == "+0"
    assert inst.query("*CAL?") == "+0"
    inst.write("*ESE 60;*SRE 32")
    assert inst.query("*ESE?;*SRE?") == "+60;+32"
    assert codes(inst) == []


# (long form, short form, query, expected answer) in swept sine with four channels
COMMANDS = [
    ("INSTRUMENT:SELECT SINE", "INST SINE", "INST?", "SINE"),
    ("INSTRUMENT:NSELECT 3", "INST:NSEL 3", "INST:NSEL?", "+3"),
    ("SENSE:FREQUENCY:START 20 HZ", "FREQ:STAR 20", "FREQ:STAR?", 20.0),
    ("SENSE:FREQUENCY:STOP 0.12 KHZ", "FREQ:STOP 120HZ", "FREQ:STOP?", 120.0),
    ("SENSE:SWEEP:SPACING LOGARITHMIC", "SWE:SPAC LOG", "SWE:SPAC?", "LOG"),
    ("SENSE:SWEEP:DIRECTION DOWN", "SWE:DIR DOWN", "SWE:DIR?", "DOWN"),
    ("SENSE:SWEEP:MODE MANUAL", "SWE:MODE MAN", "SWE:MODE?", "MAN"),
    ("SENSE:FREQUENCY:MANUAL 50 HZ", "FREQ:MAN 50", "FREQ:MAN?", 50.0),
    ("SENSE:FREQUENCY:RESOLUTION 201 PNT/SWP", "FREQ:RES 201 PNT/SWP", "FREQ:RES?", 201.0),
    ("SENSE:FREQUENCY:RESOLUTION:AUTO OFF", "FREQ:RES:AUTO 0", "FREQ:RES:AUTO?", "+0"),
    ("SENSE:SWEEP:STIME 100 CYCLE", "SWE:STIM 100 CYCLE", "SWE:STIM?", 100.0),
    ("SENSE:SWEEP:DWELL 0.5 S", "SWE:DWEL 500 MS", "SWE:DWEL?", 0.5),
    ("INPUT2:STATE ON", "INP2 1", "INP2?", "+1"),
    ("INPUT4 ON", "INP4 ON", "INP4:STAT?", "+1"),
    ("SENSE:REFERENCE SINGLE", "REF SING", "REF?", "SING"),
    ("INPUT3:COUPLING AC", "INP3:COUP AC", "INP3:COUP?", "AC"),
    ("INPUT3:LOW GROUND", "INP3:LOW GRO", "INP3:LOW?", "GRO"),
    ("INPUT4:BIAS:STATE ON", "INP4:BIAS ON", "INP4:BIAS?", "+1"),
    ("SENSE:VOLTAGE2:RANGE:UPPER -11 DBVRMS", "VOLT2:RANG -11", "VOLT2:RANG?", -11.0),
    ("SENSE:VOLTAGE2:RANGE:AUTO ON", "VOLT2:RANG:AUTO 1", "VOLT2:RANG:AUTO?", "+1"),
    ("SENSE:VOLTAGE3:RANGE:UNIT:XDCR:LABEL N", "VOLT3:RANG:UNIT:XDCR:LAB N",
     "VOLT3:RANG:UNIT:XDCR:LAB?", "N"),
    ("SENSE:VOLTAGE4:RANGE:UNIT:USER:SFACTOR 0.0102 V/EU", "VOLT4:RANG:UNIT:USER:SFAC 0.0102",
     "VOLT4:RANG:UNIT:USER:SFAC?", 0.0102),
    ("SENSE:VOLTAGE4:RANGE:UNIT:USER:STATE ON", "VOLT4:RANG:UNIT:USER ON",
     "VOLT4:RANG:UNIT:USER?", "+1"),
    ("OUTPUT:STATE ON", "OUTP ON", "OUTP?", "+1"),
    ("SOURCE:VOLTAGE:LEVEL:IMMEDIATE:AMPLITUDE 1.5 VPK", "SOUR:VOLT 1.5", "SOUR:VOLT?", 1.5),
    ("SOURCE:VOLTAGE:AUTO:STATE ON", "SOUR:VOLT:AUTO ON", "SOUR:VOLT:AUTO?", "+1"),
    ("SOURCE:VOLTAGE:REFERENCE:CHANNEL INP4", "SOUR:VOLT:REF:CHAN INP4", "SOUR:VOLT:REF:CHAN?",
     "INP4"),
    ("SOURCE:VOLTAGE:REFERENCE:LEVEL 1 EU", "SOUR:VOLT:REF 1 EU", "SOUR:VOLT:REF?", 1.0),
    ("SOURCE:VOLTAGE:REFERENCE:TOLERANCE 1 DB", "SOUR:VOLT:REF:TOL 1", "SOUR:VOLT:REF:TOL?", 1.0),
    ("SOURCE:VOLTAGE:LIMIT 2 VPK", "SOUR:VOLT:LIM 2", "SOUR:VOLT:LIM?", 2.0),
    ("SOURCE:VOLTAGE:LIMIT:INPUT 100 EU", "SOUR:VOLT:LIM:INP 100 EU", "SOUR:VOLT:LIM:INP?", 100.0),
    ("SOURCE:VOLTAGE:SLEW 5", "SOUR:VOLT:SLEW 5", "SOUR:VOLT:SLEW?", 5.0),
    ("CALCULATE1:FEED 'XFR:POW:RAT 4,3'", "CALC1:FEED 'XFR:POW:RAT 4,3'", "CALC1:FEED?",
     '"XFR:POW:RAT 4,3"'),
    ("CALCULATE2:FEED 'XFR:POW:LIN 4'", "CALC2:FEED 'XFR:POW:LIN 4'", "CALC2:FEED?",
     '"XFR:POW:LIN 4"'),
    ("CALCULATE3:FEED 'XFR:POW:CROS 1,2'", "CALC3:FEED 'XFR:POW:CROS 1,2'", "CALC3:FEED?",
     '"XFR:POW:CROS 1,2"'),
    ("CALCULATE4:FEED 'XFR:POW:VAR 2'", "CALC4:FEED 'XFR:POW:VAR 2'", "CALC4:FEED?",
     '"XFR:POW:VAR 2"'),
    ("CALCULATE4:FEED 'XTIM:VOLT 1'", "CALC4:FEED 'XTIM:VOLT 1'", "CALC4:FEED?",
     '"XTIM:VOLT 1"'),
    ("CALCULATE1:FORMAT NYQUIST", "CALC1:FORM NYQ", "CALC1:FORM?", "NYQ"),
    ("CALCULATE2:FORMAT MLOGARITHMIC", "CALC2:FORM MLOG", "CALC2:FORM?", "MLOG"),
    ("FORMAT:DATA REAL,32", "FORM REAL,32", "FORM?", "REAL,+32"),
    ("FORMAT:DATA ASCII,7", "FORM ASC,7", "FORM?", "ASC,+7"),
    ("INITIATE:CONTINUOUS ON", "INIT:CONT ON", "INIT:CONT?", "+1"),
    ("STATUS:OPERATION:ENABLE 16", "STAT:OPER:ENAB 16", "STAT:OPER:ENAB?", "+16"),
    ("STATUS:QUESTIONABLE:VOLTAGE:ENABLE 15", "STAT:QUES:VOLT:ENAB 15", "STAT:QUES:VOLT:ENAB?",
     "+15"),
]


@pytest.mark.parametrize("form", [0, 1], ids=["long", "short"])
@pytest.mark.parametrize(("long", "short", "query", "expected"), COMMANDS,
                         ids=[c[1] for c in COMMANDS])
def test_every_command_in_long_and_short_form(inst, form, long, short, query, expected) -> None:
    inst.write(SETUP_4CH)
    command = (long, short.lower() if form else short)[form]
    if "FREQ:MAN" in short or "FREQUENCY:MANUAL" in long:
        inst.write("SWE:MODE MAN")
    inst.write(command)
    answer = inst.query(query)
    assert codes(inst) == []
    if isinstance(expected, float):
        assert float(answer) == pytest.approx(expected)
    else:
        assert answer == expected


def test_queries_without_optional_nodes_and_status_registers(inst) -> None:
    for query in ("STAT:OPER:COND?", "STAT:OPER?", "STAT:QUES:VOLT:COND?", "STAT:QUES:VOLT:EVEN?",
                  "STAT:QUES:COND?", "STAT:QUES?", "*STB?", "*ESR?", "SYST:ERR?"):
        assert inst.query(query).lstrip("+-").split(",")[0].isdigit(), query
    inst.write("STAT:PRES")
    assert codes(inst) == []


def test_compound_messages_paths_and_case(inst) -> None:
    inst.write("inst:sel sine;:sens:freq:star 30 hz;stop 90;:SWE:STIM 7 CYCLE;DWEL 3 CYCLE")
    assert inst.query("FREQ:STAR?;STOP?;:SWE:DWEL?") == (
        "+3.00000000000E+001;+9.00000000000E+001;+3.00000000000E+000")
    assert codes(inst) == []
    inst.write("FREQ:STAR 20;SWE:DIR UP")  # SWE is not under FREQ: the path rule refuses it
    assert codes(inst) == [-113]


def test_numbers_units_keywords_and_unit_queries(inst) -> None:
    inst.write("INST:SEL SINE;:SWE:DWEL 10 MS")
    assert float(inst.query("SWE:DWEL?")) == pytest.approx(0.01)
    assert inst.query("SWE:DWEL? UNIT") == '"S"'
    inst.write("SWE:DWEL 12")  # a bare number keeps the unit in use (inferred)
    assert inst.query("SWE:DWEL? UNIT") == '"S"'
    inst.write("SWE:STIM 2.5e1 CYCLES")
    assert inst.query("SWE:STIM? UNIT") == '"CYCLE"'
    assert inst.query("FREQ:STAR? UNIT") == '"HZ"'
    inst.write("SOUR:VOLT MAX")
    assert float(inst.query("SOUR:VOLT?")) == 5.0
    inst.write("SOUR:VOLT 1 VRMS")
    assert float(inst.query("SOUR:VOLT?")) == pytest.approx(np.sqrt(2))
    inst.write("VOLT1:RANG 3;:VOLT1:RANG UP")
    assert float(inst.query("VOLT1:RANG?")) == 5.0
    inst.write("VOLT1:RANG DOWN;RANG DOWN")
    assert float(inst.query("VOLT1:RANG?")) == 1.0
    inst.write("FREQ:STAR 2 KHZ")
    assert float(inst.query("FREQ:STAR?")) == 2000.0
    assert codes(inst) == []


def test_frequency_rounding_resolution_and_limits(inst) -> None:
    inst.write(SETUP_4CH)
    inst.write("FREQ:STAR 20.01 HZ")
    assert float(inst.query("FREQ:STAR?")) == pytest.approx(20.015625)  # 15.625 mHz grid
    inst.write("FREQ:STAR 20;STOP 120;:FREQ:RES 0.25 HZ")
    assert float(inst.query("FREQ:RES?")) == pytest.approx(0.25)
    inst.write("FREQ:RES 0.1 HZ")  # 1001 points: more than 801
    assert codes(inst) == [-222]
    assert float(inst.query("FREQ:RES?")) == pytest.approx(0.25)  # value not changed
    inst.write("FREQ:RES 801 PNT/SWP")
    assert codes(inst) == []
    inst.write("FREQ:STOP 30 KHZ")  # above the four-channel limit of 25.6 kHz
    assert codes(inst) == [-222]
    inst.write("FREQ:STOP 25.6 KHZ")
    assert codes(inst) == []


def test_dwell_settle_range_and_source_limits(inst) -> None:
    inst.write("INST:SEL SINE")
    cases = {
        "SWE:DWEL 0.5 CYCLE": -222,  # at least one cycle
        "SWE:DWEL 100 US": -222,  # at least 250 us
        "SWE:DWEL 250 US": 0,
        "SWE:DWEL 1 CYCLE": 0,
        "SWE:STIM 0 CYCLE": 0,
        "VOLT1:RANG 29 DBVRMS": -222,
        "VOLT1:RANG -53 DBVRMS": -222,
        "SOUR:VOLT 5.5 VPK": -222,
        "SOUR:VOLT:LIM 6": -222,
        "SOUR:VOLT:REF:TOL 25 DB": -222,
        "SOUR:VOLT:REF:TOL 0.05": -222,
        "FREQ:STAR 1 S": -131,
        "SWE:SPAC SIDEWAYS": -224,
        "FORM REAL,16": -224,
        "FORM ASC,2": -224,
        "FORM ASC,13": -224,
        "SOUR:VOLT:REF:CHAN INP5": -224,
        "CALC1:FEED 'XFR:POW:BOGUS 2,1'": -224,
        "FREQ:BOGUS 3": -113,
        "INP5 ON": -114,
        "INP1 ON,OFF": -108,
    }
    for command, code in cases.items():
        inst.write(command)
        assert codes(inst) == ([code] if code else []), command
    inst.write("VOLT1:RANG 4")  # the smallest 2 dB step that holds the level
    assert float(inst.query("VOLT1:RANG?")) == 5.0
    assert inst.query("VOLT1:RANG:AUTO?") == "+0"


@pytest.mark.parametrize("command", ["TRIG:SOUR INT", "*TRG", "ARM:SOUR IMM", "WIND HANN",
                                     "AVER:TYPE RMS", "FREQ:SPAN:FULL", "VOLT1:RANG:AUTO:DIR UP"])
def test_fft_only_commands_conflict_in_swept_sine(inst, command) -> None:
    inst.write("INST:SEL SINE")
    inst.write(command)
    assert codes(inst) == [-221]


def test_fft_settings_accepted_in_fft_mode(inst) -> None:
    for command in ("WIND HANN", "AVER:TYPE RMS", "FREQ:SPAN:FULL", "VOLT1:RANG:AUTO:DIR UP",
                    "TRIG:SOUR INT"):
        inst.write(command)
    assert codes(inst) == []


def test_coherence_is_fft_only_and_feeds_follow_the_reference(inst) -> None:
    inst.write(SETUP_4CH)
    inst.write("CALC1:FEED 'XFR:POW:COH 2,1'")
    assert codes(inst) == [-221]
    inst.write("CALC1:FEED 'XFR:POW:RAT 4,1'")  # REF PAIR: 1 refers 2, 3 refers 4
    assert codes(inst) == [-221]
    inst.write("REF SING;:CALC1:FEED 'XFR:POW:RAT 4,1'")
    assert codes(inst) == []
    inst.write("*RST;:INST:SEL SINE;:CALC1:FEED 'XFR:POW:LIN 3'")  # channel 3 is off
    assert codes(inst) == [-221]


def test_error_queue_keeps_the_oldest_and_says_overflow(inst) -> None:
    for i in range(7):
        inst.write(f"BOGUS{i}")
    found = errors(inst)
    assert [c for c, _ in found] == [-113, -113, -113, -113, -350]
    assert "BOGUS0" in found[0][1] and "BOGUS3" in found[3][1]
    assert found[4][1] == "Queue overflow"
    inst.write("BOGUS")
    inst.write("*CLS")
    assert inst.query("SYST:ERR?") == '+0,"No error"'
    inst.write("BOGUS")
    assert int(inst.query("*ESR?")) & 32  # command error bit
    assert codes(inst) == [-113]


def test_modes_keep_their_own_settings(inst) -> None:
    assert inst.query("INST?") == "FFT"  # power-up and reset mode
    inst.write("INST:NSEL 3;:FREQ:STAR 20")
    inst.write("INST:SEL FFT;:FREQ:STAR 100")
    inst.write("INST:SEL SINE")
    assert float(inst.query("FREQ:STAR?")) == 20.0
    inst.write("INST:SEL FFT")
    assert float(inst.query("FREQ:STAR?")) == 100.0
    assert codes(inst) == []


def test_rst_and_preset_leave_different_states(inst) -> None:
    inst.write("INST:SEL SINE;:INIT:CONT ON;:FREQ:RES:AUTO OFF")
    inst.write("*RST")
    inst.write("INST:SEL SINE")
    assert inst.query("INIT:CONT?;:FREQ:RES:AUTO?") == "+0;+1"
    inst.write("SYST:PRES")
    assert inst.query("INST?") == "FFT"
    inst.write("INST:SEL SINE")
    assert inst.query("INIT:CONT?;:FREQ:RES:AUTO?") == "+1;+0"


def test_options_can_be_removed(rm) -> None:
    with SimulatedAnalyserServer("table", options=("1D2",)) as two_channel:
        inst = open_socket(rm, two_channel)
        assert inst.query("*OPT?") == "1D2"
        inst.write("INST:SEL SINE;:INP4 ON")
        assert codes(inst) == [-241]
        inst.close()
    with SimulatedAnalyserServer("table", options=()) as bare:
        inst = open_socket(rm, bare)
        assert inst.query("*OPT?") == "0"
        inst.write("INST:SEL SINE")
        assert codes(inst) == [-241]
        assert inst.query("INST?") == "FFT"
        inst.close()


# --------------------------------------------------------------------------------------------
# measurement and data


def test_zero_source_pauses_the_measurement(inst) -> None:
    inst.write(SETUP_4CH + ";:FREQ:RES 5 PNT/SWP;:OUTP OFF;:SOUR:VOLT 0.2")
    inst.write("INIT;*OPC")
    found = errors(inst)
    assert [c for c, _ in found] == [-221]
    assert "SOURCE LEVEL is 0 Volts, measurement paused" in found[0][1]
    assert int(inst.query("*ESR?")) & 1 == 0  # not complete
    assert inst.query("CALC1:DATA:HEAD:POIN?") == "+0"
    inst.write("OUTP ON;:INIT:CONT ON")
    assert inst.query("*OPC?") == "+1"
    assert inst.query("CALC1:DATA:HEAD:POIN?") == "+5"


def read_block(inst, query: str, dtype: str) -> np.ndarray:
    """Read an IEEE 488.2 definite-length block byte by byte, as the manual describes it."""
    inst.write(query)
    head = inst.read_bytes(2)
    assert head[:1] == b"#"
    length = int(inst.read_bytes(int(head[1:2])))
    payload = inst.read_bytes(length + 1)
    assert payload.endswith(b"\n")
    return np.frombuffer(payload[:-1], dtype=dtype)


def test_real64_real32_and_ascii_reads_agree(inst) -> None:
    run_sweep(inst, points=31)
    inst.write("CALC1:FORM NYQ;:TRAC:DATA D1,TRAC1")
    inst.write("FORM REAL,64")
    real64 = read_block(inst, "TRAC:DATA? D1", ">f8")
    x64 = read_block(inst, "TRAC:X? D1", ">f8")
    via_pyvisa = inst.query_binary_values("CALC1:DATA?", datatype="d", is_big_endian=True,
                                          container=np.array)
    inst.write("FORM REAL,32")
    real32 = read_block(inst, "TRAC:DATA? D1", ">f4")
    inst.write("FORM ASC,12")
    ascii12 = np.array(inst.query("TRAC:DATA? D1").split(","), float)
    x_ascii = np.array(inst.query("TRAC:X? D1").split(","), float)
    assert real64.size == 62 and x64.size == 31  # interleaved real, imag
    np.testing.assert_allclose(x64, np.linspace(20, 120, 31))
    np.testing.assert_allclose(x_ascii, x64, rtol=1e-11)
    np.testing.assert_allclose(ascii12, real64, rtol=1e-10)
    np.testing.assert_allclose(real32, real64, rtol=1e-6)
    np.testing.assert_array_equal(via_pyvisa, real64)  # NYQ displayed data = raw pairs
    assert codes(inst) == []


def test_display_formats_are_consistent(inst) -> None:
    run_sweep(inst, points=11)
    inst.write("FORM REAL,64")
    values = {}
    for form in ("NYQ", "MLIN", "MLOG", "PHAS", "REAL", "IMAG", "UPH"):
        inst.write(f"CALC1:FORM {form}")
        values[form] = inst.query_binary_values("CALC1:DATA?", datatype="d", is_big_endian=True,
                                                container=np.array)
    h = values["NYQ"][0::2] + 1j * values["NYQ"][1::2]
    np.testing.assert_allclose(values["MLIN"], np.abs(h))
    np.testing.assert_allclose(values["MLOG"], 20 * np.log10(np.abs(h)))
    np.testing.assert_allclose(values["PHAS"], np.degrees(np.angle(h)))
    np.testing.assert_allclose(values["REAL"], h.real)
    np.testing.assert_allclose(values["IMAG"], h.imag)
    np.testing.assert_allclose(np.cos(np.radians(values["UPH"])), np.cos(np.angle(h)), atol=1e-9)
    assert inst.query("CALC1:DATA:HEAD:POIN?") == "+11"


def test_point_lists_spacing_direction_and_manual(inst) -> None:
    run_sweep(inst, points=9, start=10, stop=1000, extra="SWE:SPAC LOG;DIR DOWN")
    x = np.array(inst.query("CALC1:X:DATA?").split(","), float)
    np.testing.assert_allclose(x, np.geomspace(1000, 10, 9))
    run_sweep(inst, points=9, extra="SWE:MODE MAN;:FREQ:MAN 42.5 HZ")
    x = np.array(inst.query("CALC1:X:DATA?").split(","), float)
    np.testing.assert_allclose(x, [42.5])


def test_engineering_units_scale_the_traces(inst) -> None:
    run_sweep(inst, points=5, extra="CALC2:FEED 'XFR:POW:LIN 2';:CALC2:FORM NYQ;:CALC1:FORM NYQ")
    volts_frf = np.array(inst.query("CALC1:DATA?").split(","), float)
    volts_lin = np.array(inst.query("CALC2:DATA?").split(","), float)
    run_sweep(inst, points=5, extra="CALC2:FEED 'XFR:POW:LIN 2';:CALC2:FORM NYQ;:CALC1:FORM NYQ;"
              ":VOLT1:RANG:UNIT:USER:SFAC 0.01124 V/EU;:VOLT1:RANG:UNIT:USER ON;"
              ":VOLT2:RANG:UNIT:USER:SFAC 0.0102 V/EU;:VOLT2:RANG:UNIT:USER ON")
    assert codes(inst) == []
    eu_frf = np.array(inst.query("CALC1:DATA?").split(","), float)
    eu_lin = np.array(inst.query("CALC2:DATA?").split(","), float)
    # the rig is linear and the noise small: EU = V / sensitivity, so the FRF scales by s1/s2
    def pairs(values):
        return values[0::2] + 1j * values[1::2]

    h_volts, h_eu = pairs(volts_frf), pairs(eu_frf)
    assert np.max(np.abs(h_eu / (h_volts * 0.01124 / 0.0102) - 1)) < 1e-2
    lin_volts, lin_eu = pairs(volts_lin), pairs(eu_lin)
    assert np.max(np.abs(np.abs(lin_eu) / (np.abs(lin_volts) / 0.0102) - 1)) < 1e-2


def test_opc_esr_and_status_byte(inst) -> None:
    start_sweep(inst, points=5)
    inst.write("*ESE 1;*OPC")
    deadline = time.monotonic() + 10
    while not int(inst.query("*ESR?")) & 1:
        assert time.monotonic() < deadline
    assert int(inst.query("STAT:OPER:COND?")) == 0
    inst.write("*OPC")
    assert int(inst.query("*STB?")) & 32  # ESB: the enabled OPC bit
    assert int(inst.query("*ESR?")) == 1
    assert int(inst.query("*STB?")) & 32 == 0


def test_overload_and_half_range_bits(inst) -> None:
    run_sweep(inst, points=5, extra="VOLT1:RANG -51 DBVRMS")  # far below the force signal
    event = int(inst.query("STAT:QUES:VOLT:EVEN?"))
    assert event & 1  # overload on channel 1
    assert int(inst.query("STAT:QUES:VOLT:EVEN?")) == 0  # reading clears the event register
    run_sweep(inst, points=5, extra="VOLT1:RANG 27 DBVRMS")  # far above: no overload
    assert int(inst.query("STAT:QUES:VOLT:EVEN?")) & 1 == 0


def test_mount_swaps_the_rig_between_sweeps(inst, server) -> None:
    extra = "CALC1:FORM MLIN"
    run_sweep(inst, points=3, extra=extra)
    soft = np.array(inst.query("CALC1:DATA?").split(","), float)
    server.analyser.mount("table")
    try:
        run_sweep(inst, points=3, extra=extra)
        bare = np.array(inst.query("CALC1:DATA?").split(","), float)
    finally:
        server.analyser.mount("soft-0")
    assert not np.allclose(soft, bare, rtol=0.05)
    start_sweep(inst, points=3, extra="OUTP OFF")  # paused at 0 V: a sweep is in progress
    inst.query("*STB?")  # the server has handled INIT
    with pytest.raises(RuntimeError):
        server.analyser.mount("table")
    inst.write("ABOR")
    assert [c for c, _ in errors(inst)] == [-221]


# --------------------------------------------------------------------------------------------
# paced sweeps: pause, abort, timeouts


@pytest.fixture(scope="module")
def paced():
    # 2000 simulated seconds per second: 41 points of 200 cycles at 20-120 Hz take ~0.1 s of
    # simulated time each, so the sweep lasts a couple of wall seconds
    with SimulatedAnalyserServer("soft-0", pace=100.0, seed=5) as srv:
        yield srv


def wait_points(inst, at_least: int, timeout_s: float = 10.0) -> int:
    deadline = time.monotonic() + timeout_s
    while True:
        count = int(inst.query("CALC1:DATA:HEAD:POIN?"))
        if count >= at_least:
            return count
        assert time.monotonic() < deadline, f"only {count} points after {timeout_s} s"
        time.sleep(0.01)


def test_pause_resume_and_abort_mid_sweep(rm, paced) -> None:
    inst = open_socket(rm, paced)
    start_sweep(inst, points=41, cycles=100)  # about 3 s of wall time
    assert int(inst.query("STAT:OPER:COND?")) & 16  # measuring
    wait_points(inst, 2)
    inst.write("INIT:CONT OFF")
    paused_at = int(inst.query("CALC1:DATA:HEAD:POIN?"))
    time.sleep(0.3)
    assert int(inst.query("CALC1:DATA:HEAD:POIN?")) == paused_at
    assert int(inst.query("STAT:OPER:COND?")) & 16 == 0
    inst.write("INIT:CONT ON")
    wait_points(inst, paused_at + 2)
    inst.write("ABOR")
    aborted_at = int(inst.query("CALC1:DATA:HEAD:POIN?"))
    assert paused_at + 2 <= aborted_at < 41
    time.sleep(0.2)
    assert int(inst.query("CALC1:DATA:HEAD:POIN?")) == aborted_at  # the points so far stay
    x = np.array(inst.query("CALC1:X:DATA?").split(","), float)
    np.testing.assert_allclose(x, np.linspace(20, 120, 41)[:aborted_at])
    assert inst.query("*OPC?") == "+1"
    assert codes(inst) == []
    inst.close()


def test_settling_bit_and_a_real_timeout(rm, paced) -> None:
    inst = open_socket(rm, paced, timeout_ms=300)
    start_sweep(inst, points=41, cycles=100)
    seen = 0
    deadline = time.monotonic() + 1.0
    while time.monotonic() < deadline:
        seen |= int(inst.query("STAT:OPER:COND?"))
    assert seen & 2 and seen & 16  # settling and measuring
    with pytest.raises(pyvisa.errors.VisaIOError):
        inst.query("*OPC?")  # the sweep outlasts the VISA timeout
    inst.close()
    inst = open_socket(rm, paced)
    inst.write("ABOR")
    assert inst.query("*IDN?").count("35670A") == 1
    inst.close()


# --------------------------------------------------------------------------------------------
# faults


def test_injected_faults_are_observable(rm, server) -> None:
    inst = open_socket(rm, server, timeout_ms=300)
    inst.write("*CLS")
    server.faults.no_reply()
    with pytest.raises(pyvisa.errors.VisaIOError):
        inst.query("*IDN?")
    assert "35670A" in inst.query("*IDN?")
    server.faults.garble_reply("*IDN?")
    assert "35670A" not in inst.query("*IDN?")
    server.faults.error(-310, "System error; injected")
    assert inst.query("SYST:ERR?") == '-310,"System error; injected"'
    server.faults.overload(4)
    run_sweep(inst, points=3)
    assert int(inst.query("STAT:QUES:VOLT:EVEN?")) & 8  # channel 4 overload
    server.faults.drop_connection("*IDN?")
    with pytest.raises(pyvisa.errors.VisaIOError):
        inst.query("*IDN?")
    inst.close()
    inst = open_socket(rm, server)  # the server still accepts new connections
    assert "35670A" in inst.query("*IDN?")
    assert server.faults.pending == []
    inst.close()
