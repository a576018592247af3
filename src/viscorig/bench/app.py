"""The bench page's web application: the JSON API of ``viscorig bench serve`` and its page.

Built on Starlette and served by uvicorn on 127.0.0.1 (another address only when the station's
``[bench] address`` says so). Every request passes :class:`Guard` first:

- its ``Host`` must name this server (a page of another site cannot reach it by DNS
  rebinding), and a request that carries an ``Origin`` must come from this server's own;
- it must carry the token: ``Authorization: Bearer TOKEN``, or the cookie the page sets when it
  is opened with ``/?token=TOKEN``;
- at most :data:`RATE_PER_S` requests a second are served (429 beyond), counted apart for the
  client in control, for the other clients with the token and for requests without it, so
  that a flood from a read-only page or a stranger never slows the one that can pause or abort;
  no body may exceed :data:`MAX_BODY_BYTES` (413).

One client controls the bench at a time (the first to send a command; a client is its browser's
cookie, or a script's ``X-Bench-Client`` header): a second one is read-only (409, and its page
says so) until the first has been silent for :data:`CONTROL_LEASE_S`. Closing the browser never
stops a run. Every refusal is a 4xx whose JSON body is ``{"error": "one line"}``.
"""

from __future__ import annotations

import hmac
import json
import secrets
import signal
import socket
import threading
import time
from collections.abc import Awaitable, Callable
from functools import cache
from importlib import resources
from pathlib import Path
from typing import Any

from starlette.applications import Starlette
from starlette.concurrency import run_in_threadpool
from starlette.requests import Request
from starlette.responses import HTMLResponse, JSONResponse, Response
from starlette.routing import Route

from viscorig import jsontext
from viscorig.bench.service import BenchError, BenchService
from viscorig.errors import InputError
from viscorig.storage import CampaignFile
from viscorig.watch.server import page_html as live_html
from viscorig.watch.snapshot import Snapshots

#: A request handler of the application.
Endpoint = Callable[[Request], Awaitable[Response]]

#: Requests served per second to each of: the controlling client, the other clients with the
#: token, requests without it; a burst of that many is allowed.
RATE_PER_S = 50
#: Largest request body, bytes.
MAX_BODY_BYTES = 64 * 1024
#: A controlling client silent this long loses control, s.
CONTROL_LEASE_S = 15.0
#: A connection that has sent no whole request head this long after it opened (or after its
#: last answer) is closed, s: idle or trickling connections from anyone cannot pile up.
REQUEST_HEAD_S = 10.0
#: The page's and the live view's policies: nothing from elsewhere, frames only from here.
_PAGE_POLICY = ("default-src 'none'; script-src 'unsafe-inline'; style-src 'unsafe-inline'; "
                "connect-src 'self'; img-src data:; frame-src 'self'; base-uri 'none'; "
                "form-action 'none'; frame-ancestors 'none'")
_LIVE_POLICY = ("default-src 'none'; script-src 'unsafe-inline'; style-src 'unsafe-inline'; "
                "connect-src 'self'; img-src data:; base-uri 'none'; form-action 'none'; "
                "frame-ancestors 'self'")


@cache
def page_html() -> str:
    """The bench page, as shipped with the package."""
    return resources.files("viscorig.bench").joinpath("page.html").read_text(encoding="utf-8")


def _is_unicode(text: str) -> bool:
    """``text`` can be written as UTF-8 (JSON's ``"\\ud800"`` reads to a lone surrogate, which
    no file name, note or HDF5 attribute can hold)."""
    try:
        text.encode("utf-8")
    except UnicodeEncodeError:
        return False
    return True


def error(status: int, message: str) -> JSONResponse:
    """A refusal: ``{"error": message}`` (one line)."""
    return JSONResponse({"error": " ".join(str(message).split())}, status_code=status,
                        headers={"Cache-Control": "no-store"})


class RateLimit:
    """A token bucket: ``rate`` requests a second, bursts of ``rate``."""

    def __init__(self, rate: float) -> None:
        self.rate = float(rate)
        self.tokens = float(rate)
        self.last = time.monotonic()
        self._lock = threading.Lock()

    def take(self) -> bool:
        with self._lock:
            now = time.monotonic()
            self.tokens = min(self.rate, self.tokens + (now - self.last) * self.rate)
            self.last = now
            if self.tokens < 1.0:
                return False
            self.tokens -= 1.0
            return True


