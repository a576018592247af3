"""A station file's text as a lab writes it: the four inputs wired in order, their
sensitivities, the shaker's limits and the source's."""

from __future__ import annotations


def station_toml(
    resource: str, *, force_v_per_n: float, acceleration_v_per_m_s2: float,
    device_force_v_per_n: float | None = None,
    device_acceleration_v_per_m_s2: float | None = None,
    force_limit_n: float = 100.0, gain_n_per_v: float | None = None,
    source_limit_v: float = 2.0,
) -> str:
    """The station's text; the device's sensors are the excitation's unless given."""
    device_force = force_v_per_n if device_force_v_per_n is None else device_force_v_per_n
    device_acceleration = (acceleration_v_per_m_s2 if device_acceleration_v_per_m_s2 is None
                           else device_acceleration_v_per_m_s2)
    gain = "" if gain_n_per_v is None else f"gain_n_per_v = {gain_n_per_v}\n"
    return f"""\
resource = "{resource}"
[channels]
excitation_force = 1
table_acceleration = 2
device_force = 3
device_acceleration = 4
[sensitivity]
excitation_force_v_per_n = {force_v_per_n}
table_acceleration_v_per_m_s2 = {acceleration_v_per_m_s2}
device_force_v_per_n = {device_force}
device_acceleration_v_per_m_s2 = {device_acceleration}
[shaker]
force_limit_n = {force_limit_n}
{gain}[source]
limit_v = {source_limit_v}
"""
