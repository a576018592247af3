"""Identify runs of a campaign file: the high-level layer between storage and the fitting core.

A specimen run needs the table's ``M_s, K_s, C_s``: they come from a bare-table run of the same
file (specimen ``"none"``, identified on the fly with the ``table`` model), else from the
``/rig`` attributes (data-format.md). Their uncertainty goes with them into the specimen fit's
covariance (:mod:`viscorig.fitting.uncertainty`): the bare-table fit's covariance, or the
standard uncertainties ``/rig`` gives (``table_*_stderr_*``); ``/rig`` values without one are
taken as exact. Points flagged with an input overload are left out (their FRF is not a linear
measurement); points where the level was not reached are kept, because the FRF of a linear rig
does not depend on the level.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import TypeVar

import numpy as np
from numpy.typing import NDArray

from viscorig.compare import Change, compare_fits, system_changes
from viscorig.errors import InputError
from viscorig.estimates import (
    MeasuredResonance,
    SystemProperties,
    measured_resonance,
    system_properties_with_uncertainty,
)
from viscorig.estimates import system_properties as voigt_system_properties
from viscorig.fitting import MISFIT_RATIO, FitResult, FrfData, Known, fit
from viscorig.models import parse_spec
from viscorig.numbers import Estimate, with_uncertainty
from viscorig.rig import RigDescription
from viscorig.storage import INPUT_OVERLOAD, CampaignFile, FitRecord, RunMetadata, RunRecord

#: The paper's analysis band (physics.md), used by the campaign summary.
PAPER_BAND_HZ = (20.0, 120.0)


def is_bare_table(run: RunRecord | RunMetadata) -> bool:
    """The run (or its metadata alone) has no specimen (``specimen == "none"``)."""
    metadata = run.metadata if isinstance(run, RunRecord) else run
    return str(metadata.specimen).strip().lower() in {"none", ""}


def run_data(run: RunRecord) -> FrfData:
    """A run's FRFs as every analysis reads them (:class:`FrfData`): without the overloaded
    points, in frequency order, repeats of one frequency merged (:meth:`RunRecord.merged`), so that
    a run an adaptive plan measured (repeats, any order) is fitted, diagnosed and reported as a
    full sweep is."""
    kept = ~run.flagged(INPUT_OVERLOAD)
    if run.points and not kept.any():
        raise InputError(f"every one of its {run.points} points overloaded an input (flags "
                         f"bit {INPUT_OVERLOAD}): none can be fitted", f"run '{run.name}'")
    run = run.select(kept).merged()
    bare = is_bare_table(run)
    return FrfData(
        run.frequency_hz,
        run.accelerance_table,
        None if bare else run.accelerance_support,
        run.time_s,
        run.reference_amplitude,
        name=f"run '{run.name}'",
        variance_table=run.variance_table,
        variance_support=None if bare else run.variance_support,
        temperature_c=recorded_temperature_c(run),
    )


def recorded_temperature_c(run: RunRecord, every_point: bool = True
                           ) -> NDArray[np.float64] | None:
    """The specimen's temperature recorded at each point of ``run`` (°C; a chamber run's
    ``temperature_c`` dataset, NaN where a point has none), or ``None`` when the run has none,
    or, with ``every_point``, not at every point."""
    if "temperature_c" not in run.extra:
        return None
    values, units = run.extra["temperature_c"]
    values = np.asarray(values, dtype=float)
    if units.strip().lower() in {"k", "kelvin"}:
        values = values - 273.15
    if not values.size or (every_point and not bool(np.all(np.isfinite(values)))):
        return None
    return values


#: The table's parameters, as a specimen fit inherits them.
TABLE_NAMES = ("M_s", "K_s", "C_s")


@dataclass(frozen=True)
class TableSource:
    """The table parameters used, and where they came from (``"run 'table'"`` or ``"/rig"``).

    ``stderr`` holds standard uncertainties given with ``/rig`` values (none: exact).
    """

    values: dict[str, float]
    source: str
    fit: FitResult | None = None
    stderr: dict[str, float] | None = None

    @property
    def known(self) -> Known:
        """The values with their covariance, as a specimen fit inherits them."""
        if self.fit is not None:
            return Known.from_fit(self.fit, TABLE_NAMES, self.source)
        if self.stderr:
            return Known.with_stderr(self.values, self.stderr, self.source)
        return Known.exact(self.values, self.source)


#: A bare-table fit whose M_s or K_s has a larger relative standard error than this has not
#: determined it (a bare table's resonance gives both to well under 1 %).
TABLE_RELATIVE_STDERR_MAX = 0.1


def table_parameters(campaign: CampaignFile, spec: str = "table") -> TableSource | None:
    """The table's ``M_s, K_s, C_s``: from a bare-table run, else ``/rig``, else ``None``.

    The bare-table run is fitted over every point it has: its band was chosen to cover the
    table's own resonance (about 19 Hz), which the specimen band (20-120 Hz) leaves out.
    ``spec`` is the model of the table (``"table+frame(2000)"`` to take out the frame under
    it); only ``M_s, K_s, C_s`` are passed on, with their covariance.
    """
    model = parse_spec(spec)
    if model.modulus_term is None or model.modulus_term.has_disc:
        raise InputError(f"'{model.spec}' is not a model of the bare table (use 'table+...')",
                         "table model")
    for name in campaign.run_names:
        if not is_bare_table(campaign.run_metadata(name)):
            continue
        run = campaign.run(name)
        if run.points:
            result = fit(model, run_data(run), weighting="noise")
            values = {n: result.values[n] for n in TABLE_NAMES}
            for n in ("M_s", "K_s"):  # what every specimen fit holds fixed: known, or refused
                value, stderr = values[n], result.stderr.get(n, math.nan)
                if not (value > 0 and stderr < TABLE_RELATIVE_STDERR_MAX * value):
                    raise InputError(
                        f"the bare-table fit ({model.spec}) leaves {n} undetermined "
                        f"({with_uncertainty(value, stderr)} {model.by_name[n].unit}): no "
                        "specimen fit can hold it fixed; fit the table with another model",
                        f"run '{name}'")
            return TableSource(values, f"run '{name}'", result)
    rig = RigDescription.from_attributes(campaign.rig)
    if rig.table is not None:
        return TableSource(rig.table, "/rig", stderr=rig.table_stderr)
    return None


def _band_within(data: FrfData, band_hz: tuple[float, float] | None) -> tuple[float, float] | None:
    """The band clipped to the data's range (``None`` stays ``None``)."""
    if band_hz is None:
        return None
    lo = max(band_hz[0], float(data.frequency_hz.min()))
    hi = min(band_hz[1], float(data.frequency_hz.max()))
    return (lo, hi) if lo < hi else band_hz


