"""The report's figures, drawn with matplotlib's object API on the Agg canvas (no pyplot, no
display, no global state), each saved as PNG, and as SVG too when asked (a second drawing of
the figure by another renderer: it costs about two thirds of the PNG's time again).
"""

from __future__ import annotations

import functools
import hashlib
import io
import re
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import ParamSpec, TypeVar

import matplotlib
import numpy as np
from matplotlib import ticker
from matplotlib.artist import Artist
from matplotlib.figure import Figure
from matplotlib.patches import Patch

from viscorig.compare import Pair, loss_factor_of, storage_stiffness_of
from viscorig.report.analysis import (
    CampaignAnalysis,
    ModulusCurves,
    RunAnalysis,
    rubbers,
    storage_and_loss,
    term_change,
)
from viscorig.report.parallel import parallel_map
from viscorig.storage import INPUT_OVERLOAD, RunRecord
from viscorig.storage.layout import NAME

FRF_TITLES = {"table": "ẍ_s/F_e (table)", "support": "ẍ_v/F_v (disc)"}
FRF_SHORT = {"table": "table", "support": "disc"}
MEASURED = "#1f4e79"
MODEL = "#c0392b"
FLAGGED = "#e67e22"
BAND = "#f5b7b1"
PRELOAD_STYLES = ("o", "s", "^", "D")
RUBBER_COLOURS = ("#1f77b4", "#2ca02c", "#d62728", "#9467bd", "#8c564b")
DPI = 100
_P = ParamSpec("_P")
_R = TypeVar("_R")


def styled(builder: Callable[_P, _R]) -> Callable[_P, _R]:
    """``builder`` (a function making a figure) run with the report's matplotlib settings.

    - Titles sit at the top of their axes (``axes.titley`` set, not left to matplotlib's
      automatic placement): no figure of the report puts ticks or labels above an axes, and the
      automatic placement measured every y tick label again for each title, about a tenth of
      drawing the report's figures (the pixels are the same).
    - Titles, axis labels, legends and notes are text, not mathtext (:func:`_as_text`).
    """

    @functools.wraps(builder)
    def wrapper(*args: _P.args, **kwargs: _P.kwargs) -> _R:
        with matplotlib.rc_context({"axes.titley": 1.0}):
            figure = builder(*args, **kwargs)
        if isinstance(figure, Figure):
            _as_text(figure)
        return figure

    return wrapper


def figure_stem(kind: str, name: str) -> str:
    """The file stem of the figure ``kind`` (``frf``, ``moduli``...) of ``name`` (a run, a
    specimen, a group of runs): ``kind-name`` where the name is a plain file name (as a run's
    name is, :data:`viscorig.storage.layout.NAME`); else its
    letters and digits with a digest of the whole name, so that a specimen named in a file
    (``soft/25``, ``../x``) writes no figure outside the report's folder and two names never
    share one file."""
    if NAME.fullmatch(name):
        return f"{kind}-{name}"
    plain = re.sub(r"[^A-Za-z0-9_+-]+", "_", name).strip("_")[:40]
    digest = hashlib.sha256(name.encode("utf-8", "surrogatepass")).hexdigest()[:10]
    return f"{kind}-{plain}-{digest}" if plain else f"{kind}-{digest}"


def _as_text(figure: Figure) -> None:
    """Draw the figure's titles, axis labels, legends and notes as they read, never as
    matplotlib's mathtext: a specimen's name or a run's status comes from the file, and one
    holding ``$...$`` stopped the report on anything mathtext cannot parse. Tick labels keep
    mathtext: their formatters write it (and :func:`_log_axes` rewrites it as plain text)."""
    texts = list(figure.texts)
    for legend in [*figure.legends, *(ax.get_legend() for ax in figure.axes)]:
        if legend is not None:
            texts += legend.get_texts()
    for ax in figure.axes:
        texts += [ax.title, ax.xaxis.label, ax.yaxis.label, *ax.texts]
    for text in texts:
        text.set_parse_math(False)


