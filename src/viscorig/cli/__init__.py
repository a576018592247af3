"""The ``viscorig`` command line.

Each command lives in a module of this package that exposes ``register(subparsers)``, which adds
its sub-parser(s) and sets ``handler`` to a function ``handler(args) -> int``. A command is listed
in :data:`COMMANDS` only once it works. Only the module of the command being run is imported, so
that the program starts quickly whatever the other commands need (scipy, matplotlib, pyvisa).
A command module imports the ``viscorig`` modules it uses at its top; it imports a heavy
subsystem that only some of its paths need (scipy for an adaptive step, matplotlib for
``--plot``, the bench's web server) inside the function that needs it, with a comment saying it
keeps the command's start fast (``tests/test_import_cycles.py`` holds every other
function-level import of ``viscorig`` for an error). The driver and the simulated rig, which
the command line wires in through :mod:`viscorig.stations`, are imported where they are used.

Every command takes ``-v``/``-q`` (before or after its name): they set the level of the standard
``logging`` module for the ``viscorig`` logger, whose records go to stderr as ``viscorig: ...``
lines (``-v`` information such as how long a step took, ``-vv`` debugging, ``-q`` errors only).
Modules log with ``logging.getLogger(__name__)``; results stay on stdout.
"""

from __future__ import annotations

import argparse
import importlib
import logging
import os
import sys
import time
from collections.abc import Sequence
from typing import NamedTuple

from viscorig.runtime import limit_blas_threads

limit_blas_threads()

from viscorig.errors import ViscorigError  # noqa: E402
from viscorig.version import __version__  # noqa: E402  (after the BLAS setting, before numpy loads)


class Command(NamedTuple):
    """Where a command is defined and its one-line description."""

    module: str
    summary: str


#: Every command, in the order ``--help`` lists them.
COMMANDS: dict[str, Command] = {
    "run": Command("run", "run a test sequence into a new campaign file"),
    "resume": Command("run", "continue an interrupted campaign file"),
    "note": Command("note", "store a note with its time in a campaign's journal, also mid-run"),
    "show": Command("show", "list the runs and fits of a campaign file"),
    "identify": Command("identify", "fit a model to one run and store the fit in the file"),
    "diagnose": Command(
        "diagnose", "show where a model fails and which physical effect is missing"
    ),
    "summary": Command(
        "summary", "Table 1 and Table 2 of the paper for every run of a campaign"
    ),
    "report": Command("report", "HTML report with figures (PNG, SVG on request) of a campaign"),
    "export": Command(
        "exchange",
        "write a run's FRFs to UFF 58 or CSV, or a material card (Abaqus, ANSYS, LS-DYNA)",
    ),
    "import": Command(
        "exchange", "add a run to a campaign from UFF 58, CSV, SDF (35670A family) or DMA files"
    ),
    "master": Command(
        "master", "master curve, shift factors and Prony series of a material over temperature"
    ),
    "sim": Command("sim", "simulated rig and analyser"),
    "check": Command("check", "list every problem of a sequence (and station) file at once"),
    "plan": Command("plan", "predict each step's test time and the total, touching no instrument"),
    "watch": Command("watch", "live view of a campaign file in the browser, on loopback"),
    "bench": Command("bench", "check the station; serve the bench page (queue, run, pause, notes)"),
}


def summary_of(command: str) -> str:
    """The one-line description of ``command`` (for its module's ``add_parser``)."""
    return COMMANDS[command].summary


class _Parser(argparse.ArgumentParser):
    """An argument parser whose usage errors are one line on stderr and exit status 2."""

    def error(self, message: str) -> None:  # type: ignore[override]
        self.exit(2, f"{self.prog}: error: {message}\n")


#: The logger every module of the package logs to (``logging.getLogger(__name__)``).
LOGGER = "viscorig"


