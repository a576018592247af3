"""The report's section on materials: the master curve of every DMA run of the campaign, and of
every specimen measured by rig runs at two or more temperatures.

Per material: the master curve with the ± of each point's shift, the Prony series through it;
the shift factors with their ± and the fitted WLF and Arrhenius; the fit's residuals
``ln(model/measured)`` of E' and E'' against reduced frequency; and in words the superposition
verdict, the points the Kramers-Kronig check names and the figures of the fit. A material that
cannot be built (what is missing) is one sentence instead.
"""

from __future__ import annotations

import html
import logging
import math
from collections import Counter
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from matplotlib.figure import Figure

from viscorig.errors import InputError
from viscorig.materials.dmastore import dma_run_names, dma_specimen
from viscorig.materials.master import MasterCurve
from viscorig.materials.shift import temperature_groups
from viscorig.materials.sources import master_curve
from viscorig.report.figures import SavedFigure, figure_stem, legend_below, save, styled
from viscorig.storage import CampaignFile

log = logging.getLogger(__name__)


@dataclass(frozen=True)
class Material:
    """One material of the campaign: its runs, and its master curve or why there is none."""

    runs: tuple[str, ...]
    master: MasterCurve | None
    problem: str = ""


def _number(value: object, missing: float) -> float:
    """A numeric run attribute as a float (0 is a value: a run at 0 °C has a temperature);
    ``missing`` when it is absent or not a number."""
    if isinstance(value, (int, float, np.number)) and not isinstance(value, bool):
        return float(value)
    return missing


def _one_level_per_temperature(
    members: list[tuple[float, float, str]],
) -> list[tuple[float, float, str]]:
    """The runs ``(temperature, level, name)`` at the level nearest (in ratio) the most common
    one, at each temperature (:func:`~viscorig.materials.shift.temperature_groups`); every run
    where levels are unknown."""
    levels = Counter(level for _, level, _ in members if level > 0)
    usual = levels.most_common(1)[0][0] if levels else math.nan

    def distance(level: float) -> float:
        return abs(math.log(level / usual)) if level > 0 and usual > 0 else math.inf

    at: dict[int, list[tuple[float, float, str]]] = {}
    groups = temperature_groups([temperature for temperature, _, _ in members])
    for group, member in zip(groups.tolist(), members, strict=True):
        at.setdefault(group, []).append(member)
    kept = []
    for runs in at.values():
        nearest = min(distance(level) for _, level, _ in runs)
        kept += [run for run in runs if distance(run[1]) == nearest]
    return kept


def candidate_groups(campaign: CampaignFile) -> list[tuple[str, ...]]:
    """Each DMA run alone, or with the other DMA runs of its specimen (imported with
    ``--specimen``); rig runs of one specimen and preload at two or more temperatures.

    At a temperature where the specimen was run at several vibration levels (strain steps, which
    measure the amplitude dependence, not the temperature's), only the runs at the level nearest
    the group's most common one join: a master curve holds one amplitude per temperature."""
    groups: list[tuple[str, ...]] = []
    dma_by_specimen: dict[str, list[str]] = {}
    for name in dma_run_names(campaign):
        try:
            specimen = dma_specimen(campaign, name)
        except InputError as error:  # the run stands alone; its own reading says what is wrong
            log.warning("%s; DMA run %s taken alone", error, name)
            specimen = None
        if specimen is None:
            groups.append((name,))
        else:
            dma_by_specimen.setdefault(specimen, []).append(name)
    groups += [tuple(names) for names in dma_by_specimen.values()]
    by_specimen: dict[tuple[str, float], list[tuple[float, float, str]]] = {}
    for name in campaign.run_names:
        attributes = campaign.run_attributes(name)
        specimen = str(attributes.get("specimen", ""))
        temperature = _number(attributes.get("temperature_c"), math.nan)
        if specimen.lower() in ("none", "") or not math.isfinite(temperature):
            continue
        key = (specimen, round(_number(attributes.get("preload_strain"), 0.0), 4))
        level = _number(attributes.get("level_m_per_s2"), math.nan)
        by_specimen.setdefault(key, []).append((temperature, level, name))
    for members in by_specimen.values():
        kept = _one_level_per_temperature(members)
        if np.ptp(temperature_groups([temperature for temperature, _, _ in kept])) >= 1:
            groups.append(tuple(name for _, _, name in sorted(kept)))
    return groups


def analyse_materials(campaign: CampaignFile) -> list[Material]:
    """The master curve of every candidate group (see :func:`candidate_groups`)."""
    out = []
    for runs in candidate_groups(campaign):
        try:
            with np.errstate(all="ignore"):
                master = master_curve(campaign, list(runs))
            out.append(Material(runs, master))
        except InputError as error:
            out.append(Material(runs, None, str(error)))
    return out