class Control:
    """Which client controls the bench (module text)."""

    def __init__(self, lease_s: float = CONTROL_LEASE_S) -> None:
        self.lease_s = lease_s
        self.holder: str | None = None
        self.seen = 0.0
        self._lock = threading.Lock()

    def _free(self, now: float) -> bool:
        return self.holder is None or now - self.seen > self.lease_s

    def controls(self, client: str) -> bool:
        """Does ``client`` control the bench now (without touching its lease)?"""
        with self._lock:
            return self.holder == client and not self._free(time.monotonic())

    def touch(self, client: str) -> str:
        """A request of ``client``: "you", "another client" or "free" (who controls)."""
        with self._lock:
            now = time.monotonic()
            if self.holder == client:
                self.seen = now
                return "you"
            return "free" if self._free(now) else "another client"

    def take(self, client: str) -> bool:
        """May ``client`` command? (It then controls the bench.)"""
        with self._lock:
            now = time.monotonic()
            if self.holder == client or self._free(now):
                self.holder, self.seen = client, now
                return True
            return False


def client_key(cookie: str | None, headers: Any) -> str:
    """Who sends a request: its page's client cookie, or a script's ``X-Bench-Client``."""
    return cookie or "script:" + headers.get("x-bench-client", "")[:64]


def _cookies(headers: dict[str, str]) -> dict[str, str]:
    pairs = (part.strip().partition("=") for part in headers.get("cookie", "").split(";"))
    return {name: value for name, _, value in pairs if name}


class Guard:
    """The checks every request passes before the application (module text); pure ASGI."""

    def __init__(self, app: Any, token: str, hosts: set[str], cookie: str,
                 control: Control, client_cookie: str) -> None:
        self.app = app
        self.token = token
        self.hosts = hosts
        self.cookie = cookie
        self.control = control
        self.client_cookie = client_cookie
        self.controller = RateLimit(RATE_PER_S)
        self.rate = RateLimit(RATE_PER_S)
        self.strangers = RateLimit(RATE_PER_S)

    async def __call__(self, scope: dict, receive: Any, send: Any) -> None:
        if scope["type"] == "websocket":  # none is served: refused before anything
            await send({"type": "websocket.close", "code": 1008})
            return
        if scope["type"] != "http":
            await self.app(scope, receive, send)
            return
        refusal = self._refusal(scope)
        if refusal is not None:
            await refusal(scope, receive, send)
            return
        await self.app(scope, self._bounded(receive), send)

    def _refusal(self, scope: dict) -> Response | None:
        headers = {k.decode("latin-1").lower(): v.decode("latin-1")
                   for k, v in scope.get("headers", [])}
        cookies = _cookies(headers)
        authorised = self._authorised(scope, headers, cookies)
        if not authorised:
            bucket = self.strangers
        elif self.control.controls(client_key(cookies.get(self.client_cookie), headers)):
            bucket = self.controller
        else:
            bucket = self.rate
        if not bucket.take():
            return error(429, f"too many requests: at most {RATE_PER_S} a second")
        names = [name.decode("latin-1").lower() for name, _ in scope.get("headers", [])]
        twice = next((name for name in ("host", "origin", "authorization", "cookie")
                      if names.count(name) > 1), None)
        if twice is not None:  # only the last would be checked
            return error(400, f"header {twice!r} given twice")
        host = headers.get("host", "").strip().lower()
        if host not in self.hosts:
            return error(403, f"host {host!r} is not this server")
        origin = headers.get("origin")
        if origin is not None and origin.lower() not in {f"http://{h}" for h in self.hosts}:
            return error(403, f"origin {origin!r} is not this server: requests from other "
                         "pages are refused")
        if headers.get("sec-fetch-site") == "cross-site":
            return error(403, "requests from other sites are refused")
        length = headers.get("content-length")
        if length is not None and (not length.isdigit() or int(length) > MAX_BODY_BYTES):
            return error(413, f"request body over {MAX_BODY_BYTES} bytes")
        if not authorised:
            return error(401, "missing or wrong token: open the address 'viscorig bench serve' "
                         "printed, or send 'Authorization: Bearer TOKEN'")
        return None

    def _authorised(self, scope: dict, headers: dict[str, str],
                    cookies: dict[str, str]) -> bool:
        offered = []
        authorization = headers.get("authorization", "")
        if authorization.lower().startswith("bearer "):
            offered.append(authorization[7:].strip())
        if self.cookie in cookies:
            offered.append(cookies[self.cookie])
        if scope.get("path") == "/" and scope.get("method") == "GET":
            query = scope.get("query_string", b"").decode("latin-1")
            for part in query.split("&"):
                name, _, value = part.partition("=")
                if name == "token":
                    offered.append(value)
        return any(hmac.compare_digest(value.encode(), self.token.encode())
                   for value in offered)

    @staticmethod
    def _bounded(receive: Any) -> Any:
        received = [0]

        async def bounded() -> dict:
            message = await receive()
            if message["type"] == "http.request":
                received[0] += len(message.get("body", b""))
                if received[0] > MAX_BODY_BYTES:
                    raise BenchError(f"request body over {MAX_BODY_BYTES} bytes", 413)
            return message

        return bounded


