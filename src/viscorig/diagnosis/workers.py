"""Where a diagnosis step makes its independent fits: in this process, or on an executor's.

A step fits every candidate against the same current model (:func:`~.findings.confirm`), and
the last rung of a ladder refits its model once without each effect term
(:func:`~.findings.unpaid_term`); those fits do not depend on each other. Inside
``with fitting_on(executor):`` they are handed to ``executor`` (:mod:`viscorig.executor`,
local processes or a Dask cluster); outside, or with fewer than two fits, they run here, one
after the other. Either way the results are the same numbers, in the same order: each fit gets
the same inputs and does the same arithmetic. :func:`fit_all_later` hands fits out before this
process does other work (a step's scan for local modes, while the other candidates are fitted and
a worker screens the frame's mode over its family of shapes)::

    with executor(jobs=2) as run, fitting_on(run):
        ladder = diagnose(data, "voigt").auto()
"""

from __future__ import annotations

import logging
from collections.abc import Callable, Iterator, Sequence
from concurrent.futures import BrokenExecutor
from contextlib import contextmanager
from contextvars import ContextVar
from functools import partial
from typing import Any, Protocol, TypeVar

Result = TypeVar("Result")


class Mapper(Protocol):
    """What a diagnosis needs of an executor: ``start``, which hands work out now and returns
    what waits for its results, in order, and how many ``workers`` work at once."""

    def start(self, function: Callable[..., Any], arguments: Sequence[tuple[Any, ...]]
              ) -> Callable[[], list[Any]]: ...

    @property
    def workers(self) -> int: ...


_EXECUTOR: ContextVar[Mapper | None] = ContextVar("viscorig_diagnosis_executor", default=None)
_log = logging.getLogger(__name__)


@contextmanager
def fitting_on(executor: Mapper | None) -> Iterator[None]:
    """Make the independent fits of every diagnosis step in this context on ``executor``
    (``None``: in this process)."""
    token = _EXECUTOR.set(executor)
    try:
        yield
    finally:
        _EXECUTOR.reset(token)


def fits_at_once() -> int:
    """How many fits are made at once: the workers of the executor of :func:`fitting_on`, one
    without (a fit that may turn out not to be needed is worth starting only beside others)."""
    executor = _EXECUTOR.get()
    return 1 if executor is None else max(1, executor.workers)


def fit_all(function: Callable[..., Result], arguments: Sequence[tuple[Any, ...]]
            ) -> list[Result]:
    """``[function(*a) for a in arguments]``, on the executor of :func:`fitting_on` if any.

    ``function`` is a module-level function (a worker process imports it by name) that returns
    its failures rather than raising them: one failed fit must not stop the others. A worker
    process that dies (killed for memory, say) costs no result: the fits are made here, and so
    are the rest of the context's.
    """
    return fit_all_later(function, arguments)()


def fit_all_later(function: Callable[..., Result], arguments: Sequence[tuple[Any, ...]],
                  *, fewest: int = 2) -> Callable[[], list[Result]]:
    """:func:`fit_all`, with the fits handed to the executor now and what returns their results
    (waiting for them) given back, so that this process can do other work meanwhile. Without an
    executor the fits are made when the results are asked for: the same numbers either way.

    ``fewest``: fewer pieces of work than this are made here (when their results are asked
    for); one piece is worth a worker only when this process has other work meanwhile."""
    executor = _EXECUTOR.get()
    arguments = list(arguments)
    if executor is None or len(arguments) < fewest:
        return lambda: [function(*a) for a in arguments]
    try:
        pending = executor.start(function, arguments)
    except BrokenExecutor as error:
        return partial(_here_after, error, function, arguments)

    def results() -> list[Result]:
        try:
            return list(pending())
        except BrokenExecutor as error:
            return _here_after(error, function, arguments)

    return results


def _here_after(error: BaseException, function: Callable[..., Result],
                arguments: Sequence[tuple[Any, ...]]) -> list[Result]:
    _log.warning("a worker process stopped (%s); the fits go on in this process", error)
    _EXECUTOR.set(None)
    return [function(*a) for a in arguments]
