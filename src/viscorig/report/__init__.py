"""Reports: the campaign as one self-contained HTML page with its figures, and the quick look
at one run's FRFs for the technician.

``build_report(path, out_dir)`` analyses a campaign file once (:mod:`.analysis`), draws the
figures (:mod:`.figures`, PNG, and SVG on request), and writes ``index.html`` (:mod:`.page`).
"""

from viscorig.report.analysis import CampaignAnalysis, RunAnalysis, analyse_campaign
from viscorig.report.build import build_report
from viscorig.report.quicklook import plot_run

__all__ = ["CampaignAnalysis", "RunAnalysis", "analyse_campaign", "build_report", "plot_run"]
