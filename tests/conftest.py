"""Shared pytest configuration."""

from __future__ import annotations

from viscorig.runtime import limit_blas_threads

limit_blas_threads()

import pytest  # noqa: E402


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
