"""The diagnosis of a fit: where it fails, which effect is missing, and the model with it.

>>> d = diagnose_run(campaign, "soft-0", "voigt")      # or diagnose(frf_data, "voigt", table=...)
>>> d.failures[0].what, d.findings[0].effect, d.findings[0].explanation
>>> d2 = d.with_effect("fixture(58)")                  # add it in one step; d2.rms_error falls
>>> ladder = d.auto()                                  # until nothing significant is left
"""

from __future__ import annotations

from collections.abc import Iterator, Sequence
from dataclasses import dataclass, field

import numpy as np

from viscorig.diagnosis.data import DiagnosisData, combine, from_campaign
from viscorig.diagnosis.explain import explain, extra_runs
from viscorig.diagnosis.findings import (
    Finding,
    Optima,
    candidate_fits,
    candidate_spec,
    carried_values,
    confirm,
    exact_fit,
    fit_with,
    identify_fit,
    other_family,
    refit,
    unpaid_term,
)
from viscorig.diagnosis.residuals import FailureBand, FrfResidual, failure_bands, residuals
from viscorig.diagnosis.scan import Residual, ScanResult, scan
from viscorig.diagnosis.screening import screen, screen_family_frame, screen_fixtures
from viscorig.diagnosis.significance import dispersion
from viscorig.diagnosis.weighted import Likelihood, huber, ml_refit
from viscorig.diagnosis.workers import fit_all_later
from viscorig.errors import InputError
from viscorig.fitting import FitResult, FrfData, Known, fit
from viscorig.models import Fixture, parse_spec
from viscorig.storage import CampaignFile

#: ``rms_error`` within this factor of the noise floor counts as "at the noise floor".
AT_FLOOR_RATIO = 1.25
#: The model diagnosed when none is given: Voigt K*, on both FRFs.
DEFAULT_MODEL = "voigt"
#: A residual this many standard deviations high, alone (its neighbours within
#: ``SPIKE_NEIGHBOUR``), is an outlier point, not something a model should explain.
SPIKE, SPIKE_NEIGHBOUR = 5.0, 3.0
#: Most effects ``auto`` adds.
MAX_AUTO_STEPS = 6
#: Effects a step of the ladder adds beside its best finding when they are significant next to
#: it (:meth:`DiagnosisResult.with_significant`): the rig's and the specimen's mechanics.
JOINING = ("fixture_resonance", "load_cell_compliance", "frequency_dependent_modulus")


