"""The virtual 35670A through pyvisa-py over a loopback raw SCPI socket, as a client sees it.

What is checked comes from the 35670A's programming guide (the chapter is named in each test);
the measurements are checked against physics computed here from the rig file, not against the
simulator's own code.
"""

from __future__ import annotations

import math
import time

import numpy as np
import pytest
import pyvisa
from rigsim.dynamics import ModalSystem, build_state_space
from rigsim.faults import parse_fault_spec
from rigsim.rigfile import load_preset
from rigsim.server import SimulatedAnalyserServer

MARKER = -3.40282346639e38
SETUP_4CH = "*RST;*CLS;:INST:SEL SINE;:INP2 ON;:INP3 ON;:INP4 ON;:REF PAIR;:FREQ:RES:AUTO OFF"


@pytest.fixture(scope="module")
def server():
    with SimulatedAnalyserServer("soft-0", seed=3) as srv:
        yield srv


@pytest.fixture(scope="module")
def rm():
    manager = pyvisa.ResourceManager("@py")
    yield manager
    manager.close()


def open_socket(rm, server, timeout_ms: int = 10000):
    return rm.open_resource(server.socket_resource, read_termination="\n",
                            write_termination="\n", timeout=timeout_ms)


@pytest.fixture
def inst(rm, server):
    resource = open_socket(rm, server)
    resource.write("ABOR;*RST;*CLS")
    server.analyser.front_end.reset()
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


def real64(inst, query: str) -> np.ndarray:
    return inst.query_binary_values(query, datatype="d", is_big_endian=True, container=np.array)


def run_sweep(inst, *, points: int = 21, start: float = 20.0, stop: float = 120.0,
              cycles: int = 20, extra: str = "") -> None:
    inst.write(SETUP_4CH)
    inst.write(f"FREQ:STAR {start} HZ;STOP {stop} HZ;:FREQ:RES {points} PNT/SWP")
    inst.write(f"SWE:STIM {cycles} CYCLE;DWEL {cycles} CYCLE;:SOUR:VOLT 0.2 VPK")
    if extra:
        inst.write(extra)
    inst.write("ABOR;:INIT:IMM")
    assert inst.query("*OPC?") == "+1"


def frf(rig, frequency_hz: np.ndarray, out: int, ref: int) -> np.ndarray:
    """Channel ``out`` over channel ``ref`` in volts, from the rig's state-space model."""
    modal = ModalSystem(build_state_space(rig, 1.0))
    iw = 1j * 2 * np.pi * np.asarray(frequency_hz)[:, None]
    response = (modal.b_modal / (iw - modal.eigenvalues)) @ modal.c_modal.T + modal.space.d
    sensitivity = np.array([rig.sensors.force_v_per_n, rig.sensors.acceleration_v_per_m_s2] * 2)
    volts = response * sensitivity
    return volts[:, out - 1] / volts[:, ref - 1]


# -- chapter 3: common commands; chapters 20, 21: status, system ------------------------------

def test_identity_options_and_status_bytes(inst) -> None:
    assert "35670A" in inst.query("*IDN?")
    assert inst.query("*OPT?") == '"1D2,AY6"'  # a quoted string (chapter 3)
    inst.write("*ESE 60;*SRE 40")
    assert (inst.query("*ESE?"), inst.query("*SRE?")) == ("+60", "+40")
    inst.write("FREQ:NONSENSE 3")  # a command error sets ESR bit 5
    assert int(inst.query("*STB?")) & 32
    assert int(inst.query("*ESR?")) & 32 and inst.query("*ESR?") == "+0"
    assert codes(inst) == [-113]
    assert inst.query("SYST:VERS?") == "+1.99200000000E+003"
    assert inst.query("SYST:POW:SOUR?") == "AC"


