"""Figures of the reliability tests, collected over one pytest session.

Tests add to named counters (:func:`add`); ``tests/conftest.py`` prints them at the end of the
run, so the README can quote measured numbers. Counters only grow when a test actually did the
thing counted (a fault injected and its outcome checked, a kill survived, an input fuzzed).
"""

from __future__ import annotations

import json
import os
from collections import Counter

#: Counter name -> what it means, in the order the summary lists them.
FIGURES = {
    "faults tried": "instrument faults injected and their outcome checked",
    "faults recovered": "faults after which resume (or a retry) completed the measurement",
    "kills survived": "SIGKILLs of a running campaign after which the file held every segment",
    "inputs fuzzed": "bad or random inputs given to a parser, the CLI or the driver",
    "replies fuzzed": "malformed instrument replies decoded through a loopback server",
    "injections refused": "strings with command separators refused before anything was sent",
    "writers refused": "second writers of a campaign file refused, naming the holder",
    "storage faults": "full disks, file-size limits and read-only mounts met by a command",
    "hostile files": "hostile campaign, UFF and CSV files refused in one line",
    "points lost": "committed points missing after a fault or kill (must stay 0)",
}

_counts: Counter[str] = Counter()


def add(name: str, count: int = 1) -> None:
    """Add ``count`` to the figure ``name`` (one of :data:`FIGURES`)."""
    if name not in FIGURES:
        raise KeyError(f"unknown reliability figure {name!r}")
    _counts[name] += int(count)


def value(name: str) -> int:
    """The current value of a figure."""
    return _counts[name]


def summary_lines() -> list[str]:
    """One line per figure touched in this session; also written as JSON to the file named by
    the environment variable ``VISCORIG_RELIABILITY_JSON``, if set."""
    if not _counts:
        return []
    path = os.environ.get("VISCORIG_RELIABILITY_JSON")
    if path:
        with open(path, "w", encoding="utf-8") as handle:
            json.dump({name: _counts[name] for name in FIGURES}, handle, indent=1)
    return [f"{name:<20} {_counts[name]:>7}   {FIGURES[name]}" for name in FIGURES]
