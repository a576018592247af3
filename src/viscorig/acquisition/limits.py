"""Safety limits, force estimates and point flags of a sweep (pure functions).

The source limit comes from the station's shaker before the source is ever switched on; the
force a sweep will need is estimated from what is already known before it starts; every point
gets the flags of data-format.md from what the analyser measured.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from viscorig.storage import (
    FORCE_ABOVE_SHAKER_LIMIT,
    INPUT_OVERLOAD,
    LEVEL_NOT_REACHED,
    SOURCE_AT_LIMIT,
)

#: The analyser's highest source output, V peak.
ANALYSER_SOURCE_MAX_V = 5.0
#: A force within this many dB below the shaker limit counts as "at the limit": the analyser's
#: input limit held it there. Further below, a missed level means the source limit was binding.
AT_FORCE_LIMIT_DB = 0.5
#: Force flagged as above the shaker limit only beyond this fraction over it: the input-limit
#: controller holds the force at the limit, and transducer noise must not flag those points.
FORCE_LIMIT_SLACK = 0.01
#: A reduced sweep aims this far below the shaker limit (the estimate is rough).
REDUCE_MARGIN = 0.9


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

    def dynamic_stiffness(self, frequency_hz: ArrayLike) -> NDArray[np.complex128]:
        """F_e / X_s of the rig with a rigid link: K − ω² M + iω C, N/m."""
        omega = 2.0 * np.pi * np.asarray(frequency_hz, dtype=float)
        stiffness = self.table_stiffness_n_per_m + self.specimen_stiffness_n_per_m
        mass = self.table_mass_kg + self.specimen_mass_kg
        damping = self.table_damping_ns_per_m + self.specimen_damping_ns_per_m
        return stiffness - omega**2 * mass + 1j * omega * damping


@dataclass(frozen=True)
class ForceEstimate:
    """The shaker force a sweep is expected to need."""

    frequency_hz: NDArray[np.float64]
    force_n: NDArray[np.float64]
    basis: str

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

    F ≈ |K − ω² M + iω C| · a / ω² (rigid link, so the disc and the table move alike); the
    whole grid is evaluated, which covers the band's ends and the resonance.
    """
    frequency = np.asarray(frequency_hz, dtype=float)
    omega2 = (2.0 * np.pi * frequency) ** 2
    force = np.abs(rig.dynamic_stiffness(frequency)) * level_m_per_s2 / omega2
    return ForceEstimate(frequency, force, rig.basis)


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