@dataclass
class DiagnosisResult:
    """A fitted model, where it fails, and the effects that would improve it, best first.

    Attributes
    ----------
    data
        The runs diagnosed (:class:`~viscorig.diagnosis.data.DiagnosisData`).
    fit
        The fit of the model diagnosed, by ``identify``'s fitter with uniform weights
        (:func:`~viscorig.diagnosis.findings.refit`: the fit that minimises ``rms_error``).
    likelihood
        Its maximum-likelihood fit on the whitened residual, which the tests compare.
    scan
        The scan for local modes (peaks, length, threshold).
    findings
        Candidate effects, fitted and tested, lowest ΔBIC first.
    failures
        Bands where the model stands clearly above the noise, worst first: of :attr:`fit`, or
        of :attr:`likelihood` where outliers pull :attr:`fit` off the other points
        (:attr:`pulled_by_outliers`).
    advice
        Extra runs that would separate candidates these data cannot tell apart.
    """

    data: DiagnosisData = field(repr=False)
    fit: FitResult
    likelihood: Likelihood
    scan: ScanResult | None = None
    findings: list[Finding] = field(default_factory=list)
    failures: list[FailureBand] = field(default_factory=list)
    advice: list[str] = field(default_factory=list)
    together: Likelihood | None = None
    """Likelihood fit of the model with every significant finding added."""
    optima: Optima = field(default_factory=dict, repr=False)
    """The models fitted at this rung and those before it (:data:`~.findings.Optima`)."""

    @property
    def model(self) -> str:
        """Canonical spec of the model diagnosed."""
        return self.fit.spec

    @property
    def rms_error(self) -> float:
        """``sqrt(mean |H_model/H_measured − 1|²)`` over every point of every FRF."""
        return self.fit.rms_error

    @property
    def noise_floor(self) -> float:
        """The ``rms_error`` a perfect model would reach, from the data alone."""
        return self.data.noise_floor

    def outliers(self) -> dict[str, np.ndarray]:
        """Outlier points per FRF: those the noise model found, and isolated spikes of this
        fit's residual (more than :data:`SPIKE` standard deviations, both neighbours within
        :data:`SPIKE_NEIGHBOUR`; noise alone makes one in 10¹⁰)."""
        out = {}
        masks = self.data.outliers
        for frf in self.fit.frfs:
            z = np.abs(self.fit.residuals[frf]) / np.sqrt(self.data.noise_power[frf])
            left = np.concatenate([[0.0], z[:-1]])
            right = np.concatenate([z[1:], [0.0]])
            spike = (z > SPIKE) & (left < SPIKE_NEIGHBOUR) & (right < SPIKE_NEIGHBOUR)
            out[frf] = masks[frf] | spike
        return out

    @property
    def outlier_points(self) -> int:
        """Points left out of the comparison with the noise floor (:meth:`outliers`)."""
        return int(sum(np.count_nonzero(mask) for mask in self.outliers().values()))

    @property
    def rms_error_without_outliers(self) -> float:
        """``rms_error`` over every point but the outliers: what the noise floor describes."""
        return self._without_outliers(self.fit.residuals)

    @property
    def likelihood_rms_error_without_outliers(self) -> float:
        """:attr:`rms_error_without_outliers` at the likelihood fit's values (each point weighed
        by its noise, an outlier by its own error): what the model reaches on the other points
        where the outliers pull the uniform fit off them (:attr:`pulled_by_outliers`)."""
        return self._without_outliers(self.likelihood.residuals)

    @property
    def pulled_by_outliers(self) -> bool:
        """The uniform fit misses the noise floor of the points that are not outliers, where the
        likelihood fit reaches it: the outliers keep the fit off, not the model."""
        return bool(self.outlier_points and not self.at_noise_floor
                    and self.likelihood_rms_error_without_outliers
                    <= AT_FLOOR_RATIO * self.noise_floor_without_outliers)

    def _without_outliers(self, residuals: dict[str, np.ndarray]) -> float:
        masks = self.outliers()
        kept = np.concatenate([np.abs(residuals[frf][~masks[frf]]) ** 2
                               for frf in self.fit.frfs])
        return float(np.sqrt(np.mean(kept))) if kept.size else self.rms_error

    @property
    def noise_floor_without_outliers(self) -> float:
        """:attr:`noise_floor` over every point but the outliers (:meth:`outliers`): an
        outlier point's noise power is its own error, which a few such points make the whole
        floor's."""
        masks = self.outliers()
        kept = np.concatenate([np.asarray(self.data.noise_power[frf])[~masks[frf]]
                               for frf in self.fit.frfs])
        return float(np.sqrt(np.mean(kept))) if kept.size else self.noise_floor

    @property
    def at_noise_floor(self) -> bool:
        """The error is within :data:`AT_FLOOR_RATIO` of the noise floor, outlier points left
        out on both sides: of the error (:attr:`rms_error_without_outliers`) and of the floor
        (:attr:`noise_floor_without_outliers`), which holds each outlier's own error."""
        return self.rms_error_without_outliers <= AT_FLOOR_RATIO * (
            self.noise_floor_without_outliers)

    @property
    def significant(self) -> list[Finding]:
        """The significant findings, best first."""
        return [finding for finding in self.findings if finding.significant]

    def residuals(self) -> list[FrfResidual]:
        """Magnitude (%) and phase (°) error of every FRF of every run, and whitened."""
        return residuals(self.fit, self.data)

    def with_effect(self, effect: str | Finding) -> DiagnosisResult:
        """The diagnosis of this model with one more effect (or another K* term).

        ``effect`` is a finding, a term (``"fixture(58)"``, ``"load_cell"``, ``"maxwell"``),
        or a whole spec (``"fractional+delay"``).
        """
        if isinstance(effect, Finding):
            return self._with_finding(effect)
        text = effect.strip()
        for finding in self.findings:
            if finding.term == text:
                return self._with_finding(finding)
        if "+" in text:
            return diagnose(self.data, text)
        candidate_spec(self.fit.model, text)  # checks the term
        return analyse(self.data, fit_with(self.fit, self.data, text), optima=self.optima)

    def _with_finding(self, finding: Finding) -> DiagnosisResult:
        """The diagnosis of this model with ``finding``'s effect. Its likelihood fit moved only
        the new term's parameters and the broad ones; the next rung is judged from the model's
        own optimum, every parameter free (the forward tests' when they made it)."""
        if finding.fit is None:
            finding.fit = identify_fit(finding.likelihood, self.data)
        spec = finding.likelihood.model.spec
        together = self.together
        exact = (together if together is not None and together.model.spec == spec
                 else exact_fit(finding.likelihood, self.data))
        return analyse(self.data, finding.fit, exact, self.optima)

    def with_significant(self) -> DiagnosisResult:
        """The diagnosis of this model with its best finding added, and with every mechanical
        effect found significant next to it (:data:`JOINING`: local modes, the load cell, a K*
        in place of the current one), each of which the data tell apart from every other
        effect. A sensor term, a drift or an amplitude dependence waits for the next step, where
        it is judged against a model that holds the mechanics found so far: far from the noise
        such a term soaks up misfit that a mechanical effect explains."""
        found = self.significant
        joining = [f for f in found[1:] if f.effect in JOINING and not f.alternatives]
        if not joining or self.together is None:
            return self.with_effect(found[0])
        spec = self.fit.model
        for finding in (found[0], *joining):
            spec = parse_spec(candidate_spec(spec, finding.term))
        start = {**carried_values(self.together, spec)}
        for finding in (found[0], *joining):
            start.update({k: v for k, v in carried_values(finding.likelihood, spec).items()
                          if k not in start})
        held = self.together if self.together.model.spec == spec.spec else None
        return analyse(self.data, refit(spec, self.data, start), held, self.optima)

    def auto(self, max_steps: int = MAX_AUTO_STEPS) -> list[DiagnosisResult]:
        """Add the significant effects and refit, until nothing significant is left.

        At the noise floor a small effect can still be significant (a local mode a few points
        wide hardly moves the rms error): the ladder goes on while the tests find one.

        Returns the ladder: this diagnosis, then one per step; a step adds the best finding and
        the mechanical effects found significant next to it (:meth:`with_significant`). A climb that
        ends at a Maxwell K* tries the fractional one in its place once (:meth:`in_other_family`)
        and goes on from it when the data prefer it. Last, any effect that no longer pays for
        itself in the final model is taken out again, one step each (:meth:`without_unpaid`).
        :meth:`climb` gives the same rungs as each is reached.
        """
        return list(self.climb(max_steps))

    def climb(self, max_steps: int = MAX_AUTO_STEPS) -> Iterator[DiagnosisResult]:
        """The rungs of :meth:`auto`, each as soon as it is reached (this diagnosis first), so
        that what the first steps found can be shown while the next ones are fitted."""
        yield self
        current, steps, family_checked = self, 1, False
        while True:
            while steps <= max_steps and current.significant:
                current, steps = current.with_significant(), steps + 1
                yield current
            if family_checked or steps == 1:
                break
            family_checked = True
            swapped = current.in_other_family()
            if swapped is None:
                break
            current, steps = swapped, steps + 1
            yield current
        while steps > 1:
            lighter = current.without_unpaid()
            if lighter is None:
                return
            current, steps = lighter, steps + 1
            yield current

    def in_other_family(self) -> DiagnosisResult | None:
        """The diagnosis of this model with its Maxwell K* replaced by the fractional one when
        the data prefer it (:func:`~viscorig.diagnosis.findings.other_family`), or ``None``."""
        swapped = other_family(self.likelihood, self.data, self.optima)
        if swapped is None:
            return None
        return analyse(self.data, identify_fit(swapped, self.data), swapped, self.optima)

    def without_unpaid(self) -> DiagnosisResult | None:
        """The diagnosis of this model less the effect term that no longer pays for itself in
        it (:func:`~viscorig.diagnosis.findings.unpaid_term`), or ``None``."""
        threshold = self.scan.threshold if self.scan is not None else 0.0
        found = unpaid_term(self.likelihood, self.data, threshold)
        if found is None:
            return None
        _, reduced = found
        return analyse(self.data, identify_fit(reduced, self.data), optima=self.optima)

    def to_json(self, ladder: Sequence[DiagnosisResult] | None = None) -> dict[str, object]:
        """The ``diagnose --json`` object of design.md (plus ``runs``, ``advice``, ``noise``,
        ``outlier_points``, ``rms_error_without_outliers``, ``noise_floor_without_outliers``,
        ``likelihood_rms_error_without_outliers``, ``pulled_by_outliers`` and ``scan``: what
        the thresholds and the noise-floor verdict rest on)."""
        document: dict[str, object] = {
            "run": self.data.run,
            "runs": list(self.data.runs),
            "model": self.model,
            "rms_error": float(self.rms_error),
            "noise_floor": float(self.noise_floor),
            "at_noise_floor": bool(self.at_noise_floor),
            "rms_error_without_outliers": float(self.rms_error_without_outliers),
            "noise_floor_without_outliers": float(self.noise_floor_without_outliers),
            "outlier_points": self.outlier_points,
            "likelihood_rms_error_without_outliers": float(
                self.likelihood_rms_error_without_outliers),
            "pulled_by_outliers": self.pulled_by_outliers,
            "noise": self.data.noise.describe(),
            "scan": None if self.scan is None else {
                "templates": self.scan.templates,
                "correlation_lengths": float(self.scan.length),
                "threshold_delta_chi2": float(self.scan.threshold),
            },
            "failures": [band.to_json() for band in self.failures],
            "findings": [finding.to_json() for finding in self.findings],
            "advice": list(self.advice),
        }
        if ladder is not None:
            document["ladder"] = [
                {"model": step.model, "rms_error": float(step.rms_error),
                 "noise_floor": float(step.noise_floor)}
                for step in ladder
            ]
        return document


