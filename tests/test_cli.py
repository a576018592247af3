"""The command line's own behaviour: help, version, usage errors."""

from __future__ import annotations

import subprocess
import sys

import pytest

from viscorig import __version__
from viscorig.cli import main


def test_version_is_printed(capsys: pytest.CaptureFixture[str]) -> None:
    with pytest.raises(SystemExit) as stop:
        main(["--version"])
    assert stop.value.code == 0
    assert capsys.readouterr().out.strip() == f"viscorig {__version__}"


def test_help_lists_only_registered_commands(capsys: pytest.CaptureFixture[str]) -> None:
    from viscorig.cli import COMMAND_MODULES

    assert main([]) == 0
    out = capsys.readouterr().out
    assert "usage: viscorig" in out
    for name in COMMAND_MODULES:
        assert name.replace("_", "-").split("-")[0] in out


def test_unknown_command_is_one_line_and_status_2() -> None:
    result = subprocess.run(
        [sys.executable, "-m", "viscorig", "no-such-command"],
        capture_output=True,
        text=True,
        check=False,
    )
    assert result.returncode == 2
    assert len(result.stderr.strip().splitlines()) == 1
    assert "no-such-command" in result.stderr
    assert "Traceback" not in result.stderr
