"""Build the report: analyse once, draw every figure, write the page and the figure files."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from viscorig.errors import InputError
from viscorig.identify import PAPER_BAND_HZ
from viscorig.report.analysis import analyse_campaign
from viscorig.report.figures import campaign_figures
from viscorig.report.page import build_page
from viscorig.storage import Campaign

PAGE_NAME = "index.html"


def build_report(
    campaign_path: Path,
    out_dir: Path,
    *,
    band_hz: tuple[float, float] = PAPER_BAND_HZ,
    diagnosis: bool = True,
    ladder: bool = False,
) -> Path:
    """Write ``out_dir/index.html`` and every figure as ``.png`` and ``.svg``; return the page.

    Raises
    ------
    InputError
        The campaign cannot be read, has no run, or ``out_dir`` cannot be written.
    """
    campaign = Campaign.open(campaign_path)
    if not campaign.run_names:
        raise InputError("has no run to report", str(campaign_path))
    try:
        out_dir.mkdir(parents=True, exist_ok=True)
    except OSError as error:
        raise InputError(f"cannot create the report folder ({error.strerror})",
                         str(out_dir)) from None
    with np.errstate(all="ignore"):  # trial fits at a bound warn; their results are checked
        analysis = analyse_campaign(campaign, band_hz, diagnosis=diagnosis, ladder=ladder)
    figures = campaign_figures(analysis, out_dir)
    page = out_dir / PAGE_NAME
    page.write_text(build_page(analysis, figures, f"viscorig report: {Path(campaign_path).name}"),
                    encoding="utf-8")
    return page
