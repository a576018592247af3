"""A thermal drift explained from the specimen's recorded temperature before it is inferred from
the test time: the embedded rig's chamber campaign swept up and down while the specimens were
still cooling (the time-domain simulator's rubber follows its own lagging temperature through
WLF; nothing here makes data with the core's model)."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

from viscorig.diagnosis import diagnose_run
from viscorig.diagnosis.explain import explain
from viscorig.storage import CampaignFile

SEQUENCE = """\
name = "cooling"
[defaults]
band_hz = [20.0, 120.0]
resolution_hz = 2.0
settle_cycles = 200
integrate_cycles = 200
level = "0.5 m/s^2"

[[steps]]
type = "prompt"
message = "Bare table."
simulated_rig = "table"

[[steps]]
type = "sweep"
run = "table"
specimen = "none"
band_hz = [12.0, 28.0]
resolution_hz = 0.25
settle_cycles = 60
integrate_cycles = 40
level = "1.4 m/s^2"

[[steps]]
type = "prompt"
message = "Mount."
simulated_rig = "medium-chamber"

[[steps]]
type = "temperature"
set_point_c = 0.0
soak_band_k = 20.0
soak_minutes = 0

[[steps]]
type = "sweep"
run = "early"
temperature_c = 0.0
specimen = "medium"
hardness_shore_a = 33.0

[[steps]]
type = "sweep"
run = "early-down"
temperature_c = 0.0
specimen = "medium"
hardness_shore_a = 33.0
direction = "down"
"""


@pytest.mark.slow
def test_a_drift_is_explained_by_the_recorded_temperature(tmp_path: Path) -> None:
    (tmp_path / "cooling.toml").write_text(SEQUENCE, encoding="utf-8")
    done = subprocess.run([sys.executable, "-m", "viscorig", "run", "cooling.toml", "--yes",
                           "--sim-seed", "7", "--out", "c.h5"], cwd=tmp_path,
                          capture_output=True, text=True, timeout=300, check=False)
    assert done.returncode == 0, done.stderr
    with CampaignFile.open(tmp_path / "c.h5") as campaign:
        diagnosis = diagnose_run(campaign, "early")
        assert diagnosis.data.runs == ("early", "early-down")
        low, high = diagnosis.data.temperature_range_c["early"]
        assert high - low > 5.0  # swept before the soak: the specimens cooled during the run
        ladder = diagnosis.auto()
    rungs = [step.model for step in ladder]
    found = [finding for step in ladder for finding in step.significant
             if finding.effect == "thermal_drift"]
    assert found and found[0].term.startswith("temperature("), rungs
    assert "recorded temperature" in explain(found[0], ladder[0].data)
    assert "temperature(" in rungs[-1] and "drift" not in rungs[-1]
    # The simulator's WLF (C1 6.6, C2 137 K about 25 °C) moves this rubber's frequency scale by
    # 0.05-0.06 decade per K between 0 and 17 °C, and its |K*| rises by about 0.3 in ln per
    # decade: the modulus should fall by 1.5-2 % per kelvin of warming.
    result = ladder[-1].fit
    gamma = result.values["gamma"]
    assert -0.03 < gamma < -0.008, result.values
    assert result.stderr["gamma"] < 0.2 * abs(gamma)
