"""Residuals a person reads, and the bands where a model fails.

For each FRF the residual of a fit ``H_model/H_measured − 1`` is shown as a magnitude error in
percent and a phase error in degrees, and *whitened* by the local noise (``|r_i|/σ_i``, about 1
where the model is as good as the data). A failure band is a frequency range where the
whitened residual, smoothed over a few points, stands clearly above the noise *and* out of it:
a model error is smooth along the band (the sweep resolves every mode it can hold), so
neighbouring points err alike, while noise, however much louder than its estimate, errs
independently from point to point (:func:`stands_out`); its ``what``
reads the error as a physical quantity: the model's dynamic stiffness ``Z = −ω²/H`` is too
high or too low in its real part (stiffness) or its imaginary part (damping), or the error is a
narrow peak, or a phase that drifts linearly with frequency.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray
from scipy.special import ndtri

from viscorig.diagnosis.data import DiagnosisData
from viscorig.diagnosis.significance import FAMILY_ALPHA
from viscorig.diagnosis.weighted import Likelihood
from viscorig.fitting import FitResult
from viscorig.mains import mains_multiple
from viscorig.models.effects import edge_held_median
from viscorig.numbers import significant

#: Smoothed whitened residual power above which a point belongs to a failure band.
FAILURE_LEVEL = 6.0
#: Points of the running mean of the whitened residual power.
FAILURE_WINDOW = 5
#: A failure band narrower than this (Hz) reads as "a narrow peak".
NARROW_HZ = 4.0
#: A stiffness error this many times the band's median (and narrow) makes the band "a narrow peak".
PEAK_DOMINANCE = 5.0


@dataclass(frozen=True)
class FrfResidual:
    """Residual of one FRF of one run, in frequency order.

    Attributes
    ----------
    run, frf
        Run name and FRF name (``"table"``, ``"support"``).
    frequency_hz
        Frequencies (Hz).
    complex_error
        ``H_model/H_measured − 1``.
    magnitude_error_pct
        ``(|H_model|/|H_measured| − 1) · 100``.
    phase_error_deg
        ``arg(H_model/H_measured)`` in degrees.
    whitened
        ``|H_model/H_measured − 1| / σ_i`` with ``σ_i`` the local noise estimate.
    """

    run: str
    frf: str
    frequency_hz: NDArray[np.float64]
    complex_error: NDArray[np.complex128]
    magnitude_error_pct: NDArray[np.float64]
    phase_error_deg: NDArray[np.float64]
    whitened: NDArray[np.float64]
    stiffness_error: NDArray[np.complex128]
    """``(Z_model − Z_measured)/|K*|``: the error of the dynamic stiffness ``Z = −ω²/H`` as a
    fraction of the fitted specimen stiffness (real part: stiffness, imaginary: damping)."""
    noise_sigma: NDArray[np.float64] | None = None
    """``σ_i``, the noise model's standard deviation of ``H_model/H_measured − 1`` per point."""


@dataclass(frozen=True)
class FailureBand:
    """A frequency range where the model stands clearly above the noise."""

    band_hz: tuple[float, float]
    frf: str
    what: str
    run: str
    severity: float
    """Mean whitened residual power in the band (1 is noise)."""

    def to_json(self) -> dict[str, object]:
        """``{"band_hz", "frf", "what", "run"}``."""
        return {
            "band_hz": [round(self.band_hz[0], 3), round(self.band_hz[1], 3)],
            "frf": self.frf,
            "what": self.what,
            "run": self.run,
        }


def residuals(fit: FitResult | Likelihood, data: DiagnosisData) -> list[FrfResidual]:
    """The residual of every FRF of every run of a fit on ``data`` (its uniform fit or its
    likelihood fit), in frequency order."""
    out = []
    d = data.data
    kstar = np.abs(fit.model.kstar(d.context(), fit.values))
    for frf in data.frfs:
        error = fit.residuals[frf]
        sigma = np.sqrt(data.noise_power[frf])
        z_measured = -((2 * np.pi * d.frequency_hz) ** 2) / d.frf(frf)
        with np.errstate(all="ignore"):
            stiffness_error = (1.0 / (1.0 + error) - 1.0) * z_measured / kstar
        for segment in data.segments:
            f = data.data.frequency_hz[segment.index]
            order = np.argsort(f)
            r = error[segment.index][order]
            ratio = 1.0 + r
            out.append(
                FrfResidual(
                    segment.run,
                    frf,
                    f[order],
                    r,
                    (np.abs(ratio) - 1.0) * 100.0,
                    np.degrees(np.angle(ratio)),
                    np.abs(r) / sigma[segment.index][order],
                    stiffness_error[segment.index][order],
                    sigma[segment.index][order],
                )
            )
    return out