def test_rst_and_preset_leave_the_manuals_different_states(inst) -> None:
    """*RST: INIT:CONT OFF, FREQ:RES:AUTO ON, CAL:AUTO OFF, FREQ:SPAN:LINK CENT, group-delay
    aperture at its minimum; SYST:PRES: their presets; neither touches *ESE (chapter 3)."""
    inst.write("*ESE 4")
    inst.write("*RST;:INST:SEL SINE")
    rst = [inst.query(q) for q in ("INIT:CONT?", "FREQ:RES:AUTO?", "CAL:AUTO?",
                                   "FREQ:SPAN:LINK?", "CALC:GDAP:APER?")]
    inst.write("SYST:PRES;:INST:SEL SINE")
    preset = [inst.query(q) for q in ("INIT:CONT?", "FREQ:RES:AUTO?", "CAL:AUTO?",
                                      "FREQ:SPAN:LINK?", "CALC:GDAP:APER?")]
    assert rst == ["+0", "+1", "+0", "CENT", "+2.50000000000E-001"]
    assert preset == ["+1", "+0", "+1", "STAR", "+2.00000000000E+000"]
    assert inst.query("*ESE?") == "+4"
    # SYST:PRES clears the error queue, *RST does not
    inst.write("FREQ:NONSENSE 3")
    inst.write("*RST")
    assert codes(inst) == [-113]
    inst.write("FREQ:NONSENSE 3")
    inst.write("SYST:PRES")
    assert codes(inst) == []


def test_the_error_queue_keeps_the_oldest_and_says_overflow(inst) -> None:
    for _ in range(7):
        inst.write("NOT:A:COMMAND")
    found = codes(inst)
    assert found == [-113, -113, -113, -113, -350]


def test_status_registers_with_transition_filters(inst) -> None:
    """STAT:PRES: operation enable 0, positive transitions on; an event is latched through the
    positive-transition filter and read (and cleared) by the event query (chapter 20)."""
    inst.write("STAT:PRES;:STAT:OPER:ENAB 16;:*SRE 128")
    run_sweep(inst, points=3, cycles=5)
    assert int(inst.query("STAT:OPER:EVEN?")) & 16  # measuring rose during the sweep
    assert inst.query("STAT:OPER:EVEN?") == "+0"
    inst.write("STAT:OPER:PTR 0")
    run_sweep(inst, points=3, cycles=5)
    assert inst.query("STAT:OPER:EVEN?") == "+0"
    inst.write("STAT:USER:ENAB 2;:STAT:USER:PULS 2")
    assert int(inst.query("*STB?")) & 1 and inst.query("STAT:USER:EVEN?") == "+2"


# -- chapter 2: syntax --------------------------------------------------------------------------

def test_forms_paths_strings_and_blocks(inst) -> None:
    inst.write("sense:frequency:span:link center;:Freq:Span:Link?")
    assert inst.read() == "CENT"
    inst.write("INST:SEL SINE;:SWE:DWEL 3 CYCLE;STIM 2 CYCLE")  # the path stays at SWE
    assert (inst.query("SWE:DWEL?"), inst.query("SWE:STIM?")) == (
        "+3.00000000000E+000", "+2.00000000000E+000")
    inst.write("DISP:WIND:TRAC:LAB 'it''s'")
    assert inst.query("DISP:TRAC:LAB?") == '"it\'s"'
    inst.write("DISP:FORM ULOW;")  # a trailing separator, as the manual's ARBSRC sends
    assert codes(inst) == []