def add_verbosity_options(parser: argparse.ArgumentParser, *, top: bool) -> None:
    """``-v/--verbose`` and ``-q/--quiet``, on the program and on every command.

    The command's options count apart from the program's (a sub-parser fills a namespace of its
    own), so that ``viscorig -v show`` and ``viscorig show -v`` both count, and
    ``viscorig -v show -v`` counts twice (:func:`verbosity` adds them up).
    """
    suffix = "" if top else "_command"
    group = parser.add_argument_group("messages")
    group.add_argument("-v", "--verbose", action="count", default=0, dest=f"verbose{suffix}",
                       help="say more on stderr: what is done and how long it takes (-vv: debug)")
    group.add_argument("-q", "--quiet", action="count", default=0, dest=f"quiet{suffix}",
                       help="say less on stderr: errors only, no warnings or progress")


def _add_verbosity_everywhere(parser: argparse.ArgumentParser) -> None:
    """Give every (sub-)command parser the verbosity options."""
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            for sub in action.choices.values():
                if "--verbose" not in sub._option_string_actions:
                    add_verbosity_options(sub, top=False)
                _add_verbosity_everywhere(sub)


def verbosity(args: argparse.Namespace) -> int:
    """``-v`` count minus ``-q`` count, wherever given: 0 normal, above 0 more, below 0 less."""
    return sum(int(getattr(args, name, 0) or 0) for name in ("verbose", "verbose_command")) - sum(
        int(getattr(args, name, 0) or 0) for name in ("quiet", "quiet_command"))


class _MessageFormatter(logging.Formatter):
    """``viscorig: text`` for information, ``viscorig: warning: text`` above it; with -vv the
    logger's name too."""

    def __init__(self, debug: bool) -> None:
        super().__init__()
        self.debug = debug

    def format(self, record: logging.LogRecord) -> str:
        level = "" if record.levelno == logging.INFO else f"{record.levelname.lower()}: "
        if not self.debug:
            return f"viscorig: {one_line(level + record.getMessage())}"
        text = f"viscorig: [{record.name}] {level}{record.getMessage()}"
        if record.exc_info:
            text += "\n" + self.formatException(record.exc_info)
        return text


def configure_logging(level: int) -> logging.Handler:
    """Send the package's log records (and Python warnings) to stderr at ``level``.

    One handler, replaced on every call, writing to the ``sys.stderr`` of the moment.
    """
    logger = logging.getLogger(LOGGER)
    for handler in [h for h in logger.handlers if getattr(h, "viscorig_cli", False)]:
        logger.removeHandler(handler)
    handler = logging.StreamHandler(sys.stderr)
    handler.viscorig_cli = True  # type: ignore[attr-defined]
    handler.setFormatter(_MessageFormatter(debug=level <= logging.DEBUG))
    logger.addHandler(handler)
    logger.setLevel(level)
    logger.propagate = False
    logging.captureWarnings(True)
    warnings_logger = logging.getLogger("py.warnings")
    warnings_logger.handlers = [handler]
    warnings_logger.setLevel(level)
    warnings_logger.propagate = False
    return handler


#: Verbosity (``-v`` minus ``-q``) -> logging level.
LEVELS = {-1: logging.ERROR, 0: logging.WARNING, 1: logging.INFO}


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
    add_verbosity_options(parser, top=True)
    subparsers = parser.add_subparsers(title="commands", dest="command", parser_class=_Parser)
    if command in COMMANDS:
        importlib.import_module(f"viscorig.cli.{COMMANDS[command].module}").register(subparsers)
    for name, entry in COMMANDS.items():
        if name not in subparsers.choices:
            subparsers.add_parser(name, help=entry.summary)
    _add_verbosity_everywhere(parser)
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
    configure_logging(LEVELS.get(max(-1, verbosity(args)), logging.DEBUG))
    handler = getattr(args, "handler", None)
    if handler is None:
        parser.print_help()
        return 0 if args.command is None else 2
    log = logging.getLogger(LOGGER)
    started = time.perf_counter()
    try:
        status = int(handler(args) or 0)
        log.info("%s finished in %.2f s", args.command, time.perf_counter() - started)
        return status
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
    except OSError as error:
        if error.filename is None:
            raise
        # a path the file system refuses where no reader checked it first (a name longer than
        # it takes, say): the path and the system's reason, in one line
        print(f"viscorig: {one_line(os.fsdecode(error.filename))}: "
              f"{error.strerror or error}", file=sys.stderr)
        return 2