def identify_run(
    campaign: CampaignFile,
    run_name: str,
    spec: str | None = None,
    *,
    band_hz: tuple[float, float] | None = None,
    frfs: Sequence[str] | None = None,
    table: TableSource | None = None,
    weighting: str = "noise",
) -> tuple[FitResult, TableSource | None]:
    """Fit a model to one run of a campaign.

    Parameters
    ----------
    campaign
        The open campaign.
    run_name
        Run to identify.
    spec
        Model spec; default ``"table"`` for a bare-table run, ``"voigt"`` otherwise.
    band_hz
        Band fitted (default every point).
    frfs
        FRFs to fit; default every FRF the model predicts and the run has.
    table
        Table parameters to use (default: :func:`table_parameters`).
    weighting
        ``"noise"`` (the project's estimate) or ``"uniform"`` (the paper's method); see
        :mod:`viscorig.fitting.nonlinear`.

    Returns
    -------
    result, table
        The fit, and the table parameters it used (``None`` for a bare-table run).
    """
    return _identify(campaign, campaign.run(run_name), spec, band_hz=band_hz, frfs=frfs,
                     table=table, weighting=weighting)


def _identify(
    campaign: CampaignFile,
    run: RunRecord,
    spec: str | None,
    *,
    band_hz: tuple[float, float] | None,
    frfs: Sequence[str] | None,
    table: TableSource | None,
    weighting: str = "noise",
) -> tuple[FitResult, TableSource | None]:
    """:func:`identify_run` on a run already read (``campaign`` only for the table)."""
    run_name = run.name
    if not run.points:
        raise InputError("has no measured point", f"run '{run_name}'")
    bare = is_bare_table(run)
    spec = ("table" if bare else "voigt") if spec is None else spec  # "" is an error
    model = parse_spec(spec)
    data = run_data(run)
    if bare:
        if model.modulus_term is None or model.modulus_term.has_disc:
            raise InputError(
                f"is a bare-table run (no specimen, no {'accelerance_support'}); "
                f"model '{model.spec}' needs a specimen: use 'table'",
                f"run '{run_name}'",
            )
        return fit(model, data, frfs=frfs, band_hz=band_hz, weighting=weighting), None
    if model.modulus_term is not None and not model.modulus_term.has_disc:
        raise InputError("has a specimen; the 'table' model is for bare-table runs", run_name)
    if data.support is None:
        if frfs is not None and "support" in frfs:
            raise InputError("has no accelerance_support (ẍ_v/F_v)", f"run '{run_name}'")
        frfs = ("table",)  # every FRF available: the table's alone
    table = table or table_parameters(campaign)
    if table is None:
        chosen = frfs or model.frfs
        if "table" in chosen:
            raise InputError(
                "the table's M_s, K_s, C_s are unknown: the file has no bare-table run and "
                "no table_* attributes in /rig; fit the support FRF only (--frf support)",
                f"run '{run_name}'",
            )
        return fit(model, data, frfs=frfs, band_hz=band_hz, weighting=weighting), None
    return fit(model, data, frfs=frfs, band_hz=band_hz, known=table.known,
               weighting=weighting), table


