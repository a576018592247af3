"""Build the report: analyse once, draw every figure, write the page and the figure files."""

from __future__ import annotations

import contextlib
import logging
import os
import shutil
import tempfile
import time
from collections.abc import Iterator
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
from viscorig.storage.room import cause

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
    _check_writable(out_dir)
    title = f"viscorig report: {Path(campaign_path).name}"
    analysis = None
    jobs = default_jobs() if jobs is None else max(1, jobs)
    if campaign.run_names:
        with np.errstate(all="ignore"):  # trial fits at a bound warn; their results are checked
            analysis = analyse_campaign(campaign, band_hz, diagnosis=diagnosis, ladder=ladder,
                                        jobs=jobs, scheduler=scheduler)
        _log.info("analysis: %.1f s (diagnosis %.1f s over %d process(es))", analysis.seconds,
                  analysis.diagnosis_seconds, analysis.jobs)
    with _staged(out_dir) as staging:
        section = material_section(materials, material_figures(materials, staging, svg),
                                   figure_html)
        if analysis is None:
            text = materials_page(title, section, str(campaign_path))
        else:
            started = time.perf_counter()
            figures = campaign_figures(analysis, staging, jobs, svg)
            _log.info("%d figures (%s): %.1f s", len(figures), "PNG and SVG" if svg else "PNG",
                      time.perf_counter() - started)
            text = build_page(analysis, figures, title, section)
        (staging / PAGE_NAME).write_text(text, encoding="utf-8")
    return out_dir / PAGE_NAME


def _check_writable(out_dir: Path) -> None:
    """Refuse, before the analysis, a report folder that cannot be made or written."""
    existing = next(p for p in (out_dir, *out_dir.parents) if p.exists())
    if not existing.is_dir():
        raise InputError(f"cannot create the report folder ({existing} is a file)",
                         str(out_dir))
    if not os.access(existing, os.W_OK | os.X_OK):
        raise InputError(f"cannot create the report folder ({existing} is not writable)",
                         str(out_dir))


@contextlib.contextmanager
def _staged(out_dir: Path) -> Iterator[Path]:
    """A hidden folder beside ``out_dir`` to write the report into; its files replace those of
    ``out_dir`` (made if missing), the page last, only when everything was written. A report
    stopped half way (a run the file refuses, a full disk) leaves ``out_dir`` as it was, not
    an old page beside new figures."""
    try:
        out_dir.parent.mkdir(parents=True, exist_ok=True)
        staging = Path(tempfile.mkdtemp(prefix=f".{out_dir.name}-", dir=out_dir.parent))
    except OSError as error:
        raise InputError(f"cannot create the report folder ({cause(error, out_dir)})",
                         str(out_dir)) from None
    try:
        yield staging
        target = out_dir
        try:
            out_dir.mkdir(exist_ok=True)
            for item in sorted(staging.iterdir(), key=lambda path: path.name == PAGE_NAME):
                target = out_dir / item.name
                os.replace(item, target)
        except OSError as error:
            raise InputError(f"cannot write the report ({cause(error, target)})",
                             str(out_dir)) from None
    finally:
        shutil.rmtree(staging, ignore_errors=True)
