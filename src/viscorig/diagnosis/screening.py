"""Screening: which effects to try, where to start them, and what in the data points to them.

Screening makes no nonlinear fit. For each effect of the vocabulary it proposes a candidate
term (the channel of a sensor effect, the frequency of a local mode), its start values, the
*evidence* (a sentence for the explanation) and the ``Δχ²`` its test needs
(:mod:`viscorig.diagnosis.significance`); confirmation (:mod:`.findings`) fits it. Signatures:

=============================== ==================================================================
effect                          signature
=============================== ==================================================================
load_cell_compliance            Eq. (4) and Eq. (5) estimates of K* disagree: ``1/(F_e/X_s − D_t)
                                − X_v/F_v`` is the link's compliance ``1/K_c``, zero if rigid
fixture_resonance               a peak of the matched-filter scan (:mod:`.scan`) above its
                                look-elsewhere threshold
frame_mode                      the residual follows what the inertial frame's mode on its
                                isolators changes at the low end of the band
sensor_delay                    one FRF's phase error grows linearly with ω (its sign names the
                                channel that lags); both FRFs alike: both accelerometers lag
sensor_highpass                 one FRF's phase error falls as 1/ω (a lead: the response
                                channel's high-pass; a lag: the force channel's)
sensor_gain                     one FRF's magnitude is off by a constant factor against the other
amplitude_dependence            runs at two levels disagree in stiffness
thermal_drift                   the specimen's recorded temperature moved during the run
                                (``temperature``, tried first, with ``drift`` beside it); else
                                up and down sweeps disagree, or the residual follows ``time_s``
frequency_dependent_modulus     the stiffness/damping error is a smooth trend in log frequency
=============================== ==================================================================

The sensor signatures are linear estimates on the whitened residual with the current model's
own directions projected out (:class:`~viscorig.diagnosis.scan.Residual`), so a sign and a size
come with a standard error before any fit. A sensor term, the frame, an amplitude dependence or
a drift is fitted only when its linear ``Δχ²``, in units of the misfit the model with it would
leave (:func:`per_misfit`, as the test after the fit counts it), reaches
:data:`SENSOR_TRY_SHARE` of its threshold.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

from viscorig.diagnosis.data import DiagnosisData
from viscorig.diagnosis.scan import Residual, ScanResult
from viscorig.diagnosis.significance import alpha_of, dispersion, scan_threshold, threshold
from viscorig.diagnosis.weighted import Likelihood
from viscorig.errors import InputError
from viscorig.estimates import kstar_from_support, kstar_from_table
from viscorig.fitting.jacobian import predict_many
from viscorig.models import TERMS, Fixture, Frame, Model
from viscorig.models.effects import compliance_estimate
from viscorig.models.sensors import force_channel, response_channel
from viscorig.numbers import significant, with_uncertainty

#: Most local modes tried per diagnosis step.
MAX_FIXTURES = 3
#: A scan peak is tried as a mode when its Δχ² reaches this share of the scan's threshold.
SCAN_TRY_SHARE = 0.5
#: A sensor candidate (and a frame, an amplitude dependence, a drift) is fitted when its linear
#: Δχ², in units of the misfit φ (:func:`per_misfit`), reaches this share of its threshold.
SENSOR_TRY_SHARE = 0.25


@dataclass
class Candidate:
    """What screening proposes for one effect.

    Attributes
    ----------
    effect
        Name from the vocabulary.
    term
        Spec text of the term to add, or of the K* term that replaces the current one.
    evidence
        What in the data points to it (a clause for the explanation).
    threshold
        ``Δχ²`` its test needs.
    start
        Start values of the new term's parameters (local names).
    alternatives
        Other terms for the same effect; one replaces :attr:`term` when it fits clearly better
        (its ``χ²`` lower by more than :attr:`threshold`).
    dof
        Parameters the candidate adds.
    identifiable
        These data can tell the effect apart from the other smooth changes of K*.
    """

    effect: str
    term: str
    evidence: str
    threshold: float
    start: dict[str, float] = field(default_factory=dict)
    alternatives: tuple[str, ...] = ()
    dof: int = 1
    identifiable: bool = True


def per_misfit(current: Likelihood, data: DiagnosisData, gain: float) -> float:
    """A linear ``Δχ²`` of one parameter in units of the misfit ``φ`` the model with it would
    leave, as the test that follows a fit counts it (:func:`~.significance.judge`): far from
    the noise, any term soaks up some misfit, and only its share of ``φ`` says it may pay."""
    return gain / dispersion(current.chi2 - gain, data.residual_count, len(current.free) + 1)


def _change(current: Likelihood, data: DiagnosisData, extended: Model,
            added: dict[str, float]) -> dict[str, NDArray[np.complex128]]:
    """``log(H_extended/H_current)`` per FRF: what the term ``extended`` adds to the current
    model changes, with its parameters at ``added`` (local names)."""
    ctx = data.data.context()
    known = {term.spec for term in current.model.effects}
    names = extended.local_names(next(t for t in extended.effects if t.spec not in known))
    base = current.model.predict(ctx, current.values)
    moved = extended.predict(ctx, {**current.values, **{names[k]: v for k, v in added.items()}})
    with np.errstate(all="ignore"):
        return {frf: np.log(moved[frf] / base[frf]) for frf in data.frfs}


def _has(model: Model, keyword: str, argument: str | None = None) -> bool:
    return any(
        term.keyword == keyword and (argument is None or term.spec == f"{keyword}({argument})")
        for term in model.terms
    )


def screen_modulus(current: Likelihood, data: DiagnosisData, alpha: float) -> Candidate | None:
    """A K* that changes with frequency in place of the current one."""
    term = current.model.modulus_term
    if term is None or term.keyword == "fractional":
        return None
    f = data.data.frequency_hz
    evidence = (
        f"the error changes smoothly with frequency over {f.min():g}-{f.max():g} Hz, as when "
        "stiffness and damping depend on frequency"
    )
    if term.keyword == "voigt":
        # Voigt is a limit of both families (α → 1, an arm's K → ∞): at that boundary one
        # more parameter buys the freedom of two, so the test counts two.
        return Candidate("frequency_dependent_modulus", "fractional", evidence,
                         threshold(2, alpha / 2), alternatives=("maxwell(2)",), dof=2)
    order = getattr(term, "order", None) or 1
    return Candidate("frequency_dependent_modulus", f"maxwell({order + 1})", evidence,
                     threshold(2, alpha), alternatives=("fractional",), dof=2)


def screen_load_cell(current: Likelihood, data: DiagnosisData, alpha: float) -> Candidate | None:
    """Eq. (4) against Eq. (5)."""
    if _has(current.model, "load_cell") or set(data.frfs) != {"table", "support"}:
        return None
    if data.table is None:
        return None
    d = data.data
    measured = {"table": d.frf("table"), "support": d.frf("support")}
    estimate = compliance_estimate(d.context(), data.table, measured)
    if estimate is None:
        return None
    compliance = estimate[0]
    m_v = current.values.get("M_v", 0.0)
    k4 = kstar_from_table(d.frequency_hz, measured["table"], data.table, m_v)
    k5 = kstar_from_support(d.frequency_hz, measured["support"], m_v)
    gap = float(np.median((k4.real - k5.real) / np.abs(k5))) * 100
    start = {"K_c": 1.0 / compliance} if compliance > 0 else {}
    stiffness = f"K_c ≈ {1.0 / compliance:.3g} N/m" if compliance > 0 else "no finite K_c"
    evidence = (
        f"the table FRF (Eq. 4) sees a K* {significant(abs(gap))} % "
        f"{'softer' if gap < 0 else 'stiffer'}"
        f" than the support FRF (Eq. 5) does ({stiffness})"
    )
    return Candidate("load_cell_compliance", "load_cell", evidence, threshold(1, alpha), start)


def screen_fixtures(scan: ScanResult) -> list[Candidate]:
    """The scan's strongest peaks as local modes."""
    candidates = []
    for peak in scan.peaks:
        if peak.delta_chi2 < SCAN_TRY_SHARE * scan.threshold:
            continue
        sigmas = np.sqrt(peak.delta_chi2)
        candidates.append(
            Candidate(
                "fixture_resonance",
                Fixture(round(peak.frequency_hz, 2)).spec,
                f"a scan for local modes peaks at {peak.frequency_hz:.2f} Hz, "
                f"{sigmas:.1f} standard errors high (threshold "
                f"{np.sqrt(scan.threshold):.1f} after looking everywhere)",
                scan.threshold,
                {"f_n": peak.frequency_hz, "zeta": peak.damping_ratio,
                 "m": max(peak.mass_kg, 1e-8)},
                dof=3,
            )
        )
        if len(candidates) == MAX_FIXTURES:
            break
    return candidates


