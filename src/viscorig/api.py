"""The public Python API, for notebooks and scripts: a thin layer over the core.

>>> import viscorig
>>> campaign = viscorig.open_campaign("paper.h5")        # doctest: +SKIP
>>> run = campaign["soft-0"]; [r.name for r in campaign]  # runs by name, or iterate
>>> fit = campaign.identify("soft-0", "maxwell")         # a fit (not stored unless store=True)
>>> d = campaign.diagnose("soft-0", auto=True)           # where it fails; the ladder climbed
>>> campaign.compare("soft-0", "soft-10")                # what preload changed, with ±
>>> campaign.master("dma-sweep").to_json()               # master curve, shifts, Prony series
>>> campaign.payne_fits                                  # stored Payne fits (several runs)
>>> run.to_pandas(), fit.to_xarray()                     # frequency_hz as index / coordinate

Every object has a short ``repr`` and, in Jupyter, an HTML view (``_repr_html_``) that says the
same as the report, in the same words. The internal objects stay reachable (``run.stored``,
``fit.result``, ``d.internal``) for everything this layer does not wrap.
"""

from __future__ import annotations

import html
import math
from collections.abc import Iterator, Sequence
from dataclasses import asdict, replace
from pathlib import Path
from typing import Any

import numpy as np

from viscorig.compare import compare_fits, kstar_changes
from viscorig.diagnosis import diagnose_run
from viscorig.errors import InputError
from viscorig.fitting import FitResult
from viscorig.frames import pandas as load_pandas
from viscorig.frames import run_columns, to_pandas, to_xarray
from viscorig.identify import (
    identify_run,
    is_bare_table,
    store_fit,
    stored_fits,
    table_parameters,
)
from viscorig.materials.sources import master_curve
from viscorig.numbers import Estimate, with_uncertainty
from viscorig.report import build_report, words
from viscorig.report.analysis import RunAnalysis, climb_from
from viscorig.report.figures import frf_figure
from viscorig.report.headline import describe_specimen, headline
from viscorig.report.page import diagnosis_section
from viscorig.storage import CampaignFile
from viscorig.strain import PayneFit, stored_payne_fits

_DEFAULT_BAND = None  # every point, as identify and diagnose do


def _e(text: object) -> str:
    return html.escape(str(text))