def test_a_dwell_or_settle_time_without_a_unit_is_in_seconds(inst) -> None:
    """The guide gives ``SWE:DWEL`` and ``SWE:STIM`` as ``<number>[S|CYCLE]`` with the preset
    in cycles; a bare number is taken in seconds (inferred, docs/virtual-analyser.md), never in
    the unit left in use, and never rounded up to a cycle."""
    inst.write("INST:SEL SINE")
    assert inst.query("SWE:DWEL? UNIT") == '"CYCLE"'  # preset +5.0 CYCLE
    assert inst.query("SWE:STIM? UNIT") == '"CYCLE"'
    inst.write("SWE:DWEL 0.005;STIM 0.25")  # what a driver sending seconds sends
    assert codes(inst) == []
    assert inst.query("SWE:DWEL?") == "+5.00000000000E-003"
    assert inst.query("SWE:DWEL? UNIT") == '"S"'
    assert inst.query("SWE:STIM?") == "+2.50000000000E-001"
    assert inst.query("SWE:STIM? UNIT") == '"S"'
    inst.write("SWE:DWEL 7 CYCLE;DWEL 0.01")  # from cycles: still seconds
    assert (inst.query("SWE:DWEL?"), inst.query("SWE:DWEL? UNIT")) == (
        "+1.00000000000E-002", '"S"')
    inst.write("SWE:DWEL 100E-6")  # below 250 us: refused, not rounded to a cycle
    assert codes(inst) == [-222]
    assert inst.query("SWE:DWEL?") == "+1.00000000000E-002"
    inst.write("SWE:DWEL 7 CYCLE;DWEL UP")  # a step keeps the unit in use
    assert (inst.query("SWE:DWEL?"), inst.query("SWE:DWEL? UNIT")) == (
        "+1.40000000000E+001", '"CYCLE"')


def test_units_with_si_multipliers_and_keywords(inst) -> None:
    inst.write("INST:SEL SINE;:FREQ:STOP 25.6 KHZ;:FREQ:STAR 2 MHZ")  # MHZ is megahertz
    assert codes(inst) == [-222]  # 2 MHz is out of range: value not changed
    assert inst.query("FREQ:STOP?") == "+2.56000000000E+004"
    inst.write("SWE:DWEL 20 MS")  # milliseconds
    assert inst.query("SWE:DWEL?") == "+2.00000000000E-002"
    assert inst.query("SWE:DWEL? UNIT") == '"S"'
    inst.write("SWE:DWEL MAX")
    assert inst.query("SWE:DWEL?") == "+3.27680000000E+004"
    inst.write("SWE:DWEL 5 FURLONGS")
    assert codes(inst) == [-131]
    inst.write("SWE:DWEL 0.5 CYCLE")  # less than one cycle is taken as one
    assert inst.query("SWE:DWEL?") == "+1.00000000000E+000"
    inst.write("SWE:DWEL 300 CYCLE")  # 1..234 cycles
    errors_found = errors(inst)
    assert errors_found == [(-222, "Data out of range; Out of range: value not changed.")]


def test_levels_keep_their_unit_and_convert(inst) -> None:
    """Levels accept DBVRMS, VPK, DBVPK, V, DBV, VRMS (and EU, DBEU); ? UNIT names the unit
    in use (chapters 18, 19)."""
    inst.write("SOUR:VOLT 0.5 VRMS")
    assert inst.query("SOUR:VOLT?") == "+5.00000000000E-001"
    assert inst.query("SOUR:VOLT? UNIT") == '"VRMS"'
    inst.write("SOUR:VOLT -6.02059991328 DBVPK")
    assert float(inst.query("SOUR:VOLT?")) == pytest.approx(-6.02059991328)
    inst.write("SOUR:VOLT 6 VPK")  # at most 5 Vpk
    assert codes(inst) == [-222]
    # ranges: a level that is not a range rounds up to the next one (2 dB steps, chapter 18)
    inst.write("VOLT2:RANG 1 VPK")  # -3.01 dBVrms -> the -3 dBVrms range
    assert inst.query("VOLT2:RANG? UNIT") == '"VPK"'
    assert float(inst.query("VOLT2:RANG?")) == pytest.approx(math.sqrt(2) * 10 ** (-3 / 20))
    assert inst.query("VOLT2:RANG:AUTO?") == "+0"  # a fixed range turns autorange off
    inst.write("VOLT2:RANG UP;:VOLT2:RANG -40")
    assert inst.query("VOLT2:RANG?") == "-3.90000000000E+001"
    # EU levels follow the input's transducer sensitivity
    inst.write("INST:SEL SINE;:VOLT4:RANG:UNIT:USER:SFAC 0.0102 V/EU;:VOLT4:RANG:UNIT:USER ON")
    inst.write("SOUR:VOLT:REF:CHAN INP4;:SOUR:VOLT:REF 1.5 EU")
    assert (inst.query("SOUR:VOLT:REF?"), inst.query("SOUR:VOLT:REF? UNIT")) == (
        "+1.50000000000E+000", '"EU"')
    assert codes(inst) == []