def store_fit(campaign: CampaignFile, run_name: str, result: FitResult) -> str:
    """Store a fit under ``/runs/<run>/fits/<id>`` and return its id.

    A parameter held fixed exactly in the fit is stored with ``stderr`` NaN, the campaign
    file's "unknown": it was not estimated by this fit. One inherited with an uncertainty (the
    table's, from the bare-table run) keeps its standard error. The correlation matrix of the
    parameters with a standard error is stored beside them.
    """
    uncertain = set(result.covariance_names)
    return campaign.add_fit(
        run_name,
        model=result.spec,
        band_hz=result.band_hz,
        rms_error=result.rms_error,
        noise_floor=result.noise_floor,
        parameters={
            name: e._replace(stderr=e.stderr if name in uncertain else math.nan)
            for name, e in result.parameters.items()
        },
        correlation=(tuple(result.covariance_names), result.correlation),
        weighting=result.weighting,
    )


def read_fit(record: FitRecord) -> FitResult:
    """A fit stored in a campaign file (:meth:`Campaign.fits`), as the fit the rest of the
    package uses.

    Only what the file keeps is known: the values, the standard errors (every parameter with
    one counts as fitted), their correlation matrix when stored (else taken as uncorrelated),
    the band and the error measures. There are no residuals, so two stored fits are compared
    as :mod:`viscorig.compare` says for fits without them.

    Raises
    ------
    InputError
        The stored spec is not a model, the fit lacks some of its parameters, or gives one a
        value of the wrong sign (a negative stiffness).
    """
    where = f"run '{record.run}'"
    model = parse_spec(record.model)
    values = {name: float(p.value) for name, p in record.parameters.items()}
    missing = sorted(set(model.names) - set(values))
    if missing:
        raise InputError(f"stored fit {record.id} lacks {', '.join(missing)}", where)
    for name in model.names:
        parameter, value = model.by_name[name], values[name]
        if value < 0 <= parameter.lower or (parameter.log and value <= 0):
            floor = "above" if parameter.log else "at least"
            shown = f"{value:g} {parameter.unit}".rstrip()
            raise InputError(f"stored fit {record.id} gives {name} = {shown}, which is {floor} 0 "
                             f"in every {record.model} model", where)
    known = {name: float(p.stderr) for name, p in record.parameters.items()
             if math.isfinite(p.stderr) and p.stderr > 0}
    names = tuple(known)
    correlation = np.eye(len(names))
    if record.correlation is not None:
        stored_names, matrix = record.correlation
        index = {name: i for i, name in enumerate(stored_names)}
        if all(name in index for name in names):
            order = [index[name] for name in names]
            correlation = np.asarray(matrix, dtype=float)[np.ix_(order, order)]
    sigma = np.array([known[name] for name in names])
    covariance = correlation * np.outer(sigma, sigma)
    rms_error, noise_floor = float(record.rms_error), float(record.noise_floor)
    return FitResult(
        model=model, values=values, stderr=known, free=names, covariance=covariance,
        rms_error=rms_error, noise_floor=noise_floor,
        band_hz=(float(record.band_hz[0]), float(record.band_hz[1])), points=0,
        frfs=tuple(model.frfs), frequency_hz=np.empty(0), residuals={}, bic=math.nan,
        misfit_scale=max(1.0, (rms_error / noise_floor) ** 2) if noise_floor > 0 else 1.0,
        fits_noise=bool(rms_error <= MISFIT_RATIO * noise_floor),
        weighting=record.weighting or "uniform", source=f"stored fit {record.id}", stored=True)