#: A mode's frequency this close to the edge of its window (relative) is held there by the
#: window, not by the data.
MODE_EDGE = 1e-3
#: Damping ratio below which a mode is local; a broader one at its window's edge is soaking up
#: a misfit, and its window is left where it is.
MODE_NARROW = 0.05
#: Times a mode's window is moved after it, at most.
MODE_MOVES = 3


def recentred_modes(result: FitResult, data: DiagnosisData) -> FitResult:
    """``result``, or its model refitted with every narrow local mode held at the edge of its
    window (``fixture(F)`` keeps ``f_n`` within ±5 % of ``F``) given a window centred where it
    stopped.

    A mode found on the misfit of a model still missing a broad effect can be placed a few
    percent off its frequency; its window must follow the data, or the mode stays short of them
    and the rest of the diagnosis works on its misfit.
    """
    for _ in range(MODE_MOVES):
        model = result.model
        moved: dict[str, tuple[str, dict[str, str]]] = {}
        for term in model.effects:
            if not isinstance(term, Fixture) or term.argument is None:
                continue
            names = model.local_names(term)
            f_n = result.values[names["f_n"]]
            lo, hi = term.frequency_bounds()
            narrow = result.values[names["zeta"]] < MODE_NARROW
            if narrow and min(f_n - lo, hi - f_n) < MODE_EDGE * f_n:
                try:
                    moved[term.spec] = (type(term)(float(f"{f_n:.4g}")).spec, names)
                except InputError:  # a window centred there is none a mode may have
                    continue
        if not moved:
            return result
        spec = "+".join([model.require_modulus().spec] + [
            moved[term.spec][0] if term.spec in moved else term.spec for term in model.effects])
        new = parse_spec(spec)
        start = carried_values(result, new)
        for text, old_names in moved.values():
            term = next(t for t in new.effects if t.spec == text)
            for local, name in new.local_names(term).items():
                start[name] = result.values[old_names[local]]
        result = refit(new, data, start)
    return result


