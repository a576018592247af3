"""Everything the report shows, computed once per run: models, residuals, K*, diagnosis.

Which model a run shows: its latest stored fit (``/runs/<run>/fits``) when there is one, else a
fit made on the fly. The on-the-fly fits are the ones the paper's procedure needs anyway, so
nothing is fitted twice: the table (``table`` model, bare run), Voigt on ``X_s/F_e`` with the
table fixed (Table 1 and 2, :func:`viscorig.identify.summarize`), and Maxwell on ``X_v/F_v``
(``K*`` from Eq. 5, for ``E'`` and ``η`` against frequency). When diagnosis is available, the
shown model is diagnosed on both FRFs (its fit then replaces the Table 1 Voigt on the FRF
figures, since it is fitted to what the figures show) and the ladder is climbed with
:meth:`~viscorig.diagnosis.Diagnosis.auto`.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

from viscorig.errors import InputError
from viscorig.estimates import kstar_from_support
from viscorig.fitting import FitResult, local_noise_power
from viscorig.identify import (
    PAPER_BAND_HZ,
    RunSummary,
    TableSource,
    is_bare_table,
    run_data,
    summarize,
)
from viscorig.models import Context, parse_spec
from viscorig.rig import RigDescription
from viscorig.storage import INPUT_OVERLOAD, Campaign, Fit, Run

try:  # diagnosis is optional: the report is built without its sections when it is absent
    from viscorig import diagnosis as _diagnosis
except ImportError:  # pragma: no cover - depends on the installed tree
    _diagnosis = None

Predictor = Callable[[NDArray[np.float64], NDArray | None, NDArray | None],
                     dict[str, NDArray[np.complex128]]]


@dataclass
class ModelCurve:
    """A fitted model as the report draws it.

    Attributes
    ----------
    spec
        Canonical model spec.
    source
        Where it comes from, for legends and the page ("stored fit 0002", "fitted here").
    predict
        ``predict(frequency_hz, time_s, reference_amplitude) -> {"table": ..., "support": ...}``.
    kstar
        ``kstar(frequency_hz) -> K*`` in N/m, or ``None`` for the bare table.
    values
        Parameter values by name.
    rms_error, noise_floor
        As stored or fitted.
    """

    spec: str
    source: str
    predict: Predictor
    kstar: Callable[[NDArray[np.float64]], NDArray[np.complex128]] | None
    values: dict[str, float]
    rms_error: float
    noise_floor: float

    @classmethod
    def from_fit(cls, result: FitResult, source: str) -> ModelCurve:
        """From a fit made here."""
        has_disc = result.model.modulus_term is not None and result.model.modulus_term.has_disc
        return cls(result.spec, source, result.predict, result.kstar if has_disc else None,
                   dict(result.values), result.rms_error, result.noise_floor)

    @classmethod
    def from_stored(cls, stored: Fit) -> ModelCurve:
        """From a fit stored in the campaign file."""
        model = parse_spec(stored.model)
        values = {name: parameter.value for name, parameter in stored.parameters.items()}
        missing = sorted(set(model.names) - set(values))
        if missing:
            raise InputError(f"stored fit {stored.id} lacks {', '.join(missing)}",
                             f"run '{stored.run}'")

        def predict(f, time_s=None, reference=None):
            return model.predict(Context(np.asarray(f, float), time_s, reference), values)

        def kstar(f):
            return model.kstar(Context(np.asarray(f, float)), values)

        has_disc = model.modulus_term is not None and model.modulus_term.has_disc
        return cls(model.spec, f"stored fit {stored.id}", predict, kstar if has_disc else None,
                   values, stored.rms_error, stored.noise_floor)


@dataclass
class FrfResidual:
    """``H_model/H_measured − 1`` of one FRF of the shown model, with the local noise."""

    frf: str
    frequency_hz: NDArray[np.float64]
    magnitude: NDArray[np.float64]
    noise: NDArray[np.float64]
    """Local relative noise ``σ_i`` (:func:`viscorig.fitting.local_noise_power`)."""


@dataclass
class LadderStep:
    """One rung of the diagnosis ladder."""

    model: str
    rms_error: float
    noise_floor: float


@dataclass
class ModulusCurves:
    """``K*`` of a specimen run against frequency: Eq. (5) estimates and the Maxwell model."""

    frequency_hz: NDArray[np.float64]
    measured: NDArray[np.complex128]
    model: NDArray[np.complex128]
    spec: str
    source: str
    disc_mass_kg: float


@dataclass
class RunAnalysis:
    """What the report shows for one run."""

    run: Run
    bare: bool
    band_hz: tuple[float, float]
    shown: ModelCurve | None = None
    residuals: list[FrfResidual] = field(default_factory=list)
    modulus: ModulusCurves | None = None
    summary: RunSummary | None = None
    failures: list = field(default_factory=list)
    findings: list = field(default_factory=list)
    ladder: list[LadderStep] = field(default_factory=list)
    diagnosis_error: str = ""
    notes: list[str] = field(default_factory=list)

    @property
    def name(self) -> str:
        """Run name."""
        return self.run.name


@dataclass
class CampaignAnalysis:
    """The whole campaign as the report shows it."""

    path: str
    runs: list[RunAnalysis]
    table: TableSource | None
    theta_m: float | None
    band_hz: tuple[float, float]
    diagnosis_available: bool
    notes: list[str] = field(default_factory=list)

    def run(self, name: str) -> RunAnalysis:
        """One run's analysis by name."""
        return next(r for r in self.runs if r.name == name)


