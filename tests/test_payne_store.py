"""The Payne fit (``identify --run A --run B --run C --model kraus``) is stored in the campaign
file under ``/fits/<id>`` as the other fits are under their run: read back it says what
``--json`` said, ``--no-store`` leaves the file as it was, ``show`` lists it, a second fit is
added beside the first, and a write that fails leaves no part of a fit.

The runs come from a generator of this file's own (numpy only, no simulator): a Voigt specimen
on a disc of mass ``M_v`` with Kraus's filler network added to its K* (Kraus 1984, as
literature writes it), at three levels, with the analyser's normalized variance; they are
written through :class:`CampaignFile`'s public API, as an import writes runs.
"""

from __future__ import annotations

import hashlib
import json
import subprocess
import sys
from pathlib import Path

import h5py
import numpy as np
import pytest

import viscorig
from viscorig.cli import main
from viscorig.errors import InputError
from viscorig.storage import CampaignFile, RunSettings, Segment
from viscorig.strain import identify_payne, read_payne_fit, store_payne_fit, stored_payne_fits

TRUTH = {"K_f": 3.0e4, "L_f": 4.0e3, "x_c": 2.0e-5, "m_k": 0.6}
UNITS = {"K_f": "N/m", "L_f": "N/m", "x_c": "m", "m_k": ""}
LEVELS_M_PER_S2 = {"strain-low": 0.3, "strain-mid": 1.0, "strain-high": 3.0}
RUNS = list(LEVELS_M_PER_S2)
FREQUENCY_HZ = np.arange(20.0, 120.1, 2.0)
DISC_MASS_KG = 0.15
NOISE_AT_1 = 2e-3  # relative noise of K* of a run at 1 m/s²


def _kstar(level: float) -> np.ndarray:
    """Voigt K* plus Kraus's filler network at the run's displacement amplitude, N/m."""
    omega = 2.0 * np.pi * FREQUENCY_HZ
    a = (level / omega**2) / TRUTH["x_c"]
    power = a ** TRUTH["m_k"]
    denominator = 1.0 + power**2
    filler = TRUTH["K_f"] / denominator + 2j * TRUTH["L_f"] * power / denominator
    return 1.5e5 + 1j * omega * 114.6 + filler


def _write(path: Path) -> None:
    rng = np.random.default_rng(2026)
    omega = 2.0 * np.pi * FREQUENCY_HZ
    n = FREQUENCY_HZ.size
    with CampaignFile.create(path, sequence_text="# generated\n", durable=False) as campaign:
        for name, level in LEVELS_M_PER_S2.items():
            variance = (NOISE_AT_1 / level) ** 2
            noise = rng.normal(size=(n, 2)) @ np.array([1.0, 1j])
            kstar = _kstar(level) * (1.0 + noise * np.sqrt(variance / 2.0))
            support = -(omega**2) / (kstar - omega**2 * DISC_MASS_KG)  # ẍ_v/F_v (Eq. 5)
            campaign.add_run(name, RunSettings(
                specimen="filled", level_m_per_s2=level, direction="up", settle_cycles=100,
                integrate_cycles=100, resolution_hz=2.0, temperature_c=25.0,
                instrument="generated", simulated=True), Segment(
                frequency_hz=FREQUENCY_HZ, time_s=np.arange(n, dtype=float),
                accelerance_table=np.full(n, 1.0 + 0j), accelerance_support=support,
                reference_amplitude=np.full(n, level), source_amplitude=np.full(n, 0.1),
                force_amplitude=np.full(n, 1.0), flags=np.zeros(n, dtype=int),
                variance_support=np.full(n, variance)))


@pytest.fixture(scope="module")
def template(tmp_path_factory: pytest.TempPathFactory) -> Path:
    path = tmp_path_factory.mktemp("payne-store") / "template.h5"
    _write(path)
    return path


@pytest.fixture()
def campaign(template: Path, tmp_path: Path) -> Path:
    path = tmp_path / "campaign.h5"
    path.write_bytes(template.read_bytes())
    return path


def _arguments(path: Path, *options: str) -> list[str]:
    arguments = ["identify", str(path), "--model", "kraus"]
    for run in reversed(RUNS):  # the order given is not the order kept
        arguments += ["--run", run]
    return [*arguments, *options]


def _identify(path: Path, *options: str) -> str:
    """``viscorig identify`` in a process of its own, as a user runs it; its output."""
    done = subprocess.run([sys.executable, "-m", "viscorig", *_arguments(path, *options)],
                          capture_output=True, text=True, timeout=120)
    assert done.returncode == 0, done.stderr
    return done.stdout


