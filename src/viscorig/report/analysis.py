"""Everything the report shows, computed once per run: the model reached, its failures, K*.

Which model a specimen run shows: the best the diagnosis reached. The run is diagnosed (both
FRFs, the table held at the bare-table run's values) starting from its latest stored fit's
model when the file has one, else from Voigt, and the diagnosis ladder is climbed
(:meth:`~viscorig.diagnosis.DiagnosisResult.auto`: the best significant effect is added and the
model refitted until the error reaches the noise floor or nothing significant is left). The
shown model, its failure bands and its parameters' ± all come from the last rung. Without the
ladder (``ladder=False``) the first rung is shown, with the effect most likely missing; without
diagnosis, the latest stored fit, else the Table 1 Voigt fit.

The ladders of different runs are independent, so they are climbed in parallel processes
(``jobs``); each returns plain data (:class:`Climb`), never the fitted objects themselves.

Also computed once: Table 1 and 2 (:func:`viscorig.identify.summarize`, the numbers ``summary``
prints) and, per specimen run, ``K*`` from Eq. (5) for ``E'`` and ``η`` against frequency with
the model's uncertainty band (:func:`viscorig.estimates.modulus_band`), and each FRF's residual
against the local σ of the noise model of the run (the one every fit uses).
"""

from __future__ import annotations

import itertools
import logging
import math
import time
from dataclasses import dataclass, field, replace
from pathlib import Path
from types import ModuleType
from typing import cast

import numpy as np
from numpy.typing import NDArray

from viscorig.errors import InputError
from viscorig.estimates import ModulusBand, kstar_from_support, modulus_band
from viscorig.executor import default_jobs, executor
from viscorig.fitting import FitResult, estimate_noise, fit
from viscorig.fitting.data import MIN_POINTS, FrfData
from viscorig.identify import (
    PAPER_BAND_HZ,
    RunSummary,
    TableSource,
    is_bare_table,
    read_fit,
    run_data,
    summarize,
    table_parameters,
)
from viscorig.identify import (
    preload_pairs as pair_preloaded,
)
from viscorig.numbers import Estimate
from viscorig.rig import RigDescription
from viscorig.storage import INPUT_OVERLOAD, CampaignFile, RunRecord
from viscorig.storage.journal import JournalEntry

_diagnosis: ModuleType | None
try:  # diagnosis is optional: the report is built without its sections when it is absent
    from viscorig import diagnosis as _diagnosis
except ImportError:  # pragma: no cover - depends on the installed tree
    _diagnosis = None

_log = logging.getLogger(__name__)


@dataclass(frozen=True)
class FindingSummary:
    """A candidate effect the diagnosis fitted and tested (a finding, as plain data)."""

    effect: str
    model: str
    term: str
    rms_error: float
    delta_bic: float
    significant: bool
    explanation: str
    parameters: dict[str, Estimate] = field(default_factory=dict)

    @classmethod
    def of(cls, finding) -> FindingSummary:
        """From a :class:`viscorig.diagnosis.Finding`."""
        parameters = {name: Estimate(float(p["value"]), float(p["stderr"]), str(p["unit"]))
                      for name, p in finding.parameters().items()}
        return cls(finding.effect, finding.model, finding.term, float(finding.rms_error),
                   float(finding.delta_bic), bool(finding.significant), finding.explanation,
                   parameters)


@dataclass(frozen=True)
class Rung:
    """One rung of the diagnosis ladder: the model, its error, and how it differs from the rung
    before: the findings whose terms it added, or the terms it took out again because they no
    longer paid for themselves (both empty on the first rung)."""

    model: str
    rms_error: float
    noise_floor: float
    added: tuple[FindingSummary, ...] = ()
    removed: tuple[str, ...] = ()


def term_change(before: str, after: str) -> tuple[list[str], list[str]]:
    """The terms of spec ``after`` that ``before`` lacks, and those of ``before`` it lacks."""
    old, new = before.split("+"), after.split("+")
    return [t for t in new if t not in old], [t for t in old if t not in new]


