"""The report reads each run of the campaign file once, however many ladders look at it."""

from __future__ import annotations

from collections import Counter, OrderedDict
from pathlib import Path

import numpy as np
import pytest
from campaigndata import paper_campaign

from viscorig.report import analyse_campaign
from viscorig.storage import CampaignFile


class CountingCampaign(CampaignFile):
    """A campaign that counts the runs read from its file."""

    reads: Counter

    def run(self, name):
        self.reads[name] += 1
        return super().run(name)


@pytest.mark.slow
def test_each_run_is_read_once_for_tables_figures_and_diagnoses(tmp_path: Path):
    path = paper_campaign(tmp_path / "paper.h5", runs=("table", "soft-0", "soft-10"))
    campaign = CountingCampaign.open(path)
    campaign.reads = Counter()
    with np.errstate(all="ignore"):
        analysis = analyse_campaign(campaign, ladder=False, jobs=1)
    assert [run.name for run in analysis.runs] == ["table", "soft-0", "soft-10"]
    assert all(run.climb is not None for run in analysis.runs if not run.bare)
    assert dict(campaign.reads) == {"table": 1, "soft-0": 1, "soft-10": 1}


@pytest.mark.slow
def test_each_frf_noise_is_estimated_once_for_tables_figures_and_diagnoses(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch):
    from viscorig.fitting import noise_estimation

    path = paper_campaign(tmp_path / "paper.h5", runs=("table", "soft-0", "soft-10"))
    made: Counter = Counter()
    estimated = noise_estimation._estimated

    def counted(frf, *arguments):
        made[(arguments[3], frf.size, complex(frf[0]))] += 1
        return estimated(frf, *arguments)

    monkeypatch.setattr(noise_estimation, "_estimated", counted)
    monkeypatch.setattr(noise_estimation, "_estimates", OrderedDict())  # none kept from before
    with np.errstate(all="ignore"):
        analyse_campaign(CampaignFile.open(path), ladder=False, jobs=1)
    # the table FRF of each run, the support FRF of each specimen run
    assert len(made) >= 5
    assert set(made.values()) == {1}