# -- chapter 18: swept-sine frequencies --------------------------------------------------------

def test_swept_sine_rounding_and_limits(inst) -> None:
    """Start, centre and manual round to the next lower 15.625 mHz step, stop to the next
    higher; four inputs halve the top frequency."""
    inst.write("INST:SEL SINE;:FREQ:STAR 10.01;:FREQ:STOP 20.01;:FREQ:MAN 15.01")
    assert inst.query("FREQ:STAR?") == "+1.00000000000E+001"
    assert inst.query("FREQ:STOP?") == "+2.00156250000E+001"
    assert inst.query("FREQ:MAN?") == "+1.50000000000E+001"
    inst.write("FREQ:STOP 51200")
    inst.write("INP4 ON")
    assert inst.query("FREQ:STOP?") == "+2.56000000000E+004"
    inst.write("FREQ:STOP 30000")
    assert codes(inst) == [-222]
    inst.write("INP4 OFF;:INST:SEL SINE;:FREQ:RES 0.01 HZ")  # 2.5 million points: refused
    assert codes(inst) == [-222]
    inst.write("FREQ:RES 1 PCT;:FREQ:RES? UNIT")
    assert inst.read() == '"PCT"'


def test_modes_keep_their_own_settings(inst) -> None:
    inst.write("INST:SEL SINE;:FREQ:STAR 20;:INST:SEL FFT;:FREQ:STAR 0;:FREQ:SPAN 800")
    assert float(inst.query("FREQ:SPAN?")) == 800.0
    inst.write("INST:SEL SINE")
    assert float(inst.query("FREQ:STAR?")) == 20.0
    inst.write("INST:NSEL 0")  # FFT is mode 0, swept sine 3 (chapter 13)
    assert float(inst.query("FREQ:SPAN?")) == 800.0 and inst.query("INST:NSEL?") == "+0"


@pytest.mark.parametrize(("command", "text"), [
    ("WIND HANN", "No WINDOW With SWEPT SINE Instrument Mode."),
    ("TRIG:SOUR BUS", "No TRIGGER With SWEPT SINE Instrument Mode."),
    ("AVER:COUN 4", "Measurement mode incompatible with command."),
    ("OUTP ON", "Measurement mode incompatible with command."),
    ("SOUR:FUNC RAND", "Measurement mode incompatible with command."),
    ("FREQ:SPAN:FULL", "Measurement mode incompatible with command."),
])
def test_fft_only_commands_conflict_in_swept_sine(inst, command, text) -> None:
    inst.write(f"INST:SEL SINE;:{command}")
    assert errors(inst) == [(-221, f"Settings conflict; {text}")]


def test_sine_only_commands_conflict_in_fft(inst) -> None:
    inst.write("SWE:DWEL 3 CYCLE;:FREQ:MAN 20;:SOUR:VOLT:AUTO ON")
    assert codes(inst) == [-221, -221, -221]


def test_missing_options_give_the_manuals_errors(rm) -> None:
    with SimulatedAnalyserServer("table", options=("1D2",)) as srv:
        inst = open_socket(rm, srv)
        inst.write("INP4 ON;:INST:SEL OCT")
        found = errors(inst)
        inst.close()
    assert found == [(-241, "Hardware missing; OPTION AY6 Add 2 Input Channels not installed."),
                     (-200, "Execution error; OPTION 1D1, Octave Measurements not installed.")]


# -- chapters 6, 23: traces ---------------------------------------------------------------------