def create_app(service: BenchService, token: str, port: int,
               address: str = "127.0.0.1") -> Guard:
    """The application of :class:`BenchService` at ``address:port`` with ``token``."""
    cookie = f"viscorig_bench_{port}"
    client_cookie = f"viscorig_client_{port}"
    control = Control()
    journal = _journal_endpoint(service)
    live_page, live_state = _live_endpoints(service)

    def client_of(request: Request) -> str:
        return client_key(request.cookies.get(client_cookie), request.headers)

    async def body(request: Request) -> dict[str, Any]:
        try:
            raw = await request.body()
        except BenchError as bad:
            raise bad from None
        if not raw:
            return {}
        try:
            value = json.loads(raw)
        except (ValueError, UnicodeDecodeError):
            raise BenchError("body: not JSON", 400) from None
        except RecursionError:
            raise BenchError("body: JSON nested too deep", 400) from None
        if not isinstance(value, dict):
            raise BenchError("body: a JSON object", 400)
        for key, item in value.items():
            for text in (key, item):
                if isinstance(text, str) and not _is_unicode(text):
                    raise BenchError(f"body: {key!r} holds a lone surrogate (\\ud800..\\udfff), "
                                     "not text", 400)
        return value

    async def page(request: Request) -> Response:
        response = HTMLResponse(page_html(), headers={
            "Cache-Control": "no-store", "Content-Security-Policy": _PAGE_POLICY,
            "X-Content-Type-Options": "nosniff", "Referrer-Policy": "no-referrer"})
        response.set_cookie(cookie, token, httponly=True, samesite="strict", path="/")
        if client_cookie not in request.cookies:
            response.set_cookie(client_cookie, secrets.token_urlsafe(12), httponly=True,
                                samesite="strict", path="/")
        return response

    async def state(request: Request) -> Response:
        answer = service.state()
        answer["control"] = control.touch(client_of(request))
        return JSONResponse(answer, headers={"Cache-Control": "no-store"})

    def command(action):
        async def endpoint(request: Request) -> Response:
            try:
                data = await body(request)
                if not control.take(client_of(request)):
                    return error(409, "read-only: another client controls the bench")
                # off the event loop: checking and planning a queued sequence takes seconds,
                # in which a pause or an abort must still be answered
                result = await run_in_threadpool(action, request, data)
            except BenchError as refused:
                return error(refused.status, str(refused))
            except InputError as refused:  # the campaign file refuses (locked, journal full)
                return error(409, str(refused))
            return JSONResponse(result or {"ok": True}, headers={"Cache-Control": "no-store"})
        return endpoint

    def queue_add(request: Request, data: dict) -> dict:
        item = service.add(data.get("sequence"), data.get("out"))
        return {"id": item.id, "problems": item.problems, "plan_s": item.plan_s}

    def queue_remove(request: Request, data: dict) -> None:
        service.remove(request.path_params["item"])

    def queue_move(request: Request, data: dict) -> None:
        service.move(request.path_params["item"], data.get("position"))

    simple = {
        "start": lambda request, data: service.start(),
        "pause": lambda request, data: service.pause(),
        "resume": lambda request, data: service.resume(),
        "abort": lambda request, data: service.abort(),
        "answer": lambda request, data: service.answer(data.get("prompt_id"),
                                                       data.get("answer")),
        "notes": lambda request, data: service.note(data.get("text")),
    }
    routes = [
        Route("/", page, methods=["GET"]),
        Route("/api/state", state, methods=["GET"]),
        Route("/api/journal", journal, methods=["GET"]),
        Route("/api/queue", command(queue_add), methods=["POST"]),
        Route("/api/queue/{item}", command(queue_remove), methods=["DELETE"]),
        Route("/api/queue/{item}/move", command(queue_move), methods=["POST"]),
        *(Route(f"/api/{name}", command(action), methods=["POST"])
          for name, action in simple.items()),
        Route("/live/", live_page, methods=["GET"]),
        Route("/live/state.json", live_state, methods=["GET"]),
    ]
    hosts = {f"{address}:{port}"}
    if address == "127.0.0.1":
        hosts.add(f"localhost:{port}")
    app = Starlette(routes=routes, exception_handlers=_exception_handlers())
    app.router.redirect_slashes = False  # '/api/state/' is no endpoint: a JSON 404, not a 307
    return Guard(app, token, hosts, cookie, control, client_cookie)