@dataclass
class Climb:
    """What the diagnosis of one run found, as plain data (returned by a worker process)."""

    rungs: list[Rung]
    final: FitResult
    """The fit of the last rung (its ``noise_floor`` the diagnosis's)."""
    failures: list
    candidates: list[FindingSummary]
    """The first rung's candidate effects, best first."""
    missing: list[FindingSummary]
    """The last rung's significant candidates (what is still missing), best first."""
    advice: list[str]
    seconds: float
    climbed: bool


@dataclass
class ShownResidual:
    """``H_model/H_measured − 1`` of one FRF of the shown model, with the local noise."""

    frf: str
    frequency_hz: NDArray[np.float64]
    magnitude: NDArray[np.float64]
    noise: NDArray[np.float64]
    """Local relative noise ``σ_i``: ``NoiseModel.scale(frf)`` of the run's noise model."""
    floor: float
    """The noise floor of this FRF (``NoiseModel.floor_of``)."""


@dataclass
class ModulusCurves:
    """``K*`` of a specimen run against frequency: Eq. (5) estimates and a model's, with the
    model's ``K'`` and ``η`` uncertainty band (``band``, ``K'`` in N/m: θ = 1) and the fit
    itself, for comparing two runs' models (``fit``)."""

    frequency_hz: NDArray[np.float64]
    measured: NDArray[np.complex128]
    model: NDArray[np.complex128]
    spec: str
    source: str
    disc_mass_kg: float
    band: ModulusBand | None = None
    fit: FitResult | None = None


@dataclass
class RunAnalysis:
    """What the report shows for one run."""

    run: RunRecord
    bare: bool
    band_hz: tuple[float, float]
    shown: FitResult | None = None
    residuals: list[ShownResidual] = field(default_factory=list)
    modulus: ModulusCurves | None = None
    summary: RunSummary | None = None
    climb: Climb | None = None
    diagnosis_error: str = ""
    notes: list[str] = field(default_factory=list)

    @property
    def name(self) -> str:
        """Run name."""
        return self.run.name

    @property
    def failures(self) -> list:
        """Failure bands of the model shown (none when it was not diagnosed)."""
        return self.climb.failures if self.climb is not None else []

    @property
    def ladder(self) -> list[Rung]:
        """The rungs climbed (one when the ladder was not climbed)."""
        return self.climb.rungs if self.climb is not None else []

    @property
    def candidates(self) -> list[FindingSummary]:
        """The first rung's candidate effects."""
        return self.climb.candidates if self.climb is not None else []


@dataclass
class CampaignAnalysis:
    """The whole campaign as the report shows it."""

    path: str
    runs: list[RunAnalysis]
    table: TableSource | None
    theta_m: float | None
    band_hz: tuple[float, float]
    diagnosis_available: bool
    ladder: bool = False
    notes: list[str] = field(default_factory=list)
    seconds: float = 0.0
    diagnosis_seconds: float = 0.0
    """CPU-side sum of every run's diagnosis (and ladder) time."""
    jobs: int = 1
    journal: list[JournalEntry] = field(default_factory=list)
    """The bench's notes and run events (``/journal``), in the order written."""

    def run(self, name: str) -> RunAnalysis:
        """One run's analysis by name."""
        return next(r for r in self.runs if r.name == name)


def _clipped(run: RunRecord, band_hz: tuple[float, float]) -> tuple[float, float] | None:
    """``band_hz`` clipped to the run's frequencies; ``None`` when it holds none of them."""
    lo = max(band_hz[0], float(run.frequency_hz.min()))
    hi = min(band_hz[1], float(run.frequency_hz.max()))
    return (lo, hi) if lo < hi else None


def _band(run: RunRecord, band_hz: tuple[float, float]) -> tuple[float, float]:
    return _clipped(run, band_hz) or (float(run.frequency_hz.min()),
                                      float(run.frequency_hz.max()))


