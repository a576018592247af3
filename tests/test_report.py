"""The report: builds from a simulated campaign, self-contained, opens in a browser; quick look."""

from __future__ import annotations

import html
import os
import re
import shutil
from pathlib import Path

import h5py
import numpy as np
import pytest
from browser import CHROMIUM, console_problems, dump_dom, screenshot
from campaigndata import add_run, paper_campaign

from viscorig.cli import main
from viscorig.identify import identify_run, store_fit
from viscorig.report import analyse_campaign, build_report
from viscorig.storage import CampaignFile


@pytest.fixture(scope="module")
def campaign_file(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return paper_campaign(tmp_path_factory.mktemp("report") / "paper.h5",
                          runs=("table", "soft-0", "soft-10"))


@pytest.fixture(scope="module")
def report_dir(campaign_file: Path, tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("out") / "report"
    assert main(["report", str(campaign_file), "--out", str(out), "--no-diagnosis",
                 "--svg"]) == 0
    return out


@pytest.mark.slow
def test_report_page_is_self_contained_with_every_figure(report_dir: Path):
    page = (report_dir / "index.html").read_text(encoding="utf-8")
    for stem in ("frf-table", "frf-soft-0", "frf-soft-10", "residual-soft-0", "moduli-soft",
                 "preload"):
        assert (report_dir / f"{stem}.png").stat().st_size > 10_000, stem
        assert (report_dir / f"{stem}.svg").read_text().lstrip().startswith("<?xml"), stem
    images = re.findall(r'<img [^>]*src="([^"]+)"', page)
    assert len(images) == len(list(report_dir.glob("*.png")))
    assert all(src.startswith("data:image/png;base64,") for src in images)
    assert "<script" not in page.lower()
    assert not re.search(r'(src|href)="(https?:)?//', page)
    assert "diagnosis sections left out" in page


def test_report_tables_sit_beside_the_papers_values_and_say_its_inconsistencies(report_dir):
    page = (report_dir / "index.html").read_text(encoding="utf-8")
    assert "Table 1: Voigt fit" in page and "Table 2" in page
    assert "149986.61" in page and "163948.13" in page  # paper's K_v, soft
    assert "39.50" in page  # paper's f_r, soft-0
    assert "not fully self-consistent" in page
    assert "+9.31 %" in page  # the paper's preload variation of K_v, soft


def test_stored_fit_is_the_model_shown(tmp_path: Path, campaign_file: Path):
    path = tmp_path / "c.h5"
    path.write_bytes(campaign_file.read_bytes())
    with CampaignFile.open(path, "a") as campaign:
        result, _ = identify_run(campaign, "soft-0", "maxwell(2)", band_hz=(20, 120))
        fit_id = store_fit(campaign, "soft-0", result)
        analysis = analyse_campaign(campaign, diagnosis=False)
    shown = analysis.run("soft-0").shown
    assert shown.source == f"stored fit {fit_id}" and shown.spec == "maxwell(2)"
    f = np.linspace(20, 120, 5)
    assert np.allclose(shown.predict(f, None, None)["support"], result.predict(f)["support"])
    assert analysis.run("soft-10").shown.source.startswith("fitted here")


@pytest.fixture(scope="module")
def quick_report(campaign_file: Path, tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The report with each run diagnosed once (no ladder)."""
    pytest.importorskip("viscorig.diagnosis")
    out = tmp_path_factory.mktemp("quick") / "report"
    assert main(["report", str(campaign_file), "--out", str(out), "--no-ladder"]) == 0
    return out


@pytest.mark.slow
def test_report_climbs_the_ladder_and_shows_the_model_reached(tmp_path: Path):
    pytest.importorskip("viscorig.diagnosis")
    path = paper_campaign(tmp_path / "c.h5", runs=("table", "hard-10"))
    analysis = analyse_campaign(CampaignFile.open(path), jobs=1)
    hard = analysis.run("hard-10")
    assert analysis.diagnosis_available and analysis.ladder
    assert hard.ladder[0].model == "voigt" and len(hard.ladder) >= 3
    assert hard.ladder[0].rms_error > 10 * hard.ladder[0].noise_floor  # Voigt misses the rubber
    # The model shown is the last rung, and the failures shaded are that model's.
    assert hard.shown.spec == hard.ladder[-1].model
    assert hard.shown.rms_error == pytest.approx(hard.ladder[-1].rms_error)
    assert hard.shown.rms_error < 2 * hard.shown.noise_floor
    assert hard.failures is hard.climb.failures
    # Each rung after the first either added significant candidates, whose terms it holds, and
    # lowered the error, or took out a term of the rung before and added nothing.
    for before, after in zip(hard.ladder, hard.ladder[1:], strict=False):
        if after.removed:
            assert not after.added and all(t in before.model.split("+") for t in after.removed)
            assert all(t not in after.model.split("+") for t in after.removed)
            continue
        assert after.added and all(a.significant for a in after.added)
        assert all(a.term in after.model.split("+") or a.model == after.model
                   for a in after.added)
        assert after.rms_error < before.rms_error
    removed = [t for rung in hard.ladder for t in rung.removed]
    # The shown parameters carry their ± from the last fit (covariance of the free ones).
    assert set(hard.shown.free) <= set(hard.shown.values)
    assert all(hard.shown.stderr[name] > 0 for name in hard.shown.free)
    page = build_report(path, tmp_path / "r", jobs=1).read_text(encoding="utf-8")
    assert "How the model was reached" in page
    assert "load-cell link is not rigid" in page  # the effect the ladder added first
    assert all(f"took out <code>{t}</code>" in page for t in removed)


@pytest.mark.slow
def test_shading_is_only_where_the_model_shown_fails(quick_report: Path, campaign_file: Path):
    from viscorig.report.figures import BAND, frf_figure

    analysis = analyse_campaign(CampaignFile.open(campaign_file), ladder=False, jobs=1)
    soft = analysis.run("soft-0")
    assert soft.shown.spec == soft.ladder[-1].model == "voigt"
    assert soft.failures  # Voigt fails somewhere on this rubber
    figure = frf_figure(soft)
    axes = figure.get_axes()
    for column, frf in enumerate(("table", "support")):
        bands = [band.band_hz for band in soft.failures if band.frf == frf]
        magnitude = axes[column]
        shaded = [patch for patch in magnitude.patches
                  if np.allclose(patch.get_facecolor()[:3], _rgb(BAND))]
        spans = sorted((round(p.get_x(), 6), round(p.get_x() + p.get_width(), 6))
                       for p in shaded)
        assert spans == sorted((round(lo, 6), round(hi, 6)) for lo, hi in bands)
    # No failure, no shading: the table run is not diagnosed, so nothing is shaded.
    assert not any(axes_.patches for axes_ in frf_figure(analysis.run("table")).get_axes())


@pytest.mark.slow
def test_titles_sit_where_matplotlib_would_place_them(campaign_file: Path):
    """The figures' titles are placed once (``styled``), not measured again at every draw: the
    same pixels as matplotlib's own placement, which would differ if a figure put ticks or
    labels above an axes."""
    from viscorig.report.figures import frf_figure, ladder_figure, residual_figure, save

    analysis = analyse_campaign(CampaignFile.open(campaign_file), ladder=False, jobs=1)
    soft = analysis.run("soft-0")
    for builder in (frf_figure, residual_figure, ladder_figure):
        placed = save(builder(soft), None, "placed", "").png
        automatic = save(builder.__wrapped__(soft), None, "automatic", "").png
        assert placed == automatic, builder.__name__


def _rgb(colour: str) -> tuple[float, float, float]:
    from matplotlib.colors import to_rgb

    return to_rgb(colour)


@pytest.mark.slow
def test_the_page_leads_with_the_answer_in_words(quick_report: Path):
    page = (quick_report / "index.html").read_text(encoding="utf-8")
    glance = page.index('<table class="glance">')
    assert glance < page.index("Table 1: Voigt fit") < page.index('id="run-soft-0"')
    row = page[page.index('href="#run-soft-0"'):page.index('href="#run-soft-10"')]
    assert "voigt" in row and "far above the noise" in row  # model and its error in words
    assert re.search(r"K_v \d+\.\d+ ± \d+\.\d+ kN/m", row)  # parameters with their ±
    assert "most likely missing: stiffness and damping depend on frequency" in row
    assert "still fails" in page[glance:glance + 2000]
    # Statistics are words; their numbers only inside <details> elements.
    outside = re.sub(r"<details>.*?</details>", "", page, flags=re.S)
    assert "ΔBIC" not in outside
    assert "strong evidence" in outside and "ΔBIC" in page


@pytest.mark.slow
def test_preload_pairs_are_compared_with_their_uncertainty(quick_report: Path,
                                                           campaign_file: Path):
    from viscorig.compare import compare_fits
    from viscorig.identify import summarize

    page = (quick_report / "index.html").read_text(encoding="utf-8")
    _, summaries, _ = summarize(CampaignFile.open(campaign_file))
    fits = {s.run: s.fit for s in summaries}
    (k_v, c_v) = compare_fits(fits["soft-0"], fits["soft-10"], ["K_v", "C_v"])
    assert k_v.significant and 0.05 < k_v.relative < 0.15  # the rig's preload stiffens K_v
    line = page[page.index("What preload changed"):page.index('<table class="glance">')]
    assert f"K_v {k_v.percent()} (paper +9.31 %)" in line
    assert f"C_v {c_v.percent()} (paper +9.01 %)" in line
    assert re.search(r"K_v \+\d\.\d+ ± 0\.\d+ %", line)
    assert "K′ of the model reached" in line
    assert 'id="preload"' in page and k_v.words() in page


def test_report_and_summary_print_the_same_numbers(report_dir: Path, campaign_file: Path,
                                                  capsys):
    """Tables 1 and 2 and the preload variations come from the same fits and the same
    propagation as ``viscorig summary``: every variation it prints is on the page, as printed."""
    assert main(["summary", str(campaign_file), "--json"]) == 0
    import json

    document = json.loads(capsys.readouterr().out)
    page = html.unescape((report_dir / "index.html").read_text(encoding="utf-8"))
    tables = page[page.index("Table 1: Voigt fit"):page.index("On the paper's numbers")]
    (variation,) = document["variations"]
    assert set(variation["changes"]) == {"K_v", "C_v", "f_r", "xi", "B_r"}
    assert main(["summary", str(campaign_file)]) == 0
    text = capsys.readouterr().out
    row = next(line for line in text.splitlines() if "soft-0 → soft-10" in line)
    printed = re.findall(r"[+-]\d+\.?\d* ± \d+\.?\d* %", row)
    assert len(printed) == 5
    for change in printed:
        assert change in tables, change
    for run in document["runs"]:  # Table 2's f_r with the ± summary gives it
        f_r = run["system"]["f_r"]
        from viscorig.numbers import with_uncertainty

        assert with_uncertainty(f_r["value"], f_r["stderr"], "Hz") in tables
    assert "shared (run 'table'), counted once" in tables


def test_residuals_are_shown_against_the_runs_noise_model(campaign_file: Path):
    analysis = analyse_campaign(CampaignFile.open(campaign_file), diagnosis=False)
    result, _ = identify_run(CampaignFile.open(campaign_file), "soft-0", "voigt", band_hz=(20, 120))
    residuals = {r.frf: r for r in analysis.run("soft-0").residuals}
    assert set(residuals) == {"table", "support"}
    order = np.argsort(result.frequency_hz)
    for frf, residual in residuals.items():
        assert np.allclose(residual.frequency_hz, result.frequency_hz[order])
        assert np.allclose(residual.noise, result.noise.scale(frf)[order], rtol=1e-12)
        assert residual.floor == pytest.approx(result.noise.floor_of((frf,)))


def test_moduli_and_preload_figures_carry_the_uncertainty_bands(campaign_file: Path):
    from matplotlib.collections import PolyCollection

    from viscorig.compare import Pair, storage_stiffness_of
    from viscorig.report.analysis import rubbers
    from viscorig.report.figures import moduli_figure, preload_figure

    analysis = analyse_campaign(CampaignFile.open(campaign_file), diagnosis=False)
    groups = rubbers(analysis)
    soft = groups["soft"]
    stiffness_ax = moduli_figure("soft", soft, None).get_axes()[0]
    bands = [c for c in stiffness_ax.collections if isinstance(c, PolyCollection)]
    assert len(bands) == 2  # one per preload
    band = soft[0].modulus.band
    top = bands[0].get_paths()[0].vertices[:, 1].max()
    assert top * 1e3 == pytest.approx(np.max(band.storage_modulus + band.storage_modulus_stderr),
                                      rel=1e-9)
    assert np.all(band.storage_modulus_stderr > 0) and np.all(band.loss_factor_stderr > 0)
    change_ax = preload_figure(groups).get_axes()[0]
    (shaded,) = [c for c in change_ax.collections if isinstance(c, PolyCollection)]
    pair = Pair(soft[0].modulus.fit, soft[-1].modulus.fit)
    f = np.linspace(20, 120, 61)
    change, stderr = pair.relative(storage_stiffness_of(pair.a.model, f),
                                   storage_stiffness_of(pair.b.model, f))
    assert shaded.get_paths()[0].vertices[:, 1].max() == pytest.approx(
        np.max(100 * (change + stderr)), rel=1e-9)
    assert np.all(stderr > 0) and np.all(stderr < 0.05)


def test_report_of_a_missing_file_or_no_runs_is_one_line_exit_2(tmp_path: Path, capsys):
    assert main(["report", str(tmp_path / "none.h5"), "--out", str(tmp_path / "r")]) == 2
    CampaignFile.create(tmp_path / "empty.h5", sequence_text="", durable=False)
    assert main(["report", str(tmp_path / "empty.h5"), "--out", str(tmp_path / "r")]) == 2
    errors = capsys.readouterr().err.strip().splitlines()
    assert len(errors) == 2 and "has no run" in errors[1]


@pytest.mark.slow
def test_report_of_a_campaign_still_being_measured(tmp_path: Path):
    path = tmp_path / "live.h5"
    campaign = CampaignFile.create(path, sequence_text="", durable=False)
    add_run(campaign, "table")
    add_run(campaign, "soft-0", points=140, finish=False)
    add_run(campaign, "soft-10", points=5, finish=False)
    page = build_report(path, tmp_path / "r", diagnosis=False).read_text(encoding="utf-8")
    assert "running" in page and "5 points, too few to fit" in page
    assert (tmp_path / "r" / "frf-soft-0.png").exists()
    assert (tmp_path / "r" / "frf-soft-10.png").exists()
    analysis = analyse_campaign(CampaignFile.open(path), diagnosis=False)
    assert analysis.run("soft-0").band_hz == (20.0, pytest.approx(54.75))


def test_quick_look_of_a_run_being_measured(tmp_path: Path, capsys):
    path = tmp_path / "live.h5"
    campaign = CampaignFile.create(path, sequence_text="", durable=False)
    add_run(campaign, "soft-0", points=37, finish=False)
    out = tmp_path / "look.png"
    assert main(["show", str(path), "--plot", "soft-0", "--out", str(out)]) == 0
    assert out.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n" and out.stat().st_size > 10_000
    assert main(["show", str(path), "--plot", "hard-0"]) == 2
    assert "no such run" in capsys.readouterr().err
    assert main(["show", str(path), "--plot", "soft-0"]) == 0
    assert (tmp_path / "live-soft-0.png").exists()


def _keep(shot: Path) -> None:
    """Copy a screenshot where a person can look at it (``VISCORIG_ARTIFACTS``)."""
    keep = os.environ.get("VISCORIG_ARTIFACTS")
    if keep:
        Path(keep).mkdir(parents=True, exist_ok=True)
        shutil.copy(shot, Path(keep) / shot.name)


@pytest.mark.slow
@pytest.mark.skipif(CHROMIUM is None, reason="chromium is not installed")
def test_page_opens_in_headless_chromium_without_errors(report_dir: Path, tmp_path: Path):
    url = (report_dir / "index.html").as_uri()
    dom = dump_dom(url, tmp_path / "profile")
    assert dom.returncode == 0, dom.stderr[-2000:]
    assert "Table 1: Voigt fit" in dom.stdout and dom.stdout.count("<img") >= 6
    assert not console_problems(dom.stderr), console_problems(dom.stderr)
    shot = tmp_path / "report-screenshot.png"
    result = screenshot(url, shot, tmp_path / "profile")
    assert result.returncode == 0, result.stderr[-2000:]
    assert shot.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n" and shot.stat().st_size > 50_000
    _keep(shot)
    print(f"screenshot: {shot}")


LAYOUT_PROBE = """<script>
const table = document.querySelector("table.glance");
const rows = [...table.querySelectorAll("tbody tr")].map(row => row.getBoundingClientRect().bottom);
document.body.setAttribute("data-layout", JSON.stringify({
  rows, top: table.getBoundingClientRect().top, height: window.innerHeight,
  runs: [...table.querySelectorAll("tbody tr td:first-child b")].map(b => b.textContent)}));
</script></body>"""


@pytest.mark.slow
@pytest.mark.skipif(CHROMIUM is None, reason="chromium is not installed")
def test_every_runs_headline_is_on_the_first_screen(quick_report: Path, tmp_path: Path):
    import json

    page = (quick_report / "index.html").read_text(encoding="utf-8")
    assert "<script" not in page.lower()
    probe = tmp_path / "probe.html"  # a copy with a script that measures the layout
    probe.write_text(page.replace("</body>", LAYOUT_PROBE), encoding="utf-8")
    dom = dump_dom(probe.as_uri(), tmp_path / "profile", size=(1280, 800))
    assert dom.returncode == 0, dom.stderr[-2000:]
    layout = json.loads(html.unescape(re.search(r'data-layout="([^"]+)"', dom.stdout)[1]))
    assert layout["runs"] == ["table", "soft-0", "soft-10"]
    assert layout["height"] >= 600 and max(layout["rows"]) <= layout["height"], layout
    shot = tmp_path / "report-first-screen.png"
    result = screenshot((quick_report / "index.html").as_uri(), shot, tmp_path / "profile",
                        size=(1280, 800))
    assert result.returncode == 0 and shot.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    _keep(shot)


def test_the_finding_names_a_missing_fixture_mode_with_or_without_its_frequency():
    from viscorig.report.words import finding_sentence

    at_58 = finding_sentence("voigt", [("load_cell_compliance", "load_cell")], {"K_c": 1e7},
                             2e-3, 1e-3, ("fixture_resonance", "fixture(58)"), True)
    assert at_58.endswith("next most likely: a fixture mode at 58 Hz.")
    unplaced = finding_sentence("voigt", [], {}, 3e-2, 1e-3, "fixture_resonance", True)
    assert unplaced == "voigt is far above the noise: 30× the floor; most likely missing: a " \
        "fixture mode."


def test_a_rung_that_takes_a_term_out_is_shown_as_such():
    from viscorig.report.analysis import Rung, term_change
    from viscorig.report.page import _rung_change

    assert term_change("voigt+load_cell", "fractional+load_cell+fixture(58)") == (
        ["fractional", "fixture(58)"], ["voigt"])
    assert term_change("fractional+fixture(58)+fixture(38)", "fractional+fixture(58)") == (
        [], ["fixture(38)"])
    change, evidence = _rung_change(Rung("fractional+fixture(58)", 1e-3, 1e-3,
                                         removed=("fixture(38)",)), 3)
    assert change == "took out <code>fixture(38)</code>" and "no longer worth" in evidence
    assert _rung_change(Rung("voigt", 1e-2, 1e-3), 0) == ("start", "")


def test_log_axes_are_labelled_as_matplotlib_labels_them_in_plain_text() -> None:
    from matplotlib.figure import Figure

    from viscorig.report.figures import save

    figure = Figure(figsize=(4, 3))
    axes = figure.subplots()
    axes.semilogy([1.0, 2.0], [0.2, 0.9])  # within a decade: minor ticks labelled too
    reference = Figure(figsize=(4, 3))
    reference.subplots().semilogy([1.0, 2.0], [0.2, 0.9])
    reference.canvas.draw()
    save(figure, None, "log", "a log axis")
    expected = [text.get_text() for text in reference.axes[0].get_yticklabels(minor=True)
                if text.get_text()]
    shown = [text.get_text() for text in axes.get_yticklabels(minor=True) if text.get_text()]
    majors = [text.get_text() for text in axes.get_yticklabels() if text.get_text()]
    assert len(shown) == len(expected) == 4
    assert shown == ["2×10⁻¹", "3×10⁻¹", "4×10⁻¹", "6×10⁻¹"] and "10⁻¹" in majors
    assert not any("$" in label for label in shown + majors)


def test_specimen_names_from_the_file_stay_text_and_inside_the_report(tmp_path: Path):
    # a name holding '/' stopped the report (and '..' pointed its figure outside the folder);
    # one holding $...$ was parsed as mathtext and stopped it with a traceback
    from viscorig.storage import RunSettings, Segment

    f = np.linspace(20.0, 120.0, 41)
    segment = Segment(frequency_hz=f, time_s=np.arange(f.size) * 2.0,
                      accelerance_table=np.full(f.size, 0.1 + 0.01j),
                      accelerance_support=np.full(f.size, 0.1 + 0.01j),
                      reference_amplitude=np.ones(f.size), source_amplitude=np.full(f.size, 0.1),
                      force_amplitude=np.full(f.size, 10.0), flags=np.zeros(f.size, np.uint16))
    names = ["soft/25 $\\frac{$", "soft_25 $\\frac{$", "../../../x", "a" * 200]
    path = tmp_path / "odd.h5"
    with CampaignFile.create(path, sequence_text="", durable=False) as campaign:
        for index, name in enumerate(names):
            for preload in (0.0, 0.1):
                settings = RunSettings(specimen=name, level_m_per_s2=1.0, direction="up",
                                       settle_cycles=100, integrate_cycles=100,
                                       resolution_hz=2.5, preload_strain=preload, simulated=True)
                campaign.add_run(f"r{index}-{preload:g}", settings, segment)
    out = tmp_path / "deep" / "report"
    assert main(["report", str(path), "--out", str(out), "--no-diagnosis"]) == 0
    written = sorted(p.relative_to(tmp_path).as_posix() for p in tmp_path.rglob("*")
                     if p.is_file() and p != path)
    assert all(name.startswith("deep/report/") and name.count("/") == 2 for name in written)
    moduli = [name for name in written if "/moduli-" in name]
    assert len(moduli) == len(names)  # one figure per specimen, none overwriting another
    page = (out / "index.html").read_text(encoding="utf-8")
    assert page.count('src="data:image/png;base64,') == len(written) - 1  # every figure shown
    assert html.escape("soft/25 $\\frac{$") in page


def test_a_band_that_misses_the_runs_is_said_and_the_table_stays_known(campaign_file: Path,
                                                                        tmp_path: Path):
    # Table 1 refuses a band holding no point of a specimen run; that used to make the table's
    # M_s, K_s, C_s "unknown (no bare-table run)" for every diagnosis, with a bare table there,
    # and the runs were drawn over their own band without a word
    out = tmp_path / "report"
    assert main(["report", str(campaign_file), "--band", "0:1", "--no-ladder",
                 "--out", str(out)]) == 0
    page = html.unescape((out / "index.html").read_text(encoding="utf-8"))
    assert "Table 1 and 2 not computed: run 'soft-0', band 0:1 Hz: 0 points" in page
    assert "M_s, K_s, C_s are unknown" not in page
    assert page.count("the band 0–1 Hz holds none of its points: shown and diagnosed over its "
                      "own 20–120 Hz") == 2  # soft-0 and soft-10; the bare table has its own


@pytest.mark.parametrize("command", [
    ["identify", "--run", "soft-0", "--no-store"], ["summary"],
    ["diagnose", "--run", "soft-0", "--auto"], ["report", "--no-ladder"],
])
def test_a_band_of_nine_points_is_refused_in_one_line_or_said(campaign_file: Path,
                                                               tmp_path: Path, capsys, command):
    # a fit takes 8 points and estimated its noise from them, which takes 10: with 8 or 9
    # points in the band, identify, summary, diagnose and report stopped with a traceback
    name, *options = command
    out = ["--out", str(tmp_path / "report")] if name == "report" else []
    status = main([name, str(campaign_file), *options, "--band", "20:22", *out])
    err = capsys.readouterr().err
    if name == "report":  # the report goes on, and says why there are no tables
        assert status == 0, err
        page = html.unescape((tmp_path / "report" / "index.html").read_text(encoding="utf-8"))
        assert "band 20:22 Hz: 9 points, a fit needs at least 10" in page
    else:
        assert status == 2 and err.count("\n") == 1, err
        assert "band 20:22 Hz: 9 points, a fit needs at least 10" in err, err


def test_the_report_ends_with_the_bench_journal_escaped(campaign_file: Path, tmp_path: Path):
    path = tmp_path / "noted.h5"
    path.write_bytes(campaign_file.read_bytes())
    with CampaignFile.open(path, "a", durable=False) as campaign:
        campaign.add_journal_entry("note", "specimen slipped <b>twice</b>\nre-tightened",
                                   run="soft-0")
        campaign.add_journal_entry("hold", "level missed 3 times", run="soft-10")
    out = tmp_path / "report"
    assert main(["report", str(path), "--out", str(out), "--no-diagnosis"]) == 0
    page = (out / "index.html").read_text(encoding="utf-8")
    assert '<a href="#journal">Journal</a>' in page
    journal = page.split('<h2 id="journal">Journal</h2>')[1]
    assert ('<td class="text">soft-0</td><td class="text">note</td><td class="text">specimen '
            "slipped &lt;b&gt;twice&lt;/b&gt;<br>re-tightened</td>") in journal
    assert '<td class="text">hold</td><td class="text">level missed 3 times</td>' in journal
    assert main(["report", str(campaign_file), "--out", str(tmp_path / "plain"),
                 "--no-diagnosis"]) == 0
    assert 'id="journal"' not in (tmp_path / "plain" / "index.html").read_text(encoding="utf-8")


def test_runs_measured_beyond_the_band_are_said_so_with_the_command_for_all_of_it(
    tmp_path: Path,
) -> None:
    """A campaign swept 15-200 Hz was reported over the paper's 20-120 Hz without a word but
    the band's: the page now says what was measured and how to analyse all of it."""
    wide = paper_campaign(tmp_path / "wide.h5", runs=("table", "soft-0"), step_hz=1.0,
                          band_hz=(15.0, 200.0))
    notes = analyse_campaign(CampaignFile.open(wide), diagnosis=False, jobs=1).notes
    said = [note for note in notes if "measured over 15–200 Hz" in note]
    assert len(said) == 1 and "report wide.h5 --band 15:200" in said[0]
    assert not [note for note in analyse_campaign(CampaignFile.open(wide), (15.0, 200.0),
                                                  diagnosis=False, jobs=1).notes
                if "measured over" in note]
    paper = paper_campaign(tmp_path / "paper.h5", runs=("table", "soft-0"), step_hz=1.0)
    assert not [note for note in analyse_campaign(CampaignFile.open(paper), diagnosis=False,
                                                  jobs=1).notes if "measured over" in note]


def test_a_stored_table_fit_no_suspension_has_is_said_not_a_traceback(campaign_file: Path,
                                                                      tmp_path: Path):
    """A table fit stored with K_s = -1 N/m (a damaged file) ended the report in a math
    domain error, M_s = 0 in a division by zero. The page says why the stored fit is not
    shown, and shows the table fitted here."""
    path = tmp_path / "damaged.h5"
    path.write_bytes(campaign_file.read_bytes())
    assert main(["identify", str(path), "--run", "table"]) == 0
    with h5py.File(path, "r+") as h5:
        fits = h5["runs/table/fits"]
        fits[sorted(fits)[0]]["K_s"][()] = -1.0
    out = tmp_path / "report"
    assert main(["report", str(path), "--out", str(out), "--no-diagnosis"]) == 0
    page = html.unescape((out / "index.html").read_text(encoding="utf-8"))
    assert ("stored fit not shown: run 'table': stored fit 0001 gives K_s = -1 N/m, which is "
            "above 0 in every table model") in page
    assert "The table suspension rings at 19." in page


def test_a_damaged_stored_fit_is_said_and_the_runs_measurements_still_reported(
        campaign_file: Path, tmp_path: Path):
    """A stored fit whose band reads [nan, nan], or whose K_v is negative, was shown as the
    run's model with those numbers; the run is now reported from its measurements, and the
    page says why its stored fit is not shown."""
    path = tmp_path / "damaged.h5"
    path.write_bytes(campaign_file.read_bytes())
    assert main(["identify", str(path), "--run", "soft-0", "--model", "voigt"]) == 0
    assert main(["identify", str(path), "--run", "soft-10", "--model", "voigt"]) == 0
    with h5py.File(path, "r+") as h5:
        h5["runs/soft-0/fits/0001"].attrs["band_hz"] = [np.nan, np.nan]
        h5["runs/soft-10/fits/0001/K_v"][()] = -1.0
    out = tmp_path / "report"
    assert main(["report", str(path), "--out", str(out), "--no-diagnosis"]) == 0
    page = html.unescape((out / "index.html").read_text(encoding="utf-8"))
    assert ("stored fit not shown: " f"{path}: /runs/soft-0/fits/0001.band_hz: band_hz [nan, nan] "
            "is not a band from 0 to 1e+06 Hz, low end first") in page
    assert ("stored fit not shown: run 'soft-10': stored fit 0001 gives K_v = -1 N/m, which is "
            "above 0 in every voigt model") in page
