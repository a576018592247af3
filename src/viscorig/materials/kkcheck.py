"""Kramers-Kronig consistency of a master curve: which points no linear viscoelastic material
can produce.

E' and E'' of a linear viscoelastic material are Kramers-Kronig transforms of each other. Any
sum of Maxwell terms with non-negative moduli obeys that by construction, and a dense one (four
relaxation times per decade, two decades beyond the data on each side) can follow any such
material closely. So the test fits that dense series to E' and E'' together (non-negative least
squares, each modulus weighted by its relative scatter) and names the points it cannot follow:
a point whose ``ln(measured/fitted)`` exceeds :data:`THRESHOLD_SIGMAS` times its modulus's
scatter (the data's own, about the smooth master curve; or, not given, a robust estimate about
the dense series) and :data:`MIN_DEVIATION` at least is inconsistent with its
neighbours in the way a linear material cannot be (an instrument resonance, a slipping clamp, a
wrong shift).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.optimize import nnls

from viscorig.materials.prony import maxwell_parts

THRESHOLD_SIGMAS = 5.0
MIN_DEVIATION = 0.05
PER_DECADE = 4


@dataclass(frozen=True)
class KramersKronigCheck:
    """Result: the dense series' residuals and the points flagged.

    Attributes
    ----------
    residual_storage, residual_loss
        ``ln(measured/fitted)`` at every point.
    threshold_storage, threshold_loss
        The deviation above which a point is flagged (the median over the points, where each
        point has its own).
    flagged_storage, flagged_loss
        Boolean mask of the flagged points.
    """

    residual_storage: NDArray[np.float64]
    residual_loss: NDArray[np.float64]
    threshold_storage: float
    threshold_loss: float
    flagged_storage: NDArray[np.bool_]
    flagged_loss: NDArray[np.bool_]

    @property
    def consistent(self) -> bool:
        """No point flagged."""
        return not (self.flagged_storage.any() or self.flagged_loss.any())


def _robust_sigma(values: NDArray[np.float64]) -> float:
    return float(1.4826 * np.median(np.abs(values - np.median(values))))


def check_kramers_kronig(omega: ArrayLike, storage_pa: ArrayLike, loss_pa: ArrayLike,
                         scatter: tuple[ArrayLike, ArrayLike] | None = None
                         ) -> KramersKronigCheck:
    """Fit a dense non-negative Maxwell series to E' and E''; flag the points it cannot follow.

    Parameters
    ----------
    omega
        Reduced angular frequency of each point (rad/s).
    storage_pa, loss_pa
        Measured E' and E'' (Pa).
    scatter
        Rms ``ln`` scatter of E' and E'' about a smooth curve, if known: two numbers, or two
        arrays of one value per point (the scatter of each point's sweep).
    """
    omega, storage, loss = (np.asarray(v, dtype=float) for v in (omega, storage_pa, loss_pa))
    lo, hi = 0.01 / omega.max(), 100.0 / omega.min()
    tau = np.geomspace(lo, hi, int(np.log10(hi / lo) * PER_DECADE) + 1)
    x, _, y = maxwell_parts(np.log(omega)[:, None] + np.log(tau)[None, :])
    columns_storage = np.hstack([np.ones((omega.size, 1)), x])
    columns_loss = np.hstack([np.zeros((omega.size, 1)), y])
    n = omega.size
    if scatter is None:
        ws, wl = np.ones(n), np.ones(n)
    else:
        ws = np.broadcast_to(np.maximum(np.asarray(scatter[0], float), 1e-4), (n,)).copy()
        wl = np.broadcast_to(np.maximum(np.asarray(scatter[1], float), 1e-4), (n,)).copy()
    keep_storage = np.ones(n, dtype=bool)
    keep_loss = np.ones(n, dtype=bool)
    for _ in range(4):
        # a flagged point is left out of the next fit, so that it cannot drag the dense series
        # towards itself and make its neighbours look wrong
        a = np.vstack([columns_storage[keep_storage]
                       / (storage[keep_storage] * ws[keep_storage])[:, None],
                       columns_loss[keep_loss] / (loss[keep_loss] * wl[keep_loss])[:, None]])
        b = np.concatenate([1 / ws[keep_storage], 1 / wl[keep_loss]])
        x = nnls(a, b, maxiter=50 * a.shape[1])[0]
        rs = np.log(storage / np.maximum(columns_storage @ x, 1e-300))
        rl = np.log(loss / np.maximum(columns_loss @ x, 1e-300))
        if scatter is None:
            ws = np.full(n, max(_robust_sigma(rs[keep_storage]), 1e-4))
            wl = np.full(n, max(_robust_sigma(rl[keep_loss]), 1e-4))
        ts = np.maximum(THRESHOLD_SIGMAS * ws, MIN_DEVIATION)
        tl = np.maximum(THRESHOLD_SIGMAS * wl, MIN_DEVIATION)
        flagged_storage, flagged_loss = np.abs(rs) > ts, np.abs(rl) > tl
        if np.array_equal(~flagged_storage, keep_storage) and np.array_equal(~flagged_loss,
                                                                            keep_loss):
            break
        keep_storage, keep_loss = ~flagged_storage, ~flagged_loss
    return KramersKronigCheck(rs, rl, float(np.median(ts)), float(np.median(tl)),
                              flagged_storage, flagged_loss)
