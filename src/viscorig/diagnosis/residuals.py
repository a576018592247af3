"""Residuals a person reads, and the bands where a model fails.

For each FRF the residual of a fit ``H_model/H_measured − 1`` is shown as a magnitude error in
percent and a phase error in degrees, and *whitened* by the local noise (``|r_i|/σ_i``, about 1
where the model is as good as the data). A failure band is a frequency range where the
whitened residual, smoothed over a few points, stands clearly above the noise; its ``what``
reads the error as a physical quantity: the model's dynamic stiffness ``Z = −ω²/H`` is too
high or too low in its real part (stiffness) or its imaginary part (damping), or the error is a
narrow peak, or a phase that drifts linearly with frequency.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from viscorig.diagnosis.data import DiagnosisData
from viscorig.fitting import FitResult
from viscorig.models.effects import edge_held_median

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


def residuals(fit: FitResult, data: DiagnosisData) -> list[FrfResidual]:
    """The residual of every FRF of every run of a fit, in frequency order."""
    out = []
    d = data.data
    kstar = np.abs(fit.model.kstar(d.context(), fit.values))
    for frf in fit.frfs:
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
        return (
            f"a narrow peak at {f[peak]:.1f} Hz not in the model "
            f"({excess[peak] * 100:.1f} % of |K*|)"
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
        return f"model stiffness too {sense} (by {abs(k.real) * 100:.1f} % of |K*| near {where})"
    sense = "high" if k.imag > 0 else "low"
    return f"model damping too {sense} (by {abs(k.imag) * 100:.1f} % of |K*| near {where})"


def failure_bands(
    fit: FitResult, data: DiagnosisData, level: float = FAILURE_LEVEL
) -> list[FailureBand]:
    """Frequency ranges where the residual stands clearly above the noise, worst first.

    A point belongs to a band when the whitened residual power ``|r|²/σ²``, averaged over
    :data:`FAILURE_WINDOW` points, exceeds ``level`` (noise alone averages 1 and exceeds 6
    over five points with a probability below 1e-5). Bands closer than 1 Hz merge; single
    points are left out.
    """
    bands = []
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
        for s, e in merged:
            if e - s < 2:
                continue
            part = slice(s, e)
            bands.append(
                FailureBand(
                    (float(f[s]), float(f[e - 1])),
                    residual.frf,
                    _describe(residual, part),
                    residual.run,
                    float(np.mean(power[part])),
                )
            )
    return sorted(bands, key=lambda band: -band.severity * (band.band_hz[1] - band.band_hz[0] + 1))