def _in_band(run: RunRecord, band: tuple[float, float]) -> NDArray[np.intp]:
    """Indices of the unoverloaded points in the band, in frequency order."""
    keep = np.flatnonzero((run.frequency_hz >= band[0]) & (run.frequency_hz <= band[1])
                          & ~run.flagged(INPUT_OVERLOAD))
    return keep[np.argsort(run.frequency_hz[keep])]


def _residuals(run: RunRecord, curve: FitResult, band: tuple[float, float]) -> list[ShownResidual]:
    """The shown model's residual of each FRF, beside the local σ of the run's noise model
    (estimated on the same points as a fit of the band estimates it)."""
    data = run_data(run).in_band(band)
    if data.frequency_hz.size < MIN_POINTS:
        return []
    order = np.argsort(data.frequency_hz, kind="stable")
    f = data.frequency_hz[order]
    predicted = curve.predict(data.frequency_hz, data.time_s, data.reference_amplitude)
    frfs = [name for name in data.available if name in predicted and _fittable(data, name)]
    if not frfs:
        return []
    noise = estimate_noise(data, tuple(frfs))
    return [ShownResidual(name, f, np.abs(predicted[name] / data.frf(name) - 1.0)[order],
                        noise.scale(name)[order], noise.floor_of((name,))) for name in frfs]


def _fittable(data: FrfData, frf: str) -> bool:
    """A fit would take this FRF of ``data`` (what it refuses has no noise model)."""
    try:
        data.checked((frf,), None)
    except InputError:
        return False
    return True


def _modulus(run: RunRecord, curve: FitResult, band: tuple[float, float], source: str
             ) -> ModulusCurves:
    index = _in_band(run, band)
    f = run.frequency_hz[index]
    mass = float(curve.values["M_v"])
    measured = kstar_from_support(f, run.accelerance_support[index], mass)
    grid = np.linspace(f.min(), f.max(), 121) if f.size else f
    return ModulusCurves(f, measured, curve.kstar(f), curve.spec, source, mass,
                         modulus_band(curve, grid, 1.0), curve)


class ReadOnce:
    """A campaign whose runs are each read from the file once.

    The report reads every run for Tables 1 and 2, for what it shows, and for each ladder
    again with the run's companions (every run of the campaign is looked at to find them):
    sixty reads of seven runs. Everything else is the campaign's own.
    """

    def __init__(self, campaign: CampaignFile) -> None:
        self._campaign = campaign
        self._runs: dict[str, RunRecord] = {}

    def run(self, name: str) -> RunRecord:
        """Run ``name``, read on the first call only."""
        if name not in self._runs:
            self._runs[name] = self._campaign.run(name)
        return self._runs[name]

    def __getattr__(self, name: str) -> object:
        return getattr(self._campaign, name)


#: Campaigns read in this process, by (path, modification time, size): a ladder climbed here
#: (``--jobs 1``, or a forked worker) reads no run the report has read already.
_READ: dict[tuple[str, int, int], ReadOnce] = {}


def read_once(path: str, campaign: CampaignFile | None = None) -> CampaignFile:
    """The :class:`ReadOnce` of the campaign file at ``path`` in its present state (opened
    unless ``campaign`` is given), typed as the campaign it stands in for: it answers every
    attribute but :meth:`ReadOnce.run` with the campaign's own."""
    try:
        stat = Path(path).stat()
    except OSError:
        return cast(CampaignFile, ReadOnce(CampaignFile.open(path)))  # which says what is wrong
    key = (str(Path(path).resolve()), stat.st_mtime_ns, stat.st_size)
    if key not in _READ:
        _READ.clear()  # one campaign at a time
        _READ[key] = ReadOnce(campaign if campaign is not None else CampaignFile.open(path))
    return cast(CampaignFile, _READ[key])


