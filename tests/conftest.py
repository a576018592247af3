"""Shared pytest configuration."""

from __future__ import annotations

import signal

from viscorig.runtime import limit_blas_threads

limit_blas_threads()

import pytest  # noqa: E402

# The tests that press Ctrl-C on a command (SIGINT to a subprocess) play a terminal's foreground
# job. Run as a background job of a shell without job control (a CI runner's script), the test
# process inherits SIGINT ignored, its subprocesses would too, and no Ctrl-C would reach them.
if signal.getsignal(signal.SIGINT) == signal.SIG_IGN:
    signal.signal(signal.SIGINT, signal.default_int_handler)


def pytest_addoption(parser: pytest.Parser) -> None:
    parser.addoption(
        "--resource",
        default=None,
        help="VISA resource of a real 35670A for the hardware tests (or env VISCORIG_RESOURCE)",
    )


def pytest_terminal_summary(terminalreporter) -> None:
    """Print the reliability figures (faults tried, kills survived, ...) measured in this run."""
    from reliability_tally import summary_lines

    lines = summary_lines()
    if lines:
        terminalreporter.write_sep("-", "reliability figures")
        for line in lines:
            terminalreporter.write_line(line)
