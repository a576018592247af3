"""The report as one self-contained HTML page: inline CSS, figures as base64 PNG, no script,
nothing fetched from anywhere.

The answer comes first: one row per run with the model reached, its error against the noise,
the main parameters with their ±, where it still fails and the finding in one sentence; then
what preload changed, with its ±. The paper's tables, the E' and η figures and each run's
details (figures, ladder, candidates) follow. Statistics are said in words; their numbers are
in ``<details>`` elements a reader opens on request.
"""

from __future__ import annotations

import base64
import html
import math
from datetime import UTC, datetime

from viscorig.compare import compare_fits, kstar_changes
from viscorig.identify import Variation, preload_variations
from viscorig.numbers import with_uncertainty
from viscorig.paper import (
    PAPER_TABLE_1,
    PAPER_TABLE_2,
    PAPER_TABLE_PARAMETERS,
    consistency_notes,
    paper_variation,
)
from viscorig.report.analysis import (
    CampaignAnalysis,
    FindingSummary,
    RunAnalysis,
    preload_pairs,
    rubbers,
)
from viscorig.report.figures import SavedFigure, figure_stem
from viscorig.report.headline import FRF_WORDS, headline
from viscorig.report.words import error_words, evidence_words
from viscorig.storage import FLAG_NAMES, count_flags
from viscorig.storage.journal import JournalEntry
from viscorig.version import __version__

STYLE = """
body { font-family: "DejaVu Sans", Arial, sans-serif; margin: .8em auto; max-width: 1250px;
       color: #222; line-height: 1.35; padding: 0 1em; }
h1 { font-size: 1.35em; border-bottom: 2px solid #1f4e79; padding-bottom: .15em;
     margin: .2em 0 .3em; }
h2 { font-size: 1.2em; color: #1f4e79; margin-top: 1.6em; border-bottom: 1px solid #ccc; }
h3 { font-size: 1.05em; margin-top: 1.2em; }
p.lead { margin: .2em 0 .5em; font-size: .92em; color: #444; }
table { border-collapse: collapse; margin: .5em 0; font-size: .9em; }
th, td { border: 1px solid #bbb; padding: .2em .5em; text-align: right; vertical-align: top; }
th { background: #e8eef5; }
td.text, th.text { text-align: left; }
tr.paper td { color: #555; font-style: italic; }
table.glance { font-size: .8em; width: 100%; }
table.glance td { text-align: left; }
table.glance { table-layout: fixed; }
table.glance code { font-size: .92em; background: none; }
ul.changes { margin: .2em 0; padding-left: 1.2em; font-size: .9em; }
figure { margin: .8em 0 1.4em; }
figure img { max-width: 100%; border: 1px solid #ddd; }
figcaption { font-size: .85em; color: #444; }
details { margin: .3em 0 .8em; font-size: .9em; }
summary { cursor: pointer; color: #1f4e79; }
.note { background: #fff8e1; border-left: 4px solid #f0b400; padding: .4em .8em; margin: .5em 0; }
.ok { color: #1e7b34; font-weight: bold; }
.bad { color: #b03a2e; font-weight: bold; }
.finding { font-style: italic; }
nav ul { columns: 4; font-size: .85em; margin: .3em 0; }
code { background: #f2f2f2; padding: 0 .2em; }
"""


def _e(text: object) -> str:
    return html.escape(str(text))


def _num(value: float, digits: str = ".4g") -> str:
    return "–" if value is None or not math.isfinite(value) else format(value, digits)


def figure_html(saved: SavedFigure | None) -> str:
    """One saved figure as an ``<figure>`` with the PNG inline."""
    return _figure(saved)


def _figure(saved: SavedFigure | None) -> str:
    if saved is None:
        return ""
    data = base64.b64encode(saved.png).decode("ascii")
    return (f'<figure><img alt="{_e(saved.caption)}" src="data:image/png;base64,{data}">'
            f'<figcaption>{_e(saved.caption)} Files: <code>{_e(saved.stem)}.png</code>, '
            f'<code>{_e(saved.stem)}.svg</code>.</figcaption></figure>')


