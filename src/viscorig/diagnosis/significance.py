"""When a candidate effect is significant: thresholds stated in terms of the noise.

Every comparison is a likelihood-ratio test on the residual whitened by the noise model
(:mod:`viscorig.diagnosis.weighted`): adding an effect with ``k`` parameters to a correct model
lowers ``χ²`` by a chi-square variable with ``k`` degrees of freedom when the effect is absent.
An effect is significant when the drop ``Δχ²`` exceeds the ``1 − α`` quantile of that
distribution. One diagnosis step makes a family of such tests (the scan for local modes, the
frame, every sensor term of every FRF, K*, the load cell...: :func:`family_size` counts them
for the model and data at hand, about a dozen), and clean data must give a false finding in at
most :data:`FAMILY_ALPHA` of the diagnoses, whichever test makes it: each test gets
``α = FAMILY_ALPHA / m`` of the ``m`` in the family (Bonferroni, :func:`test_alpha`), a test
that tries two alternative terms half of that. With the thirteen tests of a run with both FRFs
this is ``α ≈ 3.8·10⁻⁴``, ``Δχ² > 12.6`` for one parameter: 3.5 of its own standard errors.

The scan for local modes looks everywhere along the band and at several widths, so its largest
``Δχ²`` is the maximum of a chi-square *process*, not one chi-square variable. Its threshold
accounts for that (the look-elsewhere effect) through the expected number of upcrossings of the
matched-filter statistic (Rice, Davies; :mod:`viscorig.diagnosis.scan`): with ``L`` the length of
the scan measured in correlation lengths of the statistic, ``P(max Δχ² > u) ≈ L e^{−u/2}/(2π)``,
and the threshold is the ``u`` that makes it ``α``. On a 401-point paper sweep ``L`` is 400 to
1000 and, at the ``α`` of one test of the family, the threshold ``Δχ² ≈ 24-26``: a mode is
reported when its mass exceeds about 5 of its own standard errors.

A model that does not fit to the noise makes every test too easy: the residual holds structure
that any extra parameter partly absorbs. Each test is therefore made against the larger of the
two models compared, as in an F test: ``Δχ²`` is divided by ``φ = max(1, χ²/(n − p))`` of the
model with the candidate, the misfit the noise does not explain (:func:`judge`, which also
holds the other guards: a local mode against the noise next to it and without its best point,
a smooth effect against the drift the noise model found, every finding removing a real share
of the misfit).
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from scipy.special import chdtrc, chdtri

from viscorig.diagnosis.data import DiagnosisData
from viscorig.diagnosis.weighted import Likelihood
from viscorig.fitting.outliers import OUTLIER_LEVEL
from viscorig.models import Model

#: False-finding probability allowed to one diagnosis step, all its tests together.
FAMILY_ALPHA = 5e-3


def test_alpha(tests: int, family_alpha: float = FAMILY_ALPHA) -> float:
    """``α`` of each of ``tests`` tests so that all together stay within ``family_alpha``."""
    return family_alpha / max(int(tests), 1)
#: A significant finding removes at least this share of the χ² in excess of the noise.
MIN_EXCESS_FRACTION = 0.1
#: Terms a slow drift of the transducers (sensitivity, conditioning phase) can pass for along a
#: sweep, where test time and frequency advance together: a constant gain offset, a smooth phase
#: trend (a delay, a filter), a change of the whole K* (drift, amplitude dependence), the frame's
#: slow trend.
DRIFT_LIKE = ("gain", "delay", "lowpass", "highpass", "drift", "amplitude", "frame")


def threshold(dof: int, alpha: float) -> float:
    """``Δχ²`` an effect with ``dof`` parameters must exceed (chi-square ``1 − α`` quantile)."""
    return float(chdtri(max(int(dof), 1), alpha))


def scan_threshold(length: float, alpha: float) -> float:
    """``Δχ²`` the largest peak of a scan of ``length`` correlation lengths must exceed.

    ``P(max > u) ≈ length · e^{−u/2} / (2π) + P(χ²₁ > u)/2`` (upcrossings of the matched filter
    plus the chance of starting above ``u``), solved for ``P = α``.
    """
    base = threshold(1, alpha)
    if length <= 0:
        return base
    u = 2.0 * np.log(length / (2.0 * np.pi * alpha))
    for _ in range(20):  # fixed point of u = 2 ln(L / (2π (α − P(χ²₁ > u)/2)))
        rest = alpha - 0.5 * float(chdtrc(1, u))
        if rest <= 0:
            return max(base, u)
        u = 2.0 * np.log(length / (2.0 * np.pi * rest))
    return max(base, float(u))


def dispersion(chi2_value: float, residual_count: int, parameter_count: int) -> float:
    """``φ = max(1, χ²/(n − p))``: how far a model's misfit exceeds what the noise explains."""
    dof = max(residual_count - parameter_count, 1)
    return max(1.0, chi2_value / dof)


