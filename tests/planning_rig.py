"""The time-domain rig simulator as a *measure* callable for the planning core, and the rigs the
planning tests race on.

The measure callable (:mod:`viscorig.stations.simpoints`, where ``viscorig plan`` finds floors with
it) measures on :class:`rigsim.engine.RigSimulator` as the analyser's manual sweep would; it
converts the simulator's channel amplitudes into the stored quantities and shares no model code
with the identification core.
"""

from __future__ import annotations

from viscorig.stations.simpoints import SimulatedRig, load, paper_sweep

__all__ = ["ADAPTIVE_SEQUENCE", "TABLE", "VOIGT_RIG", "VOIGT_TRUTH", "SimulatedRig", "load",
           "paper_sweep"]

#: The paper's table (physics.md) and transducers, shaker and sensor noise of the presets.
VOIGT_RIG = """
[table]
mass_kg = 3.4
stiffness_n_per_m = 50194.0
damping_ns_per_m = 5.05

[device]
mass_kg = 0.15
model = "voigt"
stiffness_n_per_m = 149986.61
damping_ns_per_m = 114.59

[sensors]
force_v_per_n = 0.01124
acceleration_v_per_m_s2 = 0.0102

[shaker]
force_n_per_v = 50.0
force_limit_n = 100.0

[noise]
excitation_force_n_per_sqrt_hz = 2.0e-4
table_acceleration_m_per_s2_per_sqrt_hz = 2.0e-5
device_force_n_per_sqrt_hz = 2.0e-4
disc_acceleration_m_per_s2_per_sqrt_hz = 2.0e-5
adc_noise_db_re_range_per_sqrt_hz = -100.0
"""

#: The truth of :data:`VOIGT_RIG` in the model's names (a rigid link: the disc mass is M_v).
VOIGT_TRUTH = {"M_s": 3.4, "K_s": 50194.0, "C_s": 5.05, "K_v": 149986.61, "C_v": 114.59,
               "M_v": 0.15}  # fmt: skip
TABLE = {name: VOIGT_TRUTH[name] for name in ("M_s", "K_s", "C_s")}

#: A sequence of one adaptive Voigt sweep on the Voigt rig; format it with the targets ``K_v``,
#: ``C_v`` and ``extra`` (more lines of the sweep step).
ADAPTIVE_SEQUENCE = """
name = "adaptive-voigt"
[defaults]
band_hz = [20.0, 120.0]
level = "1.4 m/s^2"
[[steps]]
type = "prompt"
message = "Mount the Voigt damper."
[[steps]]
type = "sweep"
run = "voigt"
specimen = "voigt damper"
plan = "adaptive"
model = "voigt"
target_uncertainty = {{ K_v = {K_v}, C_v = {C_v} }}
{extra}
"""