def _pm(value: float, stderr: float) -> str:
    """``value ± stderr`` with the value's sign."""
    return with_uncertainty(value, stderr, signed=True)


def _frf_words(frf: str) -> str:
    return {"table": "table FRF (ẍ_s/F_e)", "support": "support FRF (ẍ_v/F_v)"}[frf]


def screen_sensors(
    current: Likelihood, data: DiagnosisData, residual: Residual, alpha: float
) -> list[Candidate]:
    """Delay, high-pass and gain of each FRF's channels, from linear estimates."""
    omega = 2 * np.pi * data.data.frequency_hz
    model = current.model
    out: list[Candidate] = []
    need = threshold(1, alpha)

    def tried(gain: float) -> bool:
        return per_misfit(current, data, gain) >= SENSOR_TRY_SHARE * need

    if set(data.frfs) == {"table", "support"} and not _has(model, "delay"):
        tau, stderr, gain = residual.estimate({frf: -1j * omega for frf in data.frfs})
        if tried(gain):
            out.append(Candidate(
                "sensor_delay", "delay",
                f"both FRFs' phase errors grow linearly with frequency alike "
                f"({_pm(tau * 1e6, stderr * 1e6)} µs)",
                need, {"tau_d": tau}))
    for frf in data.frfs:
        response, force = response_channel(frf), force_channel(frf)
        tau, stderr, gain = residual.estimate({frf: -1j * omega})
        lagging = response if tau > 0 else force
        if tried(gain) and not _has(model, "delay", lagging.name):
            out.append(Candidate(
                "sensor_delay", f"delay({lagging.name})",
                f"the {_frf_words(frf)} phase error grows linearly with frequency "
                f"({_pm(tau * 1e6, stderr * 1e6)} µs)",
                threshold(1, alpha / 2), {f"tau_{lagging.name}": abs(tau)},
                alternatives=(f"lowpass({lagging.name})",)))
        corner, stderr, gain = residual.estimate({frf: 2j * np.pi / omega})
        filtered = response if corner > 0 else force
        if tried(gain) and not _has(model, "highpass", filtered.name):
            out.append(Candidate(
                "sensor_highpass", f"highpass({filtered.name})",
                f"the {_frf_words(frf)} phase error falls as 1/f, a "
                f"{'lead' if corner > 0 else 'lag'} of ({_pm(abs(corner), stderr)} Hz)/f",
                need, {f"f_hp_{filtered.name}": float(np.clip(abs(corner), 1e-3, 50.0))}))
        if len(data.frfs) < 2:
            continue  # one FRF alone cannot tell a gain from K* and M_v
        ratio, stderr, gain = residual.estimate({frf: np.ones_like(omega)})
        if tried(gain) and not _has(model, "gain", response.name):
            out.append(Candidate(
                "sensor_gain", f"gain({response.name})",
                f"the {_frf_words(frf)} magnitude is off by a constant "
                f"{_pm(ratio * 100, stderr * 100)} % against the other FRF",
                need, {f"gain_{response.name}": float(np.clip(1.0 + ratio, 0.6, 1.6))}))
    return out


