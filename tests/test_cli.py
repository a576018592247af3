"""The command line's own behaviour: help, version, usage errors."""

from __future__ import annotations

import subprocess
import sys

import pytest

from viscorig.cli import main
from viscorig.version import __version__


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


def test_every_command_takes_verbose_and_quiet(capsys: pytest.CaptureFixture[str]) -> None:
    for name in registered_commands():
        for words in ([name, "-v", "--help"], ["-q", name, "--help"]):
            with pytest.raises(SystemExit) as stop:
                main(words)
            assert stop.value.code == 0, words
        assert "-v, --verbose" in capsys.readouterr().out, name


def test_verbosity_sets_the_logging_level_and_goes_to_stderr(
    tmp_path, capsys: pytest.CaptureFixture[str]
) -> None:
    import logging

    from viscorig.storage import CampaignFile

    path = tmp_path / "c.h5"
    CampaignFile.create(path, sequence_text="", durable=False)
    expected = {(): logging.WARNING, ("-v",): logging.INFO, ("-vv",): logging.DEBUG,
                ("-q",): logging.ERROR, ("-v", "-v"): logging.DEBUG, ("-v", "-q"): logging.WARNING}
    for options, level in expected.items():
        # before the command, after it, or both: they add up
        words = [*options[:1], "show", str(path), *options[1:]]
        assert main(words) == 0
        assert logging.getLogger("viscorig").getEffectiveLevel() == level, options
        captured = capsys.readouterr()
        said = [line for line in captured.err.splitlines() if "show finished in" in line]
        assert len(said) == (1 if level <= logging.INFO else 0), options
        assert captured.out.startswith(str(path))  # results stay on stdout
    logging.getLogger("viscorig").warning("a %s", "test")
    assert capsys.readouterr().err == "viscorig: warning: a test\n"
    main(["-q", "show", str(path)])
    logging.getLogger("viscorig.report").warning("hidden")
    assert capsys.readouterr().err == ""


@pytest.mark.parametrize("command", [["run", "{paper}", "--yes", "--out", "{long}.h5"]])
def test_a_path_the_file_system_refuses_is_one_line(tmp_path, capsys, command) -> None:
    """A name longer than the file system takes ended 'run --out' and 'report --out' in an
    OSError traceback."""
    from pathlib import Path

    paper = Path(__file__).resolve().parents[1] / "sequences" / "paper.toml"
    long = str(tmp_path / ("a" * 300))
    words = [word.format(paper=paper, long=long) for word in command]
    assert main(words) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.startswith(f"viscorig: {long}")
    assert err.rstrip().endswith(": File name too long") and "Traceback" not in err
