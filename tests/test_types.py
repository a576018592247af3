"""The type hints are checked: mypy (configured in pyproject.toml) finds nothing in the drivers."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]

pytest.importorskip("mypy")


@pytest.mark.slow
def test_mypy_finds_nothing_in_the_drivers() -> None:
    done = subprocess.run(
        [sys.executable, "-m", "mypy", "--no-incremental", "drivers/agilent35670a",
         "drivers/eurotherm3200"],
        cwd=ROOT, capture_output=True, text=True, timeout=600, check=False,
    )
    assert done.returncode == 0, done.stdout + done.stderr
