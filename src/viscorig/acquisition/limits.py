"""Safety limits, force estimates and point flags of a sweep (pure functions).

The source limit comes from the station's shaker before the source is ever switched on; the
force a sweep will need is predicted before it starts, from a low-level probe of the mounted rig
(:func:`estimate_force_from_probe`) or from what is already known (:func:`estimate_force`); every
point gets the flags of data-format.md from what the analyser measured.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from viscorig.analyser import ANALYSER_SOURCE_MAX_V
from viscorig.storage import (
    FORCE_ABOVE_SHAKER_LIMIT,
    INPUT_OVERLOAD,
    LEVEL_NOT_REACHED,
    SOURCE_AT_LIMIT,
)

#: A force within this many dB below the shaker limit counts as "at the limit": the analyser's
#: input limit held it there. Further below, a missed level means the source limit was binding.
AT_FORCE_LIMIT_DB = 0.5
#: Force flagged as above the shaker limit only beyond this fraction over it: the input-limit
#: controller holds the force at the limit, and transducer noise must not flag those points.
FORCE_LIMIT_SLACK = 0.01
#: A reduced sweep aims this far below the shaker limit (the estimate is rough).
REDUCE_MARGIN = 0.9
#: A probe measures at this fraction of the run's level (-20 dB): a specimen ten times stiffer
#: than one that just fits under the shaker limit still fits under it during the probe, and the
#: source and input limits (set first) hold anything stiffer.
PROBE_LEVEL_FRACTION = 0.1
#: A reference reading this far below the level asked for (60 dB: a thousand times) cannot be a
#: rig that is merely too stiff or held back by a limit: the accelerometer does not see the
#: motion, so the wiring or the mounting is wrong. Advice built on it would be absurd.
DEAD_REFERENCE_DB = 60.0
#: A shaker force below this fraction of its limit means the shaker is hardly driven.
UNDRIVEN_FORCE_FRACTION = 0.01


def source_limit_v(
    station_limit_v: float, force_limit_n: float, gain_n_per_v: float | None
) -> float:
    """Highest source output for a sweep, V peak.

    The station's own source limit, lowered to ``force_limit_n / gain_n_per_v`` when the
    shaker's gain is known (the source then cannot drive the shaker past its limit even if the
    analyser's input limit failed), and never above the analyser's 5 V.
    """
    limit = min(float(station_limit_v), ANALYSER_SOURCE_MAX_V)
    if gain_n_per_v:
        limit = min(limit, float(force_limit_n) / float(gain_n_per_v))
    return limit


@dataclass(frozen=True)
class RigEstimate:
    """Rough mechanical parameters for a force estimate (SI).

    Table ``M_s, K_s, C_s``; specimen ``K, C, M`` (Voigt equivalents) or zero when unknown.
    """

    table_mass_kg: float
    table_stiffness_n_per_m: float
    table_damping_ns_per_m: float
    specimen_stiffness_n_per_m: float = 0.0
    specimen_damping_ns_per_m: float = 0.0
    specimen_mass_kg: float = 0.0
    basis: str = ""
    """Where the numbers come from, for the operator."""
    motion_ratio: float = 1.0
    """|ẍ_s / ẍ_ref|: how much more the table moves than the reference accelerometer (the disc,
    behind a compliant load cell); 1 for a rigid link or a bare table."""

    def dynamic_stiffness(self, frequency_hz: ArrayLike) -> NDArray[np.complex128]:
        """F_e / X_s of the rig with a rigid link: K − ω² M + iω C, N/m."""
        omega = 2.0 * np.pi * np.asarray(frequency_hz, dtype=float)
        stiffness = self.table_stiffness_n_per_m + self.specimen_stiffness_n_per_m
        mass = self.table_mass_kg + self.specimen_mass_kg
        damping = self.table_damping_ns_per_m + self.specimen_damping_ns_per_m
        return stiffness - omega**2 * mass + 1j * omega * damping


@dataclass(frozen=True)
class ProbeReading:
    """One low-level point measured before a sweep: the rig's dynamic stiffness there."""

    frequency_hz: float
    dynamic_stiffness_n_per_m: complex
    """F_e / X_s = -ω² / (ẍ_s / F_e), measured (valid whatever level the controller reached)."""
    level_m_per_s2: float
    """Reference level the probe asked for."""
    reference_m_per_s2: float
    """Reference amplitude reached."""
    force_n: float
    """Shaker force |F_e| during the probe."""
    flags: int
    """Point flags (data-format.md) against the probe's level and the shaker limit."""
    test_time_s: float
    """Settle and integration time of the probe point."""

    @property
    def motion_ratio(self) -> float:
        """|ẍ_s / ẍ_ref| = |F_e| ω² / (|F_e/X_s| |ẍ_ref|): the table moves more than the disc
        behind a compliant load cell, so holding the disc's level takes more force."""
        omega2 = (2.0 * math.pi * self.frequency_hz) ** 2
        return self.force_n * omega2 / (abs(complex(self.dynamic_stiffness_n_per_m))
                                        * self.reference_m_per_s2)

    @property
    def shortfall_db(self) -> float:
        """How far the reference stayed below the level asked for, dB (inf for no reading)."""
        if not (math.isfinite(self.reference_m_per_s2) and self.reference_m_per_s2 > 0.0):
            return math.inf
        return 20.0 * math.log10(self.level_m_per_s2 / self.reference_m_per_s2)

    @property
    def table_acceleration_m_per_s2(self) -> float:
        """|ẍ_s| = |F_e| ω² / |F_e/X_s|: what the table accelerometer read."""
        omega2 = (2.0 * math.pi * self.frequency_hz) ** 2
        stiffness = abs(complex(self.dynamic_stiffness_n_per_m))
        return self.force_n * omega2 / stiffness if stiffness > 0 else math.nan

    @property
    def usable(self) -> bool:
        """A finite, non-zero dynamic stiffness and force, and no input overload."""
        stiffness = complex(self.dynamic_stiffness_n_per_m)
        return (math.isfinite(stiffness.real) and math.isfinite(stiffness.imag)
                and abs(stiffness) > 0.0 and math.isfinite(self.force_n) and self.force_n > 0.0
                and self.reference_m_per_s2 > 0.0 and math.isfinite(self.motion_ratio)
                and not self.flags & int(INPUT_OVERLOAD))