class Campaign:
    """A campaign file opened for analysis: its runs by name, and what can be done with them.

    Use :func:`open_campaign`. ``campaign["soft-0"]`` is a :class:`Run`; iterating gives every
    run in the order they were measured.
    """

    def __init__(self, stored) -> None:
        self.stored = stored
        """The :class:`viscorig.storage.CampaignFile`."""

    @property
    def path(self) -> Path:
        """The campaign file."""
        return self.stored.path

    @property
    def names(self) -> list[str]:
        """Run names, in the order they were started."""
        return self.stored.run_names

    def __getitem__(self, name: str) -> Run:
        if not isinstance(name, str):
            raise TypeError("runs are looked up by name, e.g. campaign['soft-0']")
        return Run(self, self.stored.run(name))

    def __iter__(self) -> Iterator[Run]:
        for name in self.names:
            yield self[name]

    def __len__(self) -> int:
        return len(self.names)

    def __contains__(self, name: object) -> bool:
        return name in self.names

    @property
    def table(self) -> dict[str, float] | None:
        """The table's ``M_s, K_s, C_s`` every specimen fit holds fixed (``None`` if unknown)."""

        source = table_parameters(self.stored)
        return None if source is None else dict(source.values)

    @property
    def payne_fits(self) -> list[PayneFit]:
        """The Payne fits stored in the file (``identify --run A --run B ... --model kraus``,
        under ``/fits``), oldest first: each a :class:`viscorig.strain.PayneFit` with its
        runs, parameters (``K_f``, ``L_f``, ``x_c``, ``m_k`` with standard errors), band,
        ``fit_id`` and ``created``."""
        return stored_payne_fits(self.stored)

    def identify(self, run: str, model: str | None = None, *,
                 band_hz: tuple[float, float] | None = _DEFAULT_BAND,
                 frfs: Sequence[str] | None = None, store: bool = False) -> Fit:
        """Fit ``model`` to a run (as ``viscorig identify``); store it when ``store``.

        Parameters
        ----------
        run
            Run name.
        model
            Model spec (default ``table`` for a bare-table run, ``voigt`` otherwise).
        band_hz, frfs
            Band and FRFs fitted (default: every point, every FRF the model predicts).
        store
            Add the fit to the file (open the campaign with ``mode="a"``).
        """

        if store and self.stored.mode != "a":
            raise InputError("opened read-only; open_campaign(path, mode='a') to store fits",
                             str(self.path))
        with np.errstate(all="ignore"):
            result, _ = identify_run(self.stored, run, model, band_hz=band_hz, frfs=frfs)
        result.source = "fitted here"
        if store:
            result.source = f"stored fit {store_fit(self.stored, run, result)}"
        return Fit(self[run], result)

    def master(self, *runs: str, reference_temperature_c: float | None = None,
               disc_mass_kg: float | None = None, kstar: str = "support",
               vertical: str = "none", expansion_per_k: float = 0.0):
        """The master curve of a DMA run, or of rig runs of one specimen at several temperatures
        (as ``viscorig master``): shift factors with ±, WLF and Arrhenius, checks, Prony series.
        ``vertical="ferry"`` reduces the moduli by Ferry's ``b_T`` first (with the density's
        volumetric thermal expansion ``expansion_per_k``, 1/K).

        Returns a :class:`viscorig.materials.master.MasterCurve`; ``.to_json()`` is the object
        ``master --json`` prints, ``.text()`` what it prints without ``--json``.
        """
        names = [name for group in runs for name in ([group] if isinstance(group, str)
                                                      else group)]
        with np.errstate(all="ignore"):
            return master_curve(self.stored, names, reference_temperature_c, disc_mass_kg,
                                kstar, vertical, expansion_per_k)

    def diagnose(self, run: str, model: str | None = None, *, auto: bool = False,
                 band_hz: tuple[float, float] | None = _DEFAULT_BAND,
                 alone: bool = False) -> Diagnosis:
        """Diagnose a run (as ``viscorig diagnose``); ``auto`` climbs the ladder of effects.

        With ``auto`` the diagnosis returned is the last rung's, and ``.ladder`` holds them all.
        """

        with np.errstate(all="ignore"):
            first = diagnose_run(self.stored, run, model, band_hz=band_hz,
                                 with_companions=not alone)
            steps = first.auto() if auto else [first]
        return Diagnosis(self[run], steps[-1], steps if auto else None)

    def compare(self, before: str | Fit, after: str | Fit, *, model: str = "voigt",
                band_hz: tuple[float, float] | None = (20.0, 120.0),
                frequencies_hz: Sequence[float] | None = None) -> Comparison:
        """What changed from one run (or fit) to another, with the propagated ±.

        Runs given by name are fitted with ``model`` over ``band_hz`` first. The changes are
        those of the parameters both fits share and, when a K* depends on frequency, of ``K'``
        and ``η`` at ``frequencies_hz`` (default: both ends and the middle of the band). Their ±
        are :mod:`viscorig.compare`'s, as the report and ``summary`` give them: the table both
        fits inherit counted once, a misfit both runs share paired out point by point.
        """

        fits = [x if isinstance(x, Fit) else self.identify(x, model, band_hz=band_hz)
                for x in (before, after)]
        first, second = fits[0].result, fits[1].result
        shared = [name for name in first.free if name in second.free]
        changes = compare_fits(first, second, shared)
        frequency_dependent = any(term is not None and term.keyword != "voigt"
                                  for term in (first.model.modulus_term,
                                               second.model.modulus_term))
        if first.has_disc and second.has_disc and frequency_dependent:
            if frequencies_hz is None:
                lo = max(f.band_hz[0] for f in fits)
                hi = min(f.band_hz[1] for f in fits)
                frequencies_hz = [lo, round((lo + hi) / 2, 1), hi]
            changes += kstar_changes(first, second, frequencies_hz)
        return Comparison(fits[0], fits[1], changes)

    def report(self, out_dir: str | Path, **options: Any) -> Path:
        """Write the HTML report (:func:`viscorig.report.build_report`); return the page."""

        return build_report(self.path, Path(out_dir), **options)

    def __repr__(self) -> str:
        names = self.names
        shown = ", ".join(names[:6]) + (", ..." if len(names) > 6 else "")
        return f"<Campaign {self.path.name}: {len(names)} runs ({shown})>"

    def _repr_html_(self) -> str:
        rows = "".join(
            f"<tr><td>{_e(run.name)}</td><td>{_e(run.describe())}</td>"
            f"<td>{run.stored.points}</td><td>{_e(run.band_text())}</td>"
            f"<td>{len(run.fits)}</td></tr>" for run in self)
        return (f"<b>Campaign</b> <code>{_e(self.path)}</code><table><thead><tr><th>run</th>"
                "<th>what</th><th>points</th><th>band</th><th>fits stored</th></tr></thead>"
                f"<tbody>{rows}</tbody></table>")


