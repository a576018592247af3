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


def registered_commands() -> list[str]:
    """Names of the sub-commands the parser knows."""
    import argparse

    from viscorig.cli import build_parser

    actions = build_parser()._subparsers._group_actions  # type: ignore[union-attr]
    subparsers = next(a for a in actions if isinstance(a, argparse._SubParsersAction))
    return sorted(subparsers.choices)


def test_help_lists_every_registered_command(capsys: pytest.CaptureFixture[str]) -> None:
    assert main([]) == 0
    out = capsys.readouterr().out
    assert "usage: viscorig" in out
    commands = registered_commands()
    assert {"run", "resume", "show", "identify", "diagnose", "sim"} <= set(commands)
    for name in commands:
        assert name in out


def test_every_command_has_working_help(capsys: pytest.CaptureFixture[str]) -> None:
    for name in registered_commands():
        with pytest.raises(SystemExit) as stop:
            main([name, "--help"])
        assert stop.value.code == 0, name
        assert f"usage: viscorig {name}" in capsys.readouterr().out


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


def test_listing_commands_loads_no_heavy_library() -> None:
    """``viscorig --help`` and a light command start quickly: only the chosen command's module
    is imported."""
    probe = (
        "import sys\n"
        "from viscorig.cli import main\n"
        "main([])\n"
        "heavy = {'scipy', 'matplotlib', 'pyvisa', 'h5py', 'rigsim'} & set(sys.modules)\n"
        "print(sorted(heavy))\n"
    )
    result = subprocess.run(
        [sys.executable, "-c", probe], capture_output=True, text=True, check=True
    )
    assert result.stdout.strip().splitlines()[-1] == "[]"