@dataclass(frozen=True)
class ForceEstimate:
    """The shaker force a sweep is expected to need."""

    frequency_hz: NDArray[np.float64]
    force_n: NDArray[np.float64]
    basis: str
    probes: tuple[ProbeReading, ...] = ()
    """The probe points it rests on (none when it comes from earlier runs or the station)."""

    @property
    def peak_n(self) -> float:
        """Largest force over the band, N."""
        return float(self.force_n.max())

    @property
    def peak_frequency_hz(self) -> float:
        """Where the largest force is needed, Hz."""
        return float(self.frequency_hz[int(np.argmax(self.force_n))])

    def level_for(self, force_limit_n: float, level_m_per_s2: float) -> float:
        """A level whose estimated peak force is :data:`REDUCE_MARGIN` of the limit."""
        return level_m_per_s2 * REDUCE_MARGIN * force_limit_n / self.peak_n


def estimate_force(
    frequency_hz: ArrayLike, level_m_per_s2: float, rig: RigEstimate
) -> ForceEstimate:
    """Force amplitude needed to hold ``level_m_per_s2`` at each frequency.

    F ≈ |K − ω² M + iω C| · r · a / ω², with ``r`` the rig's :attr:`RigEstimate.motion_ratio`
    (1 for a rigid link, so the disc and the table move alike); the whole grid is evaluated,
    which covers the band's ends and the resonance.
    """
    frequency = np.asarray(frequency_hz, dtype=float)
    omega2 = (2.0 * np.pi * frequency) ** 2
    force = (np.abs(rig.dynamic_stiffness(frequency)) * rig.motion_ratio * level_m_per_s2
             / omega2)
    return ForceEstimate(frequency, force, rig.basis)


def estimate_force_from_probe(
    frequency_hz: ArrayLike,
    level_m_per_s2: float,
    probes: tuple[ProbeReading, ...],
    table: RigEstimate | None,
    basis: str,
) -> ForceEstimate:
    """Force needed over the grid, from probe points and (if known) the table.

    What the table does not explain at a probe point, ``ΔD = F_e/X_s − D_table``, is the newly
    mounted part (the specimen; the whole rig when the table is unknown). It is carried over the
    band by two models, and the larger force of the two is taken at every frequency:

    - a spring and viscous damper through the lowest probe point (stiffness-dominated
      extrapolation, ``K = Re ΔD``, ``C = Im ΔD / ω``): the force at constant acceleration is
      largest at the low edge for a stiff specimen, and there it is the measured one. Ignoring
      the specimen's mass keeps ``|D|`` high below the resonance, and a viscous ``C`` grows
      ``Im D`` with frequency faster than rubber's loss does, so both err on the high side;
    - with a second probe point, the spring-mass-damper ``K − ω² M + iω C`` through both, which
      covers a mass-dominated high end (a band above the resonance).

    The force then follows as ``|D| · r · a / ω²``, with ``r`` the largest
    :attr:`ProbeReading.motion_ratio` of the probe points: behind a compliant load cell the
    table moves more than the disc whose level is held (about 10 % for the hard rubber).

    Rubber is stiffer at the probe's small amplitude than at the run's (Payne effect), which
    also errs on the high side. Not seen: local modes between the probe points and a modulus
    rising with frequency; both matter little where the force is largest.
    """
    frequency = np.asarray(frequency_hz, dtype=float)
    omega = 2.0 * np.pi * frequency
    usable = sorted((p for p in probes if p.usable), key=lambda p: p.frequency_hz)
    if not usable:
        raise ValueError("no usable probe point")

    def known(at_hz: float | NDArray[np.float64]) -> NDArray[np.complex128]:
        if table is None:
            return np.zeros(np.shape(at_hz), dtype=complex)
        return table.dynamic_stiffness(at_hz)

    omega_p = np.array([2.0 * np.pi * p.frequency_hz for p in usable])
    unknown = np.array([complex(p.dynamic_stiffness_n_per_m) for p in usable]) - known(
        np.array([p.frequency_hz for p in usable]))
    damping = max(float(np.max(unknown.imag / omega_p)), 0.0)
    spring = known(frequency) + unknown[0].real + 1j * omega * damping
    dynamic = np.abs(spring)
    if len(usable) > 1 and omega_p[-1] > omega_p[0]:
        # K − ω² M through the lowest and highest probe points (real parts)
        mass = -(unknown[-1].real - unknown[0].real) / (omega_p[-1] ** 2 - omega_p[0] ** 2)
        stiffness = unknown[0].real + omega_p[0] ** 2 * mass
        both = known(frequency) + stiffness - omega**2 * mass + 1j * omega * damping
        dynamic = np.maximum(dynamic, np.abs(both))
    ratio = max(p.motion_ratio for p in usable)
    force = dynamic * ratio * level_m_per_s2 / omega**2
    return ForceEstimate(frequency, force, basis, tuple(probes))