@dataclass(frozen=True)
class SavedFigure:
    """A figure written to disk: its file stem, caption and PNG bytes (for embedding)."""

    stem: str
    caption: str
    png: bytes


_SUPERSCRIPT = str.maketrans("-0123456789", "⁻⁰¹²³⁴⁵⁶⁷⁸⁹")
_MATHTEXT = re.compile(r"^\$\\mathdefault\{(.*)\}\$$")
_POWER = re.compile(r"\^\{(-?\d+)\}")


class _PlainLogFormatter(ticker.LogFormatterSciNotation):
    """Matplotlib's labels of a log axis (the same ticks labelled, ``10⁻²``, ``2×10⁻¹``)
    written in plain text: parsing their mathtext took about an eighth of drawing the report's
    figures."""

    def __call__(self, x: float, pos: int | None = None) -> str:
        label = super().__call__(x, pos)
        match = _MATHTEXT.match(label)
        if match is None:
            return label
        text = _POWER.sub(lambda m: m.group(1).translate(_SUPERSCRIPT),
                          match.group(1).replace("\\times", "×"))
        return label if "\\" in text or "{" in text else text


#: A log axis spanning this many decades or more gets minor ticks at 2 and 5 of each decade
#: only: drawing the other six (tick marks whose markers matplotlib copies one by one) took
#: about a third of drawing a figure with such an axis.
SPARSE_MINOR_DECADES = 2.0


def _log_axes(figure: Figure) -> None:
    """Plain-text labels on every log axis (:class:`_PlainLogFormatter`), and minor ticks at 2
    and 5 only on those spanning :data:`SPARSE_MINOR_DECADES` or more."""
    for axes in figure.axes:
        for axis, limits in ((axes.xaxis, axes.get_xlim), (axes.yaxis, axes.get_ylim)):
            base = getattr(axis.get_transform(), "base", None)
            if base is None:
                continue
            low, high = sorted(limits())
            if low > 0 and np.log10(high / low) >= SPARSE_MINOR_DECADES:
                axis.set_minor_locator(ticker.LogLocator(base, subs=(2.0, 5.0)))
            for formatter, setter in ((axis.get_major_formatter(), axis.set_major_formatter),
                                      (axis.get_minor_formatter(), axis.set_minor_formatter)):
                if type(formatter) is ticker.LogFormatterSciNotation:
                    setter(_PlainLogFormatter(base, labelOnlyBase=formatter.labelOnlyBase,
                                              minor_thresholds=formatter.minor_thresholds))


#: Size (points) of legend and tick-label text set in small type.
SMALL_FONT = 7.0
#: Width of a character of :data:`SMALL_FONT` text, as a share of the font size: DejaVu Sans,
#: matplotlib's font, averages 0.55 to 0.57 on model specs and words (digits 0.64).
CHARACTER_WIDTH = 0.58
#: Height of a line of text, as a share of the font size.
LINE_HEIGHT = 1.3


_BREAKS = re.compile(r"(?<=\+)(?=\S)|(?<=[^+−] )")


def wrapped(text: str, characters: int) -> str:
    """``text`` broken into lines of at most ``characters`` characters where it can be: at its
    spaces (a sign ``+`` or ``−`` stays with the word after it) and after each ``+`` joining the
    terms of a model spec; a single word longer than a line stays whole."""
    pieces = [piece for piece in _BREAKS.split(text) if piece]
    lines: list[str] = []
    line = ""
    for piece in pieces:
        if line and len(line + piece.rstrip()) > characters:
            lines.append(line.rstrip())
            line = piece.lstrip()
        else:
            line += piece
    lines.append(line.rstrip())
    return "\n".join(lines)


def _characters(width_in: float) -> int:
    """Characters of :data:`SMALL_FONT` text that fit in ``width_in`` inches."""
    return max(8, int(width_in * 72 / (CHARACTER_WIDTH * SMALL_FONT)))


