"""The report as one self-contained HTML page: inline CSS, figures as base64 PNG, no script,
nothing fetched from anywhere.
"""

from __future__ import annotations

import base64
import html
import math
from datetime import UTC, datetime

from viscorig import __version__
from viscorig.paper import (
    PAPER_TABLE_1,
    PAPER_TABLE_2,
    PAPER_TABLE_PARAMETERS,
    consistency_notes,
)
from viscorig.report.analysis import CampaignAnalysis, RunAnalysis
from viscorig.report.figures import SavedFigure
from viscorig.storage import FLAG_NAMES, count_flags

STYLE = """
body { font-family: "DejaVu Sans", Arial, sans-serif; margin: 1.5em auto; max-width: 1150px;
       color: #222; line-height: 1.4; padding: 0 1em; }
h1 { font-size: 1.6em; border-bottom: 2px solid #1f4e79; padding-bottom: .2em; }
h2 { font-size: 1.3em; color: #1f4e79; margin-top: 2em; border-bottom: 1px solid #ccc; }
h3 { font-size: 1.1em; margin-top: 1.4em; }
table { border-collapse: collapse; margin: .6em 0; font-size: .9em; }
th, td { border: 1px solid #bbb; padding: .25em .55em; text-align: right; }
th { background: #e8eef5; }
td.text, th.text { text-align: left; }
tr.paper td { color: #555; font-style: italic; }
figure { margin: .8em 0 1.4em; }
figure img { max-width: 100%; border: 1px solid #ddd; }
figcaption { font-size: .85em; color: #444; }
.note { background: #fff8e1; border-left: 4px solid #f0b400; padding: .4em .8em; margin: .5em 0; }
.ok { color: #1e7b34; font-weight: bold; }
.bad { color: #b03a2e; font-weight: bold; }
nav ul { columns: 3; font-size: .9em; }
code { background: #f2f2f2; padding: 0 .2em; }
"""


def _e(text: object) -> str:
    return html.escape(str(text))


def _num(value: float, digits: str = ".4g") -> str:
    return "–" if value is None or not math.isfinite(value) else format(value, digits)


def _pm(value: float, stderr: float, digits: str = ".6g") -> str:
    if not math.isfinite(stderr) or stderr == 0:
        return _num(value, digits)
    return f"{_num(value, digits)} ± {stderr:.2g}"


def _figure(saved: SavedFigure | None) -> str:
    if saved is None:
        return ""
    data = base64.b64encode(saved.png).decode("ascii")
    return (f'<figure><img alt="{_e(saved.caption)}" src="data:image/png;base64,{data}">'
            f'<figcaption>{_e(saved.caption)} Files: <code>{_e(saved.stem)}.png</code>, '
            f'<code>{_e(saved.stem)}.svg</code>.</figcaption></figure>')


def _table(header: list[str], rows: list[list[str]], text_columns: int = 1,
           classes: list[str] | None = None, text_last: bool = False) -> str:
    def text(i: int) -> bool:
        return i < text_columns or (text_last and i == len(header) - 1)

    head = "".join(f'<th class="text">{_e(h)}</th>' if text(i) else f"<th>{_e(h)}</th>"
                   for i, h in enumerate(header))
    body = []
    for index, row in enumerate(rows):
        cells = "".join(f'<td class="text">{c}</td>' if text(i) else f"<td>{c}</td>"
                        for i, c in enumerate(row))
        css = f' class="{classes[index]}"' if classes and classes[index] else ""
        body.append(f"<tr{css}>{cells}</tr>")
    return f"<table><thead><tr>{head}</tr></thead><tbody>{''.join(body)}</tbody></table>"


def _flags(run) -> str:
    counts = {flag: n for flag, n in count_flags(run.flags).items() if n}
    if not counts:
        return "0"
    return _e(f"{int(run.flagged().sum())} (" + ", ".join(
        f"{FLAG_NAMES[flag]} {n}" for flag, n in counts.items()) + ")")


def overview(analysis: CampaignAnalysis) -> str:
    """The runs, one row each."""
    rows = []
    for r in analysis.runs:
        m = r.run.metadata
        band = (f"{r.run.frequency_hz.min():.2f}–{r.run.frequency_hz.max():.2f}"
                if r.run.points else "–")
        shown = r.shown
        ratio = (f"{shown.rms_error / shown.noise_floor:.1f}"
                 if shown and shown.noise_floor > 0 else "–")
        rows.append([f'<a href="#run-{_e(r.name)}">{_e(r.name)}</a>', _e(m.status),
                     str(r.run.points), band, _e(m.specimen), _num(m.hardness_shore_a, "g"),
                     _num(m.preload_strain, "g"), _num(m.level_m_per_s2, "g"), _flags(r.run),
                     _e(f"{shown.spec} ({shown.source})") if shown else "–", ratio])
    return _table(["run", "status", "points", "band [Hz]", "specimen", "Shore A", "preload",
                   "level [m/s²]", "flagged", "model shown", "rms/floor"], rows, text_columns=2)