def _table(header: list[str], rows: list[list[str]], text_columns: int = 1,
           classes: list[str] | None = None, text_last: bool = False, css: str = "") -> str:
    def text(i: int) -> bool:
        return i < text_columns or (text_last and i == len(header) - 1)

    head = "".join(f'<th class="text">{_e(h)}</th>' if text(i) else f"<th>{_e(h)}</th>"
                   for i, h in enumerate(header))
    body = []
    for index, row in enumerate(rows):
        cells = "".join(f'<td class="text">{c}</td>' if text(i) else f"<td>{c}</td>"
                        for i, c in enumerate(row))
        kind = f' class="{classes[index]}"' if classes and classes[index] else ""
        body.append(f"<tr{kind}>{cells}</tr>")
    table_class = f' class="{css}"' if css else ""
    return (f"<table{table_class}><thead><tr>{head}</tr></thead>"
            f"<tbody>{''.join(body)}</tbody></table>")


def _flags(run) -> str:
    counts = {flag: n for flag, n in count_flags(run.flags).items() if n}
    if not counts:
        return "0"
    return _e(f"{int(run.flagged().sum())} (" + ", ".join(
        f"{FLAG_NAMES[flag]} {n}" for flag, n in counts.items()) + ")")


def _verdict(rms_error: float, noise_floor: float) -> str:
    words = error_words(rms_error, noise_floor)
    css = "ok" if words.startswith("at the noise floor") else "bad"
    return f'<span class="{css}">{_e(words)}</span>'


# -- the answer first ---------------------------------------------------------------------------


def _spec(spec: str) -> str:
    """A model spec that may wrap after each ``+``."""
    return "<code>" + "+<wbr>".join(_e(part) for part in spec.split("+")) + "</code>"


GLANCE_COLUMNS = (("run", 11), ("model reached", 15), ("error", 9),
                  ("main parameters (± one standard error)", 22), ("still fails", 18),
                  ("finding", 25))


def glance(analysis: CampaignAnalysis) -> str:
    """One row per run: model reached, error, parameters ±, where it fails, the finding."""
    rows = []
    for run in analysis.runs:
        h = headline(run)
        error = _verdict(run.shown.rms_error, run.shown.noise_floor) if run.shown else "–"
        parameters = "<br>".join(_e(p) for p in h.parameters) or "–"
        cells = [f'<a href="#run-{_e(run.name)}"><b>{_e(run.name)}</b></a><br>{_e(h.what)}',
                 _spec(h.model) if h.model else "–", error, parameters, _e(h.fails),
                 f'<span class="finding">{_e(h.finding)}</span>']
        rows.append("<tr>" + "".join(f"<td>{cell}</td>" for cell in cells) + "</tr>")
    columns = "".join(f'<col style="width:{width}%">' for _, width in GLANCE_COLUMNS)
    head = "".join(f"<th class=\"text\">{_e(name)}</th>" for name, _ in GLANCE_COLUMNS)
    return (f'<table class="glance"><colgroup>{columns}</colgroup><thead><tr>{head}</tr>'
            f"</thead><tbody>{''.join(rows)}</tbody></table>")


def _pair_changes(base: RunAnalysis, other: RunAnalysis, band: tuple[float, float]):
    """(Table 1 Voigt changes, changes of the models reached) of one preload pair."""
    voigt = []
    if base.summary is not None and other.summary is not None:
        voigt = compare_fits(base.summary.fit, other.summary.fit, ["K_v", "C_v"])
    reached = []
    if (base.shown is not None and other.shown is not None and base.shown.has_disc
            and other.shown.has_disc and base.climb is not None and other.climb is not None):
        lo, hi = band
        try:
            reached = kstar_changes(base.shown, other.shown, [lo, round((lo + hi) / 2), hi])
        except (ValueError, ArithmeticError, KeyError):
            reached = []
    return voigt, reached


def _paper_change(base: str, other: str, name: str) -> str:
    """The paper's own change of ``name`` from ``base`` to ``other`` ("" when not its runs)."""
    return _paper_percent(paper_variation(other, base), name)


