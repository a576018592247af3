"""The whole example sequence sequences/temperature-strain.toml on the embedded rig: every run
at its temperature, the master curve's shift factors against the simulator's WLF (through
``viscorig master --json``), and the Payne parameters against the simulator's Kraus model, each
within 3 standard errors.

The truth is read from the simulator's rig preset (``rigsim``), the estimates come from the
campaign file through the core: no code is shared between the two.
"""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from viscorig.report.figures import figure_stem
from viscorig.storage import CampaignFile
from viscorig.strain import identify_payne

ROOT = Path(__file__).resolve().parents[1]
SEQUENCE = ROOT / "sequences" / "temperature-strain.toml"
#: The disc's mass (the preset's): master finds it by fitting the runs, for K* from Eq. (5).
DISC_MASS_KG = 0.15
#: One realisation of the rig's noise, the same at every run: with honest standard errors each
#: estimate checked here (a dozen shift factors, four Payne parameters) still falls outside 3 of
#: them 0.27 % of the time, so a fresh realisation per run would fail about one run in 25 by
#: chance. The errors' calibration over many realisations is tested apart
#: (test_payne_standard_errors_mean_what_they_say, and the shift factors' in
#: tests/test_materials_master.py).
SEED = 2026
STRAIN_RUNS = ["medium_25C_strain1", "medium_25C_strain2", "medium_25C_strain3"]


@pytest.fixture(scope="module")
def campaign(tmp_path_factory) -> Path:
    out = tmp_path_factory.mktemp("temperature-strain") / "campaign.h5"
    done = subprocess.run([sys.executable, "-m", "viscorig", "run", str(SEQUENCE), "--yes",
                           "--out", str(out), "--sim-seed", str(SEED)], capture_output=True,
                          text=True, timeout=1200, cwd=out.parent)
    assert done.returncode == 0, done.stderr
    return out


def _truth():
    from rigsim.rigfile import load_preset

    return load_preset("medium-chamber")


@pytest.mark.slow
def test_every_run_at_its_temperature(campaign: Path) -> None:
    file = CampaignFile.open(campaign)
    for name in file.run_names:
        if not name.startswith("medium_"):
            continue
        run = file.run(name)
        values, units = run.extra["temperature_c"]
        assert units == "degC" and run.metadata.status == "complete"
        soaked_band = 0.1 if "strain" in name else 0.5
        assert np.all(np.abs(values - run.metadata.temperature_c) <= soaked_band), name
        assert not np.any(run.flags & 16), name


