"""Confirmation: fit each candidate warm-started from the current fit, rank by BIC, test it.

Fits. Every candidate is fitted as ``identify`` fits it (the design's error measure, so its
``rms_error`` and parameters are the ones ``identify --model`` gives); for the statistic below
the fit is then polished to maximum likelihood (:mod:`viscorig.diagnosis.weighted`).

Statistic. The noise of an FRF changes by orders of magnitude along a band (constant
acceleration), so every comparison is made on the residual *whitened* by the local noise
estimate of the data (:func:`viscorig.fitting.local_noise_power`):
``χ² = Σ 2|r_i|²/σ_i²`` over every point of every FRF, which is a chi-square with ``n = 2N``
degrees of freedom when the model is right (real and imaginary parts each carry ``σ²/2``).
The Bayesian information criterion with known noise is ``BIC = χ² + k ln n`` (``k`` free
parameters); ``delta_bic`` of a candidate is its BIC minus the current model's, negative when
it is better.

Significance. A candidate is ``significant`` when ``delta_bic < −SIGNIFICANT_DELTA_BIC``: its
improvement is beyond what ``k`` extra parameters fitted to noise give (on average ``k``, so
``ΔBIC ≈ k(ln n − 1) > 0``), with a margin for the search a fixture or a delay makes over the
band. On clean simulated data (no hidden effect, several seeds, every candidate) the best
candidate's ΔBIC stayed above the threshold (see the tests and the report).

Relevance. A statistically clear improvement can still be too small to matter: near the noise
floor, with thousands of points, a term such as ``drift`` may absorb a sliver of a systematic
misfit it does not explain. A significant finding must therefore also remove at least
:data:`MIN_EXCESS_FRACTION` of the current model's error above the noise floor,
``rms² − floor²``; a model at or below the floor leaves nothing to remove.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np

from viscorig.diagnosis.data import DiagnosisData
from viscorig.diagnosis.screening import Signature
from viscorig.diagnosis.weighted import polish
from viscorig.errors import InputError
from viscorig.fitting import FitResult, fit
from viscorig.models import TERMS, Fixture, Model, parse_spec

#: ΔBIC (whitened) below minus this is beyond noise.
SIGNIFICANT_DELTA_BIC = 20.0
#: A significant finding removes at least this share of the error above the noise floor.
MIN_EXCESS_FRACTION = 0.1
#: Two candidates within this ΔBIC of each other are not told apart by the data.
AMBIGUOUS_DELTA_BIC = 10.0
#: ... or when the other's rms_error is within this factor: the two differ only in the exact
#: shape of a smooth change along the band, which the data alone do not vouch for.
AMBIGUOUS_RMS_RATIO = 1.5
#: Effects that all reshape K* smoothly along a constant-acceleration up sweep.
CONFOUNDED = ("frequency_dependent_modulus", "amplitude_dependence", "thermal_drift")


@dataclass
class Finding:
    """A candidate effect, fitted and tested.

    Attributes
    ----------
    effect
        Name from the vocabulary (``fixture_resonance``...).
    model
        Spec of the candidate model, accepted as is by ``identify --model``.
    fit
        Its fit on the diagnosed data.
    delta_bic
        Whitened BIC of the candidate minus that of the current model.
    significant
        Improvement beyond what noise explains.
    explanation
        One or two sentences a technician can act on.
    evidence
        What screening saw.
    alternatives
        Effects the data cannot tell apart from this one (ΔBIC within
        :data:`AMBIGUOUS_DELTA_BIC`).
    term
        Spec text of the term the finding adds (or the K* term it puts instead).
    """

    effect: str
    model: str
    fit: FitResult = field(repr=False)
    delta_bic: float
    significant: bool
    evidence: str
    term: str
    explanation: str = ""
    alternatives: list[str] = field(default_factory=list)
    bic: float = float("nan")
    """Whitened BIC of the candidate."""

    @property
    def rms_error(self) -> float:
        """``rms_error`` of the candidate model."""
        return self.fit.rms_error

    def parameters(self) -> dict[str, dict[str, float | str]]:
        """The parameters the finding adds (or the new K* term's), with stderr and unit."""
        new = added_parameters(self.fit.model, self.term)
        return {
            name: {"value": float(e.value), "stderr": float(e.stderr), "unit": e.unit}
            for name, e in self.fit.parameters.items()
            if name in new
        }

    def to_json(self) -> dict[str, object]:
        """The finding as in the ``diagnose --json`` contract (plus ``alternatives``)."""
        return {
            "effect": self.effect,
            "model": self.model,
            "rms_error": float(self.rms_error),
            "delta_bic": float(self.delta_bic),
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
        if term.keyword == keyword:
            return set(model.local_names(term).values())
    return set()


def whitened_chi2(result: FitResult, data: DiagnosisData) -> float:
    """``Σ 2|r_i|²/σ_i²`` over every point of every FRF fitted."""
    return float(
        sum(np.sum(2 * np.abs(result.residuals[frf]) ** 2 / data.noise_power[frf])
            for frf in result.frfs)
    )


def whitened_bic(result: FitResult, data: DiagnosisData) -> float:
    """``χ² + k ln n`` with ``n`` real residuals and ``k`` free parameters (of a fit polished
    by :func:`viscorig.diagnosis.weighted.polish`, for the statistic to be calibrated)."""
    n = 2 * sum(data.noise_power[frf].size for frf in result.frfs)
    return whitened_chi2(result, data) + len(result.free) * np.log(n)


def candidate_spec(current: Model, term_text: str) -> str:
    """The current model with a term added, or its K* term replaced by a K* term."""
    keyword = term_text.split("(")[0].strip()
    if keyword in TERMS and TERMS[keyword].kind == "modulus":
        return "+".join([term_text, *(term.spec for term in current.effects)])
    return f"{current.spec}+{term_text}"


def carried_values(old: FitResult, new: Model) -> dict[str, float]:
    """Values of ``old`` for every term ``new`` shares with it, under ``new``'s names."""
    values = {name: old.values[name] for name in ("M_s", "K_s", "C_s") if name in old.values}
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
    return values


def fit_with(
    current: FitResult, data: DiagnosisData, term_text: str, start: dict[str, float] | None = None
) -> FitResult:
    """Fit the current model plus ``term_text``, warm-started from the current fit."""
    spec = candidate_spec(current.model, term_text)
    model = parse_spec(spec)
    values = carried_values(current, model)
    if start:
        added = [t for t in model.effects if t.spec == term_text]
        names = model.local_names(added[-1]) if added else {}
        values.update({names[k]: v for k, v in start.items() if k in names})
    fixed = dict(data.table or {})
    result = fit(model, data.data, frfs=data.frfs, fixed=fixed,
                 start={k: v for k, v in values.items() if k not in fixed})
    result.noise_floor = data.noise_floor
    return result


def confirm(
    current: FitResult,
    data: DiagnosisData,
    signatures: list[Signature],
    base_bic: float | None = None,
) -> list[Finding]:
    """Fit every screened candidate and return the findings, best (lowest ΔBIC) first.

    ``base_bic``: the current fit's whitened BIC when already known (a finding's ``bic``).
    """
    base = whitened_bic(polish(current, data), data) if base_bic is None else base_bic
    findings: list[Finding] = []
    for signature in signatures:
        terms = [signature.term]
        if signature.effect == "frequency_dependent_modulus" and signature.term == "fractional":
            terms.append("maxwell")  # both families; the better one is the finding
        best: tuple[float, FitResult, str] | None = None
        for term in terms:
            try:
                result = fit_with(current, data, term, signature.start)
            except (InputError, ValueError, np.linalg.LinAlgError):
                continue
            bic = whitened_bic(polish(result, data), data)
            if best is None or bic < best[0]:
                best = (bic, result, term)
        if best is None:
            continue
        bic, result, term = best
        if term == "maxwell":
            term = result.model.modulus_term.spec  # the order the fit chose
        if signature.effect == "fixture_resonance":
            result, term = _fixture_at_fitted_frequency(result, term)
        delta = bic - base
        findings.append(
            Finding(
                signature.effect,
                result.spec,
                result,
                float(delta),
                bool(delta < -SIGNIFICANT_DELTA_BIC)
                and removes_enough(current.rms_error, result.rms_error, data.noise_floor),
                signature.evidence,
                term,
                bic=float(bic),
            )
        )
    findings.sort(key=lambda finding: finding.delta_bic)
    _mark_ambiguities(findings)
    return findings


def removes_enough(rms_before: float, rms_after: float, noise_floor: float) -> bool:
    """The change removes at least :data:`MIN_EXCESS_FRACTION` of the error above the floor."""
    excess = rms_before**2 - noise_floor**2
    return excess > 0.0 and rms_before**2 - rms_after**2 >= MIN_EXCESS_FRACTION * excess


def _fixture_at_fitted_frequency(result: FitResult, term: str) -> tuple[FitResult, str]:
    """Name the fixture in the spec by the frequency the fit found (its range moves with it)."""
    model = result.model
    fixture = next((t for t in model.effects if t.spec == term), None)
    if fixture is None:
        return result, term
    f_n = result.values[model.local_names(fixture)["f_n"]]
    new_term = Fixture(round(f_n, 2)).spec
    specs = [t.spec if t is not fixture else new_term for t in model.terms]
    try:
        new_model = parse_spec("+".join(specs))
    except InputError:
        return result, term
    return replace(result, model=new_model), new_term


def _mark_ambiguities(findings: list[Finding]) -> None:
    """Name, for the best finding, the confounded effects the data do not tell apart from it."""
    for finding in findings[:1]:
        if not finding.significant or finding.effect not in CONFOUNDED:
            continue
        finding.alternatives = [
            other.effect
            for other in findings
            if other is not finding
            and other.significant
            and other.effect in CONFOUNDED
            and other.effect != finding.effect
            and (
                other.delta_bic - finding.delta_bic < AMBIGUOUS_DELTA_BIC
                or other.rms_error < AMBIGUOUS_RMS_RATIO * finding.rms_error
            )
        ]
