"""The technician's quick look: one run's FRFs as a PNG, during or after a sweep.

Reads whatever the campaign file holds (a run still "running" shows the points committed so
far), draws the measured FRFs with flagged points marked, and the latest stored fit if there is
one. Nothing is fitted, so it takes well under a second.
"""

from __future__ import annotations

from pathlib import Path

from viscorig.errors import InputError
from viscorig.identify import is_bare_table, read_fit
from viscorig.report.analysis import RunAnalysis
from viscorig.report.figures import frf_figure
from viscorig.storage import CampaignFile


def default_png(campaign_path: Path, run_name: str, out: str | None) -> Path:
    """``out``, else ``<campaign stem>-<run>.png`` beside the campaign file."""
    if out:
        return Path(out)
    return campaign_path.with_name(f"{campaign_path.stem}-{run_name}.png")


def plot_run(campaign_path: Path, run_name: str, out: Path) -> Path:
    """Write the FRF figure of run ``run_name`` to ``out`` (PNG); return ``out``.

    Raises
    ------
    InputError
        No such run, a run with no point yet, or ``out`` cannot be written.
    """
    campaign = CampaignFile.open(campaign_path)
    run = campaign.run(run_name).merged()  # one point per frequency, as analysis reads a run
    if not run.points:
        raise InputError("has no measured point yet", f"run '{run_name}'")
    analysis = RunAnalysis(run, is_bare_table(run), (0.0, 0.0))
    try:
        stored = campaign.fits(run_name)
        analysis.shown = read_fit(stored[-1]) if stored else None
    except InputError:  # a damaged fit: the measurements are still drawn
        analysis.shown = None
    figure = frf_figure(analysis)
    try:
        figure.savefig(out, format="png", dpi=100)
    except OSError as error:
        raise InputError(f"cannot write the figure ({error.strerror})", str(out)) from None
    return out