def test_a_swept_sine_trace_holds_401_or_801_points(inst) -> None:
    run_sweep(inst, points=21, cycles=5)
    inst.write("FORM REAL,64;:CALC1:FEED 'XFR:POW:RAT 2,1';:TRAC:DATA D1,TRAC1")
    x = real64(inst, "TRAC:X? D1")
    y = real64(inst, "TRAC:DATA? D1")
    assert x.size == 401 and y.size == 802
    np.testing.assert_allclose(x[:21], np.linspace(20, 120, 21))
    assert np.all(x[21:] == MARKER) and np.all(y[42:] == MARKER)
    assert inst.query("CALC1:DATA:HEAD:POIN?") == "+401"
    run_sweep(inst, points=402, cycles=1, stop=121.0)
    assert inst.query("CALC1:DATA:HEAD:POIN?") == "+801"
    inst.write("FORM REAL,32")
    y32 = inst.query_binary_values("CALC1:DATA?", datatype="f", is_big_endian=True,
                                   container=np.array)
    assert y32.size == 801 and y32[-1] == np.float32(MARKER)


def test_data_formats_agree(inst) -> None:
    run_sweep(inst, points=11, cycles=5)
    inst.write("CALC1:FEED 'XFR:POW:RAT 4,3';:CALC1:FORM NYQ;:FORM REAL,64")
    pairs = real64(inst, "CALC1:DATA?")[:22]
    inst.write("FORM ASC,12")
    ascii_pairs = np.array(inst.query("CALC1:DATA?").split(","), float)[:22]
    np.testing.assert_allclose(ascii_pairs, pairs, rtol=1e-11)
    z = pairs[0::2] + 1j * pairs[1::2]
    inst.write("CALC1:FORM MLOG")
    db = np.array(inst.query("CALC1:DATA?").split(","), float)[:11]
    np.testing.assert_allclose(db, 20 * np.log10(np.abs(z)), atol=1e-9)
    inst.write("CALC1:FORM PHAS;:CALC1:UNIT:ANGL RAD")
    phase = np.array(inst.query("CALC1:DATA?").split(","), float)[:11]
    np.testing.assert_allclose(phase, np.angle(z), atol=1e-9)


def test_swept_sine_measures_the_rigs_frequency_response(inst, server) -> None:
    run_sweep(inst, points=41, start=20, stop=60, cycles=50)
    inst.write("FORM REAL,64;:CALC1:FEED 'XFR:POW:RAT 4,3';:TRAC:DATA D1,TRAC1")
    x = real64(inst, "TRAC:X? D1")[:41]
    y = real64(inst, "TRAC:DATA? D1")[:82]
    measured = y[0::2] + 1j * y[1::2]
    expected = frf(server.analyser.simulator.rig, x, 4, 3)
    assert np.median(np.abs(measured / expected - 1)) < 2e-3


# -- FFT mode ------------------------------------------------------------------------------------

def test_fft_resolution_of_1600_lines_with_one_or_two_inputs_only(inst) -> None:
    """1600-line displays exist "only in 1 or 2 channel mode" (the specifications); the
    programming guide's table stops at 800. Four inputs on bring the resolution down to 800."""
    inst.write("*RST;*CLS;:INST:SEL FFT;:FREQ:RES 1600")
    assert float(inst.query("FREQ:RES?")) == 1600
    assert inst.query("CALC1:DATA:HEAD:POIN?") == "+1601"
    inst.write("INP3 ON;:INP4 ON")
    assert float(inst.query("FREQ:RES?")) == 800
    inst.write("FREQ:RES 1600")
    assert codes(inst) == [-222]
    inst.write("FREQ:RES MAX")
    assert float(inst.query("FREQ:RES?")) == 800
    inst.write("INP3 OFF;:INP4 OFF;:FREQ:RES 1000")  # a value between: the next one up
    assert float(inst.query("FREQ:RES?")) == 1600
    inst.write(":TCAP:DEL")  # no capture buffer to remove: accepted, as the manual says
    assert codes(inst) == []