#: The frame is tried once the model's whitened χ² is within this factor of the noise's: its
#: signature (a few per cent of stiffness at the band's low end, fading as 1/f²) is subtle, and
#: a grossly wrong model leaves misfit there that its three parameters would soak up.
FRAME_NEAR_NOISE = 4.0
#: Start of the frame's mode when a diagnosis tries it: a heavy frame on soft isolators.
FRAME_START = {"M_f": 2000.0, "f_g": 3.0, "zeta_g": 0.1}


def screen_frame(
    current: Likelihood, data: DiagnosisData, residual: Residual, alpha: float
) -> Candidate | None:
    """The inertial frame's rigid-body mode: what a frame of :data:`FRAME_START` would change,
    compared with the residual (to first order)."""
    model = current.model
    if _has(model, "frame") or "table" not in data.frfs or data.table is None:
        return None
    if current.chi2 > FRAME_NEAR_NOISE * data.residual_count:
        return None  # far from the noise, a frame would only soak up what else is missing
    try:
        framed = Model((*model.terms, Frame()))
    except InputError:
        return None  # a coupling term that cannot sit on a frame
    size, stderr, gain = residual.estimate(_change(current, data, framed, FRAME_START))
    scaled = per_misfit(current, data, gain)
    need = threshold(3, alpha)
    if scaled < SENSOR_TRY_SHARE * need:
        return None  # short of the lower threshold: no need for the look-elsewhere length
    need = max(need, scan_threshold(_frame_length(model, framed, current, data, residual),
                                    alpha))
    if scaled < SENSOR_TRY_SHARE * need:
        return None
    evidence = (
        "the error changes at the low end of the band as when the inertial frame under the "
        f"table moves on its isolators (a {FRAME_START['M_f']:.0f} kg frame at "
        f"{FRAME_START['f_g']:g} Hz would explain {_pm(size, stderr)} of it)"
    )
    return Candidate("frame_mode", "frame", evidence, need, dict(FRAME_START), dof=3)