def stored_fits(campaign: CampaignFile, run_name: str) -> list[FitResult]:
    """The fits of a run that the file stores whole (:func:`read_fit`), oldest first; one
    that is not a whole fit (a spec no model reads, a parameter missing) is left out."""
    out = []
    for record in campaign.fits(run_name):
        try:
            out.append(read_fit(record))
        except InputError:
            continue
    return out


#: A run fitted over less than this share of the band asked for covers part of it only (a
#: sweep's last point a step short of the band's edge still covers it).
COVERED_SHARE = 0.95


@dataclass(frozen=True)
class RunSummary:
    """Table 1 and Table 2 quantities of one run (Voigt on the table FRF, as the paper).

    ``fit`` is the paper's method (every point weighted the same); ``weighted`` the same model
    fitted by the project's estimate (weighted by the noise, as ``identify``); ``None`` for the
    bare table. ``system_uncertain`` holds ``f_r``, ``xi`` and ``B_r`` with their uncertainty
    (:func:`viscorig.estimates.system_properties_with_uncertainty`); ``specimen``,
    ``hardness_shore_a`` and ``preload_strain`` come from the run's metadata.
    """

    run: str
    bare: bool
    fit: FitResult
    system: SystemProperties | None
    measured: MeasuredResonance
    system_uncertain: dict[str, Estimate] | None = None
    specimen: str = ""
    hardness_shore_a: float = math.nan
    preload_strain: float = 0.0
    weighted: FitResult | None = None
    direction: str = "up"
    level_m_per_s2: float = math.nan

    def covers(self, band_hz: tuple[float, float]) -> bool:
        """The fit spans at least :data:`COVERED_SHARE` of ``band_hz``: not a run whose points
        stop short of the band (an interrupted sweep, a narrower one)."""
        lo, hi = self.fit.band_hz
        inside = min(hi, band_hz[1]) - max(lo, band_hz[0])
        return inside >= COVERED_SHARE * (band_hz[1] - band_hz[0])


@dataclass(frozen=True)
class LeftOut:
    """A specimen run the tables could not fit, and why."""

    run: str
    reason: str


@dataclass(frozen=True)
class Variation:
    """What preload changed: a run against the same specimen without preload.

    ``changes`` maps ``K_v``, ``C_v``, ``f_r``, ``xi``, ``B_r`` to their relative change with
    its uncertainty (:mod:`viscorig.compare`: both fits' uncertainty, the table they share
    counted once, the misfit they share paired point by point).
    """

    run: str
    base: str
    changes: dict[str, Change]

    def statements(self) -> list[str]:
        """``"C_v rose 9.0 ± 0.4 % with preload (soft-0 → soft-10)"``, one per quantity."""
        return [change.words(f"with preload ({self.base} → {self.run})")
                for change in self.changes.values()]

    @property
    def basis(self) -> tuple[str, ...]:
        """How the two fits' errors were related, in words."""
        return next(iter(self.changes.values())).basis if self.changes else ()


Mounted = TypeVar("Mounted")