def fft_setup(inst, source: str, window: str, averages: int = 20, span: float = 200.0) -> None:
    inst.write("*RST;:INP4 ON;:REF PAIR")
    inst.write(f"FREQ:SPAN:LINK STAR;:FREQ:STAR 0;:FREQ:SPAN {span} HZ;:FREQ:RES 400")
    inst.write(f"SOUR:FUNC {source};:SOUR:FREQ 25;:SOUR:VOLT 0.5 VPK;:OUTP ON;:WIND {window}")
    inst.write(f"AVER ON;:AVER:COUN {averages};:FORM REAL,64")
    inst.write("CALC1:FEED 'XFR:POW:RAT 4,3';:CALC2:FEED 'XFR:POW:COH 3,4';:CALC2:FORM MLIN")
    inst.write("ABOR;:INIT:IMM")
    assert inst.query("*OPC?") == "+1"


def read_h1(inst) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Frequencies, complex H1 (trace A) and coherence (trace B) of the finished measurement."""
    inst.write("CALC1:FORM REAL")
    real = real64(inst, "CALC1:DATA?")
    inst.write("CALC1:FORM IMAG")
    imag = real64(inst, "CALC1:DATA?")
    return real64(inst, "CALC1:X:DATA?"), real + 1j * imag, real64(inst, "CALC2:DATA?")


def test_fft_h1_with_a_periodic_chirp_is_the_rigs_response(rm) -> None:
    """A periodic chirp through the noiseless rig, uniform window: H1 is the rig's response
    line by line and the coherence is one (the record holds whole periods)."""
    rig = load_preset("soft-0").noiseless()
    with SimulatedAnalyserServer(rig, seed=1) as srv:
        inst = open_socket(rm, srv)
        fft_setup(inst, "PCH", "UNIF", averages=4)
        x, h1, coherence = read_h1(inst)
        inst.write("TRAC:DATA D1,TRAC1")
        stored = real64(inst, "TRAC:X? D1")
        found = codes(inst)
        inst.close()
    assert x.size == h1.size == 401 and x[-1] == pytest.approx(200.0)
    assert stored.size == 513  # the stored trace holds the alias lines (chapter 23)
    band = (x >= 2) & (x <= 180)
    expected = frf(rig, x[band], 4, 3)
    assert np.max(np.abs(h1[band] / expected - 1)) < 2e-3
    assert np.min(coherence[band]) > 0.999
    assert found == []


def test_fft_h1_with_random_noise_and_a_hann_window(inst, server) -> None:
    """Random excitation, Hann window, 20 averages on the noisy rig: H1 within a few per cent
    where the coherence is high."""
    fft_setup(inst, "RAND", "HANN")
    x, h1, coherence = read_h1(inst)
    good = (x >= 20) & (x <= 180) & (coherence > 0.95)
    assert good.sum() > 200
    expected = frf(server.analyser.simulator.rig, x[good], 4, 3)
    assert np.median(np.abs(h1[good] / expected - 1)) < 0.03


def test_fft_noise_floor_with_the_source_off_is_the_transducers_noise(inst, server) -> None:
    """RMS-averaged power spectra of the table accelerometer with no drive: the density is
    the rig file's noise (transducer plus the analyser's floor on its range)."""
    inst.write("*RST;:FREQ:SPAN:LINK STAR;:FREQ:SPAN 400 HZ;:FREQ:RES 400;:OUTP OFF")
    inst.write("WIND UNIF;:AVER ON;:AVER:COUN 60;:FORM REAL,64")
    inst.write("CALC1:FEED 'XFR:POW 2';:ABOR;:INIT:IMM")
    assert inst.query("*OPC?") == "+1"
    inst.write("TRAC:DATA D1,TRAC1")
    power = real64(inst, "TRAC:DATA? D1")[50:401]  # rms² per 1 Hz line, away from DC
    range_vpk = math.sqrt(2) * 10 ** (float(inst.query("VOLT2:RANG?")) / 20)
    noise = server.analyser.simulator.rig.noise
    sensor = (noise.table_acceleration_m_per_s2_per_sqrt_hz * 0.0102) ** 2
    adc = 10 ** (noise.adc_noise_db_re_range_per_sqrt_hz / 10) * range_vpk**2
    density = np.mean(power) / 1.0  # uniform window: noise bandwidth 1 line = 1 Hz
    assert density == pytest.approx(sensor + adc, rel=0.15)


def test_a_power_spectrum_of_zero_holds_the_no_data_marker_in_db(rm) -> None:
    """The dB value of zero is minus infinity: the analyser puts its marker there."""
    with SimulatedAnalyserServer(load_preset("table").noiseless(), seed=1) as srv:
        inst = open_socket(rm, srv)
        inst.write("*RST;:OUTP OFF;:FORM REAL,64;:CALC1:FEED 'XFR:POW 1';:CALC1:FORM MLOG")
        inst.write("ABOR;:INIT:IMM")
        assert inst.query("*OPC?") == "+1"
        values = real64(inst, "CALC1:DATA?")
        inst.close()
    assert values.size == 401 and np.all(values == MARKER)


# -- timing and status while a sweep runs -------------------------------------------------

def test_a_paced_sweep_takes_the_instruments_time_and_shows_it(rm) -> None:
    """Per point: settle + integration + the analyser's own 0.45 s; STAT:OPER shows measuring
    (16) and settling (2) as it runs; *OPC sets ESR bit 0 at the end."""
    with SimulatedAnalyserServer("soft-0", pace=10.0, seed=1) as srv:
        inst = open_socket(rm, srv)
        inst.write(SETUP_4CH + ";:FREQ:STAR 20;STOP 40;:FREQ:RES 5 PNT/SWP")
        inst.write("SWE:STIM 10 CYCLE;DWEL 10 CYCLE;:SOUR:VOLT 0.1 VPK;:*CLS")
        expected = sum(20 / f + 0.45 for f in (20, 25, 30, 35, 40)) / 10.0
        started = time.monotonic()
        inst.write("ABOR;:INIT:IMM;*OPC")
        seen = set()
        while not int(inst.query("*ESR?")) & 1:
            seen.add(int(inst.query("STAT:OPER:COND?")))
            time.sleep(0.01)
        elapsed = time.monotonic() - started
        inst.close()
    assert expected * 0.9 < elapsed < expected + 1.0
    assert any(bits & 16 for bits in seen) and any(bits & 2 for bits in seen)


def test_an_auto_calibration_pauses_the_sweep_and_sets_bit_0(rm) -> None:
    with SimulatedAnalyserServer("soft-0", pace=20.0, seed=1) as srv:
        inst = open_socket(rm, srv)
        inst.write(SETUP_4CH + ";:FREQ:STAR 20;STOP 22;:FREQ:RES 3 PNT/SWP;:SOUR:VOLT 0.1 VPK")
        srv.faults.autocal(":INIT:IMM")
        inst.write("ABOR;:INIT:IMM;*OPC")
        calibrating = False
        while not int(inst.query("*ESR?")) & 1:
            calibrating |= bool(int(inst.query("STAT:OPER:COND?")) & 1)
            time.sleep(0.01)
        inst.close()
    assert calibrating


def test_a_zero_source_pauses_the_sweep(inst, server) -> None:
    inst.write(SETUP_4CH + ";:SOUR:VOLT 0 VPK;:ABOR;:INIT:IMM")
    assert errors(inst) == [(-221, "Settings conflict; SOURCE LEVEL is 0 Volts, "
                                   "measurement paused.")]
    assert server.analyser.state == "PAUSED"
    inst.write("SOUR:VOLT 0.1 VPK;:INIT:CONT ON")
    assert server.analyser.wait_until_idle(30)


# -- wiring faults (rigsim.faults) ----------------------------------------------------------

@pytest.mark.parametrize(("spec", "check"), [
    ("invert=4", lambda z, good: np.allclose(z, -good, rtol=1e-6)),
    ("gain=4:10", lambda z, good: np.allclose(z, 10 * good, rtol=1e-6)),
])
def test_wiring_faults_change_what_an_input_reads(rm, spec, check) -> None:
    def measure(fault: str | None) -> np.ndarray:
        with SimulatedAnalyserServer(load_preset("soft-0").noiseless(), seed=1) as srv:
            if fault:
                srv.faults.add(parse_fault_spec(fault))
            inst = open_socket(rm, srv)
            run_sweep(inst, points=5, start=30, stop=34, cycles=20)
            inst.write("FORM REAL,64;:CALC1:FEED 'XFR:POW:RAT 4,3';:TRAC:DATA D1,TRAC1")
            values = real64(inst, "TRAC:DATA? D1")[:10]
            inst.close()
        return values[0::2] + 1j * values[1::2]

    assert check(measure(spec), measure(None))


def _linear_and_variance(rm, fault: str | None, start: float, stop: float, points: int,
                         cycles: int = 100, noiseless: bool = True
                         ) -> tuple[np.ndarray, np.ndarray]:
    """Input 3's linear spectrum (complex volts) and normalized variance over a swept sine."""
    rig = load_preset("soft-0")
    with SimulatedAnalyserServer(rig.noiseless() if noiseless else rig, seed=1) as srv:
        if fault:
            srv.faults.add(parse_fault_spec(fault))
        inst = open_socket(rm, srv)
        run_sweep(inst, points=points, start=start, stop=stop, cycles=cycles)
        inst.write("FORM REAL,64;:CALC1:FEED 'XFR:POW:LIN 3';:TRAC:DATA D1,TRAC1")
        values = real64(inst, "TRAC:DATA? D1")[:2 * points]
        inst.write("CALC2:FEED 'XFR:POW:VAR 3';:TRAC:DATA D2,TRAC2")
        variance = real64(inst, "TRAC:DATA? D2")[:points]
        inst.close()
    return values[0::2] + 1j * values[1::2], variance