@pytest.mark.slow
def test_payne_parameters_within_three_standard_errors(campaign: Path) -> None:
    truth = _truth().payne
    fit = identify_payne(CampaignFile.open(campaign), STRAIN_RUNS)
    expected = {"K_f": truth.storage_drop_n_per_m, "L_f": truth.loss_peak_n_per_m,
                "x_c": truth.critical_displacement_m, "m_k": truth.exponent}
    for name, (value, stderr, _) in fit.parameters.items():
        assert stderr > 0 and abs(value - expected[name]) <= 3 * stderr, (name, value, stderr)
    assert 0.5 < fit.reduced_chi_square < 2.0
    done = subprocess.run([sys.executable, "-m", "viscorig", "identify", str(campaign),
                           "--run", "medium_25C_strain1", "--run", "medium_25C_strain2",
                           "--run", "medium_25C_strain3", "--model", "kraus", "--json"],
                          capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, done.stderr
    document = json.loads(done.stdout)
    assert document["model"] == "kraus" and document["points"] == fit.points
    assert document["parameters"]["x_c"]["value"] == pytest.approx(fit.parameters["x_c"][0])


@pytest.mark.slow
def test_payne_standard_errors_mean_what_they_say(tmp_path: Path) -> None:
    """Twelve realisations of the sequence's strain runs alone (bare table, mount, 25 °C, three
    levels): the Payne parameters' errors against the simulator's Kraus model, in their standard
    errors, scatter as a unit normal does."""
    text = SEQUENCE.read_text(encoding="utf-8")
    start = text.index('[[steps]]\ntype = "repeat"\ntemperatures_c')
    sequence = tmp_path / "strain.toml"
    sequence.write_text(text[:start] + text[text.index("[[steps]]\ntype = \"temperature\""):],
                        encoding="utf-8")
    truth = _truth().payne
    expected = {"K_f": truth.storage_drop_n_per_m, "L_f": truth.loss_peak_n_per_m,
                "x_c": truth.critical_displacement_m, "m_k": truth.exponent}
    z = []
    for seed in range(12):
        out = tmp_path / f"strain-{seed}.h5"
        done = subprocess.run([sys.executable, "-m", "viscorig", "run", str(sequence), "--yes",
                               "--out", str(out), "--sim-seed", str(seed), "-q"],
                              capture_output=True, text=True, timeout=300, cwd=tmp_path)
        assert done.returncode == 0, done.stderr
        fit = identify_payne(CampaignFile.open(out), STRAIN_RUNS)
        z += [(value - expected[name]) / stderr
              for name, (value, stderr, _) in fit.parameters.items()]
    z = np.array(z)
    assert 0.7 < np.sqrt(np.mean(z**2)) < 1.35, z
    assert abs(np.mean(z)) < 0.6 and np.max(np.abs(z)) < 4.0, z


def _master_available() -> bool:
    from viscorig.cli import main

    try:
        main(["master", "--help"])
    except SystemExit as end:
        return end.code == 0
    return False


@pytest.mark.slow
def test_shift_factors_within_three_standard_errors_of_the_wlf(campaign: Path) -> None:
    if not _master_available():
        pytest.skip("viscorig master is not in this tree yet")
    file = CampaignFile.open(campaign)
    runs = [name for name in file.run_names if name.startswith("medium_T")]
    command = [sys.executable, "-m", "viscorig", "master", str(campaign), "--json",
               "--reference-temperature", "25"]  # the runs as they are: M_v from fits
    for name in runs:
        command += ["--run", name]
    done = subprocess.run(command, capture_output=True, text=True, timeout=600)
    assert done.returncode == 0, done.stderr
    document = json.loads(done.stdout)
    mass, mass_stderr = (float(text) for text in
                         document["source"].split("(M_v ")[1].split(" kg")[0].split(" ± "))
    assert abs(mass - DISC_MASS_KG) <= 3 * mass_stderr, document["source"]
    wlf = _truth().temperature

    def log10_shift(temperature_c: float) -> float:
        delta = temperature_c - wlf.reference_temperature_c
        return -wlf.c1 * delta / (wlf.c2_k + delta)

    # master refers the curve to the measured temperature nearest the one asked for
    reference = document["reference_temperature_c"]
    assert abs(reference - 25.0) < 0.5
    factors = document["shift_factors"]
    assert len(factors) == len(runs)
    for factor in factors:
        temperature = factor["temperature_c"]
        if temperature == reference:
            continue
        expected = log10_shift(temperature) - log10_shift(reference)
        error = factor["log10_aT_stderr"]
        assert abs(factor["log10_aT"] - expected) <= 3 * error, (temperature, factor, expected)
    parameters = document["shift_function"]["parameters"]
    for name, truth in (("C1", wlf.c1), ("C2_K", wlf.c2_k)):
        assert abs(parameters[name]["value"] - truth) <= 3 * parameters[name]["stderr"], name


@pytest.mark.slow
def test_the_report_puts_the_temperature_series_alone_in_its_master_curve(campaign: Path,
                                                                           tmp_path: Path) -> None:
    # the strain steps at 25 °C joined the series' master curve, and the report stopped with a
    # traceback (a shift slope divided by the zero step between sweeps at one temperature)
    out = tmp_path / "report"
    done = subprocess.run([sys.executable, "-m", "viscorig", "report", str(campaign),
                           "--no-diagnosis", "--out", str(out)], capture_output=True, text=True,
                          timeout=600)
    assert done.returncode == 0, done.stderr
    series = [name for name in CampaignFile.open(campaign).run_names
              if name.startswith("medium_T")]
    assert len(series) == 13
    # one master curve, of the series' runs exactly (its file is named after them)
    (master,) = out.glob("material-*-master.png")
    assert master.name == f"{figure_stem('material', '-'.join(series))}-master.png"
    page = (out / "index.html").read_text(encoding="utf-8")
    assert "Materials over temperature and frequency" in page