def removes_enough(chi2_before: float, chi2_after: float, excess_before: float) -> bool:
    """The change removes at least :data:`MIN_EXCESS_FRACTION` of ``excess_before``, the
    ``χ²`` the noise does not explain (none left: any drop will do)."""
    return chi2_before - chi2_after >= MIN_EXCESS_FRACTION * max(excess_before, 0.0)


#: Half-width of the neighbourhood of a local mode whose residual measures the local noise
#: (Hz, and in half-power bandwidths of the mode), and of the guard band left out around it.
NEIGHBOURHOOD_HZ, NEIGHBOURHOOD_WIDTHS, GUARD_WIDTHS = 4.0, 5.0, 1.5
#: Largest whitened residual power a point brings to the local dispersion (outliers clipped).
LOCAL_CLIP = 9.0


def local_dispersion(result: Likelihood, term_text: str, data: DiagnosisData) -> float:
    """Misfit of the noise model around a local mode: mean whitened residual power of
    ``result`` over the mode's neighbourhood, its own half-power band left out, in the FRF where
    it is largest (at least 1).

    A detector that compares a local feature with the noise next to it (constant false-alarm
    rate): where the noise model underestimates the noise over a few hertz (near the system's
    resonance, where the force dips and the relative noise climbs faster than a running
    estimate follows), the mode's ``Δχ²`` is scaled down by as much.
    """
    term = next((t for t in result.model.effects if t.spec == term_text), None)
    if term is None or term.keyword != "fixture":
        return 1.0
    names = result.model.local_names(term)
    f_n, zeta = result.values[names["f_n"]], result.values[names["zeta"]]
    width = 2 * zeta * f_n
    f = data.data.frequency_hz
    near = (np.abs(f - f_n) <= max(NEIGHBOURHOOD_HZ, NEIGHBOURHOOD_WIDTHS * width)) & (
        np.abs(f - f_n) > GUARD_WIDTHS * width)
    masks = data.outliers
    whitened = data.whitened_power(result.residuals)
    worst = 1.0
    for frf in data.frfs:  # each FRF's noise model may be off on its own
        power = np.minimum(whitened[frf], LOCAL_CLIP)[near & ~masks[frf]]
        if power.size >= 8:
            worst = max(worst, float(np.mean(power)))
    return worst


def single_point_share(before: Likelihood, after: Likelihood, data: DiagnosisData) -> float:
    """The largest drop of ``χ²`` one point brings to ``after`` against ``before``: what a
    local mode narrow enough to fit one outlier point would gain from it alone. Capped at what
    an outlier the noise model leaves in can bring (a point above ``OUTLIER_LEVEL`` times its
    noise power is left out as an outlier, so no single point brings more, in two parts)."""
    old, new = data.whitened_power(before.residuals), data.whitened_power(after.residuals)
    largest = float(max(np.max(2.0 * (old[frf] - new[frf])) for frf in data.frfs))
    return min(largest, 2.0 * OUTLIER_LEVEL)


def drift_confusion_factor(
    before: Likelihood, after: Likelihood, term_text: str, data: DiagnosisData
) -> float:
    """How much a smooth effect's test is weakened by the drift the noise model found.

    A drift slower than the sweep leaves in the FRFs a smooth change of up to its own rms ``σ``
    (a constant gain offset, a slow trend) that no single sweep tells from a smooth effect
    (the noise model resolves the drift only up to its longest lag). With ``r`` the rms change
    of ``log H`` the effect makes (``after`` against ``before``) and ``Δχ²`` its drop, its own
    standard error in those units is ``r/√Δχ²``; adding the drift's ``σ²`` (of the magnitude
    and of the phase, each as much as the effect changes that part) to its variance divides
    ``Δχ²`` by ``1 + σ² Δχ²/r²``: an effect must stand out against the drift. White noise (no
    drift) leaves the test alone; so do effects whose shape a drift in test time does not take
    (a local mode, the load cell's and K*'s frequency shapes): only the terms of
    :data:`DRIFT_LIKE` are weighed.
    """
    if term_text.split("(")[0] not in DRIFT_LIKE:
        return 1.0
    delta = before.chi2 - after.chi2
    if not delta > 0:
        return 1.0
    drift, size2, count = 0.0, 0.0, 0
    for frf in data.frfs:
        re = max(block.correlated_power[0] for block in data.noise.blocks[frf])
        im = max(block.correlated_power[1] for block in data.noise.blocks[frf])
        with np.errstate(all="ignore"):
            change = np.log((1.0 + after.residuals[frf]) / (1.0 + before.residuals[frf]))
        change = change[np.isfinite(change)]
        # the drift of each part weighs as much as the effect changes that part
        drift += re * float(np.sum(change.real**2)) + im * float(np.sum(change.imag**2))
        size2 += float(np.sum(np.abs(change) ** 2))
        count += change.size
    if not (drift > 0 and size2 > 0):
        return 1.0
    size2 /= count
    drift /= count * size2
    return 1.0 + drift * delta / size2