def _journal_endpoint(service: BenchService) -> Endpoint:
    """``GET /api/journal``: the last 200 entries of the current campaign's journal."""

    async def journal(request: Request) -> Response:
        path = service.campaign_path
        entries = []
        if path is not None and Path(path).exists():
            try:
                entries = [e.__dict__ for e in CampaignFile.open(path).journal][-200:]
            except Exception as failure:
                return error(409, f"{path}: {failure}")
        return JSONResponse({"campaign": None if path is None else str(path),
                             "entries": entries}, headers={"Cache-Control": "no-store"})

    return journal


def _live_endpoints(service: BenchService) -> tuple[Endpoint, Endpoint]:
    """``GET /live/`` and ``/live/state.json``: the watch page of the campaign being measured,
    its snapshots answered as ``unchanged`` while their version is the one the page has."""
    live: dict[str, Snapshots] = {}

    async def live_page(request: Request) -> Response:
        return HTMLResponse(live_html(), headers={
            "Cache-Control": "no-store", "Content-Security-Policy": _LIVE_POLICY,
            "X-Content-Type-Options": "nosniff"})

    async def live_state(request: Request) -> Response:
        path = service.campaign_path
        if path is None:
            return JSONResponse({"version": "", "error": "no campaign yet"})
        snapshots = live.get(str(path))
        if snapshots is None:
            live.clear()
            snapshots = live[str(path)] = Snapshots(Path(path))
        version, snapshot = snapshots.latest()
        known = request.query_params.get("version", "")
        answer: dict[str, Any] = {"version": version, "error": snapshots.error}
        if known == str(version) and snapshot is not None:
            answer["unchanged"] = True
        else:
            answer["snapshot"] = snapshot
        return Response(jsontext.dumps(answer, compact=True),
                        media_type="application/json", headers={"Cache-Control": "no-store"})

    return live_page, live_state


def _exception_handlers() -> dict[Any, Callable[[Request, Exception], Awaitable[Response]]]:
    """One JSON error for every failure: no endpoint, a method not allowed, a request the bench
    refuses, an internal error (the run goes on)."""

    async def not_found(request: Request, exc: Exception) -> Response:
        return error(404, f"{request.method} {request.url.path}: no such endpoint")

    async def not_allowed(request: Request, exc: Exception) -> Response:
        return error(405, f"{request.method} {request.url.path}: method not allowed")

    async def refused(request: Request, exc: Exception) -> Response:
        return error(getattr(exc, "status", 400), str(exc))

    async def failed(request: Request, exc: Exception) -> Response:
        return error(500, f"internal error ({type(exc).__name__}); the run goes on")

    return {404: not_found, 405: not_allowed, BenchError: refused, Exception: failed}


def _protocol() -> type:
    """uvicorn's HTTP/1.1 protocol (h11) closing a connection that has sent no whole request
    head :data:`REQUEST_HEAD_S` after it opened or after its last answer."""
    from uvicorn.protocols.http.h11_impl import H11Protocol

    class Protocol(H11Protocol):
        def connection_made(self, transport: Any) -> None:
            super().connection_made(transport)
            self._head_due = self.loop.call_later(REQUEST_HEAD_S, self._head_overdue)

        def on_response_complete(self) -> None:
            super().on_response_complete()
            self._head_due.cancel()
            self._head_due = self.loop.call_later(REQUEST_HEAD_S, self._head_overdue)

        def connection_lost(self, exc: Exception | None) -> None:
            self._head_due.cancel()
            super().connection_lost(exc)

        def _head_overdue(self) -> None:
            waiting = self.cycle is None or self.cycle.response_complete
            if waiting and not self.transport.is_closing():
                self.transport.close()

        def send_400_response(self, msg: str) -> None:
            # a request that is not HTTP (no Host, a malformed Content-Length): refused in the
            # JSON every other refusal is written in, not uvicorn's plain text
            import h11

            reason = " ".join(msg.split())
            body = jsontext.dumps({"error": f"not a valid HTTP request ({reason})"}).encode()
            headers = [(b"content-type", b"application/json"), (b"connection", b"close"),
                       (b"content-length", str(len(body)).encode())]
            for event in (h11.Response(status_code=400, headers=headers, reason=b"Bad Request"),
                          h11.Data(data=body), h11.EndOfMessage()):
                self.transport.write(self.conn.send(event))
            self.transport.close()

    return Protocol


