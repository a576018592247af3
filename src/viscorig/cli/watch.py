"""``viscorig watch FILE.h5 [--port N] [--no-browser]``: a live view of a campaign in the browser.

::

    viscorig watch paper.h5                 # serves http://127.0.0.1:8765/ and opens it
    viscorig watch paper.h5 --port 0 --no-browser

The page follows the file as it is written, by this machine's ``viscorig run`` or any other
process: the FRFs of every run growing point by point, the achieved level and force against
their limits, flagged points, the time left and the state of the run. It reads only committed
data, read-only, so it never slows or endangers the measurement. Served on 127.0.0.1 only, and
nothing on the page comes from the internet. Ctrl-C stops it.
"""

from __future__ import annotations

import argparse
import contextlib
import os
import re
import subprocess
import sys
import threading
import time
import webbrowser
from collections.abc import Iterator
from pathlib import Path
from typing import TYPE_CHECKING

from viscorig.cli import summary_of
from viscorig.cli.arguments import port_number
from viscorig.errors import InputError
from viscorig.watch import WatchServer

if TYPE_CHECKING:
    from viscorig.watch import WatchServer

#: The port a technician can bookmark.
DEFAULT_PORT = 8765


def register(subparsers: argparse._SubParsersAction) -> None:
    """Add the ``watch`` command."""
    parser = subparsers.add_parser(
        "watch", help=summary_of("watch"),
        description="Serve a live view of a campaign file on 127.0.0.1 and open it in the "
        "browser: FRF magnitude and phase of every run growing point by point, achieved level "
        "and force against their limits, flagged points, time left and the state of the run. "
        "The file may be written by another process; it is only read.")
    parser.add_argument("file", metavar="FILE.h5", help="campaign file (it may not exist yet)")
    parser.add_argument("--port", type=port_number, default=DEFAULT_PORT,
                        help=f"TCP port on 127.0.0.1 (default {DEFAULT_PORT}; 0: any free one)")
    parser.add_argument("--no-browser", action="store_true",
                        help="only serve and print the address; open no browser")
    parser.set_defaults(handler=watch_command)


def open_in_browser(url: str) -> bool:
    """Open ``url`` in the desktop's browser; False where there is no desktop (a terminal-only
    session, where a text browser would take the operator's terminal)."""
    desktop = sys.platform in ("darwin", "win32") or bool(
        os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY"))
    if not desktop:
        return False
    try:
        return bool(webbrowser.open(url))
    except Exception:  # a broken browser setting must not stop the live view
        return False


def serve(path: Path, port: int) -> tuple[WatchServer, str]:
    """Start serving ``path``; return the server and its address.

    Raises
    ------
    InputError
        The port is taken or cannot be used.
    """
    try:
        server = WatchServer(path, port)
    except OSError as error:
        raise InputError(f"cannot serve on 127.0.0.1:{port} ({error.strerror or error}); "
                         "choose another --port, or --port 0 for any free one",
                         "--port") from None
    return server, server.url


def watch_command(args: argparse.Namespace) -> int:
    """``viscorig watch``: serve until Ctrl-C."""
    path = Path(args.file)
    if path.exists() and not path.is_file():
        raise InputError("not a file", str(path))
    if not path.parent.is_dir():
        raise InputError("folder does not exist", str(path))
    server, url = serve(path, args.port)
    _lower_priority()
    print(f"live view of {path}: {url}  (Ctrl-C stops it)", flush=True)
    if not args.no_browser and not open_in_browser(url):
        print(f"no browser could be opened here: open {url} in one", flush=True)
    try:
        server.serve_forever()
    except KeyboardInterrupt:
        print("live view stopped")
    finally:
        server.close()
    return 0


#: After a run ends, the live view serves this long more, so an open page shows the end.
FINAL_STATE_S = 2.5


#: The watching process runs this much nicer than others: the measurement comes first.
NICENESS = 10


def _lower_priority() -> None:
    """Yield the processor to the measurement (where the system allows it)."""
    with contextlib.suppress(AttributeError, OSError):
        os.nice(NICENESS)


@contextlib.contextmanager
def live_view(path: Path, *, open_browser: bool, say=print) -> Iterator[str | None]:
    """Serve the live view of ``path`` from a separate, lower-priority process while the body
    runs; yield its address (None if it could not start: the measurement goes on without).

    A separate process shares nothing with the measurement but the file it reads, and runs at
    a lower priority (as ``viscorig watch`` always does); it is started in its own session, so
    the operator's Ctrl-C reaches the run alone.
    """
    process = subprocess.Popen(
        [sys.executable, "-m", "viscorig", "watch", str(path), "--port", "0", "--no-browser"],
        stdin=subprocess.DEVNULL, stdout=subprocess.PIPE, stderr=subprocess.DEVNULL, text=True,
        start_new_session=True,
    )
    address: list[str] = []
    output = process.stdout
    assert output is not None  # stdout=PIPE
    reader = threading.Thread(target=lambda: address.append(output.readline()), daemon=True)
    reader.start()
    reader.join(timeout=15)
    found = re.search(r"http://127\.0\.0\.1:\d+/", address[0]) if address else None
    url = found.group(0) if found else None
    if url is None:
        say("WARNING: the live view could not start; measuring without it")
    else:
        say(f"live view: {url}")
        if open_browser and not open_in_browser(url):
            say(f"(no browser could be opened here: open {url} in one)")
    try:
        yield url
    finally:
        if url is not None:
            time.sleep(FINAL_STATE_S)
        process.terminate()
        try:
            process.wait(timeout=5)
        except subprocess.TimeoutExpired:
            process.kill()
            process.wait(timeout=5)
        if process.stdout is not None:
            process.stdout.close()
