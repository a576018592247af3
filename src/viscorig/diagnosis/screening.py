"""Screening: the signature each missing effect leaves in the data and the current residual.

Screening is cheap (no fit) and does two things for each effect of the vocabulary: it says
what in the data points to it (the *evidence*, a sentence used in the explanation), and it
gives the start values from which confirmation fits the candidate. Signatures:

=============================== ==================================================================
effect                          signature
=============================== ==================================================================
load_cell_compliance            Eq. (4) and Eq. (5) estimates of K* disagree: ``1/(F_e/X_s − D_t)
                                − X_v/F_v`` is the link's compliance ``1/K_c``, zero if rigid
fixture_resonance               a narrow peak of the residual above a running median (per FRF)
sensor_delay                    the phase error is linear in ω
amplitude_dependence            runs at two levels disagree in stiffness
thermal_drift                   up and down sweeps disagree, or the residual follows ``time_s``
frequency_dependent_modulus     the stiffness/damping error is a smooth trend in log frequency
=============================== ==================================================================

Each signature has a *score*, a z-like number (about 0-3 for noise), used only to order the
evidence; whether an effect is there is decided by confirmation (:mod:`.findings`).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from scipy.signal import find_peaks

from viscorig.diagnosis.data import DiagnosisData
from viscorig.estimates import kstar_from_support, kstar_from_table
from viscorig.fitting import FitResult
from viscorig.models.effects import Fixture, compliance_estimate, fixture_start, running_median

#: Whitened height a residual peak needs to be tried as a fixture mode.
PEAK_THRESHOLD = 3.5
#: Most fixture frequencies tried per diagnosis.
MAX_FIXTURES = 3


@dataclass
class Signature:
    """What screening found for one candidate term."""

    effect: str
    term: str
    """Spec text of the term to add, or of the K* term that replaces the current one."""
    score: float
    evidence: str
    start: dict[str, float] = field(default_factory=dict)
    """Start values of the new term's parameters (local names)."""


def _weighted_lstsq(columns, target, weight):
    a = columns * weight[:, None]
    b = target * weight
    coefficients, *_ = np.linalg.lstsq(a, b, rcond=None)
    residual = b - a @ coefficients
    dof = max(b.size - a.shape[1], 1)
    s2 = float(residual @ residual) / dof
    try:
        covariance = s2 * np.linalg.inv(a.T @ a)
    except np.linalg.LinAlgError:
        covariance = np.full((a.shape[1], a.shape[1]), np.inf)
    return coefficients, np.sqrt(np.abs(np.diag(covariance))), float(b @ b - residual @ residual)


def _log_errors(fit: FitResult, data: DiagnosisData):
    """``log(H_model/H_meas)`` per FRF over all points, and the per-point noise σ."""
    out = {}
    for frf in fit.frfs:
        with np.errstate(all="ignore"):
            e = np.log(1.0 + fit.residuals[frf])
        out[frf] = (e, np.sqrt(data.noise_power[frf]))
    return out


def screen_load_cell(fit: FitResult, data: DiagnosisData) -> Signature | None:
    """Eq. (4) vs Eq. (5)."""
    if "load_cell" in fit.spec or set(data.frfs) != {"table", "support"} or data.table is None:
        return None
    d = data.data
    measured = {"table": d.frf("table"), "support": d.frf("support")}
    estimate = compliance_estimate(d.context(), data.table, measured)
    if estimate is None:
        return None
    compliance, stderr = estimate
    m_v = fit.values.get("M_v", 0.0)
    k4 = kstar_from_table(d.frequency_hz, measured["table"], data.table, m_v)
    k5 = kstar_from_support(d.frequency_hz, measured["support"], m_v)
    gap = float(np.median((k4.real - k5.real) / np.abs(k5))) * 100
    score = compliance / stderr if stderr > 0 else 0.0
    start = {"K_c": 1.0 / compliance} if compliance > 0 else {}
    stiffness = f"K_c ≈ {1.0 / compliance:.3g} N/m" if compliance > 0 else "no finite K_c"
    evidence = (
        f"the table FRF (Eq. 4) sees a K* {abs(gap):.1f} % {'softer' if gap < 0 else 'stiffer'}"
        f" than the support FRF (Eq. 5) does ({stiffness})"
    )
    return Signature("load_cell_compliance", "load_cell", float(score), evidence, start)


