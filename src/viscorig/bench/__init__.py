"""The bench page (``viscorig bench serve``): a queue of sequences run one after another by the
same run engine as ``viscorig run``, driven from a web page or any client of its local JSON API.

:mod:`~viscorig.bench.service` holds the queue and runs it; :mod:`~viscorig.bench.app` serves it
(Starlette, on loopback) with the page :file:`page.html`.
"""

from viscorig.bench.service import API_STATES, BenchError, BenchService, QueueItem

__all__ = ["API_STATES", "BenchError", "BenchService", "QueueItem"]
