"""The public notebook API: runs by name, fits and diagnoses, pandas/xarray, short reprs."""

from __future__ import annotations

import math
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from campaigndata import paper_campaign

import viscorig
from viscorig.errors import InputError
from viscorig.storage import CampaignFile


@pytest.fixture(scope="module")
def path(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return paper_campaign(tmp_path_factory.mktemp("api") / "c.h5",
                          runs=("table", "soft-0", "soft-10"), step_hz=1.0)


def test_runs_by_name_and_in_order(path: Path):
    campaign = viscorig.open_campaign(path)
    assert [run.name for run in campaign] == ["table", "soft-0", "soft-10"] == campaign.names
    assert len(campaign) == 3 and "soft-0" in campaign and "hard-0" not in campaign
    run = campaign["soft-0"]
    stored = CampaignFile.open(path).run("soft-0")
    assert np.array_equal(run.frequency_hz, stored.frequency_hz)  # the stored run's arrays
    assert run.metadata.specimen == "soft" and not run.bare and campaign["table"].bare
    with pytest.raises(InputError, match="no such run"):
        campaign["hard-0"]
    with pytest.raises(InputError):
        viscorig.open_campaign(path.with_name("missing.h5"))


def test_run_as_pandas_and_xarray_keeps_points_and_units(path: Path):
    pytest.importorskip("pandas")
    pytest.importorskip("xarray")
    run = viscorig.open_campaign(path)["soft-0"]
    stored = CampaignFile.open(path).run("soft-0")
    frame = run.to_pandas()
    assert frame.index.name == "frequency_hz"
    assert np.array_equal(frame.index.to_numpy(), stored.frequency_hz)
    assert np.array_equal(frame["accelerance_support"].to_numpy(), stored.accelerance_support)
    assert frame.attrs["units"]["frequency_hz"] == "Hz"
    assert frame.attrs["units"]["accelerance_table"] == "m/s^2/N"
    assert frame.attrs["units"]["force_amplitude"] == "N"
    assert frame.attrs["preload_strain"] == 0.0 and frame.attrs["run"] == "soft-0"
    dataset = run.to_xarray()
    assert list(dataset.coords) == ["frequency_hz"]
    assert dataset["frequency_hz"].attrs["units"] == "Hz"
    assert dataset["reference_amplitude"].attrs["units"] == "m/s^2"
    assert np.array_equal(dataset["accelerance_table"].values, stored.accelerance_table)
    assert dataset.attrs["specimen"] == "soft"
    # The coordinate selects by frequency, as a person would.
    assert dataset.sel(frequency_hz=60.0)["accelerance_table"].item() == pytest.approx(
        stored.accelerance_table[stored.frequency_hz == 60.0][0])


def test_a_fit_as_tables_matches_its_own_prediction(path: Path):
    pytest.importorskip("xarray")
    campaign = viscorig.open_campaign(path)
    fit = campaign.identify("soft-0", "maxwell", band_hz=(30, 110))
    assert fit.result is not None and fit.model.startswith("maxwell(")
    frame = fit.to_pandas()
    assert frame.index.min() >= 30 and frame.index.max() <= 110
    stored = CampaignFile.open(path).run("soft-0")
    inside = (stored.frequency_hz >= 30) & (stored.frequency_hz <= 110)
    model = fit.result.predict(stored.frequency_hz[inside])["support"]
    assert np.allclose(frame["model_support"].to_numpy(), model)
    residual = model / stored.accelerance_support[inside] - 1
    assert np.allclose(frame["residual_support"].to_numpy(), residual)
    # rms of the residual columns is the fit's rms_error (both FRFs, every point)
    both = np.concatenate([frame["residual_table"], frame["residual_support"]])
    assert math.sqrt(np.mean(np.abs(both) ** 2)) == pytest.approx(fit.rms_error, rel=1e-6)
    table = fit.parameter_table()
    assert table.loc["K_0", "unit"] == "N/m" and table.loc["K_0", "stderr"] > 0
    assert math.isnan(table.loc["M_s", "stderr"])  # held at the table run's value
    dataset = fit.to_xarray()
    assert dataset["K_0"].attrs["units"] == "N/m"
    assert dataset["K_0"].item() == pytest.approx(fit.result.values["K_0"])
    assert dataset.attrs["model"] == fit.model


@pytest.mark.slow
def test_short_reprs_and_html_views(path: Path):
    campaign = viscorig.open_campaign(path)
    run = campaign["soft-0"]
    fit = campaign.identify("soft-0")
    diagnosis = campaign.diagnose("soft-0")
    for item in (campaign, run, fit, diagnosis):
        assert len(repr(item)) < 300, repr(item)
    assert repr(run).startswith("<Run soft-0: soft, 25 Shore A, no preload, complete, 101 points")
    assert "far above the noise" in repr(fit) and "K_v = " in repr(fit) and " ± " in repr(fit)
    assert "most likely missing: frequency_dependent_modulus" in repr(diagnosis)
    assert "<table>" in run._repr_html_() and "101" in run._repr_html_()
    assert "value ± standard error" in fit._repr_html_()
    page = diagnosis._repr_html_()
    assert "Candidate effects on voigt" in page and "strong evidence" in page
    assert "most likely missing" in page
    # the internal objects' reprs are short too, not every point of every array
    assert len(repr(run.stored)) < 1000
    assert len(repr(diagnosis.internal)) < 20_000


def test_stored_fits_and_storing(path: Path, tmp_path: Path):
    copy = tmp_path / "c.h5"
    copy.write_bytes(path.read_bytes())
    with pytest.raises(InputError, match="read-only"):
        viscorig.open_campaign(copy).identify("soft-0", store=True)
    campaign = viscorig.open_campaign(copy, mode="a")
    made = campaign.identify("soft-0", "voigt", store=True)
    (stored,) = campaign["soft-0"].fits
    assert stored.result.stored and stored.model == "voigt"
    assert stored.parameters["K_v"][0] == pytest.approx(made.parameters["K_v"][0])
    assert stored.parameters["K_v"][1] == pytest.approx(made.parameters["K_v"][1])
    assert made.source == stored.source == "stored fit 0001"


def test_compare_runs_gives_the_change_with_its_uncertainty(path: Path):
    from viscorig.compare import compare_fits
    from viscorig.identify import identify_run

    campaign = viscorig.open_campaign(path)
    comparison = campaign.compare("soft-0", "soft-10")
    stored = CampaignFile.open(path)
    before, _ = identify_run(stored, "soft-0", "voigt", band_hz=(20, 120))
    after, _ = identify_run(stored, "soft-10", "voigt", band_hz=(20, 120))
    (expected,) = compare_fits(before, after, ["K_v"])
    k_v = comparison["K_v"]
    assert k_v.relative == pytest.approx(expected.relative)
    assert k_v.relative_stderr == pytest.approx(expected.relative_stderr)
    assert k_v.significant and 0.05 < k_v.relative < 0.15
    assert f"K_v {k_v.percent()}" in repr(comparison)
    frame = comparison.to_pandas()
    assert frame.loc["K_v", "relative_change"] == pytest.approx(k_v.relative)


def test_importing_viscorig_stays_light():
    probe = ("import sys, viscorig\n"
             "print(sorted({'numpy', 'h5py', 'pandas', 'xarray'} & set(sys.modules)))\n"
             "print(viscorig.open_campaign.__module__)\n")
    result = subprocess.run([sys.executable, "-c", probe], capture_output=True, text=True,
                            check=True)
    assert result.stdout.split("\n")[:2] == ["[]", "viscorig.api"]