def screen_fixtures(fit: FitResult, data: DiagnosisData) -> list[Signature]:
    """Narrow residual peaks, per FRF and run, as fixture candidates (largest first)."""
    found: list[tuple[float, float, str, dict[str, float]]] = []
    d = data.data
    for frf, (e, sigma) in _log_errors(fit, data).items():
        for segment in data.segments:
            f = d.frequency_hz[segment.index]
            order = np.argsort(f)
            f, r, s = f[order], e[segment.index][order], sigma[segment.index][order]
            if f.size < 16:
                continue
            step = float(np.median(np.diff(f)))
            half = max(round(4.0 / step), 3)
            excess = np.abs(r - (running_median(r.real, half) + 1j * running_median(r.imag, half)))
            z = excess / s
            smooth = np.convolve(z, np.ones(3) / 3, mode="same")
            peaks, _ = find_peaks(smooth, height=PEAK_THRESHOLD, distance=max(round(2.0 / step), 1))
            for i in peaks:
                measured = d.frf(frf)[segment.index][order]
                ctx = d.select(segment.index).select(order).context()
                start = fixture_start(float(f[i]), float(excess[i]), ctx, measured)
                found.append((float(smooth[i]), float(f[i]), frf, start))
    found.sort(reverse=True)
    signatures: list[Signature] = []
    existing = [v for k, v in fit.values.items() if k.startswith("f_n")]
    for score, frequency, frf, start in found:
        near = [s for s in signatures if abs(s.start["f_n"] - frequency) < 2.0]
        if near or any(abs(f_n - frequency) < 1.0 for f_n in existing):
            continue
        signatures.append(
            Signature(
                "fixture_resonance",
                Fixture(round(frequency, 2)).spec,
                score,
                f"the {frf} FRF has a narrow peak at {frequency:.2f} Hz "
                f"({score:.0f} times the noise)",
                start,
            )
        )
        if len(signatures) == MAX_FIXTURES:
            break
    return signatures


def screen_delay(fit: FitResult, data: DiagnosisData) -> Signature | None:
    """Phase error linear in ω."""
    if "delay" in fit.spec:
        return None
    omega = 2 * np.pi * data.data.frequency_hz
    target, weight, columns = [], [], []
    for e, sigma in _log_errors(fit, data).values():
        target.append(e.imag)
        weight.append(1.0 / sigma)
        columns.append(np.stack([np.ones_like(omega), omega], axis=1))
    coefficients, stderr, _ = _weighted_lstsq(
        np.concatenate(columns), np.concatenate(target), np.concatenate(weight)
    )
    tau = float(coefficients[1])  # model/measured phase = +ωτ when the data lag by τ
    score = abs(tau) / stderr[1] if stderr[1] > 0 else 0.0
    evidence = f"the phase error grows linearly with frequency ({tau * 1e6:+.1f} µs)"
    return Signature("sensor_delay", "delay", float(score), evidence, {"tau_d": tau})