#: Frequencies (Hz, log-spaced over the frame term's range) and damping ratios of the frame's
#: mode along which its look-elsewhere length is measured.
FRAME_SCAN_HZ = np.geomspace(0.05, 100.0, 160)
FRAME_SCAN_ZETA = (0.02, 0.1, 0.5, 2.0)


def _log(z: NDArray[np.complex128]) -> NDArray[np.complex128]:
    """``log z`` as ``log|z| + i arg z``: numpy's complex logarithm, which treats every branch
    cut and special value on its own, took five times as long on the frame's families."""
    return np.log(np.abs(z)) + 1j * np.angle(z)


def _frame_length(model: Model, framed: Model, current: Likelihood, data: DiagnosisData,
                  residual: Residual) -> float:
    """The frame's look-elsewhere length: its free frequency and damping move the shape of
    what it changes, so its largest ``Δχ²`` is the maximum over a family of shapes, as the scan
    for local modes is. Summed arc length of the normalised, whitened and projected change
    along :data:`FRAME_SCAN_HZ`, for each damping of :data:`FRAME_SCAN_ZETA`."""
    ctx = data.data.context()
    frame = next(term for term in framed.effects if term.keyword == "frame")
    names = framed.local_names(frame)
    base = model.predict(ctx, current.values)
    values = {**current.values, names["M_f"]: FRAME_START["M_f"]}
    # every frequency of every damping in one evaluation of the framed model, and the
    # families whitened together
    rows = np.column_stack([np.tile(FRAME_SCAN_HZ, len(FRAME_SCAN_ZETA)),
                            np.repeat(FRAME_SCAN_ZETA, FRAME_SCAN_HZ.size)])
    moved = predict_many(framed, ctx, values, (names["f_g"], names["zeta_g"]), rows)
    with np.errstate(all="ignore"):
        columns = {frf: np.nan_to_num(_log(moved[frf] / base[frf][None, :]).T)
                   for frf in data.frfs}
    # the sign of a frame's change is fixed by its mass: one-sided families
    families = residual.families(columns, [FRAME_SCAN_HZ.size] * len(FRAME_SCAN_ZETA))
    return float(sum(family.length for family in families))