def _identify_here(path: Path, capsys: pytest.CaptureFixture[str], *options: str) -> str:
    """The same in this process (faster, for the tests after the first)."""
    assert main(_arguments(path, *options)) == 0
    return capsys.readouterr().out


def _digest(path: Path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


def _still_whole(path: Path) -> None:
    """What other tests ask of a campaign file: it opens (the layout's checks) and every run
    reads whole; a run's own fits are not touched by a fit of several runs."""
    campaign = CampaignFile.open(path)
    assert campaign.run_names == RUNS
    for run in campaign.runs():
        assert run.points == FREQUENCY_HZ.size and run.metadata.status == "complete"
        assert campaign.fits(run.name) == []


def test_stored_fit_reads_back_as_json_said(campaign: Path) -> None:
    document = json.loads(_identify(campaign, "--json"))
    fits = stored_payne_fits(CampaignFile.open(campaign))
    assert len(fits) == 1
    fit = fits[0]
    assert fit.fit_id == "0001" and fit.created.endswith("Z")
    assert list(fit.runs) == document["runs"] == RUNS  # lowest level first
    assert fit.points == document["points"] == 2 * FREQUENCY_HZ.size
    assert fit.reduced_chi_square == document["reduced_chi_square"]
    assert list(fit.band_hz) == document["band_hz"] == [20.0, 120.0]
    assert list(fit.displacement_range_m) == document["displacement_range_m"]
    for name, stored in fit.parameters.items():
        printed = document["parameters"][name]
        assert (stored.value, stored.stderr, stored.unit) == (
            printed["value"], printed["stderr"], printed["unit"]), name
        assert stored.unit == UNITS[name] and stored.stderr > 0
        assert abs(stored.value - TRUTH[name]) < 4 * stored.stderr, (name, stored)
    assert fit.correlation is not None
    assert np.allclose(fit.correlation, document["correlation"]["matrix"], atol=1e-6)
    assert np.allclose(np.diag(fit.correlation), 1.0)
    # the same through the public API, and as the layout documents it for other tools
    assert [f.parameters for f in viscorig.open_campaign(campaign).payne_fits] == [
        fit.parameters]
    with h5py.File(campaign, "r") as h5:
        group = h5["fits/0001"]
        assert group.attrs["model"] == "kraus"
        assert group.attrs["runs"] == "strain-low strain-mid strain-high"
        assert group.attrs["points"] == fit.points
        assert group["K_f"][()] == fit.parameters["K_f"].value
        assert group["x_c"].attrs["units"] == "m"
        assert group["x_c"].attrs["stderr"] == fit.parameters["x_c"].stderr
    _still_whole(campaign)


def test_no_store_leaves_the_file_unchanged(campaign: Path,
                                           capsys: pytest.CaptureFixture[str]) -> None:
    before = _digest(campaign)
    assert "not stored (--no-store)" in _identify_here(campaign, capsys, "--no-store")
    _identify_here(campaign, capsys, "--no-store", "--json")
    assert _digest(campaign) == before
    assert CampaignFile.open(campaign).joint_fits() == []


def test_show_lists_it(campaign: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert "stored as fit /fits/0001" in _identify_here(campaign, capsys)
    assert main(["show", str(campaign)]) == 0
    listing = capsys.readouterr().out
    assert "/fits/0001  kraus  runs strain-low, strain-mid, strain-high  20-120 Hz" in listing
    for name in TRUTH:
        assert f"      {name} = " in listing
    assert main(["show", str(campaign), "--json"]) == 0
    joint = json.loads(capsys.readouterr().out)["joint_fits"]
    stored = stored_payne_fits(CampaignFile.open(campaign))[0]
    assert [fit["id"] for fit in joint] == ["0001"] and joint[0]["runs"] == RUNS
    assert joint[0]["parameters"]["L_f"]["stderr"] == stored.parameters["L_f"].stderr


def test_a_second_fit_is_added_beside_the_first(campaign: Path,
                                                capsys: pytest.CaptureFixture[str]) -> None:
    _identify_here(campaign, capsys)
    first = stored_payne_fits(CampaignFile.open(campaign))
    _identify_here(campaign, capsys, "--band", "30:110")
    fits = stored_payne_fits(CampaignFile.open(campaign))
    assert [fit.fit_id for fit in fits] == ["0001", "0002"]
    assert fits[0] == first[0]  # the first as it was
    assert fits[1].band_hz == (30.0, 110.0) and fits[1].points < fits[0].points
    _still_whole(campaign)


def test_a_failed_write_leaves_no_part_of_a_fit(campaign: Path,
                                               monkeypatch: pytest.MonkeyPatch) -> None:
    fit = identify_payne(CampaignFile.open(campaign), RUNS)
    with CampaignFile.open(campaign, "a", durable=False) as writer:
        store_payne_fit(writer, fit)
    before = _digest(campaign)
    import viscorig.storage.campaign as module

    def fails() -> str:  # called inside the commit, after the fit's group was created
        raise RuntimeError("killed mid-write")

    monkeypatch.setattr(module, "utc_now", fails)
    with CampaignFile.open(campaign, "a", durable=False) as writer, \
            pytest.raises(RuntimeError, match="killed mid-write"):
        store_payne_fit(writer, fit)
    monkeypatch.undo()
    with CampaignFile.open(campaign, "a", durable=False) as writer, \
            pytest.raises(InputError, match="no such run"):
        writer.add_joint_fit(["strain-low", "gone"], model="kraus", band_hz=(20.0, 120.0),
                             reduced_chi_square=1.0, points=1, parameters={})
    assert _digest(campaign) == before
    assert [f.fit_id for f in stored_payne_fits(CampaignFile.open(campaign))] == ["0001"]
    _still_whole(campaign)


def test_a_fit_of_another_model_is_not_read_as_payne(campaign: Path) -> None:
    with CampaignFile.open(campaign, "a", durable=False) as writer:
        writer.add_joint_fit(RUNS[:2], model="other", band_hz=(20.0, 120.0),
                             reduced_chi_square=1.0, points=2,
                             parameters={"a": (1.0, 0.1, "1")})
    record = CampaignFile.open(campaign).joint_fits()[0]
    assert record.runs == tuple(RUNS[:2]) and record.parameters["a"] == (1.0, 0.1, "1")
    with pytest.raises(InputError, match="not 'kraus'"):
        read_payne_fit(record)
    assert stored_payne_fits(CampaignFile.open(campaign)) == []


@pytest.mark.parametrize("where", ["run", "joint"])
def test_a_full_fits_group_refuses_one_more_and_the_file_still_reads(campaign: Path,
                                                                     where: str) -> None:
    """Readers refuse a fits group of more than ``MAX_FITS`` members (a hostile file's cap): a
    run's ``fits`` and ``/fits`` each take that many and no more, and what is there still reads."""
    from viscorig.storage import layout

    group = f"runs/{RUNS[0]}/fits" if where == "run" else "fits"
    with h5py.File(campaign, "a") as h5:  # filled to the cap by another writer
        fits = h5.require_group(group)
        for number in range(1, layout.MAX_FITS + 1):
            fits.create_group(f"{number:04d}")
    before = _digest(campaign)
    with CampaignFile.open(campaign, mode="a") as stored, pytest.raises(
            InputError, match=f"holds {layout.MAX_FITS} fits"):
        parameters = {"K_v": (1.5e5, 1e2, "N/m")}
        if where == "run":
            stored.add_fit(RUNS[0], model="voigt", band_hz=(20, 120), rms_error=0.1,
                           noise_floor=0.01, parameters=parameters)
        else:
            stored.add_joint_fit(RUNS, model="kraus", band_hz=(20, 120),
                                 reduced_chi_square=1.0, points=10, parameters=parameters)
    assert _digest(campaign) == before
    assert CampaignFile.open(campaign).run(RUNS[0]).points == FREQUENCY_HZ.size


@pytest.mark.parametrize(("attribute", "value", "said"), [
    ("specimen", "other", "differ in specimen ('filled' and 'other')"),
    ("preload_strain", 0.104, "differ in preload (0.0 and 0.104)"),
    ("temperature_c", 40.0, "differ in temperature (25.0 and 40.0)"),
    ("level_m_per_s2", None, "are both at"),
])
def test_runs_of_other_specimens_or_one_level_are_refused(
        campaign: Path, capsys: pytest.CaptureFixture[str], attribute: str, value, said: str
) -> None:
    """Runs of two specimens (or one specimen at two preloads) were fitted as one specimen's
    strain dependence: a Payne fit of reduced chi-square 9e7, printed and stored."""
    with h5py.File(campaign, "r+") as h5:
        first, second = h5[f"runs/{RUNS[0]}"], h5[f"runs/{RUNS[1]}"]
        second.attrs[attribute] = value if value is not None else first.attrs[attribute]
    before = _digest(campaign)
    assert main(_arguments(campaign)) == 2
    assert said in capsys.readouterr().err
    assert _digest(campaign) == before
