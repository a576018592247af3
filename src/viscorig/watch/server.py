"""The live view's web server: one page and its data, on loopback only.

``GET /`` is the page (:file:`page.html`: HTML, CSS, JavaScript and SVG in one file, nothing
fetched from anywhere else; its Content-Security-Policy forbids it). ``GET /state.json?version=N``
answers ``{"version": V, "snapshot": {...}}`` when the file changed since version ``N``, else
``{"version": N, "unchanged": true}``; the page asks once a second. Requests naming another
host than the server's (a DNS-rebinding page in the same browser) are refused.
"""

from __future__ import annotations

import threading
from functools import cache
from http import HTTPStatus
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer
from importlib import resources
from pathlib import Path
from typing import Any
from urllib.parse import parse_qs, urlsplit

from viscorig import jsontext
from viscorig.watch.snapshot import Snapshots

#: Only this interface is ever served.
LOOPBACK = "127.0.0.1"
_POLICY = ("default-src 'none'; script-src 'unsafe-inline'; style-src 'unsafe-inline'; "
           "connect-src 'self'; img-src data:; base-uri 'none'; form-action 'none'")


@cache
def page_html() -> str:
    """The page, as shipped with the package."""
    return resources.files("viscorig.watch").joinpath("page.html").read_text(encoding="utf-8")


class _Handler(BaseHTTPRequestHandler):
    server: _Server
    protocol_version = "HTTP/1.1"

    def log_message(self, format: str, *args: Any) -> None:
        """Quiet: the terminal belongs to the operator."""

    def _send(self, status: HTTPStatus, body: bytes, content_type: str) -> None:
        self.send_response(status)
        self.send_header("Content-Type", content_type)
        self.send_header("Content-Length", str(len(body)))
        self.send_header("Cache-Control", "no-store")
        self.send_header("Content-Security-Policy", _POLICY)
        self.send_header("X-Content-Type-Options", "nosniff")
        self.end_headers()
        if self.command != "HEAD":
            self.wfile.write(body)

    def _host_allowed(self) -> bool:
        host = (self.headers.get("Host") or "").strip().lower()
        port = self.server.server_address[1]
        return host in {f"{LOOPBACK}:{port}", f"localhost:{port}"}

    def do_HEAD(self) -> None:
        self.do_GET()

    def do_GET(self) -> None:
        if not self._host_allowed():
            self._send(HTTPStatus.FORBIDDEN, b"forbidden\n", "text/plain; charset=utf-8")
            return
        url = urlsplit(self.path)
        if url.path == "/":
            self._send(HTTPStatus.OK, page_html().encode("utf-8"), "text/html; charset=utf-8")
        elif url.path == "/state.json":
            self._send(HTTPStatus.OK, self._state(url.query), "application/json")
        elif url.path == "/favicon.ico":
            self._send(HTTPStatus.NO_CONTENT, b"", "image/x-icon")
        else:
            self._send(HTTPStatus.NOT_FOUND, b"not found\n", "text/plain; charset=utf-8")

    def _state(self, query: str) -> bytes:
        known = parse_qs(query).get("version", [""])[0]
        version, snapshot = self.server.snapshots.latest()
        answer: dict[str, Any] = {"version": version, "error": self.server.snapshots.error}
        if known == str(version) and snapshot is not None:
            answer["unchanged"] = True
        else:
            answer["snapshot"] = snapshot
        return jsontext.dumps(answer, compact=True).encode("utf-8")


class _Server(ThreadingHTTPServer):
    daemon_threads = True
    snapshots: Snapshots


class WatchServer:
    """Serve the live view of one campaign file on 127.0.0.1.

    Parameters
    ----------
    path
        The campaign file (it may be written by another process, or not exist yet).
    port
        TCP port; 0 for any free one.

    Raises
    ------
    OSError
        The port is taken.
    """

    def __init__(self, path: str | Path, port: int = 0) -> None:
        self.path = Path(path)
        self._server = _Server((LOOPBACK, port), _Handler)
        self._server.snapshots = Snapshots(self.path)
        self._thread: threading.Thread | None = None

    @property
    def port(self) -> int:
        return int(self._server.server_address[1])

    @property
    def url(self) -> str:
        return f"http://{LOOPBACK}:{self.port}/"

    def serve_forever(self) -> None:
        """Serve until :meth:`close` (or Ctrl-C in the caller)."""
        self._server.serve_forever(poll_interval=0.2)

    def start(self) -> WatchServer:
        """Serve from a background thread."""
        self._thread = threading.Thread(target=self.serve_forever, name="viscorig-watch",
                                        daemon=True)
        self._thread.start()
        return self

    def close(self) -> None:
        """Stop serving and release the port."""
        if self._thread is not None:
            self._server.shutdown()
            self._thread.join(timeout=5)
        self._server.server_close()

    def __enter__(self) -> WatchServer:
        return self.start()

    def __exit__(self, *exc: object) -> None:
        self.close()
