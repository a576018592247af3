"""Independent pieces of the report (one run's ladder, one run's figures) in worker processes.

The machine's cores are used when there are several: runs do not depend on each other. The
workers are those of :mod:`viscorig.executor` (local processes, or a Dask cluster for the
ladders). Work handed to them and results returned are plain picklable data.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from typing import Any, TypeVar

from viscorig.executor import LocalExecutor, default_jobs

__all__ = ["default_jobs", "parallel_map"]

Result = TypeVar("Result")


def parallel_map(function: Callable[..., Result], arguments: Sequence[tuple[Any, ...]],
                 jobs: int) -> list[Result]:
    """``[function(*a) for a in arguments]``, in up to ``jobs`` local processes, in order."""
    with LocalExecutor(min(max(1, jobs), max(1, len(arguments)))) as pool:
        return pool.map(function, arguments)
