"""One estimator for the project, one reading of a run.

- Fits weighted by each point's noise (the project's estimate) against the paper's uniform
  weighting, on sweeps the time-domain simulator measured: the same truth, several times the
  precision, honest ± both.
- A run an adaptive plan measured (repeats of one frequency, any order) reads, for every
  analysis, as one point per frequency in frequency order, each repeat weighted by its noise; its
  noise is the analyser's variance at face value, where a sweep's would be read from the
  differences of neighbouring points.
"""

from __future__ import annotations

import numpy as np
import pytest
from planning_rig import TABLE, VOIGT_RIG, VOIGT_TRUTH, SimulatedRig, paper_sweep
from simdata import DEFAULT_NOISE, rig_text, simulate_run

from viscorig.fitting import FrfData, estimate_noise, fit
from viscorig.fitting.noise_estimation import regular_grid
from viscorig.storage import CampaignFile, RunSettings, Segment

NAMES = ("K_v", "C_v", "M_v")


def test_the_noise_weighted_fit_holds_several_times_the_information_of_the_uniform_one() -> None:
    """On the paper's own sweep (20-120 Hz every 0.25 Hz, 100 + 100 periods) of a Voigt rig:
    the uniform fit uses a fraction of what the points hold; weighted by the noise the same
    points give standard errors several times smaller, and both cover the truth."""
    ratios, z = [], {"noise": [], "uniform": []}
    for seed in range(4):
        data = paper_sweep(SimulatedRig(VOIGT_RIG, 1.4, seed=500 + seed)).frf_data()
        noise = estimate_noise(data)
        fits = {w: fit("voigt", data, fixed=TABLE, noise=noise, weighting=w)
                for w in ("noise", "uniform")}
        assert fits["noise"].weighting == "noise" and fits["uniform"].weighting == "uniform"
        ratios.append([fits["uniform"].stderr[n] / fits["noise"].stderr[n] for n in NAMES])
        for weighting, result in fits.items():
            z[weighting] += [(result.values[n] - VOIGT_TRUTH[n]) / result.stderr[n]
                             for n in NAMES]
    assert np.median(np.array(ratios)[:, :2]) > 3.0  # K_v and C_v
    for weighting, values in z.items():
        assert np.max(np.abs(values)) < 4.0, (weighting, values)


def test_a_noise_weighted_fit_of_a_misfitting_model_says_so_and_scales_its_errors() -> None:
    """The frame under the table, left out of the model: the weighted residual leaves more than
    the noise explains, and the ± grow with it."""
    frame = "[frame]\nmass_kg = 2000.0\nfrequency_hz = 3.0\ndamping_ratio = 0.1\n"
    quiet = {"excitation_force_n_per_sqrt_hz": 2e-5, "table_acceleration_m_per_s2_per_sqrt_hz":
             2e-6, "device_force_n_per_sqrt_hz": 2e-5, "disc_acceleration_m_per_s2_per_sqrt_hz":
             2e-6}
    run = simulate_run(rig_text(noise=quiet, extra=frame), seed=41, start_hz=12.0,
                       stop_hz=28.0, step_hz=0.125, settle_cycles=200.0)
    plain = fit("table", run.frf_data(), weighting="noise")
    framed = fit("table+frame(2000)", run.frf_data(), weighting="noise")
    assert plain.misfit_scale > 1.5 and framed.misfit_scale < plain.misfit_scale
    assert plain.stderr["K_s"] > framed.stderr["K_s"]


def _store(tmp_path, frequency, table, variance, integrate=None):
    n = frequency.size
    campaign = CampaignFile.create(tmp_path / "c.h5", sequence_text="", durable=False)
    campaign.start_run("r", RunSettings(specimen="soft", level_m_per_s2=1.0, direction="up",
                                        settle_cycles=10, integrate_cycles=10,
                                        resolution_hz=0.25))
    campaign.append_segment("r", Segment(
        frequency_hz=frequency, time_s=np.arange(1.0, n + 1.0), accelerance_table=table,
        accelerance_support=table * 2.0, reference_amplitude=np.ones(n),
        source_amplitude=np.full(n, np.nan), force_amplitude=np.full(n, 10.0),
        flags=np.zeros(n, dtype=np.uint16), variance_table=variance, variance_support=variance,
        settle_cycles=np.full(n, 10), integrate_cycles=integrate if integrate is not None
        else np.full(n, 10),
    ), {"test_time_s": float(n)})
    return campaign


def test_a_run_with_repeats_reads_as_one_point_per_frequency_weighted_by_its_noise(tmp_path):
    frequency = np.array([30.0, 20.0, 30.0, 25.0, 30.0])
    table = np.array([1.0 + 1j, 2.0, 3.0 + 3j, 4.0, 5.0 - 1j])
    variance = np.array([1e-4, 1e-4, 4e-4, 1e-4, 1e-4])
    campaign = _store(tmp_path, frequency, table, variance, np.array([10, 10, 5, 10, 10]))
    run = campaign.run("r")
    assert run.points == 5 and campaign.run_attributes("r")["test_time_s"] == 5.0
    np.testing.assert_array_equal(run.integrate_cycles, [10, 10, 5, 10, 10])
    merged = run.merged()
    np.testing.assert_array_equal(merged.frequency_hz, [20.0, 25.0, 30.0])
    weights = 1.0 / variance[[0, 2, 4]]
    expected = np.sum(table[[0, 2, 4]] * weights) / weights.sum()
    assert merged.accelerance_table[2] == pytest.approx(expected)
    assert merged.variance_table[2] == pytest.approx(1.0 / weights.sum())
    assert merged.integrate_cycles[2] == 25 and merged.accelerance_table[0] == 2.0
    # a sweep (up or down, no repeat) is read as it was measured
    down = _store(tmp_path / "..", np.array([30.0, 25.0, 20.0]), table[:3], variance[:3])
    assert down.run("r").merged().frequency_hz.tolist() == [30.0, 25.0, 20.0]


def test_a_plan_grid_takes_the_analysers_variance_at_face_value() -> None:
    """Differences of neighbours read the noise on a sweep's grid; between a plan's sparse and
    repeated points they would read the FRF's shape."""
    run = simulate_run(rig_text({"mass_kg": 0.25, "model": "voigt",
                                 "stiffness_n_per_m": 1.5e5, "damping_ns_per_m": 114.59},
                                noise=DEFAULT_NOISE), seed=3)
    data = run.frf_data()
    assert regular_grid(data.frequency_hz)
    sweep = estimate_noise(data, ("table",)).blocks["table"][0]
    assert sweep.source == "analyser variance"
    pick = np.r_[0:400:37, 10, 10, 150, 150, 150, 399]  # sparse, with repeats
    sparse = FrfData(data.frequency_hz[pick], data.table[pick], time_s=np.arange(pick.size),
                     variance_table=data.variance_table[pick])
    assert not regular_grid(sparse.frequency_hz)
    noise = estimate_noise(sparse, ("table",)).blocks["table"][0]
    np.testing.assert_allclose(noise.white_power, data.variance_table[pick])
    assert not noise.correlated
    # without the variance, the differences are all there is, and the noise says so
    bare = FrfData(sparse.frequency_hz, sparse.table)
    assert estimate_noise(bare, ("table",)).blocks["table"][0].source.endswith("(irregular grid)")
