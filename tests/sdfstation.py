"""The station the SDF import tests convert volt-over-volt responses with."""

from stationfile import station_toml

#: Station of the tests: force transducer on input 1, table accelerometer on input 2.
SENSITIVITY_F_V_PER_N = 0.01124
SENSITIVITY_A_V_PER_M_S2 = 0.0102
STATION = station_toml("GPIB0::11::INSTR", force_v_per_n=SENSITIVITY_F_V_PER_N,
                       acceleration_v_per_m_s2=SENSITIVITY_A_V_PER_M_S2,
                       device_force_v_per_n=0.02, device_acceleration_v_per_m_s2=0.005)