def analyse(
    data: DiagnosisData, result: FitResult, likelihood: Likelihood | None = None,
    optima: Optima | None = None,
) -> DiagnosisResult:
    """Failures, screening and confirmed findings of a fit already made on ``data``.

    ``likelihood``: the model's maximum-likelihood fit when already made (else it is made here);
    ``optima``: the models the ladder fitted before (:data:`~.findings.Optima`).
    """
    recentred = recentred_modes(result, data)
    if recentred is not result:
        result, likelihood = recentred, None
    start: FitResult | Likelihood = result
    if data.nuisance:
        chi2 = float(np.sum(huber(data.whiten(result.residuals))))
        scaled = data.with_prior_scale(dispersion(chi2, data.residual_count, len(result.free)))
        if scaled is not data:
            # the likelihood fit under the table's prior weighed as before is the nearer start
            data, start, likelihood = scaled, likelihood or result, None
    current = ml_refit(start, data) if likelihood is None else likelihood
    residual = Residual(current, data)
    candidates = screen(current, data, residual)
    # on the workers while this process scans
    frame = fit_all_later(screen_family_frame, [(current, data, residual)], fewest=1)
    optima = dict(optima or {})
    early = candidate_fits(current, data, candidates, optima)
    existing = tuple(v for k, v in current.values.items() if k.startswith("f_n"))
    peaks = scan(current, data, existing)
    scanned = [*frame()[0], *screen_fixtures(peaks)]
    late = candidate_fits(current, data, scanned, optima)
    fitted = early() + late()
    optima.update((fit.model.spec, fit.values) for fit in (current, *fitted) if fit is not None)
    findings, together = confirm(current, data, candidates + scanned, fitted)
    best = next((finding for finding in findings if finding.significant), None)
    if best is not None and best.fit is None:
        best.fit = identify_fit(best.likelihood, data)
    advice: list[str] = []
    for finding in findings:
        finding.explanation = explain(finding, data)
        if finding.significant and finding.alternatives:
            names = ", ".join(finding.alternatives)
            finding.explanation += f" These data cannot tell it apart from {names}."
            for text in extra_runs(finding, data):
                if text not in advice:
                    advice.append(text)
    diagnosis = DiagnosisResult(data, result, current, peaks, findings, [], advice, together,
                                optima)
    # where outliers pull the uniform fit off the other points, its bands are theirs
    diagnosis.failures = failure_bands(current if diagnosis.pulled_by_outliers else result, data)
    return diagnosis


