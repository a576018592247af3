"""The ``viscorig`` command line.

Each command lives in a module of this package that exposes ``register(subparsers)``, which adds
its sub-parser(s) and sets ``handler`` to a function ``handler(args) -> int``. A command is listed
in :data:`COMMANDS` only once it works. Only the module of the command being run is imported, so
that the program starts quickly whatever the other commands need (scipy, matplotlib, pyvisa).
"""

from __future__ import annotations

import argparse
import importlib
import os
import sys
from collections.abc import Sequence
from typing import NamedTuple

from viscorig.runtime import limit_blas_threads

limit_blas_threads()

from viscorig import __version__  # noqa: E402  (after the BLAS setting, before numpy loads)
from viscorig.errors import ViscorigError  # noqa: E402


class Command(NamedTuple):
    """Where a command is defined and its one-line description."""

    module: str
    summary: str


#: Every command, in the order ``--help`` lists them.
COMMANDS: dict[str, Command] = {
    "run": Command("run", "run a test sequence into a new campaign file"),
    "resume": Command("run", "continue an interrupted campaign file"),
    "show": Command("show", "list the runs and fits of a campaign file"),
    "identify": Command("identify", "fit a model to one run and store the fit in the file"),
    "diagnose": Command(
        "diagnose", "show where a model fails and which physical effect is missing"
    ),
    "summary": Command(
        "summary", "Table 1 and Table 2 of the paper for every run of a campaign"
    ),
    "report": Command("report", "HTML report with figures (PNG, SVG) of a campaign file"),
    "export": Command(
        "exchange", "write a run's FRFs to a universal file (dataset 58) or CSV"
    ),
    "import": Command(
        "exchange", "add a run to a campaign from UFF 58, CSV or 35670A SDF files"
    ),
    "sim": Command("sim", "simulated rig and analyser"),
    "bench": Command("bench", "check the test station in a minute before a campaign"),
}


def summary_of(command: str) -> str:
    """The one-line description of ``command`` (for its module's ``add_parser``)."""
    return COMMANDS[command].summary


class _Parser(argparse.ArgumentParser):
    """An argument parser whose usage errors are one line on stderr and exit status 2."""

    def error(self, message: str) -> None:  # type: ignore[override]
        self.exit(2, f"{self.prog}: error: {message}\n")


def build_parser(command: str | None = None) -> argparse.ArgumentParser:
    """Build the top-level parser.

    Parameters
    ----------
    command
        The command about to run: its module is imported and defines its full parser. Every
        other command gets a placeholder that only lists it in ``--help``. ``None`` for none.
    """
    parser = _Parser(
        prog="viscorig",
        description="Swept-sine characterisation of viscoelastic dampers.",
    )
    parser.add_argument("--version", action="version", version=f"viscorig {__version__}")
    subparsers = parser.add_subparsers(title="commands", dest="command", parser_class=_Parser)
    if command in COMMANDS:
        importlib.import_module(f"viscorig.cli.{COMMANDS[command].module}").register(subparsers)
    for name, entry in COMMANDS.items():
        if name not in subparsers.choices:
            subparsers.add_parser(name, help=entry.summary)
    return parser


def requested_command(argv: Sequence[str]) -> str | None:
    """The command named on the command line (the first word that is not an option)."""
    return next((word for word in argv if not word.startswith("-")), None)


def one_line(message: str) -> str:
    """The message with line breaks and other control characters escaped (``\\n``), so a value
    quoted from a file or the command line cannot break the one-line error or forge a second."""
    return "".join(
        char if char.isprintable() else repr(char)[1:-1] for char in message
    )


def main(argv: Sequence[str] | None = None) -> int:
    """Run the command line and return its exit status."""
    words = sys.argv[1:] if argv is None else list(argv)
    parser = build_parser(requested_command(words))
    args = parser.parse_args(words)
    handler = getattr(args, "handler", None)
    if handler is None:
        parser.print_help()
        return 0 if args.command is None else 2
    try:
        return int(handler(args) or 0)
    except ViscorigError as error:
        print(f"viscorig: {one_line(str(error))}", file=sys.stderr)
        return error.exit_status
    except KeyboardInterrupt:
        print("viscorig: interrupted", file=sys.stderr)
        return 130
    except BrokenPipeError:
        # the reader of our output went away (``viscorig show FILE | head``): not an error
        sys.stdout = open(os.devnull, "w")  # noqa: SIM115  (stays open until the process exits)
        return 0