def preload_summary(analysis: CampaignAnalysis) -> str:
    """What preload changed, one line per pair, with the ± of the fits."""
    items = []
    for base, other in preload_pairs(analysis):
        voigt, reached = _pair_changes(base, other, other.band_hz)
        if not voigt and not reached:
            continue
        m0, m1 = base.run.metadata, other.run.metadata
        parts = []
        for change in voigt:
            paper = _paper_change(base.name, other.name, change.quantity)
            parts.append(f"{change.quantity} {change.percent()}"
                         + (f" (paper {paper})" if paper else ""))
        stiff = [c for c in reached if c.quantity.startswith("K'")]
        stiff = [stiff[0], stiff[-1]] if len(stiff) > 2 else stiff
        if stiff and base.shown is not None and other.shown is not None:  # reached needs both
            same = base.shown.spec == other.shown.spec
            parts.append(("K′ of the model reached " if same else
                          "K′ of the models reached (not the same model in both runs) ")
                         + ", ".join(
                f"{c.percent()} at {c.quantity.split(' at ')[1]}" for c in stiff))
        level = ("" if abs(m1.level_m_per_s2 / m0.level_m_per_s2 - 1) < 0.05 else
                 f" (measured at {m1.level_m_per_s2:.3g} against {m0.level_m_per_s2:.3g} m/s²)")
        items.append(f"<li><b>{_e(m1.specimen)}</b>, preload {m1.preload_strain:g} "
                     f"({_e(other.name)} against {_e(base.name)}){_e(level)}: "
                     f"{_e('; '.join(parts))}.</li>")
    if not items:
        return ""
    return ("<p class=\"lead\"><b>What preload changed</b> (Table 1 Voigt fits and the models "
            "reached; ± one standard uncertainty of the change, the table and the misfit the "
            "two runs share counted once; <a href=\"#preload\">details</a>):</p>"
            f"<ul class=\"changes\">{''.join(items)}</ul>")


def preload_section(analysis: CampaignAnalysis) -> str:
    """Every change a preload pair shows, with the paper's where it has one."""
    parts, bases = [], {}
    for base, other in preload_pairs(analysis):
        voigt, reached = _pair_changes(base, other, other.band_hz)
        rows = []
        for change in voigt:
            rows.append([f"{_e(change.quantity)} (Table 1 Voigt)", _e(change.percent()),
                         _e(_paper_change(base.name, other.name, change.quantity) or "–"),
                         _e(change.words())])
        for change in reached:
            rows.append([f"{_e(change.quantity)} (model reached)", _e(change.percent()), "–",
                         _e(change.words())])
        if rows:
            parts.append(f"<h3>{_e(other.name)} against {_e(base.name)}</h3>")
            parts.append(_table(["quantity", "change", "paper", "in words"], rows,
                                text_columns=1, text_last=True))
            for kind, changes in (("Table 1 Voigt fits", voigt), ("models reached", reached)):
                if changes:
                    bases[f"{other.name} against {base.name}, {kind}"] = changes[0].basis
    if not parts:
        return ""
    how = "".join(f"<li>{_e(pair)}: {_e('; '.join(basis))}</li>" for pair, basis in bases.items())
    return ("<p>Each change is <i>after/before − 1</i>; its ± is one standard uncertainty, "
            "propagated to first order from both fits' covariances (<code>viscorig.compare"
            "</code>): a table both fits inherited from the same bare-table run is counted "
            "once, and where both runs were measured at the same frequencies their residuals "
            "are paired point by point, so a misfit the same model shows in both runs does not "
            "count as an uncertainty of the change; fits known to be no better than "
            "independent are said to be taken as independent. A change is called a change "
            "beyond twice its ±.</p>"
            f"<ul class=\"changes\">{how}</ul>" + "".join(parts))


# -- the paper's tables -------------------------------------------------------------------------


def _pm(value: float, stderr: float, unit: str = "") -> str:
    return _e(with_uncertainty(value, stderr, unit))


