"""Terms from other packages: the example package installed with pip, used from ``--model``.

The package ``examples/dry-friction-term`` is installed into a folder of its own (pip
``--target``, so the test venv is left as it was) and put on ``PYTHONPATH`` of a ``viscorig``
subprocess; viscorig finds its term through the ``viscorig.terms`` entry-point group alone.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest
from campaigndata import paper_campaign

EXAMPLE = Path(__file__).resolve().parents[1] / "examples" / "dry-friction-term"


def viscorig(*arguments: str, path: Path | None = None) -> subprocess.CompletedProcess[str]:
    environment = dict(os.environ)
    if path is not None:
        environment["PYTHONPATH"] = os.pathsep.join(
            [str(path), *filter(None, [environment.get("PYTHONPATH")])])
    return subprocess.run([sys.executable, "-m", "viscorig", *arguments], capture_output=True,
                          text=True, env=environment, timeout=120, check=False)


@pytest.fixture(scope="module")
def installed(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The example package, installed by pip into a folder of its own."""
    target = tmp_path_factory.mktemp("site")
    result = subprocess.run(
        [sys.executable, "-m", "pip", "install", "--quiet", "--no-deps", "--no-build-isolation",
         "--no-index", "--target", str(target), str(EXAMPLE)],
        capture_output=True, text=True, timeout=300, check=False)
    assert result.returncode == 0, result.stderr[-3000:]
    assert (target / "viscorig_dry_friction").is_dir()
    return target


@pytest.fixture(scope="module")
def campaign(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return paper_campaign(tmp_path_factory.mktemp("plugin") / "c.h5", runs=("table", "soft-0"))


def fit(campaign: Path, model: str, path: Path | None) -> dict:
    result = viscorig("identify", str(campaign), "--run", "soft-0", "--model", model,
                      "--no-store", "--json", path=path)
    assert result.returncode == 0, result.stderr
    return json.loads(result.stdout)


@pytest.mark.slow
def test_installed_term_is_fitted_from_the_command_line(installed: Path, campaign: Path):
    plain = fit(campaign, "voigt", None)
    friction = fit(campaign, "voigt+dry_friction", installed)
    assert friction["model"] == "voigt+dry_friction"
    f_c = friction["parameters"]["F_c"]
    assert f_c["unit"] == "N"
    # Nested models: the extra term can only lower the error.
    assert friction["rms_error"] <= plain["rms_error"] * (1 + 1e-6)
    # The simulated rig has no friction: the fit finds none (0 within two standard errors).
    assert 0.0 <= f_c["value"] <= 2 * f_c["stderr"]
    # The rubber's parameters barely move when a term that finds nothing is added.
    for name in ("K_v", "M_v"):
        assert friction["parameters"][name]["value"] == pytest.approx(
            plain["parameters"][name]["value"], rel=1e-3)


def test_term_is_unknown_without_the_package(campaign: Path):
    result = viscorig("identify", str(campaign), "--run", "soft-0", "--model",
                      "voigt+dry_friction", "--no-store")
    assert result.returncode == 2
    assert result.stderr.count("\n") == 1
    assert "unknown term 'dry_friction'" in result.stderr


@pytest.mark.slow
def test_a_broken_entry_point_is_named_and_breaks_nothing_else(tmp_path: Path, campaign: Path):
    info = tmp_path / "broken_terms-1.0.dist-info"
    info.mkdir()
    (info / "METADATA").write_text("Metadata-Version: 2.1\nName: broken-terms\nVersion: 1.0\n")
    (info / "entry_points.txt").write_text("[viscorig.terms]\nwobble = no_such_module:Wobble\n")
    result = viscorig("identify", str(campaign), "--run", "soft-0", "--model", "voigt+wobble",
                      "--no-store", path=tmp_path)
    assert result.returncode == 2 and result.stderr.count("\n") == 1
    assert "unknown term 'wobble'" in result.stderr
    assert "not loaded: wobble = no_such_module:Wobble (ModuleNotFoundError" in result.stderr
    assert fit(campaign, "voigt", tmp_path)["model"] == "voigt"  # the built-in terms still work
