"""Build the report: analyse once, draw every figure, write the page and the figure files."""

from __future__ import annotations

import logging
import time
from pathlib import Path

import numpy as np

from viscorig.errors import InputError
from viscorig.identify import PAPER_BAND_HZ
from viscorig.report.analysis import analyse_campaign
from viscorig.report.figures import campaign_figures
from viscorig.report.materials import analyse_materials, material_figures, material_section
from viscorig.report.page import build_page, figure_html, materials_page
from viscorig.report.parallel import default_jobs
from viscorig.storage import CampaignFile

PAGE_NAME = "index.html"

_log = logging.getLogger(__name__)


def build_report(
    campaign_path: Path,
    out_dir: Path,
    *,
    band_hz: tuple[float, float] = PAPER_BAND_HZ,
    diagnosis: bool = True,
    ladder: bool = True,
    jobs: int | None = None,
    scheduler: str | None = None,
    svg: bool = False,
) -> Path:
    """Write ``out_dir/index.html`` and every figure as ``.png`` (and ``.svg`` with ``svg``);
    return the page.

    ``diagnosis``, ``ladder``, ``jobs`` and ``scheduler`` as in
    :func:`~viscorig.report.analysis.analyse_campaign`.

    Raises
    ------
    InputError
        The campaign cannot be read, has no run, or ``out_dir`` cannot be written.
    """
    campaign = CampaignFile.open(campaign_path)
    materials = analyse_materials(campaign)
    if not campaign.run_names and not materials:
        raise InputError("has no run to report", str(campaign_path))
    try:
        out_dir.mkdir(parents=True, exist_ok=True)
    except OSError as error:
        raise InputError(f"cannot create the report folder ({error.strerror})",
                         str(out_dir)) from None
    section = material_section(materials, material_figures(materials, out_dir, svg), figure_html)
    title = f"viscorig report: {Path(campaign_path).name}"
    if not campaign.run_names:
        page = out_dir / PAGE_NAME
        page.write_text(materials_page(title, section, str(campaign_path)), encoding="utf-8")
        return page
    jobs = default_jobs() if jobs is None else max(1, jobs)
    with np.errstate(all="ignore"):  # trial fits at a bound warn; their results are checked
        analysis = analyse_campaign(campaign, band_hz, diagnosis=diagnosis, ladder=ladder,
                                    jobs=jobs, scheduler=scheduler)
    _log.info("analysis: %.1f s (diagnosis %.1f s over %d process(es))", analysis.seconds,
              analysis.diagnosis_seconds, analysis.jobs)
    started = time.perf_counter()
    figures = campaign_figures(analysis, out_dir, jobs, svg)
    _log.info("%d figures (%s): %.1f s", len(figures), "PNG and SVG" if svg else "PNG",
              time.perf_counter() - started)
    page = out_dir / PAGE_NAME
    page.write_text(build_page(analysis, figures, title, section), encoding="utf-8")
    return page