def climb(path: str, run_name: str, band_hz: tuple[float, float], spec: str, ladder: bool,
          ) -> Climb | str:
    """Diagnose one run from ``spec`` and climb the ladder; plain data, or why it failed.

    Runs in a worker process: it opens the campaign itself and returns nothing that holds a
    fitted model object.
    """
    if _diagnosis is None:  # analyse_campaign asks for no ladder then
        return "the diagnosis package is not installed"
    started = time.perf_counter()
    try:
        with np.errstate(all="ignore"):  # trial fits at a bound warn; their results are checked
            campaign = read_once(path)
            data = _diagnosis.from_campaign(campaign, run_name, band_hz=band_hz)
            first = _diagnosis.diagnose(data, spec)
            steps = first.auto() if ladder else [first]
    except InputError as error:
        return str(error.detail)
    except (ValueError, ArithmeticError, np.linalg.LinAlgError) as error:
        return f"diagnosis failed ({type(error).__name__}: {error})"
    seconds = time.perf_counter() - started
    last = steps[-1]
    _log.info("run %s: %d rung(s), %s at %.2f× the noise floor, %.2f s", run_name, len(steps),
              last.model, last.rms_error / last.noise_floor, seconds)
    return climb_from(steps, seconds, ladder)


def climb_from(steps: list, seconds: float = 0.0, climbed: bool = True) -> Climb:
    """The plain-data :class:`Climb` of a ladder of :class:`viscorig.diagnosis.DiagnosisResult`
    (one element when the ladder was not climbed)."""
    rungs = [Rung(steps[0].model, float(steps[0].rms_error), float(steps[0].noise_floor))]
    for before, after in itertools.pairwise(steps):
        new_terms, removed = term_change(before.model, after.model)
        added = [f for f in before.findings if f.term in new_terms or f.model == after.model]
        rungs.append(Rung(after.model, float(after.rms_error), float(after.noise_floor),
                          tuple(FindingSummary.of(f) for f in added),
                          () if added else tuple(removed)))
    first, last = steps[0], steps[-1]
    source = "diagnosis ladder" if len(steps) > 1 else "diagnosed here"
    frfs = "both FRFs" if len(last.fit.frfs) > 1 else f"the {last.fit.frfs[0]} FRF alone"
    final = replace(last.fit, source=f"{source}, {frfs}", noise_floor=float(last.noise_floor))
    return Climb(rungs, final, list(last.failures), [FindingSummary.of(f) for f in first.findings],
                 [FindingSummary.of(f) for f in last.significant], list(last.advice), seconds,
                 climbed)


def _climb_all(path: str, requests: list[tuple[str, tuple[float, float], str]], ladder: bool,
               jobs: int, scheduler: str | None = None) -> tuple[dict[str, Climb | str], int]:
    """:func:`climb` for every request, in ``jobs`` processes (in this one when 1) or on the
    Dask cluster at ``scheduler``; the results, and how many workers shared them."""
    with executor(min(jobs, len(requests)), scheduler) as workers:
        results = workers.map(climb, [(path, name, band, spec, ladder)
                                      for name, band, spec in requests])
        count = workers.workers
    return ({name: result for (name, _, _), result in zip(requests, results, strict=True)},
            count)


