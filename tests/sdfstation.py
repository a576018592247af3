"""The station the SDF import tests convert volt-over-volt responses with."""

#: Station of the tests: force transducer on input 1, table accelerometer on input 2.
SENSITIVITY_F_V_PER_N = 0.01124
SENSITIVITY_A_V_PER_M_S2 = 0.0102
STATION = f"""
resource = "GPIB0::11::INSTR"
[channels]
excitation_force = 1
table_acceleration = 2
device_force = 3
device_acceleration = 4
[sensitivity]
excitation_force_v_per_n = {SENSITIVITY_F_V_PER_N}
table_acceleration_v_per_m_s2 = {SENSITIVITY_A_V_PER_M_S2}
device_force_v_per_n = 0.02
device_acceleration_v_per_m_s2 = 0.005
[shaker]
force_limit_n = 100.0
[source]
limit_v = 2.0
"""