#: The signals that stop ``bench serve`` (Ctrl-C, and a service manager's stop).
STOP_SIGNALS = (signal.SIGINT, signal.SIGTERM)


class BenchServer:
    """The bench's web server on ``address:port`` (0: any free port), with a fresh token.

    :meth:`run` serves in the calling thread until Ctrl-C; :meth:`start` serves from a
    background thread until :meth:`close` (tests, embedding).

    Raises
    ------
    OSError
        The address or port cannot be bound.
    """

    def __init__(self, service: BenchService, port: int = 0,
                 address: str = "127.0.0.1") -> None:
        import uvicorn

        self.service = service
        self.address = address
        self.socket = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
        self.socket.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        try:
            self.socket.bind((address, port))
        except OSError:
            self.socket.close()
            raise
        self.socket.listen(64)
        self.port = int(self.socket.getsockname()[1])
        self.token = secrets.token_urlsafe(24)
        # lifespan off: the app has no startup or shutdown work, and uvicorn's lifespan task
        # could be collected mid-protocol when a server thread stopped just as it started
        # no limit on connections (uvicorn's answers 503 to every request once that many are
        # open, a pause and an abort included): the protocol closes the idle ones instead
        config = uvicorn.Config(create_app(service, self.token, self.port, address),
                                log_level="warning", access_log=False, server_header=False,
                                http=_protocol(), timeout_keep_alive=5, lifespan="off")
        self.server = uvicorn.Server(config)
        self._thread: threading.Thread | None = None

    @property
    def url(self) -> str:
        """The address with its token (what ``bench serve`` prints first)."""
        return f"http://{self.address}:{self.port}/?token={self.token}"

    @property
    def base(self) -> str:
        """The address without the token."""
        return f"http://{self.address}:{self.port}"

    def run(self, announce: Callable[[], None] | None = None) -> None:
        """Serve until Ctrl-C or SIGTERM; then abort a run in progress (its data kept).

        Parameters
        ----------
        announce
            Called once the stop signals are handled and before serving (``bench serve``
            prints the address there): a stop that follows the address at once still stops
            the server cleanly.
        """
        # A Ctrl-C raised while asyncio builds its event loop, before uvicorn takes the
        # signals, leaves a half-built loop that prints a traceback as it is collected, and a
        # SIGTERM there kills the process: until uvicorn's own handler is in place, either
        # signal only asks the server to stop.
        main = threading.current_thread() is threading.main_thread()
        previous = {}
        if main:
            previous = {sig: signal.signal(sig, self._stop) for sig in STOP_SIGNALS}
        try:
            if announce is not None:
                announce()
            if not self.server.should_exit:
                self.server.run(sockets=[self.socket])
        finally:
            for sig, handler in previous.items():
                signal.signal(sig, handler)
            self.service.shutdown()
            self.socket.close()

    def _stop(self, signum: int, frame: object) -> None:
        self.server.should_exit = True

    def start(self) -> BenchServer:
        """Serve from a background thread."""
        self._thread = threading.Thread(target=self.server.run,
                                        kwargs={"sockets": [self.socket]},
                                        name="viscorig-bench-server", daemon=True)
        self._thread.start()
        deadline = time.monotonic() + 10
        while not self.server.started and time.monotonic() < deadline:
            time.sleep(0.01)
        return self

    def close(self) -> None:
        """Stop serving, abort a run in progress, release the port."""
        self.server.should_exit = True
        if self._thread is not None:
            self._thread.join(timeout=10)
        self.service.shutdown()
        self.socket.close()

    def __enter__(self) -> BenchServer:
        return self.start()

    def __exit__(self, *exc: object) -> None:
        self.close()