def _grow_below(figure: Figure, height_in: float) -> None:
    """Make the figure ``height_in`` inches taller at the bottom, every axes keeping its size
    and place from the top: room for what is drawn below the axes."""
    width, height = figure.get_size_inches()
    params = figure.subplotpars
    top_in, bottom_in = (1 - params.top) * height, params.bottom * height
    figure.set_size_inches(width, height + height_in)
    total = height + height_in
    figure.subplots_adjust(top=1 - top_in / total, bottom=(bottom_in + height_in) / total)


def legend_below(figure: Figure, columns: int = 1) -> None:
    """One legend for the whole figure, below its axes, in ``columns`` columns: every entry of
    every axes once (the first of a label wins), long labels wrapped to their column. The figure
    grows to hold it, so that the legend covers no data and no label, where a legend inside an
    axes hid curves and ran into the axes beside it."""
    entries: dict[str, Artist] = {}
    for axes in figure.axes:
        for handle, label in zip(*axes.get_legend_handles_labels(), strict=True):
            entries.setdefault(label, handle)
    if not entries:
        return
    # the curves first, then what is shaded (a band is drawn first, under the curves)
    ordered = sorted(entries.items(), key=lambda item: isinstance(item[1], Patch))
    labels = [label for label, _ in ordered]
    handles = [handle for _, handle in ordered]
    columns = max(1, min(columns, len(labels)))
    width_in = figure.get_size_inches()[0] * 0.92 / columns - 0.45  # the handle and the gaps
    labels = [wrapped(label, _characters(width_in)) for label in labels]
    rows = -(-len(labels) // columns)
    # matplotlib fills a legend's columns top to bottom: row r holds labels r, r + rows, ...
    lines = sum(max(labels[i].count("\n") + 1 for i in range(r, len(labels), rows))
                for r in range(rows))
    pad_in = 0.08
    _grow_below(figure, lines * LINE_HEIGHT * SMALL_FONT / 72 + rows * 0.05 + 2 * pad_in)
    figure.legend(handles, labels, loc="lower center", ncols=columns, fontsize=SMALL_FONT,
                  frameon=False, bbox_to_anchor=(0.5, pad_in / figure.get_size_inches()[1] / 2),
                  borderaxespad=0.0, columnspacing=1.5, handlelength=1.8)


def save(figure: Figure, folder: Path | None, stem: str, caption: str, *,
         svg: bool = False) -> SavedFigure:
    """Write ``stem.png`` (and ``stem.svg`` with ``svg``) in ``folder`` when given; return the
    PNG bytes."""
    _log_axes(figure)
    buffer = io.BytesIO()
    figure.savefig(buffer, format="png", dpi=DPI)
    png = buffer.getvalue()
    if folder is not None:
        (folder / f"{stem}.png").write_bytes(png)
        if svg:
            figure.savefig(folder / f"{stem}.svg", format="svg")
    return SavedFigure(stem, caption, png)


def _frfs(run: RunRecord) -> list[tuple[str, np.ndarray]]:
    out = [("table", run.accelerance_table)]
    if np.any(np.isfinite(run.accelerance_support)):
        out.append(("support", run.accelerance_support))
    return out


def _shade(axes, failures, frf: str, label: bool) -> None:
    for index, band in enumerate(b for b in failures if b.frf == frf):
        axes.axvspan(*band.band_hz, color=BAND, alpha=0.45, lw=0,
                     label="model fails here" if label and index == 0 else None)


@styled
def frf_figure(analysis: RunAnalysis, *, failures: list | None = None) -> Figure:
    """Measured and model FRFs (magnitude, phase) with failure bands and flagged points."""
    run = analysis.run
    frfs = _frfs(run)
    figure = Figure(figsize=(5.2 * len(frfs), 6.0), layout=None)
    axes = figure.subplots(2, len(frfs), sharex=True, squeeze=False)
    figure.subplots_adjust(left=0.1 if len(frfs) == 2 else 0.16, right=0.98, top=0.9,
                           bottom=0.09, wspace=0.28, hspace=0.08)
    order = np.argsort(run.frequency_hz)
    f = run.frequency_hz[order]
    flagged = run.flagged()[order]
    curve = analysis.shown
    predicted = {}
    if curve is not None and f.size:
        grid = np.linspace(f.min(), f.max(), max(800, 4 * f.size))
        time_s = np.interp(grid, f, run.time_s[order]) if np.all(np.isfinite(run.time_s)) else None
        reference = (np.interp(grid, f, run.reference_amplitude[order])
                     if np.all(np.isfinite(run.reference_amplitude)) else None)
        try:
            predicted = curve.predict(grid, time_s, reference)
        except Exception:  # a stored model needing data this run lacks: show measurement only
            predicted = {}
    for column, (name, values) in enumerate(frfs):
        h = values[order]
        magnitude, phase = axes[0, column], axes[1, column]
        for ax in (magnitude, phase):
            _shade(ax, failures or analysis.failures, name, label=ax is magnitude)
        magnitude.semilogy(f, np.abs(h), "-", lw=0.9, color=MEASURED, label="measured")
        phase.plot(f, np.degrees(np.angle(h)), "-", lw=0.9, color=MEASURED)
        if curve is not None and name in predicted:  # predicted only from a curve
            label = f"{curve.spec} ({curve.source})"
            magnitude.semilogy(grid, np.abs(predicted[name]), "-", lw=1.3, color=MODEL,
                               label=label)
            phase.plot(grid, np.degrees(np.angle(predicted[name])), "-", lw=1.3, color=MODEL)
        if flagged.any():
            magnitude.plot(f[flagged], np.abs(h[flagged]), "x", ms=6, color=FLAGGED,
                           label=f"flagged ({int(flagged.sum())} points)")
            phase.plot(f[flagged], np.degrees(np.angle(h[flagged])), "x", ms=6, color=FLAGGED)
        overloaded = run.flagged(INPUT_OVERLOAD)[order]
        if overloaded.any():
            magnitude.plot(f[overloaded], np.abs(h[overloaded]), "o", mfc="none", ms=7,
                           color="black", label="input overload (not fitted)")
        magnitude.set_title(FRF_TITLES[name])
        magnitude.set_ylabel("|accelerance| [m/s²/N]")
        phase.set_ylabel("phase [°]")
        phase.set_xlabel("frequency [Hz]")
        phase.set_ylim(-185, 185)
        phase.set_yticks([-180, -90, 0, 90, 180])
        for ax in (magnitude, phase):
            ax.grid(True, which="major", alpha=0.3)
    m = run.metadata
    status = "" if m.status == "complete" else f", {m.status}"
    figure.suptitle(f"run {run.name}: {m.specimen}, preload {m.preload_strain:g}, "
                    f"{run.points} points{status}", fontsize=11)
    legend_below(figure, columns=len(frfs))
    return figure


@styled
def residual_figure(analysis: RunAnalysis) -> Figure | None:
    """``|H_model/H_measured − 1|`` against frequency, with the local noise and the floor."""
    curve = analysis.shown
    if not analysis.residuals or curve is None:  # the residuals are the shown curve's
        return None
    count = len(analysis.residuals)
    figure = Figure(figsize=(5.2 * count, 3.2), layout=None)
    axes = figure.subplots(1, count, squeeze=False)[0]
    figure.subplots_adjust(left=0.1 if count == 2 else 0.16, right=0.98, top=0.9, bottom=0.16,
                           wspace=0.25)
    floors = ", ".join(f"{FRF_SHORT[r.frf]} {r.floor:.2g}" for r in analysis.residuals)
    for index, (ax, residual) in enumerate(zip(axes, analysis.residuals, strict=True)):
        _shade(ax, analysis.failures, residual.frf, label=True)
        ax.semilogy(residual.frequency_hz, residual.magnitude, "-", lw=0.8,
                    color=MODEL, label=f"|model/measured − 1|, {curve.spec}")
        ax.semilogy(residual.frequency_hz, residual.noise, "-", lw=1.0, color="grey",
                    label="local noise σ (the run's noise model)")
        ax.axhline(residual.floor, ls="--", lw=1.0, color="black",
                   label=f"noise floor ({floors})" if index == 0 else None)
        ax.set_title(f"residual, {FRF_TITLES[residual.frf]}")
        ax.set_xlabel("frequency [Hz]")
        ax.set_ylabel("relative error")
        ax.grid(True, which="major", alpha=0.3)
    legend_below(figure, columns=count)
    return figure


@styled
def ladder_figure(analysis: RunAnalysis) -> Figure | None:
    """Error against model as effects are added: the ladder climbed, or the first rung's
    candidates (each effect added alone) when the ladder was not climbed."""
    steps = analysis.ladder
    if not steps:
        return None
    figure = Figure(figsize=(7.5, 3.0), layout=None)
    ax = figure.subplots()
    figure.subplots_adjust(left=0.1, right=0.98, top=0.88, bottom=0.04)
    if len(steps) > 1:
        labels = [steps[0].model] + [
            _added(steps[i - 1].model, steps[i].model) for i in range(1, len(steps))]
        errors = [s.rms_error for s in steps]
        colours = [MODEL] * len(steps)
        title = f"run {analysis.name}: error as effects are added (ladder)"
    else:
        found = sorted(analysis.candidates, key=lambda f: f.rms_error)[:8]
        labels = [steps[0].model] + [_added(steps[0].model, f.model) for f in found]
        errors = [steps[0].rms_error] + [f.rms_error for f in found]
        colours = [MODEL] + [MODEL if f.significant else "#aaaaaa" for f in found]
        title = (f"run {analysis.name}: error of {steps[0].model} and with each candidate "
                 "effect (grey: not significant)")
    x = np.arange(len(errors))
    if len(steps) > 1:
        ax.semilogy(x, errors, "-", color=MODEL, lw=1)
    ax.scatter(x, errors, c=colours, zorder=3)
    ax.set_yscale("log")
    ax.axhline(steps[-1].noise_floor, ls="--", color="black",
               label=f"noise floor {steps[-1].noise_floor:.2g}")
    for i, error in enumerate(errors):
        ax.annotate(f"{error:.2g}", (i, error), textcoords="offset points", xytext=(0, 6),
                    ha="center", fontsize=7)
    # each step's label under its point, wrapped to its share of the width; a figure too
    # narrow for the longest word of a label grows wider
    longest = max(len(piece.strip()) for label in labels for piece in _BREAKS.split(label))
    width_in, height_in = figure.get_size_inches()
    span = figure.subplotpars.right - figure.subplotpars.left
    room = max(width_in * span / len(errors), longest * CHARACTER_WIDTH * SMALL_FONT / 72 + 0.1)
    if room * len(errors) > width_in * span:
        figure.set_size_inches(room * len(errors) / span, height_in)
    labels = [wrapped(label, _characters(room - 0.08)) for label in labels]
    ax.set_xticks(x, labels, fontsize=SMALL_FONT)
    ax.set_xlim(-0.5, len(errors) - 0.5)
    lines = max(label.count("\n") + 1 for label in labels)
    _grow_below(figure, lines * LINE_HEIGHT * SMALL_FONT / 72 + 0.1)
    ax.set_ylabel("rms error")
    ax.set_title(title, fontsize=9)
    ax.grid(True, which="major", alpha=0.3)
    legend_below(figure)
    return figure


def _added(before: str, after: str) -> str:
    new, removed = term_change(before, after)
    return " ".join([*(f"+ {t}" for t in new), *(f"− {t}" for t in removed)]) or after


@styled
def moduli_figure(rubber: str, members: list[RunAnalysis], theta_m: float | None) -> Figure:
    """E' (or K') and η against frequency, each preload, like the paper's Figures 10-12; the
    model's curves with their ± one standard uncertainty band."""
    figure = Figure(figsize=(10.4, 3.6), layout=None)
    stiffness_ax, loss_ax = figure.subplots(1, 2, sharex=True)
    figure.subplots_adjust(left=0.08, right=0.98, top=0.88, bottom=0.14, wspace=0.25)
    scale, unit = (1e-6, "E' [MPa]") if theta_m else (1e-3, "K' = Re K* [kN/m]")
    to_modulus = scale / theta_m if theta_m else scale
    for index, member in enumerate(members):
        curves = _moduli(member)
        e_meas, _, eta_meas, _ = storage_and_loss(curves, theta_m)
        colour = RUBBER_COLOURS[index % len(RUBBER_COLOURS)]
        label = f"{member.name} (preload {member.run.metadata.preload_strain:g})"
        marker = PRELOAD_STYLES[index % len(PRELOAD_STYLES)]
        stiffness_ax.plot(curves.frequency_hz, e_meas * scale, marker, ms=2, alpha=0.5,
                          color=colour, label=f"{label}, Eq. 5")
        loss_ax.plot(curves.frequency_hz, eta_meas, marker, ms=2, alpha=0.5, color=colour)
        band = curves.band
        if band is None:
            continue
        storage = band.storage_modulus * to_modulus
        storage_u = band.storage_modulus_stderr * to_modulus
        stiffness_ax.plot(band.frequency_hz, storage, "-", lw=1.5, color=colour,
                          label=f"{label}, {curves.spec} ± 1σ")
        stiffness_ax.fill_between(band.frequency_hz, storage - storage_u, storage + storage_u,
                                  color=colour, alpha=0.25, lw=0)
        loss_ax.plot(band.frequency_hz, band.loss_factor, "-", lw=1.5, color=colour)
        loss_ax.fill_between(band.frequency_hz, band.loss_factor - band.loss_factor_stderr,
                             band.loss_factor + band.loss_factor_stderr, color=colour,
                             alpha=0.25, lw=0)
    stiffness_ax.set_ylabel(unit)
    loss_ax.set_ylabel("loss factor η")
    for ax in (stiffness_ax, loss_ax):
        ax.set_xlabel("frequency [Hz]")
        ax.grid(True, alpha=0.3)
    figure.suptitle(f"{rubber} rubber: estimated properties", fontsize=11)
    legend_below(figure, columns=2)
    return figure


def _moduli(member: RunAnalysis) -> ModulusCurves:
    """A specimen run's K* curves (the modulus figures show only specimen runs)."""
    if member.modulus is None:
        raise ValueError(f"run {member.name} has no K* curves (a bare-table run)")
    return member.modulus


@styled
def preload_figure(groups: dict[str, list[RunAnalysis]]) -> Figure | None:
    """The preload effect per rubber: relative change of K' (= of E') and of η against
    frequency, with the ± one standard uncertainty band of the change
    (:class:`viscorig.compare.Pair`)."""
    pairs = {name: (members[0], members[-1]) for name, members in groups.items()
             if len(members) >= 2 and members[-1].run.metadata.preload_strain
             > members[0].run.metadata.preload_strain
             and members[0].modulus is not None and members[0].modulus.fit is not None
             and members[-1].modulus is not None
             and members[-1].modulus.fit is not None}
    if not pairs:
        return None
    figure = Figure(figsize=(10.4, 3.4), layout=None)
    stiffness_ax, loss_ax = figure.subplots(1, 2, sharex=True)
    figure.subplots_adjust(left=0.08, right=0.98, top=0.88, bottom=0.15, wspace=0.25)
    for index, (name, (none, loaded)) in enumerate(pairs.items()):
        before, after = _moduli(none), _moduli(loaded)
        lo = max(before.frequency_hz.min(), after.frequency_hz.min())
        hi = min(before.frequency_hz.max(), after.frequency_hz.max())
        f = np.linspace(lo, hi, 61)
        assert before.fit is not None and after.fit is not None  # kept by the filter above
        pair = Pair(before.fit, after.fit)
        colour = RUBBER_COLOURS[index % len(RUBBER_COLOURS)]
        label = f"{name}: {loaded.name} vs {none.name}"
        for ax, part in ((stiffness_ax, storage_stiffness_of), (loss_ax, loss_factor_of)):
            change, stderr = pair.relative(part(pair.a.model, f), part(pair.b.model, f))
            ax.plot(f, 100 * change, "-", color=colour, label=label)
            ax.fill_between(f, 100 * (change - stderr), 100 * (change + stderr), color=colour,
                            alpha=0.25, lw=0)
    stiffness_ax.set_ylabel("change of K' (= change of E') [%]")
    loss_ax.set_ylabel("change of η [%]")
    for ax in (stiffness_ax, loss_ax):
        ax.set_xlabel("frequency [Hz]")
        ax.grid(True, alpha=0.3)
        ax.axhline(0, color="black", lw=0.6)
    legend_below(figure, columns=len(pairs))
    figure.suptitle("preload effect (K* of the models shown, ± one standard uncertainty)",
                    fontsize=11)
    return figure


def run_figures(run: RunAnalysis, folder: Path | None, svg: bool = False
                ) -> dict[str, SavedFigure]:
    """The figures of one run (FRFs, residual, ladder), by stem (``svg`` as in :func:`save`).

    A point no analyser measures (the fits refuse it, the page names it) stretches a log axis
    past what matplotlib's tick arithmetic holds: it is drawn all the same, without numpy's
    overflow warnings.
    """
    with np.errstate(over="ignore", invalid="ignore"):
        return _run_figures(run, folder, svg)


def _run_figures(run: RunAnalysis, folder: Path | None, svg: bool) -> dict[str, SavedFigure]:
    saved: dict[str, SavedFigure] = {}
    if not run.run.points:
        return saved
    stems = {kind: figure_stem(kind, run.name) for kind in ("frf", "residual", "ladder")}
    saved[stems["frf"]] = save(
        frf_figure(run), folder, stems["frf"],
        f"Run {run.name}: measured FRFs and the model shown; shaded: bands where that "
        "model still fails (diagnosis); crosses: flagged points.", svg=svg)
    residual = residual_figure(run)
    if residual is not None:
        saved[stems["residual"]] = save(
            residual, folder, stems["residual"],
            f"Run {run.name}: relative residual of the model shown, with the local noise "
            "estimated from the data and the noise floor.", svg=svg)
    ladder = ladder_figure(run)
    if ladder is not None:
        saved[stems["ladder"]] = save(
            ladder, folder, stems["ladder"],
            f"Run {run.name}: diagnosis ladder, rms error as the most significant missing "
            "effect is added, step by step (or, without the ladder, each candidate alone).",
            svg=svg)
    return saved


def campaign_figures(analysis: CampaignAnalysis, folder: Path | None,
                     jobs: int = 1, svg: bool = False) -> dict[str, SavedFigure]:
    """Every figure of the report, by stem (``frf-soft-0``, ``moduli-soft``, ``preload``);
    ``svg`` as in :func:`save`.

    The runs' figures are drawn in ``jobs`` processes at once.
    """
    saved: dict[str, SavedFigure] = {}
    for figures in parallel_map(run_figures, [(run, folder, svg) for run in analysis.runs],
                                jobs):
        saved.update(figures)
    groups = rubbers(analysis)
    for name, members in groups.items():
        stem = figure_stem("moduli", name)
        saved[stem] = save(
            moduli_figure(name, members, analysis.theta_m), folder, stem,
            f"{name}: storage {'modulus' if analysis.theta_m else 'stiffness'} and loss factor "
            "against frequency, Eq. (5) estimates (points) and the K* of the models shown "
            "(lines).", svg=svg)
    preload = preload_figure(groups)
    if preload is not None:
        saved["preload"] = save(preload, folder, "preload",
                                "Preload effect per rubber, from the K* of the models shown.",
                                svg=svg)
    return saved