def diagnose(
    data: DiagnosisData | FrfData | Sequence[tuple[str, FrfData]],
    model: str | None = None,
    *,
    table: dict[str, float] | Known | None = None,
    band_hz: tuple[float, float] | None = None,
    frfs: Sequence[str] | None = None,
) -> DiagnosisResult:
    """Fit ``model`` (default :data:`DEFAULT_MODEL`) and diagnose it.

    Parameters
    ----------
    data
        Diagnosis data, one run's :class:`FrfData`, or ``[(run name, FrfData), ...]`` with the
        main run first and every ``time_s`` on the main run's clock.
    model
        Model spec.
    table
        The table's ``M_s, K_s, C_s`` (needed for the table FRF): their values, held as exact,
        or a :class:`~viscorig.fitting.Known` with the covariance they were found with (the
        bare-table fit's, ``TableSource.known``), which every test then allows for.
    band_hz, frfs
        Band and FRFs diagnosed (default: every point; both FRFs when the table is known).
    """
    if not isinstance(data, DiagnosisData):
        runs = [(data.name, data)] if isinstance(data, FrfData) else list(data)
        data = combine(runs, table=table, band_hz=band_hz, frfs=frfs)
    spec = parse_spec(model or DEFAULT_MODEL)
    if spec.modulus_term is None or not spec.modulus_term.has_disc:
        raise InputError(f"diagnosis needs a specimen model, not '{spec.spec}'", "model spec")
    result = fit(spec, data.data, frfs=data.frfs, fixed=dict(data.table or {}),
                 known=data.table_prior, noise=data.noise)
    return analyse(data, result)


def diagnose_run(
    campaign: CampaignFile,
    run: str,
    model: str | None = None,
    *,
    band_hz: tuple[float, float] | None = None,
    frfs: Sequence[str] | None = None,
    with_companions: bool = True,
) -> DiagnosisResult:
    """Diagnose a stored run (with the same specimen's runs at other levels or directions)."""
    data = from_campaign(
        campaign, run, band_hz=band_hz, frfs=frfs, with_companions=with_companions
    )
    return diagnose(data, model)