class Run:
    """One run: its metadata and arrays (as stored), its fits, and shortcuts to analyse it.

    Attributes the layer does not define (``frequency_hz``, ``accelerance_table``,
    ``metadata``...) are those of the stored :class:`viscorig.storage.Run`.
    """

    def __init__(self, campaign: Campaign, stored) -> None:
        self.campaign = campaign
        self.stored = stored
        """The :class:`viscorig.storage.Run`."""

    def __getattr__(self, name: str) -> Any:
        if name.startswith("_"):
            raise AttributeError(name)
        return getattr(self.stored, name)

    @property
    def name(self) -> str:
        """Run name."""
        return self.stored.name

    @property
    def bare(self) -> bool:
        """A bare-table run (no specimen)."""

        return is_bare_table(self.stored)

    @property
    def fits(self) -> list[Fit]:
        """The fits stored for this run, oldest first."""

        return [Fit(self, fit) for fit in stored_fits(self.campaign.stored, self.name)]

    def identify(self, model: str | None = None, **options: Any) -> Fit:
        """:meth:`Campaign.identify` of this run."""
        return self.campaign.identify(self.name, model, **options)

    def diagnose(self, model: str | None = None, **options: Any) -> Diagnosis:
        """:meth:`Campaign.diagnose` of this run."""
        return self.campaign.diagnose(self.name, model, **options)

    def describe(self) -> str:
        """Specimen, hardness, preload and status in a few words."""

        return f"{describe_specimen(self.stored, self.bare)}, {self.stored.metadata.status}"

    def band_text(self) -> str:
        """``"20–120 Hz"``, or ``"–"`` without points."""
        f = self.stored.frequency_hz
        return f"{f.min():g}–{f.max():g} Hz" if f.size else "–"

    def to_pandas(self):
        """Every per-point dataset as a DataFrame indexed by ``frequency_hz`` (Hz); units in
        ``frame.attrs["units"]``, the run's metadata in ``frame.attrs``."""
        columns, units = run_columns(self.stored)
        return to_pandas(self.stored.frequency_hz, columns, units, self._attributes())

    def to_xarray(self):
        """Every per-point dataset as an xarray Dataset on the coordinate ``frequency_hz``;
        each variable's unit in its ``attrs["units"]``, the metadata in the Dataset's attrs."""
        columns, units = run_columns(self.stored)
        return to_xarray(self.stored.frequency_hz, columns, units, self._attributes())

    def _attributes(self) -> dict[str, Any]:

        return {"run": self.name, **asdict(self.stored.metadata)}

    def plot(self):
        """The FRFs (magnitude and phase) with flagged points and the latest stored fit, as a
        matplotlib Figure."""

        analysis = RunAnalysis(self.stored, self.bare, (0.0, 0.0))
        fits = self.fits
        analysis.shown = fits[-1].result if fits else None
        return frf_figure(analysis)

    def __repr__(self) -> str:
        flagged = int(self.stored.flagged().sum()) if self.stored.points else 0
        return (f"<Run {self.name}: {self.describe()}, {self.stored.points} points, "
                f"{self.band_text()}, {flagged} flagged>")

    def _repr_html_(self) -> str:
        m = self.stored.metadata
        rows = [("what", self.describe()), ("points", self.stored.points),
                ("band", self.band_text()), ("level", f"{m.level_m_per_s2:g} m/s² ({m.direction})"),
                ("flagged points", int(self.stored.flagged().sum()) if self.stored.points else 0),
                ("started", m.started), ("fits stored", ", ".join(
                    f"{f.result.source.split()[-1]} {f.model}" for f in self.fits) or "none")]
        body = "".join(f"<tr><th style=\"text-align:left\">{_e(k)}</th><td style=\"text-align:"
                       f"left\">{_e(v)}</td></tr>" for k, v in rows)
        return f"<b>Run {_e(self.name)}</b><table>{body}</table>"