def _band(run: Run, band_hz: tuple[float, float]) -> tuple[float, float]:
    lo = max(band_hz[0], float(run.frequency_hz.min()))
    hi = min(band_hz[1], float(run.frequency_hz.max()))
    return (lo, hi) if lo < hi else (float(run.frequency_hz.min()), float(run.frequency_hz.max()))


def _residuals(run: Run, curve: ModelCurve, band: tuple[float, float]) -> list[FrfResidual]:
    keep = (run.frequency_hz >= band[0]) & (run.frequency_hz <= band[1]) & ~run.flagged(
        INPUT_OVERLOAD)
    order = np.argsort(run.frequency_hz[keep])
    f = run.frequency_hz[keep][order]
    predicted = curve.predict(f, run.time_s[keep][order], run.reference_amplitude[keep][order])
    out = []
    for name, measured in (("table", run.accelerance_table), ("support", run.accelerance_support)):
        values = measured[keep][order]
        if name not in predicted or f.size < 10 or not np.all(np.isfinite(values)):
            continue
        noise = np.sqrt(local_noise_power(values))
        out.append(FrfResidual(name, f, np.abs(predicted[name] / values - 1.0), noise))
    return out


def _modulus(run: Run, result: FitResult, band: tuple[float, float]) -> ModulusCurves:
    keep = (run.frequency_hz >= band[0]) & (run.frequency_hz <= band[1]) & ~run.flagged(
        INPUT_OVERLOAD)
    order = np.argsort(run.frequency_hz[keep])
    f = run.frequency_hz[keep][order]
    mass = float(result.values["M_v"])
    measured = kstar_from_support(f, run.accelerance_support[keep][order], mass)
    return ModulusCurves(f, measured, result.kstar(f), result.spec,
                         "Maxwell fit of ẍ_v/F_v (K* of Eq. 5)", mass)