def motion_ratio(
    accelerance_table: ArrayLike, force_amplitude: ArrayLike, reference_amplitude: ArrayLike
) -> float:
    """Largest |ẍ_s / ẍ_ref| = |ẍ_s/F_e| |F_e| / |ẍ_ref| over measured points (1 if none)."""
    with np.errstate(divide="ignore", invalid="ignore"):
        ratio = (np.abs(np.asarray(accelerance_table, dtype=complex))
                 * np.asarray(force_amplitude, dtype=float)
                 / np.asarray(reference_amplitude, dtype=float))
    ratio = ratio[np.isfinite(ratio) & (ratio > 0)]
    return float(ratio.max()) if ratio.size else 1.0


def specimen_from_accelerance(
    frequency_hz: ArrayLike, accelerance_table: ArrayLike, table: RigEstimate
) -> tuple[float, float, float] | None:
    """Rough Voigt ``(K, C, M)`` of a specimen from a measured table accelerance ẍ_s/F_e.

    F_e/X_s − (K_s − ω² M_s + iω C_s) = K − ω² M + iω C (Eq. 4), solved by linear least
    squares: no guess needed. ``None`` when there are too few finite points.
    """
    frequency = np.asarray(frequency_hz, dtype=float)
    accelerance = np.asarray(accelerance_table, dtype=complex)
    keep = np.isfinite(accelerance) & (np.abs(accelerance) > 0) & (frequency > 0)
    if np.count_nonzero(keep) < 3:
        return None
    frequency, accelerance = frequency[keep], accelerance[keep]
    omega = 2.0 * np.pi * frequency
    dynamic = -(omega**2) / accelerance
    bare = RigEstimate(table.table_mass_kg, table.table_stiffness_n_per_m,
                       table.table_damping_ns_per_m)
    specimen = dynamic - bare.dynamic_stiffness(frequency)
    design = np.column_stack([np.ones_like(omega), -(omega**2)])
    (stiffness, mass), *_ = np.linalg.lstsq(design, specimen.real, rcond=None)
    damping = float(np.mean(specimen.imag / omega))
    if not all(math.isfinite(v) for v in (stiffness, mass, damping)):
        return None
    return float(stiffness), max(damping, 0.0), float(mass)


def point_flags(
    reference_amplitude: ArrayLike,
    force_amplitude: ArrayLike,
    *,
    level_m_per_s2: float,
    tolerance_db: float,
    force_limit_n: float,
    overloaded: bool,
) -> NDArray[np.uint16]:
    """The ``flags`` of each point (data-format.md).

    1: the reference amplitude is outside level ± tolerance dB (or not finite);
    2: an input overloaded during the segment (the analyser latches overload per segment);
    4: the level was missed low while the force stayed more than :data:`AT_FORCE_LIMIT_DB` below
    the shaker limit, so the source limit was binding;
    8: the force exceeded the shaker limit by more than :data:`FORCE_LIMIT_SLACK`.
    """
    reference = np.asarray(reference_amplitude, dtype=float)
    force = np.asarray(force_amplitude, dtype=float)
    with np.errstate(divide="ignore", invalid="ignore"):
        error_db = 20.0 * np.log10(reference / level_m_per_s2)
    missed = ~(np.abs(error_db) <= tolerance_db)
    flags = np.zeros(reference.shape, dtype=np.uint16)
    flags[missed] |= int(LEVEL_NOT_REACHED)
    if overloaded:
        flags |= int(INPUT_OVERLOAD)
    below_limit = force < force_limit_n * 10.0 ** (-AT_FORCE_LIMIT_DB / 20.0)
    missed_low = error_db < -tolerance_db  # too little motion: more drive was wanted
    flags[missed_low & below_limit] |= int(SOURCE_AT_LIMIT)
    flags[force > force_limit_n * (1.0 + FORCE_LIMIT_SLACK)] |= int(FORCE_ABOVE_SHAKER_LIMIT)
    return flags