def _describe(residual: FrfResidual, part: slice) -> str:
    """What the error in a band is, in words."""
    f = residual.frequency_hz[part]
    ratio = 1.0 + residual.complex_error[part]
    dz = residual.stiffness_error[part]
    size = np.abs(dz)
    worst = int(np.argmax(size))
    where = f"{f[worst]:.1f} Hz"
    # What stands above a running median over ±NARROW_HZ is narrow.
    steps = np.diff(f)
    step = float(np.median(steps[steps > 0])) if np.any(steps > 0) else 1.0
    half = int(np.clip(round(NARROW_HZ / step), 2, max(f.size // 3, 2)))
    excess = np.abs(dz - (edge_held_median(dz.real, half) + 1j * edge_held_median(dz.imag, half)))
    peak = int(np.argmax(excess))
    wide = f[excess > 0.5 * excess[peak]]
    if f[-1] - f[0] < NARROW_HZ or (
        excess[peak] > PEAK_DOMINANCE * np.median(excess) and np.ptp(wide) < NARROW_HZ
    ):
        mains = mains_multiple(float(f[peak]))
        return (
            f"a narrow peak at {f[peak]:.1f} Hz not in the model "
            f"({significant(100 * excess[peak])} % of |K*|)"
            + ("" if mains is None else f"; at {mains:g} Hz, a multiple of the mains "
               "frequency: interference more likely than a mode (see the noise)")
        )
    phase = np.unwrap(np.angle(ratio))
    magnitude = np.log(np.abs(ratio))
    if f.size >= 6 and np.std(phase) > 2 * np.std(magnitude):
        slope, intercept = np.polyfit(f, phase, 1)
        if np.std(phase - (slope * f + intercept)) < 0.3 * np.std(phase):
            return f"a phase trend: the phase error drifts {np.degrees(slope):+.3f} °/Hz"
    mean = complex(np.median(dz.real) + 1j * np.median(dz.imag))
    k = mean if abs(mean) > 0.3 * size[worst] else dz[worst]
    if abs(k.real) >= abs(k.imag):
        sense = "high" if k.real > 0 else "low"
        return (f"model stiffness too {sense} (by {significant(100 * abs(k.real))} % of |K*| "
                f"near {where})")
    sense = "high" if k.imag > 0 else "low"
    return (f"model damping too {sense} (by {significant(100 * abs(k.imag))} % of |K*| "
            f"near {where})")


def coherence(residual: FrfResidual, part: slice) -> tuple[float, int]:
    """``(ρ, n)``: the correlation of neighbouring points' whitened complex residuals over
    ``part`` widened by :data:`FAILURE_WINDOW` points each side, ``Re Σ z_i z̄_{i+1} /
    √(Σ|z_i|² Σ|z_{i+1}|²)``, and the ``n`` neighbouring pairs it is taken over.

    About 1 for a model error (smooth along the band, so neighbours err alike); for noise,
    independent from point to point whatever its level, about normal with mean 0 and variance
    ``1/(2n)``.
    """
    sigma = residual.noise_sigma
    if sigma is None:
        sigma = np.abs(residual.complex_error) / np.maximum(residual.whitened, 1e-300)
    lo = max(part.start - FAILURE_WINDOW, 0)
    hi = min(part.stop + FAILURE_WINDOW, residual.frequency_hz.size)
    z = residual.complex_error[lo:hi] / sigma[lo:hi]
    z = z[np.isfinite(z)]
    if z.size < 3:
        return 0.0, 0
    a, b = z[:-1], z[1:]
    scale = np.sqrt(np.sum(np.abs(a) ** 2) * np.sum(np.abs(b) ** 2))
    if not scale > 0:
        return 0.0, 0
    return float(np.real(np.sum(a * np.conj(b))) / scale), int(a.size)


def stands_out(residual: FrfResidual, part: slice, candidates: int = 1) -> bool:
    """The band ``part`` holds a model error, not a stretch of noise louder than its estimate:
    its neighbouring points err alike (:func:`coherence`) beyond what independent noise gives
    with a probability :data:`~viscorig.diagnosis.significance.FAMILY_ALPHA` shared among the
    ``candidates`` bands examined (one-sided normal test, scale-free: it holds whatever the
    noise's level)."""
    rho, pairs = coherence(residual, part)
    if pairs == 0:
        return False
    z = float(-ndtri(FAMILY_ALPHA / max(candidates, 1)))
    return rho * np.sqrt(2.0 * pairs) > z


def failure_bands(
    fit: FitResult | Likelihood, data: DiagnosisData, level: float = FAILURE_LEVEL
) -> list[FailureBand]:
    """Frequency ranges where the residual stands clearly above the noise and out of it,
    worst first: what a report lists as where the model still fails.

    A point belongs to a band when the whitened residual power ``|r|²/σ²``, averaged over
    :data:`FAILURE_WINDOW` points, exceeds ``level`` (noise alone averages 1 and exceeds 6
    over five points with a probability below 1e-5). Bands closer than 1 Hz merge; single
    points are left out. A band is kept only when it also stands out of the noise
    (:func:`stands_out`): where the noise is louder than the noise model says (a burst, a dip
    of the force the running estimate does not follow) its power is high but its points err
    independently, and what is left there is noise, however the model is.
    """
    found: list[tuple[FrfResidual, slice]] = []
    for residual in residuals(fit, data):
        power = residual.whitened**2
        kernel = np.ones(FAILURE_WINDOW) / FAILURE_WINDOW
        smooth = np.convolve(power, kernel, mode="same")
        above = smooth > level
        f = residual.frequency_hz
        if not np.any(above):
            continue
        edges = np.flatnonzero(np.diff(np.concatenate([[0], above.astype(int), [0]])))
        runs = [[s, e] for s, e in zip(edges[::2], edges[1::2], strict=True)]
        merged = [runs[0]]
        for s, e in runs[1:]:
            if f[s] - f[merged[-1][1] - 1] < 1.0:
                merged[-1][1] = e
            else:
                merged.append([s, e])
        found += [(residual, slice(s, e)) for s, e in merged if e - s >= 2]
    bands = []
    for residual, part in found:
        if not stands_out(residual, part, len(found)):
            continue
        f = residual.frequency_hz
        bands.append(
            FailureBand(
                (float(f[part.start]), float(f[part.stop - 1])),
                residual.frf,
                _describe(residual, part),
                residual.run,
                float(np.mean(residual.whitened[part] ** 2)),
            )
        )
    return sorted(bands, key=lambda band: -band.severity * (band.band_hz[1] - band.band_hz[0] + 1))