def tables(analysis: CampaignAnalysis) -> str:
    """The table suspension, Table 1 and Table 2, beside the paper's values for its runs."""
    parts = []
    summaries = [r.summary for r in analysis.runs if r.summary is not None]
    paper = any(s.run in PAPER_TABLE_1 for s in summaries)
    if analysis.table is not None:
        t = analysis.table
        rows = []
        for name, unit in (("M_s", "kg"), ("K_s", "N/m"), ("C_s", "N·s/m")):
            stderr = t.fit.stderr.get(name, math.nan) if t.fit is not None else math.nan
            row = [name, unit, _pm(t.values[name], stderr)]
            if paper:
                row.append(_num(PAPER_TABLE_PARAMETERS[name], "g"))
            rows.append(row)
        parts.append(f"<h3>Table suspension (from {_e(t.source)})</h3>")
        parts.append(_table(["parameter", "unit", "this campaign"] + (["paper"] if paper else []),
                            rows, text_columns=2))
    specimen = [s for s in summaries if not s.bare]
    if specimen:
        parts.append("<h3>Table 1: Voigt fit of X_s/F_e, table fixed "
                     f"({analysis.band_hz[0]:g}–{analysis.band_hz[1]:g} Hz)</h3>")
        rows, classes = [], []
        reference = {}
        for s in specimen:
            p = s.fit.parameters
            run = analysis.run(s.run).run
            key = (run.metadata.specimen, run.metadata.hardness_shore_a)
            k_v, c_v = p["K_v"].value, p["C_v"].value
            variation = ["", ""]
            if run.metadata.preload_strain == 0:
                reference[key] = (k_v, c_v)
            elif key in reference:
                variation = [f"{(k_v / reference[key][0] - 1) * 100:+.2f} %",
                             f"{(c_v / reference[key][1] - 1) * 100:+.2f} %"]
            rows.append([_e(s.run), _pm(k_v, p["K_v"].stderr), variation[0],
                         _pm(c_v, p["C_v"].stderr, ".5g"), variation[1],
                         _pm(p["M_v"].value, p["M_v"].stderr, ".4g"),
                         _num(s.fit.rms_error / s.fit.noise_floor, ".1f")])
            classes.append("")
            if s.run in PAPER_TABLE_1:
                pk, pc = PAPER_TABLE_1[s.run]
                base = s.run.split("-")[0] + "-0"
                pv = ["", ""]
                if s.run != base and base in PAPER_TABLE_1:
                    pk0, pc0 = PAPER_TABLE_1[base]
                    pv = [f"{(pk / pk0 - 1) * 100:+.2f} %", f"{(pc / pc0 - 1) * 100:+.2f} %"]
                rows.append([f"paper {_e(s.run)}", _num(pk, ".8g"), pv[0], _num(pc, ".5g"), pv[1],
                             "–", "–"])
                classes.append("paper")
        parts.append(_table(["run", "K_v [N/m]", "variation", "C_v [N·s/m]", "variation",
                             "M_v [kg]", "rms/floor"], rows, classes=classes))
        parts.append("<h3>Table 2: natural frequency, damping factor, half-power bandwidth</h3>")
        rows, classes = [], []
        for s in specimen:
            if s.system is None:
                continue
            sy, me = s.system, s.measured
            rows.append([_e(s.run), _num(sy.natural_frequency_hz, ".2f"),
                         _num(sy.damping_factor, ".4f"), _num(sy.bandwidth_hz, ".3f"),
                         _num(me.peak_hz, ".2f"), _num(me.bandwidth_hz, ".3f")])
            classes.append("")
            if s.run in PAPER_TABLE_2:
                f_r, xi, b_r = PAPER_TABLE_2[s.run]
                rows.append([f"paper {_e(s.run)}", _num(f_r, ".2f"), _num(xi, ".3f"),
                             _num(b_r, ".3f"), "–", "–"])
                classes.append("paper")
        parts.append(_table(["run", "f_r [Hz]", "ξ", "B_r = 2ξf_r [Hz]", "peak measured [Hz]",
                             "B_r measured [Hz]"], rows, classes=classes))
        parts.append("<p>f_r, ξ and B_r follow from the Voigt parameters "
                     "(f_r = √((K_s+K_v)/(M_s+M_v))/2π, ξ = (C_s+C_v)/(2√((K_s+K_v)(M_s+M_v)))); "
                     "the measured columns are read off |X_s/F_e| directly.</p>")
    if paper:
        notes = "".join(f"<li>{_e(note)}</li>" for note in consistency_notes())
        parts.append(f"<div class=\"note\"><b>On the paper's numbers</b><ul>{notes}</ul></div>")
    return "\n".join(parts)


