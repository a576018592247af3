"""An independent generator of viscoelastic test data with a known WLF shift.

It shares no code with ``viscorig.materials``: the material is a Havriliak-Negami modulus
(not a Prony series, not the fractional Zener of the core), shifted in frequency by a WLF law
written out here, with multiplicative noise drawn from a seeded generator.
"""

from __future__ import annotations

import math

import numpy as np

#: The material: relaxed and unrelaxed modulus (Pa), relaxation time (s), HN exponents.
RELAXED_PA = 1.0e6
UNRELAXED_PA = 1.0e9
TAU_S = 1.0e-3
HN_ALPHA = 0.6
HN_BETA = 0.5
#: The WLF law of the shift factors (log10 aT = −C1 (T − T_ref)/(C2 + T − T_ref)).
REFERENCE_C = 20.0
C1 = 8.86
C2_K = 101.6


def true_log10_at(temperature_c, reference_c: float = REFERENCE_C) -> np.ndarray:
    """The generator's log10 aT relative to ``reference_c``."""
    def wlf(t):
        dt = np.asarray(t, dtype=float) - REFERENCE_C
        return -C1 * dt / (C2_K + dt)
    return wlf(temperature_c) - wlf(reference_c)


def modulus(frequency_hz, temperature_c, scale: float = 1.0) -> np.ndarray:
    """Complex modulus (Pa, times ``scale``) at frequency and temperature."""
    omega = 2 * math.pi * np.asarray(frequency_hz, dtype=float) * 10.0 ** true_log10_at(
        temperature_c)
    relaxing = (1.0 + (1j * omega * TAU_S) ** HN_ALPHA) ** HN_BETA
    return scale * (UNRELAXED_PA - (UNRELAXED_PA - RELAXED_PA) / relaxing)


def dma_sweep(temperatures_c, frequencies_hz, storage_noise: float = 0.01,
              loss_noise: float = 0.02, seed: int = 0,
              entropic: bool = False, expansion_per_k: float = 0.0) -> dict[str, np.ndarray]:
    """A DMA-like sweep: every frequency at every temperature, multiplicative noise.

    ``entropic`` multiplies the modulus by ``T/T_ref`` (kelvin), as a rubber network's grows
    with absolute temperature, and by the density ratio ``exp(−α (T − T_ref))`` of a volumetric
    thermal expansion ``α`` = ``expansion_per_k``."""
    rng = np.random.default_rng(seed)
    f, t = np.meshgrid(np.asarray(frequencies_hz, float), np.asarray(temperatures_c, float))
    f, t = f.ravel(), t.ravel()
    value = modulus(f, t)
    if entropic:
        value = value * (t + 273.15) / (REFERENCE_C + 273.15) * np.exp(
            -expansion_per_k * (t - REFERENCE_C))
    storage = value.real * np.exp(storage_noise * rng.standard_normal(f.size))
    loss = value.imag * np.exp(loss_noise * rng.standard_normal(f.size))
    sets = np.repeat(np.arange(len(temperatures_c)), len(frequencies_hz))
    return {"frequency_hz": f, "temperature_c": t, "storage_pa": storage, "loss_pa": loss,
            "set_index": sets}


def support_accelerance(frequency_hz, temperature_c, theta_m: float, disc_mass_kg: float,
                        noise: float = 0.005, seed: int = 0) -> np.ndarray:
    """ẍ_v/F_v of the rig's disc on a specimen of this material in shear (m/s²/N)."""
    rng = np.random.default_rng(seed)
    omega = 2 * math.pi * np.asarray(frequency_hz, dtype=float)
    kstar = modulus(frequency_hz, temperature_c, scale=theta_m)
    value = -omega**2 / (kstar - omega**2 * disc_mass_kg)
    size = np.asarray(frequency_hz).size
    return value * (1 + noise * (rng.standard_normal(size) + 1j * rng.standard_normal(size))
                    / math.sqrt(2))
