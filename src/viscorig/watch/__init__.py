"""The live view of a campaign: a page on 127.0.0.1 that follows a run as it is measured.

:class:`WatchServer` serves one campaign file; :func:`read_snapshot` is what the page shows,
read from the file's committed state only (read-only, never held open), so it can follow a run
that another process writes and takes nothing from the measurement.
"""

from viscorig.watch.server import LOOPBACK, WatchServer, page_html
from viscorig.watch.snapshot import Snapshots, read_snapshot

__all__ = ["LOOPBACK", "Snapshots", "WatchServer", "page_html", "read_snapshot"]
