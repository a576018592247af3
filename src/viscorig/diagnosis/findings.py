"""Confirmation: fit each candidate, rank it, and test it next to the effects found before it.

Fits. Every candidate is fitted by maximum likelihood on the whitened residual
(:mod:`viscorig.diagnosis.weighted`), warm-started from the current model and the start
screening found (a K* that replaces the current one is first fitted by ``identify``'s fitter,
from its linear start, or from its optimum at an earlier rung of the ladder). Its ``χ²`` drop
``Δχ²`` against the current model, and ``delta_bic = −Δχ² + k ln n`` (``k`` added parameters,
``n`` the independent observations the noise model says the data are worth), rank the
candidates, best first. The fits stop first at a looser tolerance (:data:`FIRST_TOLERANCE`),
where each ``Δχ²`` is a lower bound of the finished fit's, by a fraction of the misfit ``φ`` as
a rule; the candidates whose test, rank or name could still change are finished
(:func:`_near_decision`).

K* family. A Maxwell K* that would take one more arm is also compared with the fractional K*
in its place (the candidate's alternative), and the ladder's last model with a Maxwell K* once
more (:func:`other_family`): the family is picked at the first rungs, far from the noise, and
is judged again once the other effects are in. An alternative takes a candidate's place only
when it is better by the candidate's threshold in units of the misfit (:func:`clearly_better`).

Significance. Candidates are taken best first, and each is tested against the best model so
far, that is the current model with every effect already found significant: it is fitted with
them, and is significant when its own ``Δχ²`` there still exceeds its threshold
(:mod:`viscorig.diagnosis.significance`, against the misfit ``φ`` of the larger model) and it
removes at least :data:`MIN_EXCESS_FRACTION` of that model's ``χ²`` in excess of what noise
gives (``χ² − (n − p)``, none when the model is at the noise). An effect that only soaked up the
misfit of a grossly wrong model (a drift "explaining" part of a frequency-dependent modulus)
does not survive next to the effect that was really missing.

Amplitude dependence and thermal drift scale the whole K* smoothly along one
constant-acceleration up sweep: from one run they cannot be told apart from each other (nor,
where a causal K* happens to follow the same change, from a frequency-dependent modulus). A
finding of one of them names the others the data cannot separate from it, and the run that
would.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass, field

import numpy as np

from viscorig.diagnosis.data import DiagnosisData
from viscorig.diagnosis.screening import Candidate
from viscorig.diagnosis.significance import alpha_of, dispersion, judge, threshold
from viscorig.diagnosis.weighted import TOLERANCE, Likelihood, evaluate, ml_fit
from viscorig.diagnosis.workers import fit_all, fit_all_later, fits_at_once
from viscorig.errors import InputError
from viscorig.fitting import FitResult, fit
from viscorig.fitting.arms import extended_start, maxwell_order
from viscorig.fitting.nonlinear import outlier_heavy
from viscorig.models import TERMS, Fixture, Model, Term, parse_spec
from viscorig.models.sensors import CHANNELS, Delay
from viscorig.numbers import Estimate

#: Two confounded candidates within this ΔBIC of each other are not told apart by the data.
AMBIGUOUS_DELTA_BIC = 10.0
#: ... or when the other's rms_error is within this factor: the two differ only in the exact
#: shape of a smooth change along the band, which the data alone do not vouch for.
AMBIGUOUS_RMS_RATIO = 1.5
#: Effects that all reshape K* smoothly along a constant-acceleration up sweep.
CONFOUNDED = ("frequency_dependent_modulus", "amplitude_dependence", "thermal_drift")
#: Which effect comes first when the data cannot tell two apart (their Δχ² differ by less than
#: the test's threshold): the rig's mechanics before its instrumentation, as a mechanical cause
#: is the commoner one and a calibration error of the size the mechanics would need is rare.
PRIORITY = (
    "frequency_dependent_modulus", "load_cell_compliance", "fixture_resonance", "frame_mode",
    "sensor_delay", "sensor_highpass", "sensor_gain", "amplitude_dependence", "thermal_drift",
)


@dataclass
class Finding:
    """A candidate effect, fitted and tested.

    Attributes
    ----------
    effect
        Name from the vocabulary (``fixture_resonance``...).
    model
        Spec of the candidate model, accepted as is by ``identify --model``.
    likelihood
        Its maximum-likelihood fit on the diagnosed data.
    delta_chi2
        Drop of ``χ²`` against the model diagnosed.
    delta_bic
        ``−Δχ² + k ln n``: negative when the candidate is better by the Bayesian criterion.
    threshold
        ``Δχ²`` its test needs (:mod:`viscorig.diagnosis.significance`).
    significant
        It still pays for its parameters next to the effects found before it.
    evidence
        What screening saw.
    term
        Spec text of the term the finding adds (or the K* term it puts instead).
    explanation
        One or two sentences a technician can act on.
    alternatives
        Effects the data cannot tell apart from this one.
    fit
        The fit ``identify --model`` makes of :attr:`model` (the best finding only, and any
        finding added with :meth:`Diagnosis.with_effect`); ``None`` otherwise.
    dispersion
        ``φ`` of the candidate's fit (1 when it fits to the noise).
    passes_alone
        It passes its test against the model diagnosed, before any other effect is added.
    note
        Why the finding is not significant (its test's shortfall, alone or next to the effects
        found before it).
    identifiable
        These data can tell the effect apart from the other smooth changes of K* (false for
        amplitude dependence from one level, drift from one sweep direction).
    """

    effect: str
    model: str
    likelihood: Likelihood = field(repr=False)
    delta_chi2: float
    delta_bic: float
    threshold: float
    significant: bool
    evidence: str
    term: str
    explanation: str = ""
    alternatives: list[str] = field(default_factory=list)
    fit: FitResult | None = field(default=None, repr=False)
    dispersion: float = 1.0
    passes_alone: bool = False
    note: str = ""
    identifiable: bool = True

    @property
    def rms_error(self) -> float:
        """``rms_error`` of the candidate model (of :attr:`fit` when made)."""
        return self.fit.rms_error if self.fit is not None else self.likelihood.rms_error

    def parameters(self) -> dict[str, dict[str, float | str]]:
        """The parameters the finding adds (or the new K* term's), with stderr and unit."""
        new = added_parameters(self.likelihood.model, self.term)
        stderr = self.likelihood.stderr()
        scale = np.sqrt(self.dispersion)
        model = self.likelihood.model
        return {
            name: Estimate(float(self.likelihood.values[name]),
                           float(stderr.get(name, np.nan) * scale),
                           model.by_name[name].unit).to_json()
            for name in model.names
            if name in new
        }

    def to_json(self) -> dict[str, object]:
        """The finding as in the ``diagnose --json`` contract (plus ``delta_chi2``,
        ``threshold``, ``dispersion``, ``alternatives``: the test is ``delta_chi2 / dispersion``
        against ``threshold``)."""
        return {
            "effect": self.effect,
            "model": self.model,
            "rms_error": float(self.rms_error),
            "delta_bic": float(self.delta_bic),
            "delta_chi2": float(self.delta_chi2),
            "threshold": float(self.threshold),
            "dispersion": float(self.dispersion),
            "significant": bool(self.significant),
            "explanation": self.explanation,
            "parameters": self.parameters(),
            "alternatives": list(self.alternatives),
        }


def added_parameters(model: Model, term_text: str) -> set[str]:
    """Global names of the parameters of the term written ``term_text`` in ``model``."""
    for term in model.terms:
        if term.spec == term_text or (term.keyword == term_text and term.kind == "modulus"):
            return set(model.local_names(term).values())
    keyword = term_text.split("(")[0]
    for term in model.terms:
        if term.keyword == keyword and term.kind == "modulus":
            return set(model.local_names(term).values())
    return set()


def candidate_spec(current: Model, term_text: str) -> str:
    """The current model with a term added, or its K* term replaced by a K* term."""
    keyword = term_text.split("(")[0].strip()
    if keyword in TERMS and TERMS[keyword].kind == "modulus":
        return "+".join([term_text, *(term.spec for term in current.effects)])
    return f"{current.spec}+{term_text}"


def carried_values(old: FitResult | Likelihood, new: Model) -> dict[str, float]:
    """Values of ``old`` for every term ``new`` shares with it, under ``new``'s names."""
    values: dict[str, float] = {
        name: old.values[name] for name in ("M_s", "K_s", "C_s") if name in old.values
    }
    old_terms = {term.spec: term for term in old.model.terms}
    for term in new.terms:
        match = old_terms.get(term.spec)
        if match is None:
            continue
        old_names = old.model.local_names(match)
        for local, name in new.local_names(term).items():
            values[name] = old.values[old_names[local]]
        if term.kind == "modulus" and "M_v" in old.values:
            values["M_v"] = old.values["M_v"]
    if "M_v" not in values and "M_v" in old.values and "M_v" in new.names:
        values["M_v"] = old.values["M_v"]
    return values


def _start_of(model: Model, term_text: str, local: dict[str, float]) -> dict[str, float]:
    """Global names of the start values ``local`` of the term ``term_text`` in ``model``."""
    for term in model.effects:
        if term.spec == term_text:
            names = model.local_names(term)
            return {names[k]: v for k, v in local.items() if k in names}
    return {}


def fit_with(
    current: FitResult | Likelihood,
    data: DiagnosisData,
    term_text: str,
    start: dict[str, float] | None = None,
) -> FitResult:
    """Fit (as :func:`refit` does) the current model plus ``term_text``, warm-started."""
    model = parse_spec(candidate_spec(current.model, term_text))
    values = carried_values(current, model)
    values.update(_start_of(model, term_text, start or {}))
    return refit(model, data, values)


def refit(model: Model | str, data: DiagnosisData, start: dict[str, float]) -> FitResult:
    """The fit ``identify --model ... --weights uniform`` makes of ``model`` on ``data`` (the
    table's values held, their covariance propagated), started at ``start``: the fit that
    minimises ``rms_error``, which diagnosis reports for a model."""
    fixed = dict(data.table or {})
    return fit(model, data.data, frfs=data.frfs, fixed=fixed, known=data.table_prior,
               noise=data.noise, start={k: v for k, v in start.items() if k not in fixed})


def identify_fit(likelihood: Likelihood, data: DiagnosisData) -> FitResult:
    """The :func:`refit` of a model, started at its likelihood fit."""
    return refit(likelihood.model, data, likelihood.values)


def _broad(model: Model) -> set[str]:
    """Parameters that shape the whole band: K*'s, the disc mass, the load cell's.

    A fractional K*'s relaxation time is not among them. Where ``ωτ`` stays far from 1 over the
    band, ``tau`` trades off with ``K_inf`` along a curved valley (only ``(K_inf − K_0) τ^α`` is
    determined there); following it took most of a ladder's solver steps, while ``K_0``,
    ``K_inf`` and ``alpha`` still reshape the whole K*. A new fractional K* has its ``tau``
    fitted (:func:`fit_term` adds the new term's parameters).
    """
    modulus = model.require_modulus()
    held = {"tau"} if modulus.keyword == "fractional" else set()
    names = {v for k, v in model.local_names(modulus).items() if k not in held} | {"M_v"}
    return names | {n for t in model.effects if t.keyword == "load_cell"
                    for n in model.local_names(t).values()}


def fit_term(
    current: Likelihood, data: DiagnosisData, term_text: str, start: dict[str, float],
    tolerance: float = TOLERANCE, earlier: Mapping[str, float] | None = None,
) -> Likelihood:
    """Maximum-likelihood fit of the current model with ``term_text`` added (or as its K*).

    The new term's parameters are fitted with those that shape the whole band (:func:`_broad`);
    the other terms' (a local mode elsewhere, a sensor's) stay at their current values, which a
    new term barely moves: the drop of ``χ²`` is then a lower bound, and the fit several times
    faster. The fit is on the statistic the tests compare (the drift's correlation in the
    whitening), so that where it stops moves its ``χ²`` one way only: a fit weighing each point
    by its own noise alone, judged on the whole noise model, moved the candidates' ``Δχ²`` by
    tens of ``φ`` either way with its stopping point, and the ladders with them.
    ``tolerance``: :func:`~viscorig.diagnosis.weighted.ml_fit`'s. ``earlier``: the values of
    the same model fitted at an earlier rung of the ladder (:data:`Optima`); a new K* or load
    cell starts its fitted parameters there in place of ``identify``'s fit from the linear
    start (the optimum of the same model under a prior weighed a little differently, a few
    solver steps from this one), the others at the current model's values.
    """
    model = parse_spec(candidate_spec(current.model, term_text))
    only = _broad(model) | added_parameters(model, term_text)
    order = maxwell_order(current.model)
    if order and maxwell_order(model) == order + 1:
        # One arm more: the current arms and a small new one in their widest gap start it at
        # the current model's optimum, where a linear start of the whole K* lands elsewhere.
        values = {**model.defaults(), **carried_values(current, model),
                  **extended_start(current.model, current.values, data.data.frequency_hz,
                                   model)}
        return ml_fit(model, data, values, only=only, tolerance=tolerance)
    if (model.require_modulus().spec != current.model.require_modulus().spec
            or term_text == "load_cell"):
        # A new K*, or a new coupling of table and disc, reshapes the whole band: the current
        # K* is no start for it. Fit it as identify does (linear start), then by likelihood.
        if earlier is not None:
            values = {**model.defaults(), **carried_values(current, model),
                      **{name: value for name, value in earlier.items() if name in only}}
            result = ml_fit(model, data, values, only=only, tolerance=tolerance)
            heavy = False
        else:
            first = fit_with(current, data, term_text, start)
            result = ml_fit(first.model, data, first.values, only=only, tolerance=tolerance)
            heavy = outlier_heavy(first)
        if result.chi2 <= current.chi2 and not heavy:
            return result
        # That start minimises every point's error alike: a few outlier points can drag it
        # where the likelihood ends worse than the model without the term, or in a valley far
        # from the best (a load cell's Δχ² 8,111 where it is 28,240 without the glitches).
        # Start from that model as well, and keep the better.
        other = ml_fit(model, data, _warm_start(current, model, term_text, start), only=only,
                       tolerance=tolerance)
        return other if other.chi2 < result.chi2 else result
    return ml_fit(model, data, _warm_start(current, model, term_text, start), only=only,
                  tolerance=tolerance)


def _warm_start(current: Likelihood, model: Model, term_text: str,
                start: dict[str, float]) -> dict[str, float]:
    """``model``'s values from ``current``'s, the new term's from ``start`` or its defaults."""
    values = {**model.defaults(), **carried_values(current, model)}
    values.update(_start_of(model, term_text, start))
    return values


#: Candidates are first fitted to this tolerance (a step lowering the cost by less than this
#: share of it ends the fit; :data:`~.weighted.TOLERANCE` otherwise), and those that may
#: decide something finished (:func:`_near_decision`).
FIRST_TOLERANCE = 1e-4
#: ... and finished to this one: a step then lowers ``χ²`` by less than about 0.01 ``φ`` (the
#: cost is about ``φ`` times half the residuals). On the six ladders of the benchmark campaign
#: the finished ``χ²`` is within 0.03 ``φ`` of a fit carried on to 1e-6 for nine candidates in
#: ten, 1.4 ``φ`` at most, with 40 % fewer solver steps.
FINISH_TOLERANCE = 1e-5
#: A candidate is near a decision when its first fit's ``Δχ²/φ`` is within this share of its
#: threshold below it or above, ...
NEAR_SHARE = 0.5
#: ... or its ``ΔBIC`` is within this many ``φ`` of the best candidate's, ...
NEAR_BEST = 5.0
#: ... or within this share of it: far from the noise a first fit can stop short by several
#: percent of its ``Δχ²`` (a load cell's, 9 % short of a sensor gain it then beat by 0.2 ``φ``).
NEAR_SHARE_OF_BEST = 0.2


def _fit_term_or_none(current: Likelihood, data: DiagnosisData, term_text: str,
                      start: dict[str, float], tolerance: float = TOLERANCE,
                      earlier: Mapping[str, float] | None = None) -> Likelihood | None:
    """:func:`fit_term`, or ``None`` where the term cannot be fitted to these data."""
    try:
        return fit_term(current, data, term_text, start, tolerance, earlier)
    except (InputError, ValueError, np.linalg.LinAlgError):
        return None


def _finish(first: Likelihood, data: DiagnosisData) -> Likelihood:
    """A candidate's first fit carried on to :data:`FINISH_TOLERANCE`, the same parameters
    free."""
    try:
        return ml_fit(first.model, data, first.values, only=first.fitted,
                      tolerance=FINISH_TOLERANCE)
    except (InputError, ValueError, np.linalg.LinAlgError):
        return first


def _renamed(result: Likelihood, term_text: str, data: DiagnosisData) -> tuple[Likelihood, str]:
    """Name a fixture by its fitted frequency, and a channel delay by the channel that lags."""
    model = result.model
    term = next((t for t in model.effects if t.spec == term_text), None)
    if term is None:
        return result, term_text
    names = model.local_names(term)
    values = dict(result.values)
    sign = 1.0
    if isinstance(term, Fixture):
        new: Fixture | Delay = Fixture(round(values[names["f_n"]], 2))
    elif isinstance(term, Delay) and term.channel is not None and values[names[term.name]] < 0:
        new = Delay(next(c for c in CHANNELS.values()
                         if c.frf == term.channel.frf and c is not term.channel))
        sign = -1.0
    else:
        return result, term_text
    try:
        new_model = parse_spec("+".join(t.spec if t is not term else new.spec
                                        for t in model.terms))
    except InputError:
        return result, term_text
    new_term = next(t for t in new_model.effects if t.spec == new.spec)
    new_values = {**carried_values(result, new_model)}
    old = model.local_values(term, values)
    for (local, value), name in zip(old.items(), new_model.local_names(new_term).values(),
                                    strict=True):
        new_values[name] = sign * value if local == getattr(term, "name", None) else value
    return evaluate(new_model, data, new_values), new.spec


def _inside(result: Likelihood, term_text: str, data: DiagnosisData) -> bool:
    """The local mode ``term_text`` of ``result`` has its half-power band within the data's
    band, two frequency steps at least from either end (at the edge, a mode is a trend)."""
    term = next((t for t in result.model.effects if t.spec == term_text), None)
    if term is None:
        return False
    names = result.model.local_names(term)
    f_n, zeta = result.values[names["f_n"]], result.values[names["zeta"]]
    f = data.data.frequency_hz
    steps = np.diff(np.unique(f))
    margin = max(2 * zeta * f_n, 2 * (float(np.median(steps)) if steps.size else 0.0))
    return bool(f.min() + margin < f_n < f.max() - margin)


Optima = Mapping[str, Mapping[str, float]]
"""The values of the models fitted at the earlier rungs of a ladder, by spec: a K* or a load cell
that replaces the current one starts from its own optimum when the ladder fitted the same model
before (a fractional K* tried again once the Maxwell one has an arm more)."""


def _earlier(optima: Optima, current: Model, term_text: str) -> Mapping[str, float] | None:
    try:
        return optima.get(candidate_spec(current, term_text))
    except InputError:
        return None


def candidate_fits(
    current: Likelihood, data: DiagnosisData, candidates: list[Candidate],
    optima: Optima | None = None,
) -> Callable[[], list[Likelihood | None]]:
    """Start the fits of every candidate's term and alternatives (:func:`fit_term`, ``None``
    where one cannot be fitted), in that order; what is returned gives their results.
    ``optima``: the models the ladder fitted before this step."""
    optima = optima or {}
    return fit_all_later(_fit_term_or_none, [
        (current, data, term, candidate.start, FIRST_TOLERANCE,
         _earlier(optima, current.model, term))
        for candidate in candidates for term in (candidate.term, *candidate.alternatives)])


def _near_decision(current: Likelihood, data: DiagnosisData, candidates: list[Candidate],
                   fitted: list[Likelihood | None]) -> list[bool]:
    """Which first fits (:func:`candidate_fits`, in its order) may decide something once
    finished: every term of a candidate one of whose terms is within :data:`NEAR_SHARE` of its
    threshold (:func:`judge`); passes it and names a local mode (by its fitted frequency) or
    has alternatives; or, when any candidate comes that near to passing, whose ``ΔBIC`` is
    within :data:`NEAR_BEST` ``φ`` of the best one's (or within :data:`NEAR_SHARE_OF_BEST` of
    it) or of another passing candidate's (the order of the forward tests, whose lead may be a
    candidate that does not pass). When none does, no rank decides anything (the forward tests
    take only candidates that pass), and none is finished."""
    n_eff = data.effective_points
    terms = [(index, term) for index, candidate in enumerate(candidates)
             for term in (candidate.term, *candidate.alternatives)]
    near: set[int] = set()
    rows = []
    for (index, term), result in zip(terms, fitted, strict=True):
        if result is None:
            continue
        candidate = candidates[index]
        delta, phi, *_ = judge(current, result, candidate.threshold, data, term)
        ratio = delta / phi / candidate.threshold
        passes = ratio >= 1 - NEAR_SHARE
        if abs(ratio - 1) < NEAR_SHARE or (passes and (
                candidate.effect == "fixture_resonance" or candidate.alternatives)):
            near.add(index)
        rows.append((index, passes, -delta + (len(result.free) - len(current.free))
                     * np.log(n_eff), phi))
    if not any(row[1] for row in rows):
        return [False] * len(terms)  # none can pass: their ranks decide nothing
    best = min((row[2] for row in rows), default=np.inf)
    for index, passes, bic, phi in rows:
        if bic <= best + max(NEAR_BEST * phi, -NEAR_SHARE_OF_BEST * best) or (passes and any(
                other[1] and other[0] != index and abs(other[2] - bic) < NEAR_BEST * max(
                    phi, other[3]) for other in rows)):
            near.add(index)
    return [index in near for index, _ in terms]


def _finished(current: Likelihood, data: DiagnosisData, candidates: list[Candidate],
              fitted: list[Likelihood | None]) -> list[Likelihood | None]:
    """The first fits, those near a decision (:func:`_near_decision`) finished."""
    near = _near_decision(current, data, candidates, fitted)
    at = [i for i, close in enumerate(near) if close and fitted[i] is not None]
    done = fit_all(_finish, [(fitted[i], data) for i in at])
    out = list(fitted)
    for i, result in zip(at, done, strict=True):
        out[i] = result
    return out


def confirm(
    current: Likelihood, data: DiagnosisData, candidates: list[Candidate],
    fitted: list[Likelihood | None],
) -> tuple[list[Finding], Likelihood]:
    """Rank the candidates by their fits ``fitted`` (:func:`candidate_fits`; lowest ΔBIC
    first, ``n`` the effective number of independent observations of the noise model; among
    those the data cannot tell apart, by :data:`PRIORITY`), test each next to the ones found
    significant before it, and return them significant first, with the fit of the model holding
    every significant one."""
    n = data.effective_points
    findings: list[Finding] = []
    fits = iter(_finished(current, data, candidates, fitted))
    for candidate in candidates:
        best: tuple[Likelihood, str] | None = None
        for term in (candidate.term, *candidate.alternatives):
            result = next(fits)
            if result is None:
                continue
            # an alternative replaces the first term only when the data clearly prefer it
            if best is None or clearly_better(result, best[0], candidate.threshold, data):
                best = (result, term)
        if best is None:
            continue
        result, term = best
        if term == "maxwell":
            term = result.model.require_modulus().spec
        result, term = _renamed(result, term, data)
        if candidate.effect == "fixture_resonance" and not _inside(result, term, data):
            continue  # a mode fitted outside the band is a smooth trend there, not a local mode
        delta, phi, passes, shortfall = judge(current, result, candidate.threshold, data, term)
        k = len(result.free) - len(current.free)
        findings.append(Finding(
            candidate.effect, result.spec, result, float(delta), float(-delta + k * np.log(n)),
            candidate.threshold, False, candidate.evidence, term, dispersion=phi,
            passes_alone=passes, note=shortfall, identifiable=candidate.identifiable,
        ))
    findings.sort(key=lambda finding: finding.delta_bic)
    ties = _ties(findings)
    findings[: len(ties)] = sorted(ties, key=_priority)
    _after_modulus(findings)
    forward = _forward(current, data, findings)
    for finding in findings:
        if finding.significant:  # its ± with every parameter free, not only those it moved
            finding.likelihood = evaluate(finding.likelihood.model, data,
                                          finding.likelihood.values)
    _mark_ambiguities(findings, ties)
    findings.sort(key=lambda finding: not finding.significant)  # stable: ranks kept within
    return findings, forward


def _after_modulus(findings: list[Finding]) -> None:
    """Put a drift or an amplitude dependence that one sweep cannot tell from a
    frequency-dependent modulus after the modulus: it is tested next to it, not before."""
    modulus = next((i for i, f in enumerate(findings)
                    if f.effect == "frequency_dependent_modulus" and f.passes_alone), None)
    if modulus is None:
        return
    early = [f for f in findings[:modulus] if not f.identifiable]
    if early:
        rest = [f for f in findings if f not in early]
        at = rest.index(findings[modulus]) + 1
        findings[:] = rest[:at] + early + rest[at:]


def _priority(finding: Finding) -> int:
    return PRIORITY.index(finding.effect) if finding.effect in PRIORITY else len(PRIORITY)


def _ties(findings: list[Finding]) -> list[Finding]:
    """The leading findings the data cannot tell apart from the best: each explains the best's
    ``Δχ²`` to within its own threshold (counted in units of the misfit ``φ``)."""
    if not findings or not findings[0].passes_alone:
        return findings[:1]
    best = findings[0]
    tied = [best]
    for other in findings[1:]:
        if not other.passes_alone:
            break
        if (best.delta_chi2 - other.delta_chi2) / best.dispersion < other.threshold:
            tied.append(other)
        else:
            break
    return tied


def exact_fit(result: Likelihood, data: DiagnosisData) -> Likelihood:
    """``result`` refitted on the exact whitening, every parameter free: a model the next
    candidate is judged against must be at its own optimum, so that what the candidate's fit
    gains is the candidate's and not a better convergence of the rest."""
    return ml_fit(result.model, data, result.values)


def other_family(current: Likelihood, data: DiagnosisData,
                 optima: Optima | None = None) -> Likelihood | None:
    """The fit of ``current`` with its Maxwell K* replaced by the fractional one, every other
    term kept, when the data prefer it by the Bayesian criterion (:func:`clearly_better`, with
    no margin); else ``None``.

    The ladder picks a K* family at its first rungs, far from the noise, where a local mode or
    the load cell not yet added weighs as much as the family's shape, and only adds arms to a
    Maxwell K* after that. With every effect in place, the four parameters of a fractional K*
    may describe the same data as many arms do. ``optima``: the models the ladder fitted
    before (:data:`Optima`).
    """
    if maxwell_order(current.model) is None:
        return None
    try:
        earlier = _earlier(optima or {}, current.model, "fractional")
        other = exact_fit(fit_term(current, data, "fractional", {}, earlier=earlier), data)
    except (InputError, ValueError, np.linalg.LinAlgError):
        return None
    return other if clearly_better(other, current, 0.0, data) else None


def clearly_better(other: Likelihood, first: Likelihood, margin: float,
                   data: DiagnosisData) -> bool:
    """``other`` is better than ``first`` by more than ``margin`` by the Bayesian criterion
    ``χ²/φ + k ln n`` (``n`` the effective number of independent observations, ``φ`` the misfit
    of the better-fitting of the two): far from the noise, a difference of ``χ²`` counts in
    units of the misfit, as every test of the diagnosis counts it."""
    n = data.effective_points
    phi = min(dispersion(result.chi2, data.residual_count, len(result.free))
              for result in (other, first))

    def bic(result: Likelihood) -> float:
        return result.chi2 / phi + len(result.free) * np.log(n)

    return bic(other) < bic(first) - margin


def _next_to(base: Likelihood, data: DiagnosisData, term: str, found: Likelihood
             ) -> Likelihood | None:
    """The fit of ``base`` with ``term`` added, started from ``base`` and the term's own fit
    ``found`` (the new term's parameters and the broad ones free); ``None`` where the term does
    not combine with ``base``."""
    try:
        model = parse_spec(candidate_spec(base.model, term))
    except InputError:
        return None
    start = {**model.defaults(), **carried_values(found, model), **carried_values(base, model)}
    return ml_fit(model, data, start, only=_broad(model) | added_parameters(model, term))


def _forward(current: Likelihood, data: DiagnosisData, findings: list[Finding]) -> Likelihood:
    """Mark significant the findings that pay for themselves next to those before them; the fit
    of the model with all of them.

    Each test is against the model of the findings accepted before it, so the tests that follow
    one base are independent: as many as there are workers (:func:`~.workers.fits_at_once`)
    are fitted together, and those after a finding that is accepted are fitted again against
    the new base. The numbers are those of testing one after the other."""
    base, accepted = current, list[Finding]()
    lead = findings[0] if findings else None
    if lead is None or lead.passes_alone or lead.delta_chi2 <= 0 or lead.effect == (
            "fixture_resonance"):
        lead = None
    tested: dict[int, Likelihood | None] = {}  # by position in findings, against ``base``
    for index, finding in enumerate(findings):
        if not finding.passes_alone:
            continue
        if not accepted and lead is not None:
            # The best-fitting candidate is not significant (the noise, or a drift it cannot
            # be told from, could make it): the others must still pay next to it, or one of
            # them takes the credit for what it explains better.
            base, accepted = exact_fit(lead.likelihood, data), [lead]
        if not accepted:
            finding.significant = True
            accepted.append(finding)
            base = exact_fit(finding.likelihood, data)
            continue
        if finding is lead:
            continue
        if index not in tested:
            waiting = [i for i in range(index, len(findings))
                       if findings[i].passes_alone and findings[i] is not lead][:fits_at_once()]
            results = fit_all(_next_to, [(base, data, findings[i].term, findings[i].likelihood)
                                         for i in waiting])
            tested = dict(zip(waiting, results, strict=True))
        result = tested[index]
        if result is None:
            finding.note = f"it cannot be fitted next to {', '.join(f.term for f in accepted)}"
            continue
        judgement = judge(base, result, finding.threshold, data, finding.term)
        if judgement.passes:
            finding.significant = True
            accepted.append(finding)
            base = exact_fit(result, data)
            tested = {}
        else:
            names = ", ".join(f.term for f in accepted)
            finding.note = f"next to {names} it no longer pays for itself: {judgement.shortfall}"
    return base


def term_threshold(term, scan_threshold: float, alpha: float) -> float:
    """``Δχ²`` an effect term of a model must be worth: a local mode the scan's threshold (it
    was found by looking everywhere), any other its parameters' chi-square quantile at the
    ``α`` of one test of the step's family."""
    if term.keyword == "fixture":
        return scan_threshold
    return threshold(max(len(term.parameters()), 1), alpha)


#: Solver steps of a removal fit's first pass (:func:`unpaid_term`).
REMOVAL_STEPS = 40
#: A term whose removal still costs this many times its threshold after the first pass is kept
#: without finishing its removal fit.
CLEARLY_PAID = 30.0


def _first_pass(model: Model, data: DiagnosisData, start: dict[str, float]) -> Likelihood:
    return ml_fit(model, data, start, max_steps=REMOVAL_STEPS, tolerance=FIRST_TOLERANCE)


def unpaid_term(
    current: Likelihood, data: DiagnosisData, scan_threshold: float
) -> tuple[str, Likelihood] | None:
    """The effect term of ``current`` that pays least for itself, with the fit of the model
    without it, when it no longer pays (its removal raises ``χ²`` by less than its threshold,
    against the model's misfit ``φ``); ``None`` when every term pays.

    A term added to a model far from the noise may only have soaked up misfit that a later term
    explains: judged again in the final model, it goes (backward elimination).

    Each removal is fitted first for :data:`REMOVAL_STEPS` solver steps at most, to
    :data:`FIRST_TOLERANCE`, which can only leave its ``χ²`` too high (on the six ladders of the
    benchmark campaign by 0.1 % of what the removal costs at most, every one thousands of times
    its threshold, with 37 % fewer steps than to the fits' default tolerance). A term whose
    removal then still costs :data:`CLEARLY_PAID` times its threshold is kept; the others'
    fits are finished. Without a term the model really needs, the rest of it (a Maxwell K*'s
    arms, say) wanders for up to 200 steps trying to stand in for it: most of a ladder's last
    step, for a term that costs thousands of times its threshold.
    """
    phi = dispersion(current.chi2, data.residual_count, len(current.free))
    alpha = alpha_of(current.model, data)
    reductions = []
    for term in current.model.effects:
        specs = [t.spec for t in current.model.terms if t is not term]
        try:
            reduced = parse_spec("+".join(specs))
        except InputError:
            continue
        reductions.append((term, reduced))

    def ratio(term: Term, result: Likelihood) -> float:
        return ((result.chi2 - current.chi2) / phi
                / term_threshold(term, scan_threshold, alpha))

    quick = fit_all(_first_pass, [(reduced, data, {**reduced.defaults(),
                                                   **carried_values(current, reduced)})
                                  for _, reduced in reductions])
    unsettled = [i for i, ((term, _), result) in enumerate(zip(reductions, quick, strict=True))
                 if ratio(term, result) < CLEARLY_PAID]
    finished = fit_all(ml_fit, [(quick[i].model, data, quick[i].values) for i in unsettled])
    worst: tuple[float, str, Likelihood] | None = None
    for i, result in zip(unsettled, finished, strict=True):
        term = reductions[i][0]
        value = ratio(term, result)
        if value < 1.0 and (worst is None or value < worst[0]):
            worst = (value, term.spec, result)
    return None if worst is None else (worst[1], worst[2])


#: A finding whose parameter owes more than this share of its variance to the table's inherited
#: values is said to be hard to tell from an error of them.
INHERITED_SHARE = 0.5


def inherited_confusion(finding: Finding, data: DiagnosisData) -> tuple[str, float] | None:
    """``(name, share)`` when the finding's size owes more than :data:`INHERITED_SHARE` of its
    variance to the uncertainty of the table's inherited values (nuisance parameters with the
    bare-table fit's covariance as prior, :mod:`viscorig.diagnosis.weighted`): ``share`` is
    ``1 − var(held exact)/var(with the prior)`` of the finding's first parameter, ``name`` the
    inherited parameter most correlated with it. ``None`` when the data tell them apart (or
    nothing was inherited with an uncertainty)."""
    if not data.nuisance:
        return None
    result = finding.likelihood
    nuisance = [n for n in data.nuisance if n in result.fitted]
    added = [n for n in result.fitted if n in added_parameters(result.model, finding.term)]
    if not nuisance or not added or result.jacobian.shape[1] != len(result.fitted):
        return None
    jac = result.jacobian
    at = result.fitted.index(added[0])
    keep = [i for i, n in enumerate(result.fitted) if n not in nuisance]
    try:
        full = np.linalg.pinv(jac.T @ jac)
        held = np.linalg.pinv(jac[:, keep].T @ jac[:, keep])
    except np.linalg.LinAlgError:
        return None
    var_full, var_held = full[at, at], held[keep.index(at), keep.index(at)]
    if not (var_full > 0 and var_held > 0):
        return None
    share = 1.0 - var_held / var_full
    if share <= INHERITED_SHARE:
        return None
    index = {n: result.fitted.index(n) for n in nuisance}
    correlation = {n: abs(full[at, j]) / np.sqrt(full[at, at] * max(full[j, j], 1e-300))
                   for n, j in index.items()}
    return max(correlation, key=correlation.__getitem__), float(share)


def _mark_ambiguities(findings: list[Finding], ties: list[Finding]) -> None:
    """Name, for the best finding, the effects the data do not tell apart from it: those tied
    with it, and the confounded smooth changes of K* close to it."""
    significant = [finding for finding in findings if finding.significant]
    for finding in significant[:1]:
        names = [other.effect for other in ties if other is not finding]
        if finding.effect in CONFOUNDED:
            names += [
                other.effect
                for other in findings
                if other is not finding
                and other.passes_alone
                and other.effect in CONFOUNDED
                and (
                    not other.identifiable
                    or other.delta_bic - finding.delta_bic < AMBIGUOUS_DELTA_BIC
                    or other.rms_error < AMBIGUOUS_RMS_RATIO * finding.rms_error
                )
            ]
        finding.alternatives = [name for name in dict.fromkeys(names) if name != finding.effect]
