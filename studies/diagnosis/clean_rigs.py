"""Clean rigs from a closed form: the false-finding study's generator, written apart from the core.

Nothing here imports ``viscorig`` or ``rigsim``: the FRFs are the rigid-link equations of
motion of the shared physics notes written out again, with numpy only, so that a diagnosis
that calls a finding significant on them found something these data do not hold.

A rig is the paper's table (``M_s = 3.4 kg, K_s = 50 194 N/m, C_s = 5.05 N·s/m``) carrying a
Voigt damper of the paper's Table 1 (``K_v``, ``C_v``) on a disc of mass ``M_v``:

- bare-table run, 12-28 Hz in 0.125 Hz steps (the paper plan's): ``ẍ_s/F_e = −ω²/D_s``,
  ``D_s = K_s − ω² M_s + iω C_s``;
- specimen run, 20-120 Hz in 0.25 Hz steps (or coarser, :attr:`CleanCase.step_hz`):
  ``ẍ_s/F_e = −ω²/(D_s + K_v + iω C_v − ω² M_v)`` and ``ẍ_v/F_v = −ω²/(K_v + iω C_v − ω² M_v)``.

Noise: every point of every FRF is multiplied by ``1 + σ (n₁ + i n₂)/√2`` with ``n₁, n₂``
standard normal and independent, so ``σ`` is the rms relative error of the FRFs (the noise
floor). The bare-table run and the specimen run each get their own draw.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

#: The paper's table (its step 1 result).
TABLE = {"M_s": 3.4, "K_s": 50194.0, "C_s": 5.05}
#: The paper's Table 1, Voigt fit: rig -> (K_v N/m, C_v N·s/m).
VOIGT = {
    "soft-0": (149986.61, 114.59),
    "soft-10": (163948.13, 124.91),
    "medium-0": (244605.26, 144.48),
    "medium-10": (268906.82, 150.13),
    "hard-0": (980356.04, 107.37),
    "hard-10": (1104445.91, 102.72),
}
#: The rigs of the false-finding study (those the outside check used, and two more).
RIGS = ("soft-0", "medium-10", "hard-0", "hard-10", "soft-10", "medium-0")
#: Disc masses the study draws from (kg): the paper gives none.
DISC_MASSES_KG = (0.2, 0.25, 0.35)
NOISE_LEVELS = (0.003, 0.01)
TABLE_BAND_HZ, TABLE_STEP_HZ = (12.0, 28.0), 0.125
SPECIMEN_BAND_HZ, SPECIMEN_STEP_HZ = (20.0, 120.0), 0.25
#: Cycles per point (settle plus integration) that set the time stamps.
CYCLES = 200.0


@dataclass(frozen=True)
class CleanCase:
    """One clean rig and its noise."""

    rig: str
    noise_level: float
    seed: int
    disc_mass_kg: float = 0.25
    step_hz: float = SPECIMEN_STEP_HZ
    """Frequency step of the specimen run (the paper plan's 0.25 Hz, or coarser)."""

    @property
    def name(self) -> str:
        step = "" if self.step_hz == SPECIMEN_STEP_HZ else f"-{self.step_hz:g}Hz"
        return f"{self.rig}-m{self.disc_mass_kg:g}-{self.noise_level * 100:g}%{step}-s{self.seed}"


@dataclass(frozen=True)
class Sweep:
    """A run's FRFs (``support`` is ``None`` on the bare table), times and the disc's level."""

    frequency_hz: np.ndarray
    table: np.ndarray
    support: np.ndarray | None
    time_s: np.ndarray
    reference_amplitude: np.ndarray


def _grid(band: tuple[float, float], step: float) -> np.ndarray:
    return np.round(np.arange(band[0], band[1] + step / 2, step), 6)


def _times(f: np.ndarray) -> np.ndarray:
    return np.cumsum(CYCLES / f)


def _noisy(h: np.ndarray, level: float, rng: np.random.Generator) -> np.ndarray:
    n = rng.standard_normal((2, h.size))
    return h * (1.0 + level * (n[0] + 1j * n[1]) / np.sqrt(2.0))


def bare_table(case: CleanCase) -> Sweep:
    """The bare-table run of a case (its own noise draw)."""
    rng = np.random.default_rng([case.seed, 1, int(case.noise_level * 1e6)])
    f = _grid(TABLE_BAND_HZ, TABLE_STEP_HZ)
    w = 2 * np.pi * f
    d_s = TABLE["K_s"] - w**2 * TABLE["M_s"] + 1j * w * TABLE["C_s"]
    h = _noisy(-(w**2) / d_s, case.noise_level, rng)
    return Sweep(f, h, None, _times(f), np.ones_like(f))


def specimen(case: CleanCase) -> Sweep:
    """The specimen run of a case (its own noise draw)."""
    rng = np.random.default_rng([case.seed, 2, int(case.noise_level * 1e6)])
    f = _grid(SPECIMEN_BAND_HZ, case.step_hz)
    w = 2 * np.pi * f
    k_v, c_v = VOIGT[case.rig]
    d_v = k_v + 1j * w * c_v - w**2 * case.disc_mass_kg
    d_s = TABLE["K_s"] - w**2 * TABLE["M_s"] + 1j * w * TABLE["C_s"]
    table = _noisy(-(w**2) / (d_s + d_v), case.noise_level, rng)
    support = _noisy(-(w**2) / d_v, case.noise_level, rng)
    return Sweep(f, table, support, _times(f), np.ones_like(f))


def cases(count: int, rigs=RIGS, levels=NOISE_LEVELS, first_seed: int = 0,
          step_hz: float = SPECIMEN_STEP_HZ) -> list[CleanCase]:
    """``count`` cases, cycling over rigs, noise levels and disc masses, seeds from
    ``first_seed``, specimen runs in steps of ``step_hz``."""
    out = []
    for i in range(count):
        rig = rigs[i % len(rigs)]
        level = levels[(i // len(rigs)) % len(levels)]
        mass = DISC_MASSES_KG[(i // (len(rigs) * len(levels))) % len(DISC_MASSES_KG)]
        out.append(CleanCase(rig, level, first_seed + i, mass, step_hz))
    return out