def analyse_campaign(
    campaign: CampaignFile,
    band_hz: tuple[float, float] = PAPER_BAND_HZ,
    *,
    diagnosis: bool = True,
    ladder: bool = True,
    jobs: int | None = None,
    scheduler: str | None = None,
) -> CampaignAnalysis:
    """Fit, diagnose and gather what the report shows, every fit made once.

    Parameters
    ----------
    campaign
        The open campaign.
    band_hz
        Band of the identification (the paper's 20-120 Hz by default; clipped to each run).
    diagnosis
        Diagnose each specimen run (failure bands, candidate effects).
    ladder
        Climb the ladder of effects to the best model (seconds per run); else diagnose once.
    jobs
        Processes climbing ladders at once (default: one per core).
    scheduler
        ``tcp://HOST:PORT`` of a Dask cluster whose workers climb the ladders instead
        (:mod:`viscorig.executor`).
    """
    started = time.perf_counter()
    campaign = read_once(str(campaign.path), campaign)
    rig = RigDescription.from_attributes(campaign.rig)
    notes: list[str] = []
    runs = [campaign.run(name).merged() for name in campaign.run_names]  # one point per frequency
    few = {run.name: run.points for run in runs if 0 < run.points < MIN_POINTS}
    notes += [f"run {name}: {points} points, too few to fit; shown as measured"
              for name, points in few.items()]
    try:
        table, summaries, left_out = summarize(campaign, band_hz)
        notes += [f"left out of Tables 1 and 2: {out.reason}" for out in left_out
                  if out.run not in few]  # (a run too few to fit is said above)
    except InputError as error:
        summaries = []
        notes.append(f"Table 1 and 2 not computed: {error}")
        try:  # one specimen run the tables refuse does not make the table's values unknown
            table = table_parameters(campaign)
        except InputError:
            table = None
    by_name = {summary.run: summary for summary in summaries}
    use_diagnosis = diagnosis and _diagnosis is not None
    analyses: list[RunAnalysis] = []
    requests: list[tuple[str, tuple[float, float], str]] = []
    for run in runs:
        analysis = RunAnalysis(run, is_bare_table(run), _run_band(run, band_hz),
                               summary=by_name.get(run.name))
        if run.points and not analysis.bare and _clipped(run, band_hz) is None:
            lo, hi = analysis.band_hz
            analysis.notes.append(f"the band {band_hz[0]:g}–{band_hz[1]:g} Hz holds none of its "
                                  f"points: shown and diagnosed over its own {lo:g}–{hi:g} Hz")
        analyses.append(analysis)
        spec = _first_look(campaign, analysis, table, use_diagnosis)
        if spec is not None:
            requests.append((run.name, analysis.band_hz, spec))
    notes += _beyond_band(analyses, band_hz, Path(str(campaign.path)).name)
    jobs = default_jobs() if jobs is None else max(1, int(jobs))
    climbs, workers = ({}, 1) if not requests else _climb_all(
        str(campaign.path), requests, ladder, jobs, scheduler)
    for analysis in analyses:
        _complete(analysis, climbs.get(analysis.name), table)
    if not use_diagnosis:
        notes.append("diagnosis sections left out: "
                     + ("the diagnosis package is not installed" if _diagnosis is None
                        else "switched off"))
    _READ.clear()  # the runs read are not kept past the analysis
    spent = sum(c.seconds for c in climbs.values() if isinstance(c, Climb))
    try:
        entries = campaign.journal
    except InputError as error:
        entries = []
        notes.append(f"journal not shown: {error}")
    return CampaignAnalysis(str(campaign.path), analyses, table, rig.theta, band_hz,
                            use_diagnosis, ladder and use_diagnosis, notes,
                            time.perf_counter() - started, spent,
                            min(workers, max(1, len(requests))), entries)


def _beyond_band(analyses: list[RunAnalysis], band_hz: tuple[float, float],
                 file: str) -> list[str]:
    """A note when the specimen runs were measured well beyond the band analysed (more than a
    frequency step past either end), with the command that analyses all of it."""
    measured = [analysis.run.frequency_hz for analysis in analyses
                if not analysis.bare and analysis.run.points]
    if not measured:
        return []
    lo = min(float(f.min()) for f in measured)
    hi = max(float(f.max()) for f in measured)
    steps = np.concatenate([np.diff(np.unique(f)) for f in measured])
    step = float(np.median(steps)) if steps.size else 0.0
    if lo >= band_hz[0] - step and hi <= band_hz[1] + step:
        return []
    return [f"the specimen runs were measured over {lo:g}–{hi:g} Hz and are analysed over "
            f"{band_hz[0]:g}–{band_hz[1]:g} Hz (the paper's band unless --band is given): "
            f"viscorig report {file} --band {lo:g}:{hi:g} analyses all of it"]


