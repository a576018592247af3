"""End to end: an independent client, following only the 35670A manual's commands, measures the
two accelerances of a simulated rig through pyvisa-py and gets the closed form of physics.md.

The client here is written from the manual's facts alone (not the project's driver): four
channels, ``REF PAIR``, engineering units from the rig file's ``[sensors]``, auto level on the
disc accelerometer (INP4), REAL,64 reads of data registers, X axis read, never computed.
"""

from __future__ import annotations

import time

import numpy as np
import pytest
import pyvisa
from rigsim.rigfile import load_rig
from rigsim.server import SimulatedAnalyserServer

RIG_TOML = """
name = "voigt-e2e"
[table]
mass_kg = 3.4
stiffness_n_per_m = 50194.0
damping_ns_per_m = 5.05

[device]
mass_kg = 0.25
model = "voigt"
stiffness_n_per_m = 149986.61
damping_ns_per_m = 114.59

[load_cell]
stiffness_n_per_m = 2.0e6

[sensors]
force_v_per_n = 0.01124
acceleration_v_per_m_s2 = 0.0102

[noise]
excitation_force_n_per_sqrt_hz = 2.0e-4
table_acceleration_m_per_s2_per_sqrt_hz = 2.0e-5
device_force_n_per_sqrt_hz = 2.0e-4
disc_acceleration_m_per_s2_per_sqrt_hz = 2.0e-5
"""


def closed_form(rig, frequency_hz: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Accelerances ẍ_s/F_e and ẍ_v/F_v of the two-DOF rig (physics.md, consistent signs)."""
    w = 2 * np.pi * frequency_hz
    M_s, K_s, C_s = rig.table.mass_kg, rig.table.stiffness_n_per_m, rig.table.damping_ns_per_m
    K_c = rig.load_cell.stiffness_n_per_m
    M_v = rig.device.mass_kg
    K_star = rig.device.material.stiffness_n_per_m + 1j * w * rig.device.material.damping_ns_per_m
    D_s = K_s + K_c - w**2 * M_s + 1j * w * C_s
    D_v = K_c + K_star - w**2 * M_v
    det = D_s * D_v - K_c**2
    table = -(w**2) * D_v / det  # X_s/F_e = D_v/det, times -ω²
    support = -(w**2) / (K_star - w**2 * M_v)  # X_v/F_v = 1/(K* - ω² M_v), times -ω²
    return table, support


def read_real64(inst, query: str) -> np.ndarray:
    return inst.query_binary_values(query, datatype="d", is_big_endian=True, container=np.array)


def test_accelerances_match_the_closed_form(tmp_path) -> None:
    path = tmp_path / "voigt.toml"
    path.write_text(RIG_TOML)
    rig = load_rig(path)
    sensitivity = {1: rig.sensors.force_v_per_n, 2: rig.sensors.acceleration_v_per_m_s2,
                   3: rig.sensors.force_v_per_n, 4: rig.sensors.acceleration_v_per_m_s2}
    labels = {1: "N", 2: "M/S2", 3: "N", 4: "M/S2"}
    with SimulatedAnalyserServer(path, seed=11) as server:
        rm = pyvisa.ResourceManager("@py")
        inst = rm.open_resource(server.socket_resource, read_termination="\n",
                                write_termination="\n", timeout=10000)
        try:
            assert "35670A" in inst.query("*IDN?")
            assert {"1D2", "AY6"} <= set(inst.query("*OPT?").strip('"').split(","))
            inst.write("*RST;*CLS")
            inst.write("INST:SEL SINE")
            inst.write("INP2 ON;:INP3 ON;:INP4 ON;:REF PAIR")
            inst.write("FREQ:STAR 20 HZ;:FREQ:STOP 120 HZ")
            inst.write("SWE:SPAC LIN;:SWE:DIR UP;:SWE:MODE AUTO")
            inst.write("FREQ:RES:AUTO OFF;:FREQ:RES 0.25 HZ")
            inst.write("SWE:STIM 100 CYCLE;:SWE:DWEL 100 CYCLE")
            for n in range(1, 5):
                inst.write(f"VOLT{n}:RANG:AUTO ON")
                inst.write(f"VOLT{n}:RANG:UNIT:XDCR:LAB {labels[n]}")
                inst.write(f"VOLT{n}:RANG:UNIT:USER:SFAC {sensitivity[n]} V/EU")
                inst.write(f"VOLT{n}:RANG:UNIT:USER ON")
            inst.write("SOUR:VOLT 0.05 VPK")  # the sweep drives the source: no OUTP here
            inst.write("SOUR:VOLT:AUTO ON;:SOUR:VOLT:REF:CHAN INP4;:SOUR:VOLT:REF 1 EU")
            inst.write("SOUR:VOLT:REF:TOL 1 DB;:SOUR:VOLT:LIM 2 VPK")
            inst.write("CALC1:FEED 'XFR:POW:RAT 2,1';*WAI")
            inst.write("CALC2:FEED 'XFR:POW:RAT 4,3';*WAI")
            inst.write("CALC3:FEED 'XFR:POW:LIN 4';*WAI")
            inst.write("FORM REAL,64")
            assert inst.query("SYST:ERR?") == '+0,"No error"'
            inst.write("ABOR;:INIT:IMM")
            inst.write("*OPC")
            deadline = time.monotonic() + 60
            while not int(inst.query("*ESR?")) & 1:
                assert time.monotonic() < deadline, "sweep did not finish"
                time.sleep(0.01)
            data = {}
            for trace, register in ((1, "D1"), (2, "D2"), (3, "D3")):
                inst.write(f"TRAC:DATA {register},TRAC{trace}")
                pairs = read_real64(inst, f"TRAC:DATA? {register}")
                data[trace] = pairs[0::2] + 1j * pairs[1::2]
                frequency_hz = read_real64(inst, f"TRAC:X? {register}")
            overloads = int(inst.query("STAT:QUES:VOLT:EVEN?")) & 0x0F
            assert inst.query("SYST:ERR?") == '+0,"No error"'
        finally:
            inst.close()
            rm.close()
    assert frequency_hz.size == 401
    np.testing.assert_allclose(frequency_hz, 20 + 0.25 * np.arange(401))
    table, support = closed_form(rig, frequency_hz)
    error_table = np.abs(data[1] / table - 1)
    error_support = np.abs(data[2] / support - 1)
    # noise gives a relative scatter of 1e-4..1e-3 at 1 m/s² (rig noise densities, 100 cycles)
    assert np.median(error_table) < 1e-3 and np.max(error_table) < 1e-2
    assert np.median(error_support) < 1e-3 and np.max(error_support) < 2e-2
    # the auto level held the disc acceleration at 1 m/s² within the 1 dB tolerance
    level_db = 20 * np.log10(np.abs(data[3]))
    assert np.all(np.abs(level_db) <= 1.0 + 1e-6)
    assert overloads == 0


@pytest.mark.parametrize("bad", ["mass_kg = -1", "model = 'bogus'"])
def test_a_bad_rig_file_is_refused_before_serving(tmp_path, bad) -> None:
    from rigsim.rigfile import RigFileError

    path = tmp_path / "bad.toml"
    path.write_text(RIG_TOML.replace("mass_kg = 0.25", bad))
    with pytest.raises(RigFileError):
        SimulatedAnalyserServer(path)