class Fit:
    """A fitted model of one run: parameters with ±, error against the noise, the curves.

    A notebook's view of the package's one fit (:attr:`result`, a
    :class:`viscorig.fitting.FitResult`, made here or read back from the file) beside the run
    it was fitted to; :mod:`viscorig.compare` takes ``fit.result``.
    """

    def __init__(self, run: Run, result: FitResult) -> None:
        self.run = run
        self.result = result
        """The :class:`viscorig.fitting.FitResult`."""

    @property
    def model(self) -> str:
        """Canonical model spec."""
        return self.result.spec

    @property
    def source(self) -> str:
        """Where the fit comes from (``"fitted here"``, ``"stored fit 0002"``)."""
        return self.result.source

    @property
    def rms_error(self) -> float:
        """``sqrt(mean |H_model/H_measured − 1|²)``."""
        return float(self.result.rms_error)

    @property
    def noise_floor(self) -> float:
        """The error a perfect model would reach, from the data alone."""
        return float(self.result.noise_floor)

    @property
    def band_hz(self) -> tuple[float, float]:
        """The band fitted."""
        lo, hi = self.result.band_hz
        return float(lo), float(hi)

    @property
    def parameters(self) -> dict[str, Estimate]:
        """``{name: Estimate(value, stderr, unit)}``; stderr NaN for a parameter held fixed."""
        free = set(self.result.free)
        return {name: Estimate(float(e.value), float(e.stderr) if name in free else math.nan,
                               e.unit)
                for name, e in self.result.parameters.items()}

    def predict(self, frequency_hz) -> dict[str, np.ndarray]:
        """The model's accelerances (m/s²/N) on any frequency grid (Hz)."""
        return self.result.predict(frequency_hz)

    def _columns(self) -> tuple[np.ndarray, dict[str, np.ndarray], dict[str, str]]:
        run = self.run.stored
        lo, hi = self.band_hz
        keep = (run.frequency_hz >= lo) & (run.frequency_hz <= hi)
        f = run.frequency_hz[keep]
        predicted = self.result.predict(f, run.time_s[keep], run.reference_amplitude[keep])
        columns, units = {}, {}
        for frf, measured in (("table", run.accelerance_table),
                              ("support", run.accelerance_support)):
            if frf not in predicted:
                continue
            columns[f"measured_{frf}"] = measured[keep]
            columns[f"model_{frf}"] = predicted[frf]
            with np.errstate(all="ignore"):
                columns[f"residual_{frf}"] = predicted[frf] / measured[keep] - 1.0
            units.update({f"measured_{frf}": "m/s^2/N", f"model_{frf}": "m/s^2/N",
                          f"residual_{frf}": "1"})
        return f, columns, units

    def _attributes(self) -> dict[str, Any]:
        return {"run": self.run.name, "model": self.model, "source": self.source,
                "rms_error": self.rms_error, "noise_floor": self.noise_floor}

    def to_pandas(self):
        """Measured, model and relative residual of each FRF, indexed by ``frequency_hz``
        over the band fitted; units and the fit's figures in ``frame.attrs`` (the parameters
        under ``attrs["parameters"]``, and as a table from :meth:`parameter_table`)."""
        f, columns, units = self._columns()
        frame = to_pandas(f, columns, units, self._attributes())
        frame.attrs["parameters"] = {name: {"value": v, "stderr": e, "unit": u}
                                     for name, (v, e, u) in self.parameters.items()}
        return frame

    def parameter_table(self):
        """The parameters as a DataFrame: ``value``, ``stderr``, ``unit`` by name."""
        pandas = load_pandas()
        rows = {name: {"value": v, "stderr": e, "unit": u}
                for name, (v, e, u) in self.parameters.items()}
        return pandas.DataFrame.from_dict(rows, orient="index").rename_axis("parameter")

    def to_xarray(self):
        """Measured, model and residual on the coordinate ``frequency_hz``; each parameter a
        scalar variable with its ``units`` and ``stderr`` in attrs."""
        f, columns, units = self._columns()
        scalars = {name: (v, {"units": u, "stderr": e})
                   for name, (v, e, u) in self.parameters.items()}
        return to_xarray(f, columns, units, self._attributes(), scalars)

    def __repr__(self) -> str:
        w = words
        shown = [f"{name} = {with_uncertainty(v, e, u)}"
                 for name, (v, e, u) in self.parameters.items() if name in self.result.free][:4]
        more = ", ..." if len(self.result.free) > 4 else ""
        return (f"<Fit {self.run.name} {self.model}: "
                f"{w.error_words(self.rms_error, self.noise_floor)}; {', '.join(shown)}{more}>")

    def _repr_html_(self) -> str:
        w = words
        rows = "".join(
            f"<tr><td style=\"text-align:left\">{_e(name)}</td><td>"
            f"{_e(with_uncertainty(v, e if name in self.result.free else math.nan, u))}</td>"
            f"<td style=\"text-align:left\">{'' if name in self.result.free else 'fixed'}</td>"
            "</tr>" for name, (v, e, u) in self.parameters.items())
        return (f"<b>Fit of {_e(self.run.name)}</b>: <code>{_e(self.model)}</code> "
                f"({_e(self.source)}), "
                f"{_e(w.error_words(self.rms_error, self.noise_floor))}"
                f"<table><thead><tr><th>parameter</th><th>value ± standard error</th><th></th>"
                f"</tr></thead><tbody>{rows}</tbody></table>")


