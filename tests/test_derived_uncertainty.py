"""Quantities derived from fits carry the fits' uncertainty: Table 2, E' and η (comparisons of
two fits: ``test_compare.py``).

First-order propagation is checked against the spread of the same quantity over parameter
vectors drawn from the fit's own joint covariance (so the check is of the derivatives and the
bookkeeping, which a Monte-Carlo does without them); the table taken from ``/rig`` with and
without a user-given uncertainty is checked through the command line.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from simdata import DEFAULT_NOISE, rig_text, simulate_run

from viscorig.cli import main
from viscorig.estimates import (
    modulus_band,
    natural_frequency,
    system_properties,
    system_properties_with_uncertainty,
)
from viscorig.fitting import Known, fit
from viscorig.models import Context
from viscorig.storage import CampaignFile, RunSettings, Segment

VOIGT = {"mass_kg": 0.25, "model": "voigt", "stiffness_n_per_m": 1.5e5, "damping_ns_per_m": 114.59}
TABLE = {"M_s": 3.4, "K_s": 50194.0, "C_s": 5.05}


@pytest.fixture(scope="module")
def result():
    known = Known.with_stderr(TABLE, {"M_s": 0.002, "K_s": 40.0, "C_s": 0.05}, "given")
    data = simulate_run(rig_text(VOIGT, noise=DEFAULT_NOISE), seed=71).frf_data()
    return fit("voigt", data, known=known)


def _draws(result, count: int = 4000) -> list[dict[str, float]]:
    rng = np.random.default_rng(0)
    names = list(result.covariance_names)
    centre = np.array([result.values[n] for n in names])
    samples = rng.multivariate_normal(centre, result.joint_covariance, size=count)
    return [{**result.values, **dict(zip(names, row, strict=True))} for row in samples]


def test_table_2_uncertainty_matches_the_spread_of_the_parameters(result) -> None:
    draws = _draws(result)
    quantities = system_properties_with_uncertainty(result)
    spread = {
        "f_r": np.std([system_properties(v).natural_frequency_hz for v in draws]),
        "xi": np.std([system_properties(v).damping_factor for v in draws]),
        "B_r": np.std([system_properties(v).bandwidth_hz for v in draws]),
    }
    for name, quantity in quantities.items():
        assert quantity.stderr == pytest.approx(spread[name], rel=0.06), name
    assert quantities["f_r"].unit == "Hz"
    assert quantities["f_r"].value == pytest.approx(natural_frequency(result.values))


def test_storage_modulus_and_loss_factor_bands(result) -> None:
    frequency = np.array([20.0, 60.0, 120.0])
    band = modulus_band(result, frequency, theta_m=0.01)
    draws = _draws(result, 3000)
    kstar = np.array([result.model.kstar(Context(frequency), v) for v in draws])
    assert np.allclose(band.storage_modulus_stderr, np.std(kstar.real / 0.01, axis=0), rtol=0.06)
    assert np.allclose(band.loss_factor_stderr, np.std(kstar.imag / kstar.real, axis=0),
                       rtol=0.06)
    # With the table's uncertainty in the model's K*: K_v's stderr sets E' at every frequency.
    assert band.storage_modulus_stderr[0] == pytest.approx(result.stderr["K_v"] / 0.01, rel=1e-3)


def _campaign(path: Path, rig: dict) -> None:
    run = simulate_run(rig_text(VOIGT, noise=DEFAULT_NOISE), seed=72)
    with CampaignFile.create(path, sequence_text="", rig=rig, durable=False) as campaign:
        campaign.start_run("soft-0", RunSettings(
            specimen="soft", level_m_per_s2=1.0, direction="up", settle_cycles=100,
            integrate_cycles=100, resolution_hz=0.25, simulated=True))
        campaign.append_segment("soft-0", Segment(
            run.frequency_hz, run.time_s, run.accelerance_table, run.accelerance_support,
            run.reference_amplitude, np.ones_like(run.time_s), run.force_amplitude, run.flags))
        campaign.finish_run("soft-0")


def test_rig_table_values_are_exact_unless_given_an_uncertainty(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    values = {"table_mass_kg": 3.4, "table_stiffness_n_per_m": 50194.0,
              "table_damping_ns_per_m": 5.05}
    exact, uncertain = tmp_path / "exact.h5", tmp_path / "uncertain.h5"
    _campaign(exact, values)
    _campaign(uncertain, {**values, "table_stiffness_stderr_n_per_m": 50.0})
    documents = []
    for path in (exact, uncertain):
        assert main(["identify", str(path), "--run", "soft-0", "--no-store", "--json"]) == 0
        documents.append(json.loads(capsys.readouterr().out))
    assert documents[0]["parameters"]["K_s"]["stderr"] is None
    assert documents[1]["parameters"]["K_s"]["stderr"] == pytest.approx(50.0)
    assert documents[1]["parameters"]["M_s"]["stderr"] is None  # only K_s was given one
    assert documents[1]["uncertainty"]["inherited"] == ["K_s"]
    assert (documents[1]["parameters"]["K_v"]["stderr"]
            > 1.5 * documents[0]["parameters"]["K_v"]["stderr"])  # a 50 N/m table error counts