def preload_pairs(runs: Sequence[Mounted],
                  describe: Callable[[Mounted], tuple[str, float, str, float, float]]
                  ) -> list[tuple[Mounted, Mounted]]:
    """``(without, with preload)`` pairs of specimen runs: the one rule the summary and the
    report pair a preloaded run with its base by.

    Each preloaded run is paired with its specimen's (name and hardness) least preloaded run of
    the same sweep direction, at the level nearest its own (a run measured at a reduced level is
    still compared). ``describe(run)`` gives ``(specimen, hardness_shore_a, direction,
    preload_strain, level_m_per_s2)``; pass specimen runs only.
    """
    groups: dict[tuple, list[tuple[Mounted, float, float]]] = {}
    for run in runs:
        specimen, hardness, direction, preload, level = describe(run)
        key = (specimen, hardness if math.isfinite(hardness) else None, direction)
        groups.setdefault(key, []).append((run, preload, level))
    pairs = []
    for members in groups.values():
        least = min(preload for _, preload, _ in members)
        bases = [(run, level) for run, preload, level in members if preload == least]
        for other, preload, level in members:
            if preload <= least:
                continue
            base = min(bases, key=lambda b: abs(math.log(b[1] / level))
                       if b[1] > 0 and level > 0 else math.inf)[0]
            pairs.append((base, other))
    return pairs


def preload_variations(summaries: Sequence[RunSummary]) -> list[Variation]:
    """For every preloaded specimen run, its change against its base (:func:`preload_pairs`),
    as the paper's Tables 1 and 2 discuss them."""
    variations = []
    specimens = [run for run in summaries if not run.bare]
    for base, run in preload_pairs(specimens, lambda r: (
            r.specimen, r.hardness_shore_a, r.direction, r.preload_strain, r.level_m_per_s2)):
        found = compare_fits(base.fit, run.fit, ("K_v", "C_v")) + system_changes(base.fit,
                                                                                 run.fit)
        changes = {change.quantity: change for change in found}
        variations.append(Variation(run.run, base.run, changes))
    return variations


def summarize(
    campaign: CampaignFile,
    band_hz: tuple[float, float] = PAPER_BAND_HZ,
    table_model: str = "table",
) -> tuple[TableSource | None, list[RunSummary], list[LeftOut]]:
    """Identify every run as the paper does: the table, then Voigt on ``X_s/F_e``, table fixed,
    every point weighted the same (the paper's method, which the simulated rigs were calibrated
    to reproduce Table 1 with); beside it the same fit by the project's estimate (weighted by
    the noise, :attr:`RunSummary.weighted`).

    ``table_model``: the bare table's model (``"table+frame(2000)"`` takes the frame out of
    ``K_s``; the specimen fits then stay Voigt, as the paper's).

    Returns the table's values, a summary of every run fitted, and the specimen runs that
    could not be (an aborted run of three points, a band that misses a run), each with why: one
    such run leaves the others' tables whole. When no specimen run can be fitted, the first's
    reason is raised (:class:`InputError`)."""
    table = table_parameters(campaign, table_model)
    summaries = []
    left_out: list[LeftOut] = []
    for name in campaign.run_names:
        run = campaign.run(name)
        if not run.points:
            continue
        weighted = None
        if is_bare_table(run):
            data = run_data(run)
            band = None
            if table is not None and table.fit is not None and table.source == f"run '{name}'":
                result = table.fit
            else:
                result, _ = _identify(campaign, run, table_model, band_hz=None, frfs=None,
                                      table=None)
            system = None
        else:
            if table is None:
                raise InputError(
                    "Table 1 needs the table's M_s, K_s, C_s: no bare-table run, no /rig values",
                    str(campaign.path),
                )
            try:
                data = run_data(run)
                band = _band_within(data, band_hz)
                result, _ = _identify(
                    campaign, run, "voigt", band_hz=band, frfs=("table",), table=table,
                    weighting="uniform",
                )
                weighted = fit("voigt", data, frfs=("table",), band_hz=band, known=table.known,
                               noise=result.noise, weighting="noise")
            except InputError as error:
                left_out.append(LeftOut(name, str(error)))
                continue
            system = voigt_system_properties(result.values)
        inside = data.in_band(band)
        metadata = run.metadata
        hardness = float(metadata.hardness_shore_a)
        preload = float(metadata.preload_strain)
        summaries.append(
            RunSummary(
                name,
                is_bare_table(run),
                result,
                system,
                measured_resonance(inside.frequency_hz, np.asarray(inside.table)),
                None if system is None else system_properties_with_uncertainty(result),
                str(metadata.specimen),
                hardness,
                preload if math.isfinite(preload) else 0.0,
                weighted,
                str(metadata.direction),
                float(metadata.level_m_per_s2),
            )
        )
    if left_out and all(summary.bare for summary in summaries):
        raise InputError(left_out[0].reason)  # no specimen run to table
    return table, summaries, left_out