class Diagnosis:
    """Where a model fails, which effect is missing, and (with ``auto``) the ladder climbed."""

    def __init__(self, run: Run, internal, ladder: list | None = None) -> None:
        self.run = run
        self.internal = internal
        """The :class:`viscorig.diagnosis.DiagnosisResult`."""
        self._ladder = ladder

    @property
    def model(self) -> str:
        """Spec of the model diagnosed (the last rung's with ``auto``)."""
        return self.internal.model

    @property
    def rms_error(self) -> float:
        """Its ``rms_error``."""
        return float(self.internal.rms_error)

    @property
    def noise_floor(self) -> float:
        """The noise floor of the data diagnosed."""
        return float(self.internal.noise_floor)

    @property
    def at_noise_floor(self) -> bool:
        """The model is at the noise floor."""
        return bool(self.internal.at_noise_floor)

    @property
    def failures(self) -> list:
        """Bands where the model still fails, worst first."""
        return list(self.internal.failures)

    @property
    def findings(self) -> list:
        """Candidate effects, fitted and tested, best first."""
        return list(self.internal.findings)

    @property
    def ladder(self) -> list[Diagnosis]:
        """Every rung climbed (this diagnosis alone without ``auto``)."""
        steps = self._ladder or [self.internal]
        return [Diagnosis(self.run, step) for step in steps]

    @property
    def fit(self) -> Fit:
        """The fit of the model diagnosed."""

        result = replace(self.internal.fit, source="diagnosed here",
                         noise_floor=self.noise_floor)
        return Fit(self.run, result)

    def with_effect(self, effect: str) -> Diagnosis:
        """This model with one more effect (a term, a finding's term, or a whole spec)."""
        with np.errstate(all="ignore"):
            return Diagnosis(self.run, self.internal.with_effect(effect))

    def auto(self) -> Diagnosis:
        """Climb the ladder from here; the last rung, with ``.ladder``."""
        with np.errstate(all="ignore"):
            steps = self.internal.auto()
        return Diagnosis(self.run, steps[-1], steps)

    def to_json(self) -> dict[str, Any]:
        """The ``diagnose --json`` object."""
        return self.internal.to_json(self._ladder)

    def to_pandas(self):
        """The candidate effects as a DataFrame, best first, with the evidence in words."""
        w = words
        pandas = load_pandas()
        return pandas.DataFrame([
            {"effect": f.effect, "model": f.model, "rms_error": f.rms_error,
             "delta_bic": f.delta_bic, "significant": f.significant,
             "evidence": w.evidence_words(f.delta_bic, f.significant),
             "explanation": f.explanation} for f in self.findings])

    def _climb(self):

        return climb_from(self._ladder or [self.internal], climbed=self._ladder is not None)

    def __repr__(self) -> str:
        w = words
        significant = self.internal.significant
        best = (f"; most likely missing: {significant[0].effect} ({significant[0].model})"
                if significant else "; nothing significant missing")
        rungs = f", {len(self._ladder)} rungs" if self._ladder else ""
        return (f"<Diagnosis {self.run.name} {self.model}{rungs}: "
                f"{w.error_words(self.rms_error, self.noise_floor)}{best}>")

    def _repr_html_(self) -> str:

        climb = self._climb()
        band = (float(self.internal.data.data.frequency_hz.min()),
                float(self.internal.data.data.frequency_hz.max()))
        analysis = RunAnalysis(self.run.stored, False, band, shown=climb.final, climb=climb)
        h = headline(analysis)
        parameters = "".join(f"<li>{_e(p)}</li>" for p in h.parameters)
        return (f"<b>Diagnosis of {_e(self.run.name)}</b>: <code>{_e(h.model)}</code>, "
                f"{_e(h.error)}.<br><i>{_e(h.finding)}</i><ul>{parameters}</ul>"
                f"Still fails: {_e(h.fails)}." + diagnosis_section(analysis, {}))


