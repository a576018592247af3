"""Runs measured on the time-domain rig simulator, as plain arrays, for identification tests.

The simulator (``rigsim``) integrates the rig's equations of motion and measures like the
analyser; nothing here shares model code with ``viscorig``. A run is swept as the paper does:
stepped sine, settle and integrate a number of periods per point, the source adjusted so that
the reference acceleration (the disc's, or the table's on a bare table) holds ``level``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from rigsim.engine import RigSimulator
from rigsim.measurement import SourceControl, SweepRequest
from rigsim.rigfile import Rig, load_preset, parse_rig

from viscorig.fitting import FrfData

#: Paper's table (physics.md).
PAPER_TABLE = {"mass_kg": 3.4, "stiffness_n_per_m": 50194.0, "damping_ns_per_m": 5.05}

#: Sensor noise that gives a relative FRF scatter of roughly 1e-4..1e-3 at 1 m/s².
DEFAULT_NOISE = {
    "excitation_force_n_per_sqrt_hz": 2e-3,
    "table_acceleration_m_per_s2_per_sqrt_hz": 2e-4,
    "device_force_n_per_sqrt_hz": 2e-3,
    "disc_acceleration_m_per_s2_per_sqrt_hz": 2e-4,
}


@dataclass
class SimulatedRun:
    """A run in the units of a campaign file (see data-format.md)."""

    frequency_hz: np.ndarray
    time_s: np.ndarray
    accelerance_table: np.ndarray
    accelerance_support: np.ndarray
    reference_amplitude: np.ndarray
    force_amplitude: np.ndarray
    flags: np.ndarray
    rig: Rig
    variance_table: np.ndarray | None = None
    variance_support: np.ndarray | None = None

    def frf_data(self, name: str = "simulated", variance: bool = True) -> FrfData:
        """The run as a :class:`viscorig.fitting.FrfData` (plain arrays, no storage), with the
        analyser's normalized variances as a campaign file holds them (``variance=False``:
        without, as a file imported from elsewhere)."""
        return FrfData(
            self.frequency_hz,
            self.accelerance_table,
            self.accelerance_support,
            self.time_s,
            self.reference_amplitude,
            name=name,
            variance_table=self.variance_table if variance else None,
            variance_support=self.variance_support if variance else None,
        )


def _toml_value(value: object) -> str:
    if isinstance(value, str):
        return f'"{value}"'
    if isinstance(value, list | tuple):
        return "[" + ", ".join(_toml_value(v) for v in value) + "]"
    return repr(float(value)) if isinstance(value, float) else str(value)


def rig_text(
    device: dict | None = None,
    *,
    table: dict | None = None,
    load_cell_n_per_m: float | None = None,
    fixtures: list[dict] | None = None,
    noise: dict | None = None,
    extra: str = "",
) -> str:
    """TOML text of a rig: the paper's table unless given, an optional ``[device]``."""
    sections = [("table", table or PAPER_TABLE)]
    if device is not None:
        sections.append(("device", device))
    if load_cell_n_per_m is not None:
        sections.append(("load_cell", {"stiffness_n_per_m": load_cell_n_per_m}))
    if noise is not None:
        sections.append(("noise", noise))
    lines = []
    for name, values in sections:
        lines.append(f"[{name}]")
        lines += [f"{key} = {_toml_value(value)}" for key, value in values.items()]
    for fixture in fixtures or []:
        lines.append("[[fixture]]")
        lines += [f"{key} = {_toml_value(value)}" for key, value in fixture.items()]
    return "\n".join(lines) + "\n" + extra


def simulate_run(
    rig: Rig | str,
    *,
    seed: int = 0,
    start_hz: float = 20.0,
    stop_hz: float = 120.0,
    step_hz: float = 0.25,
    level_m_per_s2: float = 1.0,
    settle_cycles: float = 100.0,
    integrate_cycles: float = 100.0,
    direction: str = "up",
    simulator: RigSimulator | None = None,
) -> SimulatedRun:
    """Sweep a rig (a :class:`Rig`, TOML text, or a preset name) and return its FRFs.

    Bare table (no device): the controller holds the table's acceleration and the support FRF is
    NaN, as a campaign file stores it. ``direction="down"`` sweeps from ``stop_hz`` down.
    ``simulator``: measure on this simulator (its clock and state go on from its last sweep;
    ``time_s`` stays on the simulator's clock) instead of a fresh one.
    """
    if isinstance(rig, str):
        rig = parse_rig(rig, "<test rig>") if "\n" in rig or "[" in rig else load_preset(rig)
    frequency = np.arange(start_hz, stop_hz + step_hz / 2, step_hz)
    if direction == "down":
        frequency = frequency[::-1]
    sensors = rig.sensors
    reference_channel = 4 if rig.device is not None else 2
    source_limit_v = rig.shaker.force_limit_n / rig.shaker.force_n_per_v
    control = SourceControl(
        source_vpk=0.05,
        auto_level=True,
        reference_channel=reference_channel,
        reference_vpk=level_m_per_s2 * sensors.acceleration_v_per_m_s2,
        tolerance_db=0.5,
        source_limit_vpk=source_limit_v,
    )
    request = SweepRequest(
        frequency_hz=frequency,
        settle_s=settle_cycles / frequency,
        integrate_s=integrate_cycles / frequency,
        control=control,
    )
    record = (simulator or RigSimulator(rig, seed=seed)).sweep(request)
    volts = record.channel_v
    force_e = volts[:, 0] / sensors.force_v_per_n
    accel_s = volts[:, 1] / sensors.acceleration_v_per_m_s2
    force_v = volts[:, 2] / sensors.force_v_per_n
    accel_v = volts[:, 3] / sensors.acceleration_v_per_m_s2
    # The analyser's normalized variance of a channel ratio: the sum of both channels'.
    variance_table = record.variance[:, 0] + record.variance[:, 1]
    variance_support = record.variance[:, 2] + record.variance[:, 3]
    if rig.device is None:
        support = np.full(frequency.shape, np.nan + 1j * np.nan)
        reference = np.abs(accel_s)
        variance_support = np.full(frequency.shape, np.nan)
    else:
        support = accel_v / force_v
        reference = np.abs(accel_v)
    flags = (
        (~record.level_reached).astype(np.uint16)
        | (record.overload.any(axis=1).astype(np.uint16) << 1)
        | (record.source_limited.astype(np.uint16) << 2)
        | (record.extras["force_limited"].astype(np.uint16) << 3)
    )
    return SimulatedRun(
        frequency_hz=frequency,
        time_s=record.end_time_s,
        accelerance_table=accel_s / force_e,
        accelerance_support=support,
        reference_amplitude=reference,
        force_amplitude=np.abs(force_e),
        flags=flags,
        rig=rig,
        variance_table=variance_table,
        variance_support=variance_support,
    )