def analyse_campaign(
    campaign: Campaign,
    band_hz: tuple[float, float] = PAPER_BAND_HZ,
    *,
    diagnosis: bool = True,
    ladder: bool = False,
) -> CampaignAnalysis:
    """Fit, diagnose and gather what the report shows, every fit made once.

    Parameters
    ----------
    campaign
        The open campaign.
    band_hz
        Band of the identification (the paper's 20-120 Hz by default; clipped to each run).
    diagnosis, ladder
        Diagnose each specimen run (failure bands, candidate effects), and climb the whole
        ladder of effects (:meth:`~viscorig.diagnosis.Diagnosis.auto`: a fit per candidate per
        rung, tens of seconds per run, so off by default).
    """
    from viscorig.fitting import fit

    rig = RigDescription.from_attributes(campaign.rig)
    notes: list[str] = []
    runs = [campaign.run(name) for name in campaign.run_names]
    measured = [run for run in runs if run.points >= 10]
    for run in runs:
        if 0 < run.points < 10:
            notes.append(f"run {run.name}: {run.points} points, too few to fit; shown as measured")
    try:
        table, summaries = summarize(campaign, band_hz)
    except InputError as error:
        table, summaries = None, []
        notes.append(f"Table 1 and 2 not computed: {error}")
    by_name = {summary.run: summary for summary in summaries}
    analyses = []
    use_diagnosis = diagnosis and _diagnosis is not None
    for run in runs:
        bare = is_bare_table(run)
        if not run.points:
            band = band_hz
        elif bare:  # the table's own band, which covers its resonance
            band = (float(run.frequency_hz.min()), float(run.frequency_hz.max()))
        else:
            band = _band(run, band_hz)
        analysis = RunAnalysis(run, bare, band, summary=by_name.get(run.name))
        analyses.append(analysis)
        if run not in measured:
            continue
        stored = campaign.fits(run.name)
        curve = None
        if stored:
            try:
                curve = ModelCurve.from_stored(stored[-1])
            except InputError as error:
                analysis.notes.append(f"stored fit not shown: {error}")
        if not bare and use_diagnosis and table is not None:
            spec = curve.spec if curve is not None else "voigt"
            try:
                data = _diagnosis.from_campaign(campaign, run.name, band_hz=band)
                diagnosed = _diagnosis.diagnose(data, spec)
                analysis.failures = list(diagnosed.failures)
                analysis.findings = list(diagnosed.findings)
                steps = diagnosed.auto() if ladder else [diagnosed]
                analysis.ladder = [LadderStep(s.model, s.rms_error, s.noise_floor) for s in steps]
                if curve is None:
                    curve = ModelCurve.from_fit(diagnosed.fit, "fitted here, both FRFs")
            except InputError as error:
                analysis.diagnosis_error = str(error)
            except (ValueError, ArithmeticError, np.linalg.LinAlgError) as error:
                analysis.diagnosis_error = f"diagnosis failed ({type(error).__name__}: {error})"
        elif not bare and use_diagnosis:
            analysis.diagnosis_error = ("the table's M_s, K_s, C_s are unknown (no bare-table "
                                        "run, no /rig values)")
        if curve is None and analysis.summary is not None:
            frfs = "X_s/F_e" if not bare else "the bare table"
            curve = ModelCurve.from_fit(analysis.summary.fit, f"fitted here to {frfs}")
        analysis.shown = curve
        if curve is not None:
            analysis.residuals = _residuals(run, curve, band)
        if not bare:
            try:
                data = run_data(run)
                result = fit("maxwell", data, frfs=("support",), band_hz=band,
                             fixed=table.values if table is not None else None)
                analysis.modulus = _modulus(run, result, band)
            except (InputError, ValueError, np.linalg.LinAlgError) as error:
                analysis.notes.append(f"K* from Eq. 5 not fitted: {error}")
    if not use_diagnosis:
        notes.append("diagnosis sections left out: "
                     + ("the diagnosis package is not installed" if _diagnosis is None
                        else "switched off"))
    theta = rig.theta
    return CampaignAnalysis(str(campaign.path), analyses, table, theta, band_hz,
                            use_diagnosis, notes)


def storage_and_loss(curves: ModulusCurves, theta_m: float | None
                     ) -> tuple[NDArray, NDArray, NDArray, NDArray]:
    """``(E' or K' measured, model, η measured, model)``; E' in Pa when θ is known, else K'."""
    scale = 1.0 / theta_m if theta_m else 1.0
    return (curves.measured.real * scale, curves.model.real * scale,
            curves.measured.imag / curves.measured.real, curves.model.imag / curves.model.real)


def rubbers(analysis: CampaignAnalysis) -> dict[str, list[RunAnalysis]]:
    """Specimen runs with a K* curve, grouped by specimen, least preload first."""
    groups: dict[str, list[RunAnalysis]] = {}
    for run in analysis.runs:
        if run.bare or run.modulus is None:
            continue
        groups.setdefault(run.run.metadata.specimen, []).append(run)
    for members in groups.values():
        members.sort(key=lambda r: (r.run.metadata.preload_strain, r.name))
    return groups


def finite(value: float) -> bool:
    """A number that is not NaN or infinite."""
    return isinstance(value, float | int) and math.isfinite(value)
