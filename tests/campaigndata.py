"""Campaign files of simulated sweeps, written through the storage API as the runner does.

Each run is swept on the time-domain rig simulator (``tests/simdata.py``, the paper's rig
presets) and stored segment by segment; nothing here shares model code with ``viscorig``.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
from simdata import simulate_run

from viscorig.storage import CampaignFile, RunSettings, Segment

#: run -> (specimen, hardness, preload strain); the names of sequences/paper.toml
PAPER_RUNS = {
    "table": ("none", math.nan, 0.0),
    "soft-0": ("soft", 25.0, 0.0),
    "soft-10": ("soft", 25.0, 0.104),
    "medium-0": ("medium", 33.0, 0.0),
    "medium-10": ("medium", 33.0, 0.104),
    "hard-0": ("hard", 48.0, 0.0),
    "hard-10": ("hard", 48.0, 0.104),
}


def add_run(campaign: CampaignFile, name: str, *, step_hz: float = 0.25, segments: int = 4,
            finish: bool = True, points: int | None = None, level: float = 1.4,
            band_hz: tuple[float, float] = (20.0, 120.0)) -> None:
    """Sweep preset ``name`` and store it as run ``name`` in a few segments (a specimen run
    over ``band_hz``)."""
    specimen, hardness, preload = PAPER_RUNS[name]
    bare = specimen == "none"
    band = (12.0, 28.0) if bare else band_hz
    step = 0.125 if bare else step_hz
    swept = simulate_run(name, start_hz=band[0], stop_hz=band[1], step_hz=step,
                         settle_cycles=200 if bare else 100, level_m_per_s2=level, seed=len(name))
    campaign.start_run(name, RunSettings(
        specimen=specimen, level_m_per_s2=level, direction="up", settle_cycles=100,
        integrate_cycles=100, resolution_hz=step, hardness_shore_a=hardness,
        preload_strain=preload, temperature_c=25.0, instrument="simulated 35670A",
        simulated=True))
    n = swept.frequency_hz.size if points is None else points
    for chunk in np.array_split(np.arange(n), segments):
        if chunk.size:
            campaign.append_segment(name, Segment(
                frequency_hz=swept.frequency_hz[chunk], time_s=swept.time_s[chunk],
                accelerance_table=swept.accelerance_table[chunk],
                accelerance_support=swept.accelerance_support[chunk],
                reference_amplitude=swept.reference_amplitude[chunk],
                source_amplitude=np.full(chunk.size, 0.1),
                force_amplitude=swept.force_amplitude[chunk], flags=swept.flags[chunk]))
    if finish:
        campaign.finish_run(name)


def paper_campaign(path: Path, runs: tuple[str, ...] = tuple(PAPER_RUNS), **options) -> Path:
    """A campaign file with the paper's runs (or a subset) swept on the simulated rig."""
    campaign = CampaignFile.create(path, sequence_text="# simulated\n", durable=False,
                               rig={"specimen_height_m": 0.012, "specimen_count": 2})
    for name in runs:
        add_run(campaign, name, **options)
    return path