def tables(analysis: CampaignAnalysis) -> str:
    """The table suspension, Table 1 and Table 2, beside the paper's values for its runs: the
    numbers ``viscorig summary`` prints (the same fits, the same propagation, the same
    preload variations)."""
    parts = []
    summaries = [r.summary for r in analysis.runs if r.summary is not None]
    paper = any(s.run in PAPER_TABLE_1 for s in summaries)
    if analysis.table is not None:
        t = analysis.table
        known = t.known
        rows = []
        for name, unit in (("M_s", "kg"), ("K_s", "N/m"), ("C_s", "N·s/m")):
            stderr = known.stderr(name)
            row = [name, _pm(t.values[name], math.nan if stderr is None else stderr, unit)
                   + ("" if stderr is not None else " (given, no uncertainty)")]
            if paper:
                row.append(_num(PAPER_TABLE_PARAMETERS[name], "g") + f" {unit}")
            rows.append(row)
        parts.append(f"<h3>Table suspension (from {_e(t.source)})</h3>")
        parts.append(_table(["parameter", "this campaign"] + (["paper"] if paper else []),
                            rows, text_columns=1))
    specimen = [s for s in summaries if not s.bare]
    if specimen:
        variations = {v.run: v for v in preload_variations(summaries)}
        parts.append("<h3>Table 1: Voigt fit of X_s/F_e, table fixed "
                     f"({analysis.band_hz[0]:g}–{analysis.band_hz[1]:g} Hz)</h3>")
        rows, classes = [], []
        for s in specimen:
            p = s.fit.parameters
            variation = variations.get(s.run)
            error = error_words(s.fit.rms_error, s.fit.noise_floor)
            if not s.covers(analysis.band_hz):
                error += (f"; fitted over {s.fit.band_hz[0]:g}–{s.fit.band_hz[1]:g} Hz only, "
                          "where the run has points: not comparable with the others")
            rows.append([_e(s.run), _pm(p["K_v"].value, p["K_v"].stderr),
                         _variation(variation, "K_v"), _pm(p["C_v"].value, p["C_v"].stderr),
                         _variation(variation, "C_v"), _pm(p["M_v"].value, p["M_v"].stderr),
                         _e(error)])
            classes.append("")
            if s.run in PAPER_TABLE_1:
                pk, pc = PAPER_TABLE_1[s.run]
                published = paper_variation(s.run, variation.base) if variation else None
                rows.append([f"paper {_e(s.run)}", _num(pk, ".8g"),
                             _paper_percent(published, "K_v"), _num(pc, ".5g"),
                             _paper_percent(published, "C_v"), "–", "–"])
                classes.append("paper")
        parts.append(_table(["run", "K_v [N/m]", "variation", "C_v [N·s/m]", "variation",
                             "M_v [kg]", "error"], rows, classes=classes, text_last=True))
        parts.append("<h3>Table 2: natural frequency, damping factor, half-power bandwidth</h3>")
        rows, classes = [], []
        for s in specimen:
            if s.system_uncertain is None:
                continue
            sy, me, variation = s.system_uncertain, s.measured, variations.get(s.run)
            rows.append([_e(s.run), _pm(sy["f_r"].value, sy["f_r"].stderr, "Hz"),
                         _variation(variation, "f_r"), _pm(sy["xi"].value, sy["xi"].stderr),
                         _variation(variation, "xi"), _pm(sy["B_r"].value, sy["B_r"].stderr, "Hz"),
                         _variation(variation, "B_r"), _num(me.peak_hz, ".2f"),
                         _num(me.bandwidth_hz, ".3f")])
            classes.append("")
            if s.run in PAPER_TABLE_2:
                f_r, xi, b_r = PAPER_TABLE_2[s.run]
                published = paper_variation(s.run, variation.base) if variation else None
                rows.append([f"paper {_e(s.run)}", _num(f_r, ".2f"),
                             _paper_percent(published, "f_r"), _num(xi, ".3f"),
                             _paper_percent(published, "xi"), _num(b_r, ".3f"),
                             _paper_percent(published, "B_r"), "–", "–"])
                classes.append("paper")
        parts.append(_table(["run", "f_r", "variation", "ξ", "variation", "B_r = 2ξf_r",
                             "variation", "peak measured [Hz]", "B_r measured [Hz]"], rows,
                            classes=classes))
        basis = next((v.basis for v in variations.values()), ())
        parts.append("<p>f_r, ξ and B_r follow from the Voigt parameters "
                     "(f_r = √((K_s+K_v)/(M_s+M_v))/2π, ξ = (C_s+C_v)/(2√((K_s+K_v)(M_s+M_v)))), "
                     "their ± propagated from the fit's covariance, the table's included; "
                     "the measured columns are read off |X_s/F_e| directly. Variations: "
                     "against the same specimen without preload"
                     + (f" ({_e('; '.join(basis))})" if basis else "")
                     + ". A Voigt model is far from the noise on these rubbers; the models "
                     "reached are in the runs' sections.</p>")
    if paper:
        notes = "".join(f"<li>{_e(note)}</li>" for note in consistency_notes())
        parts.append(f"<div class=\"note\"><b>On the paper's numbers</b><ul>{notes}</ul></div>")
    return "\n".join(parts)