@styled
def master_figure(master: MasterCurve) -> Figure:
    """Master curve with the ± of each point's shift; shift factors with WLF and Arrhenius."""
    table = master.table
    m = table.modulus
    figure = Figure(figsize=(11, 3.8), layout=None)
    left, right = figure.subplots(1, 2)
    figure.subplots_adjust(left=0.07, right=0.98, top=0.9, bottom=0.15, wspace=0.22)
    lookup = dict(zip(master.shifts.sets.tolist(), master.log10_at_stderr, strict=True))
    spread = np.array([lookup[s] for s in table.set_index.tolist()])
    fr = master.reduced_frequency_hz
    band = np.vstack([fr * (1 - 10 ** -spread), fr * (10**spread - 1)])
    left.errorbar(fr, table.storage_pa, xerr=band, fmt="o", ms=3, color="#1f4e79", alpha=0.6,
                  label=f"{m}' measured (± shift)")
    left.errorbar(fr, table.loss_pa, xerr=band, fmt="s", ms=3, color="#c0392b", alpha=0.6,
                  label=f"{m}'' measured (± shift)")
    grid = np.logspace(np.log10(fr.min()) - 0.3, np.log10(fr.max()) + 0.3, 400)
    model = master.prony.complex_modulus(2 * np.pi * grid)
    left.loglog(grid, model.real, "-", color="black", lw=1,
                label=f"Prony series, {master.prony.terms} terms")
    left.loglog(grid, model.imag, "-", color="black", lw=1)
    left.set_xlabel(f"reduced frequency f·aT [Hz] at {master.reference_temperature_c:.1f} °C")
    left.set_ylabel(f"{m}', {m}'' [Pa]")
    left.set_title("master curve")
    left.grid(True, which="major", alpha=0.3)
    right.errorbar(master.temperature_c, master.log10_at, yerr=master.log10_at_stderr,
                   fmt="o", color="black", capsize=3, ms=4, label="log10 aT ± stderr")
    t = np.linspace(master.temperature_c.min(), master.temperature_c.max(), 200)
    for function in master.shift_functions:
        chi = function.reduced_chi2
        right.plot(t, function(t), "-", lw=1,
                   label=f"{function.kind}" + ("" if math.isnan(chi) else f", χ²/dof {chi:.2g}"))
    right.set_xlabel("temperature [°C]")
    right.set_ylabel("log10 aT")
    right.set_title("shift factors")
    right.grid(True, alpha=0.3)
    legend_below(figure, columns=2)
    return figure


@styled
def master_residual_figure(master: MasterCurve) -> Figure:
    """``ln(model/measured)`` of both moduli against reduced frequency, with the scatter."""
    table = master.table
    fr = master.reduced_frequency_hz
    model = master.prony.complex_modulus(2 * np.pi * fr)
    figure = Figure(figsize=(11, 2.8), layout=None)
    ax = figure.subplots()
    figure.subplots_adjust(left=0.07, right=0.98, top=0.88, bottom=0.2)
    ax.semilogx(fr, np.log(model.real / table.storage_pa), "o", ms=3, color="#1f4e79",
                label="storage")
    ax.semilogx(fr, np.log(model.imag / table.loss_pa), "s", ms=3, color="#c0392b",
                label="loss")
    for value, colour in ((master.shifts.storage_scatter, "#1f4e79"),
                          (master.shifts.loss_scatter, "#c0392b")):
        ax.axhspan(-value, value, color=colour, alpha=0.08)
    ax.axhline(0, color="black", lw=0.8)
    ax.set_xlabel("reduced frequency f·aT [Hz]")
    ax.set_ylabel("ln(model/measured)")
    ax.set_title("Prony series residuals (bands: the data's scatter about one smooth curve)")
    legend_below(figure, columns=2)
    return figure


def material_figures(materials: list[Material], folder: Path | None, svg: bool = False
                     ) -> dict[str, SavedFigure]:
    """Every material's two figures, saved as PNG (and SVG with ``svg``)."""
    figures = {}
    for material in materials:
        if material.master is None:
            continue
        stem = figure_stem("material", "-".join(material.runs))
        figures[f"{stem}-master"] = save(master_figure(material.master), folder,
                                         f"{stem}-master", "Master curve and shift factors.",
                                         svg=svg)
        figures[f"{stem}-residuals"] = save(master_residual_figure(material.master), folder,
                                            f"{stem}-residuals",
                                            "Residuals of the Prony series.", svg=svg)
    return figures


def material_section(materials: list[Material], figures: dict[str, SavedFigure],
                     figure_html) -> str:
    """The section's HTML (``figure_html`` renders one saved figure)."""
    if not materials:
        return ""
    parts = ['<h2 id="materials">Materials over temperature and frequency</h2>']
    for material in materials:
        names = ", ".join(material.runs)
        parts.append(f"<h3>{html.escape(names)}</h3>")
        if material.master is None:
            parts.append(f'<p class="note">No master curve: {html.escape(material.problem)}</p>')
            continue
        master = material.master
        fit = master.prony_fit
        best = master.shift_function
        words = [f"{master.temperature_c.size} temperatures, reference "
                 f"{master.reference_temperature_c:.1f} °C.",
                 master.superposition.verdict[0].upper() + master.superposition.verdict[1:] + "."]
        if master.vertical_verdict():
            words.append(master.vertical_verdict()[0].upper() + master.vertical_verdict()[1:]
                         + " (viscorig master).")
        if best is not None:
            values = best.parameters_text()
            fits = "describes" if best.to_json()["describes_shifts"] else "does not describe"
            words.append(f"Shift function: {best.kind} ({values}); it {fits} the shift factors "
                         "within their errors.")
        flagged = master.flagged_points()
        words.append(f"Kramers-Kronig: {len(flagged)} point(s) named" + (
            ": " + "; ".join(f"{p['modulus']} at {p['temperature_c']:.1f} °C, "
                             f"{p['frequency_hz']:.3g} Hz" for p in flagged[:5])
            if flagged else ", every point consistent with a linear material") + ".")
        words.append(f"Prony series of {master.prony.terms} terms: rms ln error storage "
                     f"{fit.storage_rms_log_error:.3f}, loss {fit.loss_rms_log_error:.3f} "
                     f"({master.scatter_text()}); fractional model: "
                     f"{master.fractional_fit.storage_rms_log_error:.3f}, "
                     f"{master.fractional_fit.loss_rms_log_error:.3f}.")
        parts.append("<p>" + html.escape(" ".join(words)) + "</p>")
        stem = figure_stem("material", "-".join(material.runs))
        parts.append(figure_html(figures.get(f"{stem}-master")))
        parts.append(figure_html(figures.get(f"{stem}-residuals")))
    return "\n".join(parts)
