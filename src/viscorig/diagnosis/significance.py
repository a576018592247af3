"""When a candidate effect is significant: thresholds stated in terms of the noise.

Every comparison is a likelihood-ratio test on the residual whitened by the noise model
(:mod:`viscorig.diagnosis.weighted`): adding an effect with ``k`` parameters to a correct model
lowers ``χ²`` by a chi-square variable with ``k`` degrees of freedom when the effect is absent.
An effect is significant when the drop ``Δχ²`` exceeds the ``1 − α`` quantile of that
distribution, with ``α`` = :data:`FAMILY_ALPHA` for each family of candidates a diagnosis tries
(about a dozen per step, so that clean data give a false finding in about one diagnosis out of a
hundred). For one parameter this is ``Δχ² > 10.8``: the parameter is more than 3.3 of its own
standard errors away from "no effect".

The scan for local modes looks everywhere along the band and at several widths, so its largest
``Δχ²`` is the maximum of a chi-square *process*, not one chi-square variable. Its threshold
accounts for that (the look-elsewhere effect) through the expected number of upcrossings of the
matched-filter statistic (Rice, Davies; :mod:`viscorig.diagnosis.scan`): with ``L`` the length of
the scan measured in correlation lengths of the statistic, ``P(max Δχ² > u) ≈ L e^{−u/2}/(2π)``,
and the threshold is the ``u`` that makes it ``α``. On a 401-point paper sweep, ``L`` is a few
thousand and the threshold about ``Δχ² > 25``: a mode is reported when its amplitude exceeds
about five of its own standard errors.

A model that does not fit to the noise makes every test too easy: the residual holds structure
that any extra parameter partly absorbs. Each test is therefore made against the larger of the
two models compared, as in an F test: ``Δχ²`` is divided by ``φ = max(1, χ²/(n − p))`` of the
model with the candidate, the misfit the noise does not explain.
"""

from __future__ import annotations

import numpy as np
from scipy.stats import chi2

#: False-finding probability allowed to each family of candidates in one diagnosis step.
FAMILY_ALPHA = 1e-3


def threshold(dof: int, alpha: float = FAMILY_ALPHA) -> float:
    """``Δχ²`` an effect with ``dof`` parameters must exceed (chi-square ``1 − α`` quantile)."""
    return float(chi2.isf(alpha, max(int(dof), 1)))


def scan_threshold(length: float, alpha: float = FAMILY_ALPHA) -> float:
    """``Δχ²`` the largest peak of a scan of ``length`` correlation lengths must exceed.

    ``P(max > u) ≈ length · e^{−u/2} / (2π) + P(χ²₁ > u)/2`` (upcrossings of the matched filter
    plus the chance of starting above ``u``), solved for ``P = α``.
    """
    base = threshold(1, alpha)
    if length <= 0:
        return base
    u = 2.0 * np.log(length / (2.0 * np.pi * alpha))
    for _ in range(20):  # fixed point of u = 2 ln(L / (2π (α − P(χ²₁ > u)/2)))
        rest = alpha - 0.5 * float(chi2.sf(u, 1))
        if rest <= 0:
            return max(base, u)
        u = 2.0 * np.log(length / (2.0 * np.pi * rest))
    return max(base, float(u))


def dispersion(chi2_value: float, residual_count: int, parameter_count: int) -> float:
    """``φ = max(1, χ²/(n − p))``: how far a model's misfit exceeds what the noise explains."""
    dof = max(residual_count - parameter_count, 1)
    return max(1.0, chi2_value / dof)


def in_standard_errors(delta_chi2: float) -> float:
    """A ``Δχ²`` of one parameter as a distance from "no effect" in standard errors."""
    return float(np.sqrt(max(delta_chi2, 0.0)))
