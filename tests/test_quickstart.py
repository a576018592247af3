"""The README's Quick start: two commands that work on a fresh machine, PEP 668 included.

Debian's and Ubuntu's system Python refuse ``pip install`` outside a virtual environment
(PEP 668: an ``EXTERNALLY-MANAGED`` file beside the standard library). The Quick start used to
start with ``python3 -m pip install .``, which such a Python refuses; its commands now create
and use a virtual environment. The slow test runs the first command exactly as written, in a
copy of the project, with such a Python first on the PATH.
"""

from __future__ import annotations

import os
import re
import shutil
import subprocess
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]


def quick_start_commands() -> list[str]:
    text = (ROOT / "README.md").read_text(encoding="utf-8")
    section = re.search(r"^## Quick start\n(.*?)(?=^## )", text, re.S | re.M).group(1)
    return [block.strip() for block in re.findall(r"^```[^\n]*\n(.*?)^```", section,
                                                   re.S | re.M)]


def test_both_commands_make_a_virtual_environment_and_use_only_it() -> None:
    commands = quick_start_commands()
    assert len(commands) == 2 and all("\n" not in command for command in commands)
    for command in commands:
        first, *rest = command.split(" && ")
        assert first == "python3 -m venv .venv"
        for part in rest:  # nothing runs from the system's Python or PATH after that
            assert part.startswith(".venv/bin/"), part
    assert "viscorig run sequences/paper.toml" in commands[0]
    assert "viscorig summary" in commands[0]
    assert commands[1].endswith(".venv/bin/python -m pytest -q") and '".[test]"' in commands[1]


def test_ci_runs_exactly_the_readmes_test_command() -> None:
    printed = subprocess.run(["bash", str(ROOT / ".ci" / "run"), "--print-test-command"],
                             capture_output=True, text=True, timeout=60, check=True).stdout
    assert printed.strip() == quick_start_commands()[1]


def test_ci_refuses_a_readme_without_the_test_command(tmp_path) -> None:
    (tmp_path / ".ci").mkdir()
    shutil.copy(ROOT / ".ci" / "run", tmp_path / ".ci" / "run")
    (tmp_path / "README.md").write_text("# x\n\n## Quick start\n\n```\nmake\n```\n\n## Next\n")
    result = subprocess.run(["bash", str(tmp_path / ".ci" / "run")], capture_output=True,
                            text=True, timeout=60)
    assert result.returncode != 0 and "second code block" in result.stderr


def externally_managed_python() -> str | None:
    """A Python (not a virtual environment) whose pip refuses installs under PEP 668."""
    for candidate in (shutil.which("python3", path="/usr/bin"), shutil.which("python3")):
        if not candidate:
            continue
        probe = subprocess.run(
            [candidate, "-c", "import sys, sysconfig, os; print(sys.prefix == sys.base_prefix "
             "and os.path.exists(os.path.join(sysconfig.get_path('stdlib'), "
             "'EXTERNALLY-MANAGED')) and sys.version_info >= (3, 11))"],
            capture_output=True, text=True, timeout=30)
        if probe.stdout.strip() == "True":
            return candidate
    return None


SYSTEM_PYTHON = externally_managed_python()


def copy_of_the_project(folder: Path) -> Path:
    ignore = shutil.ignore_patterns(".venv", ".git", "__pycache__", "*.egg-info", "build",
                                    ".pytest_cache", ".hypothesis", "*.h5", ".ruff_cache")
    return Path(shutil.copytree(ROOT, folder / "viscorig", ignore=ignore))


def path_with(python: str, folder: Path) -> dict[str, str]:
    """An environment whose ``python3`` is ``python`` (and no virtual environment active)."""
    bin_folder = folder / "bin"
    bin_folder.mkdir()
    (bin_folder / "python3").symlink_to(python)
    environment = {key: value for key, value in os.environ.items()
                   if key not in ("VIRTUAL_ENV", "PYTHONHOME", "PYTHONPATH")}
    environment["PATH"] = os.pathsep.join([str(bin_folder), "/usr/bin", "/bin"])
    return environment


@pytest.mark.slow
@pytest.mark.skipif(SYSTEM_PYTHON is None, reason="no externally managed (PEP 668) Python here")
def test_the_first_command_works_exactly_as_written_where_pip_install_is_refused(tmp_path):
    project = copy_of_the_project(tmp_path)
    environment = path_with(SYSTEM_PYTHON, tmp_path)
    # the failure: the old first step, refused by the system's Python
    refused = subprocess.run(["python3", "-m", "pip", "install", "--dry-run", "--no-deps",
                              "."], cwd=project, env=environment, capture_output=True,
                             text=True, timeout=120)
    assert refused.returncode != 0 and "externally-managed-environment" in refused.stderr
    command = quick_start_commands()[0]
    result = subprocess.run(["bash", "-euo", "pipefail", "-c", command], cwd=project,
                            env=environment, capture_output=True, text=True, timeout=900)
    assert result.returncode == 0, result.stdout[-3000:] + result.stderr[-3000:]
    assert "sequence complete: table, soft-0, soft-10, medium-0, medium-10, hard-0, hard-10" \
        in result.stdout
    assert "Table 1" in result.stdout and "Table 2" in result.stdout
    assert (project / "paper.h5").is_file()
    assert "include-system-site-packages = false" in (project / ".venv" / "pyvenv.cfg").read_text()
