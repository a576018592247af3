"""Shared pytest configuration."""

from __future__ import annotations

import pytest


def pytest_addoption(parser: pytest.Parser) -> None:
    parser.addoption(
        "--resource",
        default=None,
        help="VISA resource of a real 35670A for the hardware tests (or env VISCORIG_RESOURCE)",
    )