def _variation(variation: Variation | None, name: str) -> str:
    if variation is None or name not in variation.changes:
        return ""
    return _e(variation.changes[name].percent())


def _paper_percent(published: dict[str, float] | None, name: str) -> str:
    return "" if published is None else f"{published[name]:+.2f} %"


# -- one run ------------------------------------------------------------------------------------


def parameter_table(run: RunAnalysis) -> str:
    """Every parameter of the model shown, with its ± (or where a fixed value came from)."""
    shown = run.shown
    if shown is None:
        return ""
    rows = []
    for name, (value, stderr, unit) in shown.parameters.items():
        fixed = name not in shown.free
        where = "fixed, from the table run" if fixed and name in ("M_s", "K_s", "C_s") else (
            "fixed" if fixed else "")
        rows.append([_e(name), _e(with_uncertainty(value, math.nan if fixed else stderr, unit)),
                     _e(where)])
    return _table(["parameter", "value ± standard error", ""], rows, text_columns=1,
                  text_last=True)


def _candidate_rows(candidates: list[FindingSummary]) -> tuple[list[list[str]], list[list[str]]]:
    words, numbers = [], []
    for c in candidates:
        evidence = evidence_words(c.delta_bic, c.significant)
        said = c.explanation if c.significant else (
            f"Adding {c.term} lowers the error to {c.rms_error:.2g}: {evidence}.")
        words.append([_e(c.effect.replace("_", " ")), f"<code>{_e(c.model)}</code>",
                      _e(evidence), _e(said)])
        numbers.append([_e(c.effect), f"<code>{_e(c.model)}</code>", _num(c.rms_error, ".3g"),
                        _num(c.delta_bic, ".4g"), "yes" if c.significant else "no"])
    return words, numbers


def _rung_change(rung, index: int) -> tuple[str, str]:
    """What a rung of the ladder changed, and the evidence for it, in words."""
    if index == 0:
        return "start", ""
    if rung.removed:
        terms = ", ".join(f"<code>{_e(t)}</code>" for t in rung.removed)
        return f"took out {terms}", "no longer worth its parameters in this model"
    return ("<br>".join(_e(a.effect.replace("_", " ")) for a in rung.added),
            "<br>".join(_e(evidence_words(a.delta_bic, a.significant)) for a in rung.added))


def diagnosis_section(run: RunAnalysis, figures: dict[str, SavedFigure]) -> str:
    """The ladder climbed, the candidates of the first rung, what still fails."""
    if run.diagnosis_error:
        return f'<p class="note">Diagnosis not possible: {_e(run.diagnosis_error)}</p>'
    climb = run.climb
    if climb is None:
        return ""
    parts = ["<h3>How the model was reached</h3>"]
    rows, numbers = [], []
    for index, rung in enumerate(climb.rungs):
        change, evidence = _rung_change(rung, index)
        rows.append([str(index), _spec(rung.model),
                     _verdict(rung.rms_error, rung.noise_floor), change, evidence])
        numbers.append([str(index), f"<code>{_e(rung.model)}</code>",
                        _num(rung.rms_error, ".4g"), _num(rung.noise_floor, ".4g"),
                        _num(rung.rms_error / rung.noise_floor, ".3g"),
                        "<br>".join(_num(a.delta_bic, ".4g") for a in rung.added) or "–"])
    parts.append(_table(["rung", "model", "error", "effect added or taken out", "evidence"],
                        rows, text_columns=5))
    parts.append("<details><summary>numbers</summary>" + _table(
        ["rung", "model", "rms_error", "noise floor", "ratio", "ΔBIC (whitened)"], numbers,
        text_columns=2) + "<p>ΔBIC: whitened Bayesian information criterion of the model with "
        "the effect minus that of the rung before; an effect counts when it is below −20 and "
        "removes at least a tenth of the error above the noise floor.</p></details>")
    if not climb.climbed:
        parts.append("<p>The ladder was not climbed (<code>--no-ladder</code>): the model "
                     "shown is the one diagnosed.</p>")
    parts.append(_figure(figures.get(figure_stem("ladder", run.name))))
    if climb.candidates:
        words, numbers = _candidate_rows(climb.candidates[:8])
        parts.append(f"<h3>Candidate effects on {_e(climb.rungs[0].model)}</h3>")
        parts.append(_table(["effect", "model", "evidence", "explanation"], words,
                            text_columns=2, text_last=True))
        parts.append("<details><summary>numbers</summary>" + _table(
            ["effect", "model", "rms_error", "ΔBIC", "significant"], numbers, text_columns=2)
            + "</details>")
    if climb.missing:
        parts.append(f"<p>Still missing (strong evidence): "
                     f"{_e(', '.join(c.effect.replace('_', ' ') for c in climb.missing))}.</p>")
    if run.failures:
        rows = [[_e(FRF_WORDS.get(f.frf, f.frf)), _e(f.run),
                 f"{f.band_hz[0]:.2f}–{f.band_hz[1]:.2f}", _e(f.what)]
                for f in run.failures[:10]]
        parts.append(f"<h3>Where <code>{_e(climb.final.spec)}</code> still fails</h3>")
        parts.append(_table(["FRF", "run", "band [Hz]", "what"], rows, text_columns=4))
    for advice in climb.advice:
        parts.append(f'<p class="note">{_e(advice)}</p>')
    return "\n".join(part for part in parts if part)