def screen_trend(fit: FitResult, data: DiagnosisData) -> Signature | None:
    """Smooth trend of the stiffness/damping error in log frequency."""
    if fit.model.modulus_term is None or fit.model.modulus_term.keyword == "fractional":
        return None
    f = data.data.frequency_hz
    u = np.log(f / np.sqrt(f.min() * f.max()))
    explained, rows = 0.0, []
    for e, sigma in _log_errors(fit, data).values():
        columns = np.stack([np.ones_like(u), u, u**2], axis=1)
        for part in (e.real, e.imag):
            coefficients, stderr, gain = _weighted_lstsq(columns, part, 1.0 / sigma)
            explained += gain
            rows.append((coefficients, stderr))
    slopes = [abs(c[1]) / s[1] if s[1] > 0 else 0.0 for c, s in rows]
    score = float(max(slopes)) if slopes else 0.0
    keyword = fit.model.modulus_term.keyword
    if keyword == "voigt":
        term = "fractional"
    else:
        order = getattr(fit.model.modulus_term, "order", None) or 1
        term = f"maxwell({order + 1})"
    lo, hi = f.min(), f.max()
    evidence = (
        f"the error changes smoothly with frequency over {lo:g}-{hi:g} Hz, as when stiffness "
        "and damping depend on frequency"
    )
    return Signature("frequency_dependent_modulus", term, score, evidence)


def screen_levels(fit: FitResult, data: DiagnosisData) -> Signature | None:
    """Runs at two levels disagree."""
    if "amplitude" in fit.spec or data.data.reference_amplitude is None:
        return None
    levels = data.levels
    if len(levels) < 2:
        evidence = (
            f"one level only ({levels[0]:.3g} m/s²): along a constant-acceleration sweep the "
            "displacement falls as 1/f², so amplitude dependence looks like frequency dependence"
        )
        return Signature("amplitude_dependence", "amplitude", 0.0, evidence)
    e, sigma = _log_errors(fit, data)[data.frfs[0]]
    means = []
    for segment in data.segments:
        w = 1.0 / sigma[segment.index] ** 2
        mean = float(np.sum(w * e.real[segment.index]) / np.sum(w))
        means.append((segment.level_m_per_s2, mean, float(1.0 / np.sqrt(np.sum(w)))))
    low, high = min(means), max(means)
    gap = (high[1] - low[1]) * 100
    score = abs(high[1] - low[1]) / np.hypot(low[2], high[2])
    evidence = (
        f"runs at {low[0]:.3g} and {high[0]:.3g} m/s² disagree by {abs(gap):.2f} % in magnitude"
    )
    return Signature("amplitude_dependence", "amplitude", float(score), evidence)


def screen_drift(fit: FitResult, data: DiagnosisData) -> Signature | None:
    """Residual against time, beyond what frequency explains."""
    d = data.data
    if "drift" in fit.spec or d.time_s is None:
        return None
    if len(data.segments) == 1 or (len(data.directions) == 1 and len(data.levels) == 1):
        evidence = (
            f"one {data.directions[0]} sweep: time and frequency advance together, so a drift "
            "looks like frequency dependence"
        )
        return Signature("thermal_drift", "drift", 0.0, evidence)
    f = d.frequency_hz
    u = np.log(f / np.sqrt(f.min() * f.max()))
    t = d.time_s / max(np.ptp(d.time_s), 1.0)
    e, sigma = _log_errors(fit, data)[data.frfs[0]]
    columns = np.stack([np.ones_like(u), u, u**2, t], axis=1)
    coefficients, stderr, _ = _weighted_lstsq(columns, e.real, 1.0 / sigma)
    score = abs(coefficients[3]) / stderr[3] if stderr[3] > 0 else 0.0
    per_hour = -coefficients[3] / max(np.ptp(d.time_s), 1.0) * 3600 * 100
    evidence = (
        f"the {'/'.join(data.directions)} sweeps disagree as the test time goes on "
        f"(about {per_hour:+.2f} % per hour)"
    )
    return Signature("thermal_drift", "drift", float(score), evidence)


def screen(fit: FitResult, data: DiagnosisData) -> list[Signature]:
    """Every signature that applies to this fit and these data, highest score first."""
    signatures: list[Signature] = []
    for method in (screen_load_cell, screen_delay, screen_trend, screen_levels, screen_drift):
        signature = method(fit, data)
        if signature is not None:
            signatures.append(signature)
    signatures += screen_fixtures(fit, data)
    return sorted(signatures, key=lambda s: -s.score)