def _run_band(run: RunRecord, band_hz: tuple[float, float]) -> tuple[float, float]:
    """The band a run is analysed in: ``band_hz`` clipped to the run; a bare table's own band,
    which covers its resonance."""
    if not run.points:
        return band_hz
    if is_bare_table(run):
        return float(run.frequency_hz.min()), float(run.frequency_hz.max())
    return _band(run, band_hz)


def _first_look(campaign: CampaignFile, analysis: RunAnalysis, table: TableSource | None,
                use_diagnosis: bool) -> str | None:
    """Show the run's latest stored fit; the spec its diagnosis starts from, or ``None`` when
    it is not diagnosed (too few points, the bare table, no table values, no diagnosis)."""
    run = analysis.run
    if run.points < MIN_POINTS:
        return None
    try:
        stored = campaign.fits(run.name)
        if stored:
            analysis.shown = read_fit(stored[-1])
    except InputError as error:  # a damaged fit: the run's measurements still count
        analysis.notes.append(f"stored fit not shown: {error}")
    if analysis.bare or not use_diagnosis:
        return None
    if table is None:
        analysis.diagnosis_error = ("the table's M_s, K_s, C_s are unknown (no bare-table "
                                    "run, no /rig values)")
        return None
    spec = "voigt"
    if analysis.shown is not None and analysis.shown.has_disc:
        spec = analysis.shown.spec
        analysis.notes.append(f"diagnosis started from {analysis.shown.source} ({spec})")
    return spec


def _complete(analysis: RunAnalysis, outcome: Climb | str | None,
              table: TableSource | None) -> None:
    """The model shown (the ladder's last rung, else the stored or Table 1 fit), its residuals
    and, for a specimen, K* from Eq. (5) with a model's."""
    if isinstance(outcome, str):
        analysis.diagnosis_error = outcome
    elif outcome is not None:
        analysis.climb = outcome
        analysis.shown = outcome.final
    if analysis.shown is None and analysis.summary is not None:
        frfs = "X_s/F_e" if not analysis.bare else "the bare table"
        analysis.shown = replace(analysis.summary.fit, source=f"fitted here to {frfs}")
    run, band = analysis.run, analysis.band_hz
    if analysis.shown is not None and run.points >= MIN_POINTS:
        analysis.residuals = _residuals(run, analysis.shown, band)
    if analysis.bare or run.points < MIN_POINTS:
        return
    if not np.any(np.isfinite(run.accelerance_support)):
        analysis.notes.append("no ẍ_v/F_v: K* from Eq. 5 not computed")
        return
    shown = analysis.shown
    try:
        if analysis.climb is not None and shown is not None and shown.has_disc:
            analysis.modulus = _modulus(run, shown, band, f"{shown.spec} ({shown.source})")
        else:
            result = fit("maxwell", run_data(run), frfs=("support",), band_hz=band,
                         fixed=table.values if table is not None else None)
            analysis.modulus = _modulus(run, replace(result, source="Maxwell fit"),
                                        band, "Maxwell fit of ẍ_v/F_v (K* of Eq. 5)")
    except (InputError, ValueError, np.linalg.LinAlgError) as error:
        analysis.notes.append(f"K* from Eq. 5 not fitted: {error}")


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


def preload_pairs(analysis: CampaignAnalysis) -> list[tuple[RunAnalysis, RunAnalysis]]:
    """``(without, with preload)`` runs of the report (:func:`viscorig.identify.preload_pairs`,
    specimen runs of ten points or more)."""
    specimens = [run for run in analysis.runs if not run.bare and run.run.points >= MIN_POINTS]
    return pair_preloaded(specimens, lambda r: (
        str(r.run.metadata.specimen), float(r.run.metadata.hardness_shore_a),
        str(r.run.metadata.direction), float(r.run.metadata.preload_strain),
        float(r.run.metadata.level_m_per_s2)))


def finite(value: float) -> bool:
    """A number that is not NaN or infinite."""
    return isinstance(value, float | int) and math.isfinite(value)

