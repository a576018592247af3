"""Which runs the report's materials section puts together: one specimen and preload measured
at two or more temperatures, whatever the temperatures are (0 °C included)."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from viscorig.report.materials import candidate_groups
from viscorig.storage import CampaignFile, RunSettings, Segment


def _segment() -> Segment:
    f = np.linspace(20.0, 120.0, 5)
    return Segment(frequency_hz=f, time_s=np.arange(f.size) * 2.0,
                   accelerance_table=np.full(f.size, 1e-3 + 0j),
                   accelerance_support=np.full(f.size, 1e-3 + 0j),
                   reference_amplitude=np.ones(f.size), source_amplitude=np.full(f.size, 0.1),
                   force_amplitude=np.full(f.size, 10.0), flags=np.zeros(f.size, np.uint16))


def test_a_run_at_zero_celsius_is_grouped_and_one_of_unknown_temperature_is_not(tmp_path: Path):
    path = tmp_path / "c.h5"
    with CampaignFile.create(path, sequence_text="", durable=False) as campaign:
        for name, temperature, preload in (("soft-0c", 0.0, 0.0), ("soft-25c", 25.0, 0.0),
                                           ("soft-unknown", math.nan, 0.0),
                                           ("soft-10-0c", 0.0, 0.104),
                                           ("soft-10-25c", 25.0, 0.104)):
            settings = RunSettings(specimen="soft", level_m_per_s2=1.0, direction="up",
                                   settle_cycles=100, integrate_cycles=100, resolution_hz=25.0,
                                   preload_strain=preload, temperature_c=temperature,
                                   simulated=True)
            campaign.add_run(name, settings, _segment())
    with CampaignFile.open(path) as campaign:
        assert candidate_groups(campaign) == [("soft-0c", "soft-25c"),
                                              ("soft-10-0c", "soft-10-25c")]


def _series(path: Path, runs: tuple[tuple[str, float, float], ...]) -> Path:
    """A campaign of one specimen's runs ``(name, temperature_c, level_m_per_s2)``."""
    with CampaignFile.create(path, sequence_text="", durable=False) as campaign:
        for name, temperature, level in runs:
            settings = RunSettings(specimen="medium", level_m_per_s2=level, direction="up",
                                   settle_cycles=100, integrate_cycles=100, resolution_hz=25.0,
                                   preload_strain=0.0, temperature_c=temperature,
                                   simulated=True)
            campaign.add_run(name, settings, _segment())
    return path


def test_strain_steps_at_one_temperature_join_no_master_curve(tmp_path: Path):
    # the temperature-strain sequence's campaign: a series at 0.2 m/s² over temperature, then
    # steps at 0.5, 1.5, 4.5 m/s² at 25 °C; the steps measure the amplitude dependence and
    # were put into the master curve (whose shift estimate then stopped the report)
    path = _series(tmp_path / "c.h5", (
        ("T0", 0.0, 0.2), ("T25", 25.0, 0.2), ("T50", 50.0, 0.2), ("s1", 25.0, 0.5),
        ("s2", 25.0, 1.5), ("s3", 25.0, 4.5), ("hot", 80.0, 0.5), ("again", 50.0, 0.2)))
    with CampaignFile.open(path) as campaign:
        # at 80 °C only another level was run: the nearest to the series' joins
        assert candidate_groups(campaign) == [("T0", "T25", "T50", "again", "hot")]


def test_strain_steps_read_a_few_hundredths_of_a_kelvin_off_their_series_still_join_none(
        tmp_path: Path):
    # the chamber holds 25 °C to a few hundredths: a step read at 25.06 °C beside the series'
    # 25.04 °C fell, rounded to 0.1 °C, at another temperature (25.1), and joined the curve
    path = _series(tmp_path / "c.h5", (
        ("T0", 0.0, 0.2), ("T25", 25.04, 0.2), ("s1", 25.06, 4.5), ("T50", 50.0, 0.2)))
    with CampaignFile.open(path) as campaign:
        assert candidate_groups(campaign) == [("T0", "T25", "T50")]