def _log_errors(current: Likelihood, data: DiagnosisData, frf: str):
    """``log(H_model/H_meas)`` of one FRF and its per-point noise σ."""
    with np.errstate(all="ignore"):
        e = np.log(1.0 + current.residuals[frf])
    return e, np.sqrt(data.noise_power[frf])


def _weighted_lstsq(columns, target, weight):
    a = columns * weight[:, None]
    b = target * weight
    coefficients, *_ = np.linalg.lstsq(a, b, rcond=None)
    try:
        covariance = np.linalg.inv(a.T @ a)
    except np.linalg.LinAlgError:
        covariance = np.full((a.shape[1], a.shape[1]), np.inf)
    return coefficients, np.sqrt(np.abs(np.diag(covariance)))


def screen_levels(current: Likelihood, data: DiagnosisData, alpha: float) -> Candidate | None:
    """Runs at two levels disagree."""
    if _has(current.model, "amplitude") or not data.data.has("reference_amplitude"):
        return None
    levels = data.levels
    if len(levels) < 2:
        evidence = (
            f"one level only ({levels[0]:.3g} m/s²): along a constant-acceleration sweep the "
            "displacement falls as 1/f², so amplitude dependence looks like frequency dependence"
        )
        return Candidate("amplitude_dependence", "amplitude", evidence, threshold(1, alpha),
                         identifiable=False)
    e, sigma = _log_errors(current, data, data.frfs[0])
    means = []
    for segment in data.segments:
        w = 1.0 / sigma[segment.index] ** 2
        mean = float(np.sum(w * e.real[segment.index]) / np.sum(w))
        means.append((segment.level_m_per_s2, mean))
    low, high = min(means), max(means)
    evidence = (
        f"runs at {low[0]:.3g} and {high[0]:.3g} m/s² disagree by "
        f"{abs(high[1] - low[1]) * 100:.2f} % in magnitude"
    )
    return Candidate("amplitude_dependence", "amplitude", evidence, threshold(1, alpha))


#: A recorded temperature that moves this much during a run may explain a drift of its
#: modulus, K: the ``temperature`` term is tried before a drift in time.
RECORDED_DRIFT_K = 0.2
#: The recorded temperature tells its effect apart from a frequency-dependent modulus when this
#: much of it (rms, K) does not follow a smooth trend in log frequency (a thermocouple's
#: resolution).
TEMPERATURE_APART_K = 0.1


def screen_recorded_temperature(current: Likelihood, data: DiagnosisData,
                                alpha: float) -> Candidate | None:
    """The specimen's recorded temperature moved during the run: ``temperature(T_ref)``, the
    modulus scaled by it, with a drift in time as its alternative."""
    d = data.data
    temperature = d.temperature_c
    if temperature is None or not d.has("temperature_c") or (
            float(np.ptp(temperature)) < RECORDED_DRIFT_K):
        return None
    reference = round(float(np.median(temperature)), 1)
    u = np.log(d.frequency_hz / np.sqrt(d.frequency_hz.min() * d.frequency_hz.max()))
    columns = np.stack([np.ones_like(u), u, u**2], axis=1)
    smooth, *_ = np.linalg.lstsq(columns, temperature, rcond=None)
    apart = float(np.sqrt(np.mean((temperature - columns @ smooth) ** 2)))
    evidence = (f"the specimen's recorded temperature moved from {temperature.min():.1f} to "
                f"{temperature.max():.1f} °C during the run")
    if apart < TEMPERATURE_APART_K:
        evidence += (" in step with the frequency, so its effect looks like frequency "
                     "dependence")
    return Candidate("thermal_drift", f"temperature({reference:g})", evidence,
                     threshold(1, alpha), alternatives=("drift",) if d.has("time_s") else (),
                     identifiable=apart >= TEMPERATURE_APART_K)


