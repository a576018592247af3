"""Where independent pieces of work run: local processes, or a Dask cluster.

One interface for the report's ladders (``viscorig report --jobs N``), a diagnosis step's fits
(``viscorig diagnose --jobs N``) and the heavy studies (``studies/diagnosis/detection_table.py``,
``studies/coverage.py``)::

    with executor(jobs=2) as run:                       # local processes (the default)
        results = run.map(function, [(a, b), (c, d)])   # in order
        pending = run.start(function, [(a, b), (c, d)]) # handed out now, while this process
        results = pending()                             # works on; collected in order
    with executor(scheduler="tcp://10.0.0.5:8786") as run:   # a Dask cluster
        for result in run.unordered(function, items):  # as they finish
            ...

Local workers are forked where the platform allows it (no re-import; terms registered in the
parent are known), else spawned. The Dask executor needs the optional extra
``pip install "viscorig[dask]"`` (``distributed``), imported only when a scheduler is given.
Its workers need viscorig installed, and any file a piece of work opens (a campaign) at the
same path. Work handed out and results returned are plain picklable data.
"""

from __future__ import annotations

import os
import re
from collections.abc import Callable, Iterable, Iterator, Sequence
from concurrent.futures import ProcessPoolExecutor, as_completed
from multiprocessing import get_all_start_methods, get_context
from types import TracebackType
from typing import Any, TypeVar

from viscorig.errors import InputError

Result = TypeVar("Result")

#: A scheduler address: ``tcp://HOST:PORT`` (or ``tls://``), HOST a name or an IPv4/IPv6 address.
SCHEDULER_PATTERN = re.compile(r"^(tcp|tls)://(\[[0-9A-Fa-f:.]+\]|[A-Za-z0-9.-]+):(\d{1,5})\Z")
#: Seconds a Dask client waits for the scheduler before giving up.
CONNECT_TIMEOUT_S = 3.0


def default_jobs() -> int:
    """One worker per core this process may use."""
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except AttributeError:  # pragma: no cover - not Linux
        return max(1, os.cpu_count() or 1)


def check_scheduler(address: str) -> str:
    """``address`` if it reads as ``tcp://HOST:PORT``; else :class:`InputError`."""
    match = SCHEDULER_PATTERN.fullmatch(address.strip())
    if match is None or not 0 < int(match.group(3)) < 65536:
        raise InputError(f"'{address}' is not a scheduler address tcp://HOST:PORT", "--scheduler")
    return address.strip()


class LocalExecutor:
    """Up to ``jobs`` local worker processes; ``jobs`` ≤ 1 runs everything in this process."""

    def __init__(self, jobs: int | None = None) -> None:
        self.jobs = default_jobs() if jobs is None else max(1, int(jobs))
        self._pool: ProcessPoolExecutor | None = None

    @property
    def workers(self) -> int:
        """Processes working at once."""
        return self.jobs

    def _started(self, pieces: int, fewest: int = 2) -> ProcessPoolExecutor | None:
        """The pool, started if need be; ``None`` (work done here) for fewer pieces than
        ``fewest`` or with one job."""
        if self.jobs <= 1 or pieces < fewest:
            return None
        if self._pool is None:
            method = "fork" if "fork" in get_all_start_methods() else "spawn"
            self._pool = ProcessPoolExecutor(self.jobs, mp_context=get_context(method))
        return self._pool

    def start(self, function: Callable[..., Result],
              arguments: Sequence[tuple[Any, ...]]) -> Callable[[], list[Result]]:
        """Hand ``[function(*a) for a in arguments]`` to the workers now (a single piece too:
        the caller does other work meanwhile), and return what waits for the results, in order
        (with one job, it computes them when called)."""
        arguments = list(arguments)
        pool = self._started(len(arguments), fewest=1)
        if pool is None:
            return lambda: [function(*a) for a in arguments]
        futures = [pool.submit(function, *a) for a in arguments]
        return lambda: [future.result() for future in futures]

    def map(self, function: Callable[..., Result],
            arguments: Sequence[tuple[Any, ...]]) -> list[Result]:
        """``[function(*a) for a in arguments]``, in order (one piece made here)."""
        arguments = list(arguments)
        if self._started(len(arguments)) is None:
            return [function(*a) for a in arguments]
        return self.start(function, arguments)()

    def unordered(self, function: Callable[[Any], Result], items: Iterable[Any]
                  ) -> Iterator[Result]:
        """``function(item)`` for every item, each result as soon as it is ready."""
        items = list(items)
        pool = self._started(len(items))
        if pool is None:
            yield from map(function, items)
            return
        for future in as_completed([pool.submit(function, item) for item in items]):
            yield future.result()

    def close(self) -> None:
        """Stop the worker processes."""
        if self._pool is not None:
            self._pool.shutdown()
            self._pool = None

    def __enter__(self) -> LocalExecutor:
        return self

    def __exit__(self, kind: type[BaseException] | None, error: BaseException | None,
                 trace: TracebackType | None) -> None:
        self.close()


class DaskExecutor:
    """The workers of a Dask cluster, through its scheduler at ``address``."""

    def __init__(self, address: str) -> None:
        try:
            from distributed import Client
        except ImportError:
            raise InputError("a scheduler needs the optional extra: pip install "
                             "'viscorig[dask]'", "--scheduler") from None
        self.address = check_scheduler(address)
        try:
            self.client = Client(self.address, timeout=CONNECT_TIMEOUT_S)
        except (OSError, TimeoutError) as error:
            raise InputError(f"no Dask scheduler answers at {self.address} ({error})",
                             "--scheduler") from None

    @property
    def workers(self) -> int:
        """Worker threads of the cluster (at least one)."""
        return max(1, sum(self.client.nthreads().values()))

    def upload(self, path: str | os.PathLike[str]) -> None:
        """Make a Python file importable on every worker (a study's helper module)."""
        self.client.upload_file(os.fspath(path))

    def start(self, function: Callable[..., Result],
              arguments: Sequence[tuple[Any, ...]]) -> Callable[[], list[Result]]:
        """Hand ``[function(*a) for a in arguments]`` to the cluster now, and return what
        waits for the results, in order."""
        if not arguments:
            return lambda: []
        futures = [self.client.submit(function, *a, pure=False) for a in arguments]
        return lambda: self.client.gather(futures)

    def map(self, function: Callable[..., Result],
            arguments: Sequence[tuple[Any, ...]]) -> list[Result]:
        """``[function(*a) for a in arguments]`` on the cluster, in order."""
        return self.start(function, arguments)()

    def unordered(self, function: Callable[[Any], Result], items: Iterable[Any]
                  ) -> Iterator[Result]:
        """``function(item)`` for every item on the cluster, each result when it is ready."""
        from distributed import as_completed as completed

        futures = [self.client.submit(function, item, pure=False) for item in items]
        for future in completed(futures):
            yield future.result()

    def close(self) -> None:
        """Leave the cluster (it keeps running)."""
        self.client.close()

    def __enter__(self) -> DaskExecutor:
        return self

    def __exit__(self, kind: type[BaseException] | None, error: BaseException | None,
                 trace: TracebackType | None) -> None:
        self.close()


def executor(jobs: int | None = None, scheduler: str | None = None
             ) -> LocalExecutor | DaskExecutor:
    """The Dask cluster at ``scheduler`` when given, else ``jobs`` local processes (default:
    one per core)."""
    if scheduler:
        return DaskExecutor(scheduler)
    return LocalExecutor(jobs)
