"""The ``viscorig`` command line.

Each command lives in its own module of this package and exposes ``register(subparsers)``,
which adds its sub-parser and sets ``handler`` to a function ``handler(args) -> int``. A command
is listed in :data:`COMMAND_MODULES` only once it works.
"""

from __future__ import annotations

import argparse
import importlib
import sys
from collections.abc import Sequence

from viscorig.runtime import limit_blas_threads

limit_blas_threads()

from viscorig import __version__  # noqa: E402  (after the BLAS setting, before numpy loads)
from viscorig.errors import ViscorigError  # noqa: E402

#: Modules of ``viscorig.cli`` that provide commands, in the order ``--help`` lists them.
COMMAND_MODULES: tuple[str, ...] = (
    "run", "show", "identify", "diagnose", "summary", "sim", "exchange", "report",
)


class _Parser(argparse.ArgumentParser):
    """An argument parser whose usage errors are one line on stderr and exit status 2."""

    def error(self, message: str) -> None:  # type: ignore[override]
        self.exit(2, f"{self.prog}: error: {message}\n")


def build_parser() -> argparse.ArgumentParser:
    """Build the top-level parser with every available command."""
    parser = _Parser(
        prog="viscorig",
        description="Swept-sine characterisation of viscoelastic dampers.",
    )
    parser.add_argument("--version", action="version", version=f"viscorig {__version__}")
    subparsers = parser.add_subparsers(title="commands", dest="command", parser_class=_Parser)
    for name in COMMAND_MODULES:
        importlib.import_module(f"viscorig.cli.{name}").register(subparsers)
    return parser


def one_line(message: str) -> str:
    """The message with line breaks and other control characters escaped (``\\n``), so a value
    quoted from a file or the command line cannot break the one-line error or forge a second."""
    return "".join(
        char if char.isprintable() else repr(char)[1:-1] for char in message
    )


def main(argv: Sequence[str] | None = None) -> int:
    """Run the command line and return its exit status."""
    parser = build_parser()
    args = parser.parse_args(argv)
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