def diagnosis_section(run: RunAnalysis, figures: dict[str, SavedFigure]) -> str:
    """Failures, findings and the ladder of one run."""
    if run.diagnosis_error:
        return f'<p class="note">Diagnosis not possible: {_e(run.diagnosis_error)}</p>'
    if not run.ladder:
        return ""
    first = run.ladder[0]
    last = run.ladder[-1]
    at_floor = last.rms_error <= 1.25 * last.noise_floor
    parts = [f"<h4>Diagnosis of {_e(first.model)}</h4>",
             f"<p>rms_error {first.rms_error:.3g}, noise floor {first.noise_floor:.3g} "
             f"({first.rms_error / first.noise_floor:.1f}× the floor).</p>"]
    if run.failures:
        rows = [[_e(f.frf), f"{f.band_hz[0]:.2f}–{f.band_hz[1]:.2f}", _e(f.what)]
                for f in run.failures[:8]]
        parts.append(_table(["FRF", "band [Hz]", "what"], rows, text_columns=3))
    if run.findings:
        rows = [[_e(f.effect), f"<code>{_e(f.model)}</code>", _num(f.rms_error, ".3g"),
                 _num(f.delta_bic, ".1f"), "yes" if f.significant else "no", _e(f.explanation)]
                for f in run.findings[:6]]
        parts.append(_table(["effect", "model", "rms_error", "ΔBIC", "significant",
                             "explanation"], rows, text_columns=2, text_last=True))
    verdict = ('<span class="ok">at the noise floor</span>' if at_floor
               else '<span class="bad">above the noise floor</span>')
    parts.append(f"<p>Ladder: {' → '.join(_e(s.model) for s in run.ladder)}; last model "
                 f"{last.rms_error:.3g}, {verdict}.</p>")
    parts.append(_figure(figures.get(f"ladder-{run.name}")))
    return "\n".join(parts)


def run_section(run: RunAnalysis, figures: dict[str, SavedFigure]) -> str:
    """One run: FRFs, residual, diagnosis."""
    m = run.run.metadata
    parts = [f'<h2 id="run-{_e(run.name)}">Run {_e(run.name)}</h2>',
             f"<p>specimen {_e(m.specimen)}, preload {_num(m.preload_strain, 'g')}, status "
             f"{_e(m.status)}, {run.run.points} points, level {_num(m.level_m_per_s2, 'g')} "
             f"m/s², started {_e(m.started)}.</p>"]
    if run.shown is not None:
        parameters = ", ".join(f"{k} = {v:.5g}" for k, v in run.shown.values.items())
        parts.append(f"<p>Model shown: <code>{_e(run.shown.spec)}</code> ({_e(run.shown.source)})"
                     f": {_e(parameters)}.</p>")
    parts += [f'<p class="note">{_e(note)}</p>' for note in run.notes]
    parts.append(_figure(figures.get(f"frf-{run.name}")))
    parts.append(_figure(figures.get(f"residual-{run.name}")))
    parts.append(diagnosis_section(run, figures))
    return "\n".join(parts)


def build_page(analysis: CampaignAnalysis, figures: dict[str, SavedFigure], title: str) -> str:
    """The whole page."""
    from viscorig.report.analysis import rubbers

    now = datetime.now(UTC).isoformat(timespec="seconds").replace("+00:00", "Z")
    contents = ["<li><a href=\"#runs\">Runs</a></li>", "<li><a href=\"#tables\">Tables 1 and 2</a>"
                "</li>", "<li><a href=\"#moduli\">E' and η against frequency</a></li>"]
    contents += [f'<li><a href="#run-{_e(r.name)}">Run {_e(r.name)}</a></li>'
                 for r in analysis.runs]
    theta = (f"θ = {analysis.theta_m:.4g} m (from /rig)" if analysis.theta_m else
             "θ unknown: /rig gives neither specimen_diameter_m nor geometry_factor_m (the "
             "paper gives h = 12 mm and no d), so the storage stiffness K' = θE' is shown "
             "instead of E'; η does not depend on θ")
    moduli = [_figure(figures.get(f"moduli-{name}")) for name in rubbers(analysis)]
    parts = [
        "<!DOCTYPE html>", '<html lang="en"><head><meta charset="utf-8">',
        '<meta name="viewport" content="width=device-width, initial-scale=1">',
        f"<title>{_e(title)}</title><style>{STYLE}</style></head><body>",
        f"<h1>{_e(title)}</h1>",
        f"<p>Campaign file <code>{_e(analysis.path)}</code>; report made {now} by viscorig "
        f"{__version__}. Identification band {analysis.band_hz[0]:g}–{analysis.band_hz[1]:g} Hz "
        "(clipped to each run).</p>",
    ]
    parts += [f'<p class="note">{_e(note)}</p>' for note in analysis.notes]
    parts += [f"<nav><ul>{''.join(contents)}</ul></nav>",
              '<h2 id="runs">Runs</h2>', overview(analysis),
              '<h2 id="tables">Tables 1 and 2</h2>', tables(analysis),
              "<h2 id=\"moduli\">E' and η against frequency (paper Figures 10–12)</h2>",
              f"<p>{_e(theta)}. Points: K* from Eq. (5) with M_v from the Maxwell fit; lines: "
              "the Maxwell model fitted to X_v/F_v (order chosen by BIC).</p>",
              *moduli, _figure(figures.get("preload"))]
    parts += [run_section(run, figures) for run in analysis.runs]
    parts.append("</body></html>")
    return "\n".join(part for part in parts if part)
