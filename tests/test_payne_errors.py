"""The Payne fit's standard errors mean what they say, on runs made by a generator of its own.

Three runs of one specimen at three acceleration levels share their frequencies; each run's K*
carries complex noise of the relative variance the analyser reports for it. The differences
against the lowest-level run then share that run's noise, and a fit that took them as
independent would report errors too small. The generator below writes Kraus's model from the
literature (Kraus 1984: ``G' − G'_∞ = ΔG'/(1 + a^{2m})``, ``G'' − G''_∞ = 2ΔG''_m a^m/(1 +
a^{2m})``, ``a`` the amplitude over its critical value), a matrix rubber that cancels in the
differences, and the analyser's normalized variance; it shares no code with
:mod:`viscorig.strain`. Over many realisations the errors of every parameter must cover the
truth as a standard deviation does.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from viscorig.storage import CampaignFile, RunSettings, Segment
from viscorig.strain import identify_payne

TRUTH = {"K_f": 3.0e4, "L_f": 4.0e3, "x_c": 2.0e-5, "m_k": 0.6}
LEVELS_M_PER_S2 = {"strain-low": 0.3, "strain-mid": 1.0, "strain-high": 3.0}
FREQUENCY_HZ = np.arange(20.0, 120.1, 2.0)
#: Relative noise of K* (rms of |δK/K|) of a run at 1 m/s²; it grows as the level falls.
NOISE_AT_1 = 2e-3
REALISATIONS = 80

pytestmark = pytest.mark.slow  # 80 campaigns, about 30 s


def filler_network(amplitude_m: np.ndarray) -> np.ndarray:
    """Kraus's storage and loss parts above the matrix's, as complex stiffness (N/m)."""
    a = amplitude_m / TRUTH["x_c"]
    power = a ** TRUTH["m_k"]
    denominator = 1.0 + a ** (2.0 * TRUTH["m_k"])
    storage = TRUTH["K_f"] / denominator
    loss = 2.0 * TRUTH["L_f"] * power / denominator
    return storage + 1j * loss


def write_campaign(path: Path, rng: np.random.Generator, specimens: int) -> None:
    """``specimens`` realisations, the runs of specimen ``i`` named ``{level}-{i}``."""
    omega = 2.0 * np.pi * FREQUENCY_HZ
    matrix = 2.0e5 * (FREQUENCY_HZ / 50.0) ** 0.12 * (1.0 + 0.15j)
    campaign = CampaignFile.create(path, sequence_text="# generated\n", durable=False,
                                   rig={"specimen_height_m": 0.012, "specimen_count": 2})
    for (name, level), index in ((item, i) for i in range(specimens)
                                 for item in LEVELS_M_PER_S2.items()):
        name = f"{name}-{index}"
        kstar = matrix + filler_network(level / omega**2)
        relative_variance = (NOISE_AT_1 / level) ** 2
        noise = rng.normal(size=(FREQUENCY_HZ.size, 2)) @ np.array([1.0, 1j])
        measured = kstar * (1.0 + noise * np.sqrt(relative_variance / 2.0))
        support = -(omega**2) / measured  # ẍ_v/F_v = −ω²/K* (Eq. 5, M_v left out)
        campaign.start_run(name, RunSettings(
            specimen="filled", level_m_per_s2=level, direction="up", settle_cycles=100,
            integrate_cycles=100, resolution_hz=2.0, temperature_c=25.0,
            instrument="generated", simulated=True))
        n = FREQUENCY_HZ.size
        campaign.append_segment(name, Segment(
            frequency_hz=FREQUENCY_HZ, time_s=np.arange(n, dtype=float),
            accelerance_table=np.full(n, 1.0 + 0j), accelerance_support=support,
            reference_amplitude=np.full(n, level), source_amplitude=np.full(n, 0.1),
            force_amplitude=np.full(n, 1.0), flags=np.zeros(n, dtype=int),
            variance_support=np.full(n, relative_variance)))
        campaign.finish_run(name)


@pytest.fixture(scope="module")
def fits(tmp_path_factory: pytest.TempPathFactory) -> list:
    rng = np.random.default_rng(20261125)
    folder = tmp_path_factory.mktemp("payne")
    out = []
    for index in range(REALISATIONS):
        path = folder / f"payne-{index}.h5"
        write_campaign(path, rng, 1)
        runs = [f"{name}-0" for name in reversed(LEVELS_M_PER_S2)]  # the order given is not kept
        out.append(identify_payne(CampaignFile.open(path), runs))
    return out


def test_runs_ordered_by_amplitude_and_every_point_fitted(fits: list) -> None:
    assert fits[0].runs == ("strain-low-0", "strain-mid-0", "strain-high-0")
    assert fits[0].points == 2 * FREQUENCY_HZ.size


@pytest.mark.parametrize("name", list(TRUTH))
def test_errors_cover_the_truth_as_a_standard_deviation_does(fits: list, name: str) -> None:
    z = np.array([(fit.parameters[name].value - TRUTH[name]) / fit.parameters[name].stderr
                  for fit in fits])
    # 80 realisations: the rms of unit normal z has a standard deviation of 0.08. Taken as
    # independent, the differences give 1.25, 1.29, 1.30 and 1.11 for these four parameters
    # on these realisations (this fit's: 0.96, 1.04, 0.95, 0.98).
    assert 0.8 < float(np.sqrt(np.mean(z**2))) < 1.17
    assert abs(float(np.mean(z))) < 0.4
    assert np.max(np.abs(z)) < 4.5


def test_reduced_chi_square_is_one_when_the_misfit_is_the_noise(fits: list) -> None:
    chi2 = np.array([fit.reduced_chi_square for fit in fits])
    # 98 degrees of freedom each: the mean of 80 has a standard deviation of 0.016
    assert float(np.mean(chi2)) == pytest.approx(1.0, abs=0.06)
