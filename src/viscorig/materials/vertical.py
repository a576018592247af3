"""Ferry's vertical shift factor of time-temperature superposition.

An entropic network's modulus is proportional to absolute temperature and density, so sweeps of
a rubbery plateau or of a melt at different temperatures differ by ``1/b_T`` besides their
shift along the frequency axis, with ``b_T = T_ref ρ_ref/(T ρ)`` (absolute temperatures; the
density constant, or falling with a volumetric thermal expansion ``α_V``).
:mod:`~viscorig.materials.master` reduces the moduli by it on request.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

#: Vertical shifts: none, or Ferry's ``b_T``.
VERTICAL_SHIFTS = ("none", "ferry")
#: Largest volumetric thermal expansion taken (1/K): rubbers and melts expand by 5e-4 to 1e-3.
MAX_EXPANSION_PER_K = 0.01


def ferry_factor(temperature_c: NDArray[np.float64] | float, reference_c: float,
                 expansion_per_k: float = 0.0) -> NDArray[np.float64]:
    """Ferry's vertical factor ``b_T = T_ref ρ_ref/(T ρ)`` with ``ρ_ref/ρ = exp(α_V (T − T_ref))``
    (``α_V`` = ``expansion_per_k``, volumetric, 1/K; 0: the density constant). The exponential
    form keeps a change of reference one common factor."""
    temperature = np.asarray(temperature_c, dtype=float)
    return ((reference_c + 273.15) / (temperature + 273.15)
            * np.exp(expansion_per_k * (temperature - reference_c)))
