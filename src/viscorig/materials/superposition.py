"""Does time-temperature superposition hold? The van Gurp-Palmen test.

For a thermo-rheologically simple material the phase angle ``δ = atan(E''/E')`` is one function
of ``|E*|`` whatever the temperature: the van Gurp-Palmen plot (δ against log |E*|) of all the
sets closes into one curve, with no shift at all. The test compares the scatter of δ about one
smooth curve through every point with the scatter of δ within each set about its own smooth
curve (an F test of the two variances): where the first is larger than the second with a chance
below :data:`SIGNIFICANCE` of being noise alone, the sets do not lie on one curve, a master curve
built from them is not a material property, and the sets farthest from the common curve are
named.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.interpolate import BSpline
from scipy.special import fdtrc

from viscorig.materials.table import ModulusTable

SIGNIFICANCE = 1e-3
#: Knot spacing of the common curve, decades of |E*|.
KNOT_SPACING_DECADES = 0.2


@dataclass(frozen=True)
class SuperpositionCheck:
    """Result of the van Gurp-Palmen test (angles in degrees)."""

    common_scatter_deg: float
    within_set_scatter_deg: float
    holds: bool
    worst_temperatures_c: tuple[float, ...]

    @property
    def ratio(self) -> float:
        """Scatter about the common curve over scatter within the sets."""
        return self.common_scatter_deg / max(self.within_set_scatter_deg, 1e-9)

    @property
    def verdict(self) -> str:
        """One sentence for a person."""
        if self.holds:
            return (f"superposition holds: the van Gurp-Palmen plot closes (phase angle "
                    f"scatters {self.common_scatter_deg:.2f}° about one curve, "
                    f"{self.within_set_scatter_deg:.2f}° within the sweeps)")
        worst = ", ".join(f"{t:.1f} °C" for t in self.worst_temperatures_c)
        return (f"superposition does not hold: the van Gurp-Palmen plot does not close (phase "
                f"angle scatters {self.common_scatter_deg:.2f}° about one curve but only "
                f"{self.within_set_scatter_deg:.2f}° within the sweeps; farthest: {worst}); "
                "the master curve is not a property of a thermo-rheologically simple material")

    def to_json(self) -> dict:
        """Figures and the verdict."""
        return {"method": "van Gurp-Palmen", "holds": self.holds,
                "common_scatter_deg": self.common_scatter_deg,
                "within_set_scatter_deg": self.within_set_scatter_deg,
                "ratio": self.ratio, "worst_temperatures_c": list(self.worst_temperatures_c),
                "verdict": self.verdict}


def check_superposition(table: ModulusTable) -> SuperpositionCheck:
    """Run the van Gurp-Palmen test on ``table`` (no shift factors needed)."""
    x = np.log10(np.hypot(table.storage_pa, table.loss_pa))
    delta = np.degrees(np.arctan2(table.loss_pa, table.storage_pa))
    lo, hi = float(x.min()) - 1e-6, float(x.max()) + 1e-6
    breaks = np.linspace(lo, hi, max(2, int(np.ceil((hi - lo) / KNOT_SPACING_DECADES)) + 1))
    knots = np.concatenate([[lo] * 3, breaks, [hi] * 3])
    basis = BSpline.design_matrix(x, knots, 3).toarray()
    normal = basis.T @ basis + 1e-8 * np.eye(basis.shape[1])
    common = delta - basis @ np.linalg.solve(normal, basis.T @ delta)
    dof_common = max(1, x.size - basis.shape[1])
    within_sum, within_dof, per_set = 0.0, 0, []
    for s, temperature in zip(table.sets, table.set_temperatures_c(), strict=True):
        members = table.set_index == s
        per_set.append((float(np.sqrt(np.mean(common[members] ** 2))), float(temperature)))
        if members.sum() >= 4:
            coefficients = np.polyfit(x[members], delta[members], 2)
            residual = delta[members] - np.polyval(coefficients, x[members])
            within_sum += float(residual @ residual)
            within_dof += int(members.sum()) - 3
    common_scatter = float(np.sqrt(common @ common / dof_common))
    within = float(np.sqrt(within_sum / within_dof)) if within_dof else common_scatter
    worst = tuple(t for _, t in sorted(per_set, reverse=True)[:3])
    ratio = common_scatter**2 / max(within**2, 1e-18)
    chance = float(fdtrc(dof_common, max(within_dof, 1), ratio))
    return SuperpositionCheck(common_scatter, within, bool(chance >= SIGNIFICANCE), worst)
