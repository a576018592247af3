"""The one fit type: a fit travels to a worker and back (pickle) and to the campaign file and
back (store_fit / read_fit) as the same fit, and a stored fit that is not whole is refused in
one line."""

from __future__ import annotations

import math
import pickle
from pathlib import Path

import numpy as np
import pytest
from simdata import DEFAULT_NOISE, rig_text, simulate_run

from viscorig.errors import InputError
from viscorig.fitting import Known, fit
from viscorig.identify import read_fit, store_fit
from viscorig.numbers import Estimate
from viscorig.storage import CampaignFile, RunSettings, Segment

DEVICE = {"mass_kg": 0.25, "model": "voigt", "stiffness_n_per_m": 1.5e5,
          "damping_ns_per_m": 114.59}
TABLE = Known({"M_s": 3.4, "K_s": 50194.0, "C_s": 5.05}, ("M_s", "K_s", "C_s"),
              np.diag([0.01, 100.0, 0.05]) ** 2, "run 'table'")


@pytest.fixture(scope="module")
def run():
    return simulate_run(rig_text(DEVICE, noise=DEFAULT_NOISE), seed=11, step_hz=1.0)


@pytest.fixture(scope="module")
def result(run):
    return fit("voigt+fixture(58)", run.frf_data(), known=TABLE, weighting="noise")


def test_a_fit_pickles_as_its_spec_and_predicts_the_same(result):
    back = pickle.loads(pickle.dumps(result))
    assert back.spec == result.spec and back.model is not result.model
    f = np.linspace(20.0, 120.0, 7)
    for frf, values in result.predict(f).items():
        assert np.array_equal(back.predict(f)[frf], values)
    assert back.parameters == result.parameters
    assert np.array_equal(back.joint_covariance, result.joint_covariance)


def test_a_stored_fit_reads_back_as_the_fit_the_file_keeps(tmp_path: Path, run, result):
    path = tmp_path / "c.h5"
    with CampaignFile.create(path, sequence_text="", durable=False) as campaign:
        settings = RunSettings(specimen="soft", level_m_per_s2=1.0, direction="up",
                               settle_cycles=100, integrate_cycles=100, resolution_hz=1.0,
                               simulated=True)
        campaign.add_run("soft-0", settings, Segment(
            run.frequency_hz, run.time_s, run.accelerance_table, run.accelerance_support,
            run.reference_amplitude, np.ones_like(run.time_s), run.force_amplitude, run.flags))
        assert store_fit(campaign, "soft-0", result) == "0001"
        (record,) = campaign.fits("soft-0")
    # the file's record holds the fit's own estimates, in the one value type of the package
    for name in result.covariance_names:
        assert isinstance(record.parameters[name], Estimate)
        assert record.parameters[name] == result.parameters[name]
    stored = read_fit(record)
    assert stored.stored and not result.stored and stored.source == "stored fit 0001"
    assert stored.spec == result.spec and stored.weighting == "noise"
    assert stored.values == pytest.approx(result.values, rel=1e-12)
    # every parameter with a standard error (fitted or inherited) is known, with its
    # correlations; none of the residuals is
    assert set(stored.free) == set(result.covariance_names)
    for name in result.covariance_names:
        assert stored.standard_error(name) == pytest.approx(result.standard_error(name),
                                                            rel=1e-9)
    names = list(result.covariance_names)
    order = [stored.covariance_names.index(name) for name in names]
    assert np.allclose(stored.correlation[np.ix_(order, order)], result.correlation, atol=1e-6)
    assert stored.residuals == {} and stored.influence is None
    assert stored.rms_error == result.rms_error and stored.noise_floor == result.noise_floor
    assert stored.fits_noise == result.fits_noise


def _three_points(path: Path) -> CampaignFile:
    """A campaign file with a run 'soft-0' of three points, open to add fits."""
    campaign = CampaignFile.create(path, sequence_text="", durable=False)
    settings = RunSettings(specimen="soft", level_m_per_s2=1.0, direction="up",
                           settle_cycles=100, integrate_cycles=100, resolution_hz=1.0,
                           simulated=True)
    f = np.linspace(20.0, 30.0, 3)
    campaign.add_run("soft-0", settings, Segment(
        f, f, np.ones(3, complex), np.ones(3, complex), np.ones(3), np.ones(3),
        np.ones(3), np.zeros(3, np.uint16)))
    return campaign


def test_a_stored_fit_that_is_not_whole_is_refused_in_one_line(tmp_path: Path):
    with _three_points(tmp_path / "c.h5") as campaign:
        campaign.add_fit("soft-0", model="voigt", band_hz=(20.0, 30.0), rms_error=0.01,
                         noise_floor=0.01, parameters={"K_v": (1e5, 1e3, "N/m")})
        campaign.add_fit("soft-0", model="voigt(3)", band_hz=(20.0, 30.0), rms_error=0.01,
                         noise_floor=0.01, parameters={"K_v": (1e5, math.nan, "N/m")})
        partial, unknown = campaign.fits("soft-0")
    with pytest.raises(InputError, match="stored fit 0001 lacks") as error:
        read_fit(partial)
    assert "\n" not in str(error.value) and "run 'soft-0'" in str(error.value)
    with pytest.raises(InputError):
        read_fit(unknown)


@pytest.mark.parametrize(("name", "value", "said"), [
    ("K_v", -1.0, "K_v = -1 N/m, which is above 0"),
    ("M_v", 0.0, "M_v = 0 kg, which is above 0"),
    ("C_v", -1e-3, "C_v = -0.001 N·s/m, which is above 0"),
])
def test_a_stored_fit_with_a_value_of_the_wrong_sign_is_refused(
        tmp_path: Path, name: str, value: float, said: str) -> None:
    with _three_points(tmp_path / "c.h5") as campaign:
        parameters = {"K_v": (1e5, 1e3, "N/m"), "C_v": (50.0, 1.0, "N·s/m"),
                      "M_v": (0.07, 0.01, "kg"), "M_s": (3.4, 0.01, "kg"),
                      "K_s": (5e4, 1.0, "N/m"), "C_s": (5.0, 0.1, "N·s/m")}
        campaign.add_fit("soft-0", model="voigt", band_hz=(20.0, 30.0), rms_error=0.01,
                         noise_floor=0.01, parameters={**parameters, name: (value, 1.0, "")})
        (record,) = campaign.fits("soft-0")
    with pytest.raises(InputError, match=f"stored fit 0001 gives {said} in every voigt model"):
        read_fit(record)