def screen_drift(current: Likelihood, data: DiagnosisData, alpha: float) -> Candidate | None:
    """The recorded temperature's effect (:func:`screen_recorded_temperature`) where it
    moved; else the residual against time, beyond what frequency explains."""
    d = data.data
    if _has(current.model, "drift") or _has(current.model, "temperature"):
        return None
    recorded = screen_recorded_temperature(current, data, alpha)
    time = d.time_s
    if recorded is not None or time is None or not d.has("time_s"):
        return recorded
    if len(data.segments) == 1 or (len(data.directions) == 1 and len(data.levels) == 1):
        evidence = (
            f"one {data.directions[0]} sweep: time and frequency advance together, so a drift "
            "looks like frequency dependence"
        )
        return Candidate("thermal_drift", "drift", evidence, threshold(1, alpha),
                         identifiable=False)
    f = d.frequency_hz
    u = np.log(f / np.sqrt(f.min() * f.max()))
    span = max(float(np.ptp(time)), 1.0)
    t = time / span
    e, sigma = _log_errors(current, data, data.frfs[0])
    columns = np.stack([np.ones_like(u), u, u**2, t], axis=1)
    coefficients, _ = _weighted_lstsq(columns, e.real, 1.0 / sigma)
    # a softening K* raises the measured accelerance: log(H_model/H_measured) falls with it
    per_hour = coefficients[3] / span * 3600 * 100
    evidence = (
        f"the {'/'.join(data.directions)} sweeps disagree as the test time goes on "
        f"(about {per_hour:+.2f} % per hour)"
    )
    return Candidate("thermal_drift", "drift", evidence, threshold(1, alpha))


#: The terms that scale K* by one parameter (zero: no change), with the step of their linear
#: estimate: screened as the sensor terms are (:data:`SENSOR_TRY_SHARE`).
SCALING_STEPS = {"amplitude": ("beta", 1e-3), "drift": ("kappa", 1e-7),
                 "temperature": ("gamma", 1e-4)}


def _weak(current: Likelihood, data: DiagnosisData, residual: Residual,
          candidate: Candidate) -> bool:
    """The candidate scales K* by one parameter and its linear ``Δχ²`` is short of
    :data:`SENSOR_TRY_SHARE` of its threshold (:func:`per_misfit`)."""
    keyword, _, argument = candidate.term.rstrip(")").partition("(")
    if keyword not in SCALING_STEPS:
        return False
    name, step = SCALING_STEPS[keyword]
    try:
        model = Model((*current.model.terms, TERMS[keyword].from_argument(argument or None)))
    except InputError:
        return False
    change = _change(current, data, model, {name: step})
    _, _, gain = residual.estimate({frf: c / step for frf, c in change.items()})
    return per_misfit(current, data, gain) < SENSOR_TRY_SHARE * candidate.threshold


def screen(current: Likelihood, data: DiagnosisData, residual: Residual) -> list[Candidate]:
    """Every candidate that applies to this model and these data but those found by scanning
    (:func:`screen_by_scan`), each with the threshold of one test of the step's family
    (:func:`alpha_of`)."""
    alpha = alpha_of(current.model, data)
    candidates: list[Candidate] = []
    for method in (screen_modulus, screen_load_cell, screen_levels, screen_drift):
        candidate = method(current, data, alpha)
        if candidate is not None and not _weak(current, data, residual, candidate):
            candidates.append(candidate)
    return candidates + screen_sensors(current, data, residual, alpha)


def screen_family_frame(current: Likelihood, data: DiagnosisData, residual: Residual
                        ) -> list[Candidate]:
    """The frame's candidate of a step (none or one), at the step's ``α``: screened over a
    family of shapes, its look-elsewhere length (:func:`screen_frame`), as the local modes are
    by the scan (:func:`screen_fixtures`). A step hands it to a worker while it scans."""
    frame = screen_frame(current, data, residual, alpha_of(current.model, data))
    return [] if frame is None else [frame]
