"""Where a diagnosis step makes its independent fits: in this process, or on an executor's.

A step fits every candidate against the same current model (:func:`~.findings.confirm`), and
the last rung of a ladder refits its model once without each effect term
(:func:`~.findings.unpaid_term`); those fits do not depend on each other. Inside
``with fitting_on(executor):`` they are handed to ``executor`` (:mod:`viscorig.executor`,
local processes or a Dask cluster); outside, or with fewer than two fits, they run here, one
after the other. Either way the results are the same numbers, in the same order: each fit gets
the same inputs and does the same arithmetic::

    with executor(jobs=2) as run, fitting_on(run):
        ladder = diagnose(data, "voigt").auto()
"""

from __future__ import annotations

import logging
from collections.abc import Callable, Iterator, Sequence
from concurrent.futures import BrokenExecutor
from contextlib import contextmanager
from contextvars import ContextVar
from typing import Any, Protocol, TypeVar

Result = TypeVar("Result")


class Mapper(Protocol):
    """What a diagnosis needs of an executor: ``map`` in order."""

    def map(self, function: Callable[..., Any], arguments: Sequence[tuple[Any, ...]]
            ) -> list[Any]: ...


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


def fit_all(function: Callable[..., Result], arguments: Sequence[tuple[Any, ...]]
            ) -> list[Result]:
    """``[function(*a) for a in arguments]``, on the executor of :func:`fitting_on` if any.

    ``function`` is a module-level function (a worker process imports it by name) that returns
    its failures rather than raising them: one failed fit must not stop the others. A worker
    process that dies (killed for memory, say) costs no result: the fits are made here, and so
    are the rest of the context's.
    """
    executor = _EXECUTOR.get()
    if executor is not None and len(arguments) >= 2:
        try:
            return list(executor.map(function, arguments))
        except BrokenExecutor as error:
            _log.warning("a worker process stopped (%s); the fits go on in this process", error)
            _EXECUTOR.set(None)
    return [function(*a) for a in arguments]