def run_section(run: RunAnalysis, figures: dict[str, SavedFigure]) -> str:
    """One run: the headline again, parameters, FRFs, residual, diagnosis."""
    m = run.run.metadata
    h = headline(run)
    parts = [f'<h2 id="run-{_e(run.name)}">Run {_e(run.name)}: {_e(h.what)}</h2>',
             f"<p>status {_e(m.status)}, {run.run.points} points, level "
             f"{_num(m.level_m_per_s2, 'g')} m/s², {_e(m.direction)} sweep, started "
             f"{_e(m.started)}; flagged points: {_flags(run.run)}.</p>"]
    if run.shown is not None:
        parts.append(f"<p>Model shown: <code>{_e(run.shown.spec)}</code> ({_e(run.shown.source)}"
                     f"), {_verdict(run.shown.rms_error, run.shown.noise_floor)}.</p>")
        parts.append(f'<p class="finding">{_e(h.finding)}</p>')
    parts += [f'<p class="note">{_e(note)}</p>' for note in run.notes]
    if run.shown is not None:
        parts.append("<details><summary>every parameter of the model shown</summary>"
                     + parameter_table(run) + "</details>")
    parts.append(_figure(figures.get(figure_stem("frf", run.name))))
    parts.append(_figure(figures.get(figure_stem("residual", run.name))))
    parts.append(diagnosis_section(run, figures))
    return "\n".join(part for part in parts if part)


def _how(analysis: CampaignAnalysis) -> str:
    if not analysis.diagnosis_available:
        return "not diagnosed"
    what = ("diagnosis ladder climbed for every specimen run" if analysis.ladder
            else "each specimen run diagnosed once (ladder not climbed)")
    return (f"{what} (analysis {analysis.seconds:.0f} s; diagnosis "
            f"{analysis.diagnosis_seconds:.0f} s of work over {analysis.jobs} process"
            f"{'es' if analysis.jobs > 1 else ''})")