class Judgement(NamedTuple):
    """What :func:`judge` found."""

    delta: float
    """``Δχ²``, the drop of ``χ²``."""
    phi: float
    """``φ``, the misfit it is counted against."""
    passes: bool
    shortfall: str
    """Why it does not pass, for a technician ("" when it passes)."""


def judge(
    before: Likelihood, after: Likelihood, needed: float, data: DiagnosisData, term: str = ""
) -> Judgement:
    """How ``after`` does against ``before`` (``term``: the term tested).

    ``φ``, the misfit the test is made against, is the larger model's (an F test), for a local
    mode the noise next to it if larger (:func:`local_dispersion`), for a smooth effect raised
    by the drift it could be mistaken for (:func:`drift_confusion_factor`). A local mode must
    also pay without its best point (:func:`single_point_share`): one outlier point is no mode.
    """
    delta = before.chi2 - after.chi2
    n = data.residual_count
    phi = max(dispersion(after.chi2, n, len(after.free)), local_dispersion(after, term, data))
    # the drift's variance adds to the effect's own (φ s²): Δχ² / (φ + σ² Δχ²/r²)
    phi += drift_confusion_factor(before, after, term, data) - 1.0
    excess = before.chi2 - (n - len(before.free))
    if delta / phi <= needed:
        against = "noise explains" if phi < 1.5 else f"the misfit left explains (φ {phi:.3g})"
        why = f"within what {against} (Δχ²/φ {delta / phi:.1f}, needs {needed:.1f})"
    elif not removes_enough(before.chi2, after.chi2, excess):
        why = (f"it removes {delta / excess:.1%} of the χ² beyond the noise, under the "
               f"{MIN_EXCESS_FRACTION:.0%} an effect must remove")
    elif term.startswith("fixture") and (
            reduced := (delta - single_point_share(before, after, data)) / phi) <= needed:
        why = (f"without its best point it does not pay (Δχ²/φ {reduced:.1f}, needs "
               f"{needed:.1f}): one outlier point is no mode")
    else:
        why = ""
    return Judgement(delta, phi, not why, why)


def _has_term(model: Model, keyword: str) -> bool:
    return any(term.keyword == keyword for term in model.terms)


def family_size(model: Model, data: DiagnosisData) -> int:
    """The tests one diagnosis step of ``model`` on ``data`` makes, whether screening then
    fits each or not (a candidate the linear screen finds weak is a test passed, not one
    skipped): the scan for local modes, K*, the load cell, the level and drift terms, every
    sensor term of every FRF and the frame, as far as they apply."""
    both = set(data.frfs) == {"table", "support"}
    d = data.data
    tests = [
        True,  # the scan for local modes (its threshold holds its own look-elsewhere)
        model.modulus_term is not None and model.modulus_term.keyword != "fractional",
        both and data.table is not None and not _has_term(model, "load_cell"),
        d.has("reference_amplitude") and not _has_term(model, "amplitude"),
        d.has("time_s") and not _has_term(model, "drift"),
        "table" in data.frfs and data.table is not None and not _has_term(model, "frame"),
        both and not _has_term(model, "delay"),
    ]
    sensors = 6 if both else 2 * len(data.frfs)  # delay, high-pass (and gain) per FRF
    return sum(bool(t) for t in tests) + sensors


def alpha_of(model: Model, data: DiagnosisData) -> float:
    """``α`` of each test of one diagnosis step (:func:`family_size`,
    :func:`~viscorig.diagnosis.significance.test_alpha`)."""
    return test_alpha(family_size(model, data))
