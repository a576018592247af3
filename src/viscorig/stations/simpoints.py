"""A simulated rig measured point list by point list, for plans run away from the analyser.

Measures the points a plan asks for on :class:`rigsim.engine.RigSimulator` as the analyser's
manual sweep would: each point settles and integrates its own number of cycles, the auto-level
controller holds the reference accelerometer at the level (every pass costing a settle and an
integration), the rig's state and the source level carry from point to point and from one call
to the next. ``viscorig plan`` and ``run`` use it to find the floor of an adaptive step on the
embedded simulated rig before anything is measured; the benchmarks race plans on it. (A run on
the embedded rig goes through the virtual analyser and the driver instead.)
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from rigsim.engine import RigSimulator
from rigsim.measurement import SourceControl, SweepRequest
from rigsim.rigfile import Rig, load_preset, parse_rig

from viscorig.planning import MeasuredPoints, PlannedPoint

__all__ = ["SimulatedRig", "load", "paper_sweep"]


def load(rig: Rig | str) -> Rig:
    """A rig from a :class:`Rig`, TOML text or a preset name."""
    if isinstance(rig, Rig):
        return rig
    return parse_rig(rig, "<test rig>") if "[" in rig else load_preset(rig)


class SimulatedRig:
    """A simulated rig measured point list by point list.

    Parameters
    ----------
    rig
        The rig (a :class:`Rig`, TOML text or a preset name).
    level_m_per_s2
        Reference acceleration (peak) the controller holds.
    seed
        Noise seed.
    tolerance_db
        Auto-level tolerance.
    """

    def __init__(
        self, rig: Rig | str, level_m_per_s2: float, *, seed: int = 0, tolerance_db: float = 1.0
    ) -> None:
        self.rig = load(rig)
        self.simulator = RigSimulator(self.rig, seed=seed)
        self.level = level_m_per_s2
        self.tolerance_db = tolerance_db
        self.source_vpk = 0.05

    def __call__(self, points: Sequence[PlannedPoint]) -> MeasuredPoints:
        f = np.array([p.frequency_hz for p in points], dtype=float)
        settle = np.array([p.settle_cycles for p in points], dtype=float)
        integrate = np.array([p.integrate_cycles for p in points], dtype=float)
        return self.measure(f, settle, integrate)

    def measure(self, frequency_hz, settle_cycles, integrate_cycles) -> MeasuredPoints:
        """Measure arrays of frequencies and cycles in order."""
        f = np.asarray(frequency_hz, dtype=float)
        settle = np.broadcast_to(np.asarray(settle_cycles, dtype=float), f.shape)
        integrate = np.broadcast_to(np.asarray(integrate_cycles, dtype=float), f.shape)
        rig = self.rig
        sensors = rig.sensors
        bare = rig.device is None
        control = SourceControl(
            source_vpk=self.source_vpk,
            auto_level=True,
            reference_channel=2 if bare else 4,
            reference_vpk=self.level * sensors.acceleration_v_per_m_s2,
            tolerance_db=self.tolerance_db,
            source_limit_vpk=rig.shaker.force_limit_n / rig.shaker.force_n_per_v,
        )
        start = self.simulator.clock_s
        record = self.simulator.sweep(
            SweepRequest(frequency_hz=f, settle_s=settle / f, integrate_s=integrate / f,
                         control=control)
        )  # fmt: skip
        self.source_vpk = float(record.source_vpk[-1])
        volts = record.channel_v
        force_e = volts[:, 0] / sensors.force_v_per_n
        accel_s = volts[:, 1] / sensors.acceleration_v_per_m_s2
        force_v = volts[:, 2] / sensors.force_v_per_n
        accel_v = volts[:, 3] / sensors.acceleration_v_per_m_s2
        flags = (
            (~record.level_reached).astype(np.uint16)
            | (record.overload.any(axis=1).astype(np.uint16) << 1)
            | (record.source_limited.astype(np.uint16) << 2)
            | (record.extras["force_limited"].astype(np.uint16) << 3)
        )
        ends = record.end_time_s
        return MeasuredPoints(
            frequency_hz=f,
            accelerance_table=np.asarray(accel_s / force_e, dtype=np.complex128),
            accelerance_support=(None if bare
                                 else np.asarray(accel_v / force_v, dtype=np.complex128)),
            reference_amplitude=np.abs(accel_s if bare else accel_v),
            force_amplitude=np.abs(force_e),
            settle_cycles=settle.astype(np.int64),
            integrate_cycles=integrate.astype(np.int64),
            duration_s=np.diff(np.concatenate([[start], ends])),
            variance_table=record.variance[:, 0] + record.variance[:, 1],
            variance_support=None if bare else record.variance[:, 2] + record.variance[:, 3],
            flags=np.asarray(flags, dtype=np.uint16),
        )


def paper_sweep(
    rig: SimulatedRig, band_hz=(20.0, 120.0), step_hz=0.25, settle=100, integrate=100
) -> MeasuredPoints:
    """The paper's plan: an upward linear sweep, the same cycles at every point."""
    f = np.arange(band_hz[0], band_hz[1] + step_hz / 2, step_hz)
    return rig.measure(f, settle, integrate)