def build_page(analysis: CampaignAnalysis, figures: dict[str, SavedFigure], title: str,
               materials: str = "") -> str:
    """The whole page; ``materials`` is the HTML of the materials section, if any."""
    now = datetime.now(UTC).isoformat(timespec="seconds").replace("+00:00", "Z")
    contents = ['<li><a href="#glance">At a glance</a></li>',
                '<li><a href="#preload">Preload</a></li>',
                '<li><a href="#tables">Tables 1 and 2</a></li>',
                "<li><a href=\"#moduli\">E' and η</a></li>",
                '<li><a href="#runs">Runs</a></li>']
    contents += [f'<li><a href="#run-{_e(r.name)}">Run {_e(r.name)}</a></li>'
                 for r in analysis.runs]
    if analysis.journal:
        contents.append('<li><a href="#journal">Journal</a></li>')
    theta = (f"θ = {analysis.theta_m:.4g} m (from /rig)" if analysis.theta_m else
             "θ unknown: /rig gives neither specimen_diameter_m nor geometry_factor_m (the "
             "paper gives h = 12 mm and no d), so the storage stiffness K' = θE' is shown "
             "instead of E'; η does not depend on θ")
    moduli = [_figure(figures.get(figure_stem("moduli", name))) for name in rubbers(analysis)]
    runs_shown = len(analysis.runs)
    band = f"{analysis.band_hz[0]:g}–{analysis.band_hz[1]:g} Hz"
    parts = [
        "<!DOCTYPE html>", '<html lang="en"><head><meta charset="utf-8">',
        '<meta name="viewport" content="width=device-width, initial-scale=1">',
        f"<title>{_e(title)}</title><style>{STYLE}</style></head><body>",
        f"<h1>{_e(title)}</h1>",
        f'<p class="lead">{runs_shown} runs; band {band} (clipped to each run); '
        f"{_e(_how(analysis))}. Per run: the best model reached, its error against the noise "
        "floor estimated from the data, and what it says.</p>",
        preload_summary(analysis),
        f'<div id="glance">{glance(analysis)}</div>',
    ]
    parts += [f'<p class="note">{_e(note)}</p>' for note in analysis.notes]
    parts += [f"<nav><ul>{''.join(contents)}</ul></nav>",
              f"<p class=\"lead\">Campaign file <code>{_e(analysis.path)}</code>; report made "
              f"{now} by viscorig {__version__}.</p>"]
    preload = preload_section(analysis)
    if preload:
        parts += ['<h2 id="preload">What preload changed</h2>', preload]
    parts += ['<h2 id="tables">Tables 1 and 2 of the paper</h2>', tables(analysis),
              "<h2 id=\"moduli\">E' and η against frequency (paper Figures 10–12)</h2>",
              f"<p>{_e(theta)}. Points: K* from Eq. (5) with the model's M_v; lines: the K* of "
              "the model shown for the run (the model reached by the diagnosis, else a Maxwell "
              "fit of X_v/F_v).</p>",
              *moduli, _figure(figures.get("preload")),
              '<h2 id="runs">Runs</h2>', overview(analysis)]
    parts += [run_section(run, figures) for run in analysis.runs]
    if analysis.journal:
        parts += ['<h2 id="journal">Journal</h2>', journal_table(analysis.journal)]
    if materials:
        parts.append(materials)
    parts.append("</body></html>")
    return "\n".join(part for part in parts if part)


def materials_page(title: str, materials: str, path: str) -> str:
    """A page for a campaign file that holds materials (DMA runs) and no rig run."""
    now = datetime.now(UTC).isoformat(timespec="seconds").replace("+00:00", "Z")
    return "\n".join([
        "<!DOCTYPE html>", '<html lang="en"><head><meta charset="utf-8">',
        '<meta name="viewport" content="width=device-width, initial-scale=1">',
        f"<title>{_e(title)}</title><style>{STYLE}</style></head><body>",
        f"<h1>{_e(title)}</h1>",
        f'<p class="lead">Campaign file <code>{_e(path)}</code>; report made {now} by viscorig '
        f"{__version__}.</p>", materials, "</body></html>"])


def journal_table(entries: list[JournalEntry]) -> str:
    """The bench's notes and run events (pauses, holds, aborts) with their time and run."""
    rows = [[_e(entry.time_utc), _e(entry.run or "–"), _e(entry.kind),
             _e(entry.text).replace("\n", "<br>")] for entry in entries]
    return ("<p>What the technician noted and what the run engine did, as the campaign file "
            "keeps it (UTC).</p>"
            + _table(["time", "run", "kind", "text"], rows, text_columns=4))


def overview(analysis: CampaignAnalysis) -> str:
    """The runs as measured, one row each."""
    rows = []
    for r in analysis.runs:
        m = r.run.metadata
        band = (f"{r.run.frequency_hz.min():.2f}–{r.run.frequency_hz.max():.2f}"
                if r.run.points else "–")
        rows.append([f'<a href="#run-{_e(r.name)}">{_e(r.name)}</a>', _e(m.status),
                     str(r.run.points), band, _e(m.specimen), _num(m.hardness_shore_a, "g"),
                     _num(m.preload_strain, "g"), _num(m.level_m_per_s2, "g"), _flags(r.run)])
    return _table(["run", "status", "points", "band [Hz]", "specimen", "Shore A", "preload",
                   "level [m/s²]", "flagged"], rows, text_columns=2)
