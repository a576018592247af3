"""The report's figures as drawn: no text leaves the canvas, no legend covers data or labels,
no two step labels of a ladder overlap, whatever the length of the model specs they name."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import materialdata
import numpy as np
import pytest
from campaigndata import paper_campaign
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure
from matplotlib.transforms import Bbox

from viscorig.materials.dmastore import import_dma
from viscorig.materials.sources import master_curve
from viscorig.materials.table import ModulusTable
from viscorig.report import analyse_campaign
from viscorig.report.analysis import Rung, rubbers
from viscorig.report.figures import (
    frf_figure,
    ladder_figure,
    moduli_figure,
    preload_figure,
    residual_figure,
    wrapped,
)
from viscorig.report.materials import master_figure, master_residual_figure
from viscorig.storage import CampaignFile

#: Pixels two boxes may share, or a box may stand past the canvas (antialiasing, rounding).
SLACK_PX = 1.0


def _overlap(a: Bbox, b: Bbox) -> bool:
    return (a.x0 < b.x1 - SLACK_PX and b.x0 < a.x1 - SLACK_PX
            and a.y0 < b.y1 - SLACK_PX and b.y0 < a.y1 - SLACK_PX)


def _inside(box: Bbox, frame: Bbox) -> bool:
    return (box.x0 >= frame.x0 - SLACK_PX and box.x1 <= frame.x1 + SLACK_PX
            and box.y0 >= frame.y0 - SLACK_PX and box.y1 <= frame.y1 + SLACK_PX)


def layout_problems(figure: Figure) -> list[str]:
    """What a reader would see wrong in ``figure`` as Agg draws it."""
    canvas = FigureCanvasAgg(figure)
    canvas.draw()
    renderer = canvas.get_renderer()
    frame = figure.bbox
    problems = []
    tight = {ax: ax.get_tightbbox(renderer) for ax in figure.axes}
    for index, ax in enumerate(figure.axes):
        if not _inside(tight[ax], frame):
            problems.append(f"axes {index}: its labels run past the figure's edge")
        labels = [text for text in ax.get_xticklabels() if text.get_text().strip()]
        boxes = [text.get_window_extent(renderer) for text in labels]
        for i in range(len(boxes) - 1):
            if _overlap(boxes[i], boxes[i + 1]):
                problems.append(f"axes {index}: tick labels {labels[i].get_text()!r} and "
                                f"{labels[i + 1].get_text()!r} overlap")
    legends = list(figure.legends) + [ax.get_legend() for ax in figure.axes
                                      if ax.get_legend() is not None]
    for legend in legends:
        box = legend.get_window_extent(renderer)
        if not _inside(box, frame):
            problems.append("a legend runs past the figure's edge")
        for index, ax in enumerate(figure.axes):
            if _overlap(box, ax.get_window_extent(renderer)):
                problems.append(f"a legend covers the data of axes {index}")
            elif legend.axes is not ax and _overlap(box, tight[ax]):
                problems.append(f"a legend covers the labels of axes {index}")
    for text in figure.texts:
        if text.get_text().strip() and not _inside(text.get_window_extent(renderer), frame):
            problems.append(f"{text.get_text()!r} runs past the figure's edge")
    return problems


@pytest.fixture(scope="module")
def analysis(tmp_path_factory: pytest.TempPathFactory):
    pytest.importorskip("viscorig.diagnosis")
    path = paper_campaign(tmp_path_factory.mktemp("layout") / "paper.h5",
                          runs=("table", "soft-0", "soft-10"))
    with np.errstate(all="ignore"):
        return analyse_campaign(CampaignFile.open(path), ladder=False, jobs=1)


#: Specs as long as a ladder reaches (a Maxwell K* of many arms, modes, sensors, a drift).
LONG = ("maxwell(4)+load_cell+fixture(37.19)+fixture(57.99)+fixture(92.01)+delay(x_v)"
        "+highpass(F_e)+gain(x_s)+drift")


class _Renamed:
    """A fit shown under another (longer) spec: its curves, the name in the legends."""

    def __init__(self, fit, spec: str) -> None:
        self._fit, self.spec = fit, spec

    def __getattr__(self, name: str):
        return getattr(self._fit, name)


def _climbed(run, specs: list[str]):
    rungs = [Rung(spec, 10.0 ** -(2 + i / 2), 2e-4) for i, spec in enumerate(specs)]
    return dataclasses.replace(run, climb=dataclasses.replace(run.climb, rungs=rungs))


def test_every_figure_of_a_diagnosed_campaign_is_laid_out_cleanly(analysis) -> None:
    groups = rubbers(analysis)
    figures = {"moduli": moduli_figure("soft", groups["soft"], analysis.theta_m),
               "preload": preload_figure(groups)}
    for run in analysis.runs:
        figures[f"frf-{run.name}"] = frf_figure(run)
        for name, builder in (("residual", residual_figure), ("ladder", ladder_figure)):
            figure = builder(run)
            if figure is not None:
                figures[f"{name}-{run.name}"] = figure
    assert {"frf-soft-0", "residual-soft-0", "ladder-soft-0", "moduli", "preload"} <= set(figures)
    problems = {name: layout_problems(figure) for name, figure in figures.items()}
    assert {name: found for name, found in problems.items() if found} == {}


@pytest.mark.parametrize("specs", [
    ["voigt", "maxwell(2)+fixture(37.19)", "maxwell(2)+load_cell+fixture(37.19)+fixture(58)"
     "+fixture(92)", "fractional+load_cell+fixture(37.19)+fixture(58)+fixture(92)"],
    ["voigt", LONG, LONG.replace("maxwell(4)", "fractional"), LONG + "+amplitude",
     "fractional+load_cell", "fractional", "voigt+delay", "voigt"],
])
def test_a_climbed_ladder_names_every_step_legibly(analysis, specs: list[str]) -> None:
    soft = _climbed(analysis.run("soft-0"), specs)
    assert layout_problems(ladder_figure(soft)) == []
    run = dataclasses.replace(soft, shown=_Renamed(soft.shown, LONG))
    for builder in (frf_figure, residual_figure):
        assert layout_problems(builder(run)) == [], builder.__name__


def test_the_material_figures_are_laid_out_cleanly(tmp_path: Path) -> None:
    path = tmp_path / "dma.h5"
    data = materialdata.dma_sweep(np.arange(-20.0, 61.0, 10.0), np.geomspace(0.1, 100.0, 16),
                               seed=3)
    import_dma(path, "sweep", ModulusTable(**data, source="generated"))
    with np.errstate(all="ignore"):
        master = master_curve(CampaignFile.open(path), ["sweep"])
    for builder in (master_figure, master_residual_figure):
        assert layout_problems(builder(master)) == [], builder.__name__


def test_a_legend_inside_the_axes_is_found_where_it_covers_data() -> None:
    """The check itself: the legends the report used to draw inside its axes are caught."""
    figure = Figure(figsize=(6, 3))
    left, right = figure.subplots(1, 2)
    for ax in (left, right):
        ax.plot([0, 1], [0, 1], label="a curve with a long name " * 3)
    left.legend(loc="upper left")
    left.set_xticks([0, 0.5, 1], ["a long tick label"] * 3)
    found = layout_problems(figure)
    assert "a legend covers the data of axes 0" in found
    assert "a legend covers the data of axes 1" in found
    assert any("overlap" in problem for problem in found)


def test_specs_wrap_between_terms_and_signs_stay_with_their_terms() -> None:
    assert wrapped("fractional+load_cell+fixture(37.19)", 12) == (
        "fractional+\nload_cell+\nfixture(37.19)")
    assert wrapped("+ maxwell(2) − voigt", 12) == "+ maxwell(2)\n− voigt"
    assert wrapped("noise floor 0.0002", 40) == "noise floor 0.0002"
    for width in (5, 10, 20, 40):
        lines = wrapped(LONG + " (diagnosis ladder, both FRFs)", width).split("\n")
        assert "".join(lines).replace(" ", "") == (LONG + "(diagnosisladder,bothFRFs)")
        assert all(len(line) <= width or ("+" not in line.rstrip("+") and " " not in line)
                   for line in lines)


def test_the_figures_of_a_report_are_files_of_their_stems(tmp_path: Path, analysis) -> None:
    from viscorig.report.figures import campaign_figures

    saved = campaign_figures(analysis, tmp_path)
    assert sorted(p.stem for p in tmp_path.glob("*.png")) == sorted(saved)
    assert all((tmp_path / f"{stem}.png").read_bytes() == figure.png
               for stem, figure in saved.items())