class Comparison:
    """Changes between two fits, with their standard uncertainties."""

    def __init__(self, before: Fit, after: Fit, changes: list) -> None:
        self.before = before
        self.after = after
        self.changes = changes
        """:class:`viscorig.compare.Change` items."""

    def __getitem__(self, quantity: str):
        return next(c for c in self.changes if c.quantity == quantity)

    def to_pandas(self):
        """One row per quantity: before, after (with stderr), relative change and its stderr."""
        pandas = load_pandas()
        return pandas.DataFrame([
            {"quantity": c.quantity, "unit": c.unit, "before": c.before,
             "before_stderr": c.before_stderr, "after": c.after, "after_stderr": c.after_stderr,
             "relative_change": c.relative, "relative_change_stderr": c.relative_stderr,
             "significant": c.significant} for c in self.changes]).set_index("quantity")

    def __repr__(self) -> str:
        head = ", ".join(f"{c.quantity} {c.percent()}" for c in self.changes[:3])
        more = ", ..." if len(self.changes) > 3 else ""
        return f"<Comparison {self.after.run.name} against {self.before.run.name}: {head}{more}>"

    def _repr_html_(self) -> str:
        rows = "".join(f"<tr><td style=\"text-align:left\">{_e(c.quantity)}</td>"
                       f"<td>{_e(c.percent())}</td><td style=\"text-align:left\">"
                       f"{_e(c.words())}</td></tr>" for c in self.changes)
        basis = "; ".join(self.changes[0].basis) if self.changes else ""
        return (f"<b>{_e(self.after.run.name)} against {_e(self.before.run.name)}</b> "
                f"(<code>{_e(self.before.model)}</code> fits; ± one standard uncertainty: "
                f"{_e(basis)})"
                f"<table><thead><tr><th>quantity</th><th>change</th><th>in words</th></tr>"
                f"</thead><tbody>{rows}</tbody></table>")


def open_campaign(path: str | Path, mode: str = "r") -> Campaign:
    """Open a campaign file for analysis (``mode="a"`` to store fits).

    Raises
    ------
    InputError
        The file is missing, not HDF5, or not a viscorig campaign.
    """

    return Campaign(CampaignFile.open(path, mode))


__all__ = ["Campaign", "Comparison", "Diagnosis", "Fit", "Run", "open_campaign"]