def test_mains_hum_on_an_input_reads_through_the_integration_window(rm) -> None:
    """hum=3:V: a 50 Hz sine on input 3, not locked to the source. A point at 50 Hz reads it
    whole, at a phase of its own; a point 0.5 Hz away, integrating 100 of its cycles (2.02 s at
    49.5 Hz), reads near the window's null (sinc 1.01: 1 %); 20 Hz away almost nothing. The
    normalized variance carries its power."""
    good, good_var = _linear_and_variance(rm, None, 49.0, 51.0, 9)
    hum, hum_var = _linear_and_variance(rm, "hum=3:0.01", 49.0, 51.0, 9)
    change = np.abs(hum - good)  # 49.0, 49.25, ..., 51.0 Hz
    assert change[4] == pytest.approx(0.01, rel=0.05)  # 100 cycles at 50 Hz: exactly 2 s
    assert change[2] < 0.02 * 0.01 and change[6] < 0.02 * 0.01  # near the window's nulls
    assert change[3] > 0.5 * 0.01  # 49.75 Hz: sinc(0.5) = 0.64 of it
    assert hum_var[4] > 1e3 * max(good_var[4], 1e-12)
    far, _ = _linear_and_variance(rm, "hum=3:0.01", 70.0, 70.0, 1)
    clean, _ = _linear_and_variance(rm, None, 70.0, 70.0, 1)
    assert np.abs(far - clean)[0] < 0.02 * 0.01


@pytest.mark.parametrize("spec", ["hum=3", "hum=3:x", "hum=3:0", "hum=3:0.005:60:1",
                                  "hum=5:0.005", "hum=3:0.005:2000"])
def test_a_hum_that_is_no_hum_is_refused_by_name(spec) -> None:
    from rigsim.faults import FaultSpecError

    with pytest.raises(FaultSpecError, match="hum"):
        parse_fault_spec(spec)
    assert parse_fault_spec("hum=3:0.005:60").frequency_hz == 60.0


def test_a_wiring_fault_leaves_the_normalized_variance_positive_and_its_own(rm) -> None:
    """An inverted or amplified input: the variance relative to the signal does not change
    (it was multiplied by the gain, negative for an inverted input)."""
    _, good = _linear_and_variance(rm, None, 30.0, 34.0, 5, cycles=20, noiseless=False)
    assert np.all(good > 0)
    for fault in ("invert=3", "gain=3:10"):
        _, faulty = _linear_and_variance(rm, fault, 30.0, 34.0, 5, cycles=20, noiseless=False)
        assert np.allclose(faulty, good, rtol=1e-6, atol=0.0)
