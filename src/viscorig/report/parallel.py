"""Independent pieces of the report (one run's ladder, one run's figures) in worker processes.

The machine's cores are used when there are several: runs do not depend on each other. Worker
processes are forked where the platform allows it (no re-import, the parent's registered terms
included), else spawned. Work handed to them and results returned are plain picklable data.
"""

from __future__ import annotations

import os
from collections.abc import Callable, Sequence
from concurrent.futures import ProcessPoolExecutor
from multiprocessing import get_all_start_methods, get_context
from typing import Any, TypeVar

Result = TypeVar("Result")


def default_jobs() -> int:
    """One worker per core this process may use."""
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except AttributeError:  # pragma: no cover - not Linux
        return max(1, os.cpu_count() or 1)


def parallel_map(function: Callable[..., Result], arguments: Sequence[tuple[Any, ...]],
                 jobs: int) -> list[Result]:
    """``[function(*a) for a in arguments]``, in up to ``jobs`` processes, in order."""
    if jobs <= 1 or len(arguments) <= 1:
        return [function(*a) for a in arguments]
    method = "fork" if "fork" in get_all_start_methods() else "spawn"
    with ProcessPoolExecutor(min(jobs, len(arguments)), mp_context=get_context(method)) as pool:
        futures = [pool.submit(function, *a) for a in arguments]
        return [future.result() for future in futures]
