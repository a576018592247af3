"""Headless Chromium for tests: load a page as a person's browser would, read it, screenshot it.

Two ways:

- :func:`dump_dom` and :func:`screenshot` run Chromium once on a URL (``--dump-dom``,
  ``--screenshot``): enough for a static page.
- :class:`Browser` keeps Chromium open and drives it over the DevTools protocol on a pipe
  (``--remote-debugging-pipe``: no port, no websocket library), so a test can watch a page
  change (``evaluate``, ``wait_for``), collect its console errors and failed requests, and take
  a screenshot at the moment it chooses.

Tests that need it skip when no Chromium is installed (:data:`CHROMIUM` is None; CI installs
Debian's ``chromium``).
"""

from __future__ import annotations

import base64
import contextlib
import itertools
import json
import os
import queue
import shutil
import subprocess
import threading
import time
from pathlib import Path
from typing import Any

CHROMIUM = shutil.which("chromium") or ("/usr/bin/chromium" if Path("/usr/bin/chromium").exists()
                                        else None)
#: Headless, offline and quiet: no network of its own, no updates, no first-run pages.
HEADLESS_FLAGS = ("--headless", "--no-sandbox", "--disable-gpu", "--no-first-run",
                  "--disable-background-networking", "--disable-component-update",
                  "--disable-sync", "--disable-default-apps", "--mute-audio",
                  "--hide-scrollbars")


def chromium_flags(profile: Path) -> list[str]:
    """The command line of a headless Chromium with its own profile folder."""
    if CHROMIUM is None:
        raise RuntimeError("chromium is not installed")
    return [CHROMIUM, *HEADLESS_FLAGS, f"--user-data-dir={profile}"]


def dump_dom(url: str, profile: Path, timeout_s: float = 120,
             size: tuple[int, int] | None = None) -> subprocess.CompletedProcess:
    """Load ``url`` and return Chromium's run: the DOM after load on stdout, its log on stderr
    (``size``: the window's width and height in pixels, for a page that measures its layout)."""
    window = [f"--window-size={size[0]},{size[1]}"] if size else []
    return subprocess.run([*chromium_flags(profile), *window, "--enable-logging=stderr",
                           "--v=0", "--dump-dom", url], capture_output=True, text=True,
                          timeout=timeout_s)


def console_problems(stderr: str) -> list[str]:
    """Console messages and failed loads in Chromium's log (from :func:`dump_dom`)."""
    return [line for line in stderr.splitlines() if "CONSOLE" in line.upper()
            or "Failed to load" in line or "net::ERR" in line]


def screenshot(url: str, path: Path, profile: Path, size: tuple[int, int] = (1280, 2400),
               timeout_s: float = 120) -> subprocess.CompletedProcess:
    """Load ``url`` and write a PNG of ``size`` (width, height) pixels to ``path``."""
    return subprocess.run([*chromium_flags(profile), f"--screenshot={path}",
                           f"--window-size={size[0]},{size[1]}", url],
                          capture_output=True, text=True, timeout=timeout_s)


class BrowserError(RuntimeError):
    """Chromium answered a command with an error, or did not answer in time."""


class Browser:
    """One headless Chromium tab, driven over the DevTools protocol on a pipe.

    Parameters
    ----------
    profile
        An empty folder for Chromium's profile.
    size
        Window width and height in pixels.

    Examples
    --------
    >>> with Browser(tmp_path / "profile") as browser:          # doctest: +SKIP
    ...     browser.open("http://127.0.0.1:8765/")
    ...     browser.wait_for("document.title.includes('complete')")
    ...     browser.save_screenshot(tmp_path / "page.png")
    """

    def __init__(self, profile: Path, size: tuple[int, int] = (1280, 900)) -> None:
        to_browser_read, self._to_browser = os.pipe()
        self._from_browser, from_browser_write = os.pipe()

        def on_descriptors_3_and_4() -> None:  # Chromium reads fd 3 and writes fd 4
            os.dup2(to_browser_read, 3)
            os.dup2(from_browser_write, 4)

        self.process = subprocess.Popen(
            [*chromium_flags(profile), "--remote-debugging-pipe",
             f"--window-size={size[0]},{size[1]}", "about:blank"],
            stdin=subprocess.DEVNULL, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
            pass_fds=(3, 4), preexec_fn=on_descriptors_3_and_4,
        )
        os.close(to_browser_read)
        os.close(from_browser_write)
        self._ids = itertools.count(1)
        self._answers: dict[int, queue.Queue[dict[str, Any]]] = {}
        self._lock = threading.Lock()
        self.events: list[dict[str, Any]] = []
        """Every event Chromium sent (method, params, sessionId)."""
        self._reader = threading.Thread(target=self._read, daemon=True)
        self._reader.start()
        self.session: str | None = None
        self.size = size

    # -- the protocol ------------------------------------------------------------------------
    def _read(self) -> None:
        buffer = b""
        while True:
            try:
                chunk = os.read(self._from_browser, 1 << 16)
            except OSError:
                return
            if not chunk:
                return
            buffer += chunk
            while b"\0" in buffer:
                raw, buffer = buffer.split(b"\0", 1)
                message = json.loads(raw)
                if "id" in message:
                    with self._lock:
                        waiting = self._answers.get(message["id"])
                    if waiting is not None:
                        waiting.put(message)
                else:
                    self.events.append(message)

    def send(self, method: str, params: dict[str, Any] | None = None, *,
             session: str | None = None, timeout_s: float = 30.0) -> dict[str, Any]:
        """Send one command (to the page's session by default) and return its result.

        Raises
        ------
        BrowserError
            An error answer, or none within ``timeout_s``.
        """
        number = next(self._ids)
        message: dict[str, Any] = {"id": number, "method": method, "params": params or {}}
        target = self.session if session is None else session
        if target:
            message["sessionId"] = target
        answer: queue.Queue[dict[str, Any]] = queue.Queue()
        with self._lock:
            self._answers[number] = answer
        os.write(self._to_browser, json.dumps(message).encode() + b"\0")
        try:
            reply = answer.get(timeout=timeout_s)
        except queue.Empty:
            raise BrowserError(f"{method}: no answer in {timeout_s:g} s") from None
        finally:
            with self._lock:
                self._answers.pop(number, None)
        if "error" in reply:
            raise BrowserError(f"{method}: {reply['error']}")
        return reply.get("result", {})

    # -- a page --------------------------------------------------------------------------------
    def open(self, url: str, timeout_s: float = 30.0) -> None:
        """Open ``url`` in a new tab and wait until it has loaded."""
        target = self.send("Target.createTarget", {"url": "about:blank"}, session="")
        attached = self.send("Target.attachToTarget", {"targetId": target["targetId"],
                                                       "flatten": True}, session="")
        self.session = attached["sessionId"]
        for domain in ("Page", "Runtime", "Log", "Network"):
            self.send(f"{domain}.enable")
        self.send("Emulation.setDeviceMetricsOverride", {
            "width": self.size[0], "height": self.size[1], "deviceScaleFactor": 1,
            "mobile": False})
        before = len(self.events)
        self.send("Page.navigate", {"url": url})
        deadline = time.monotonic() + timeout_s
        while not any(event.get("method") == "Page.loadEventFired"
                      for event in self.events[before:]):
            if time.monotonic() > deadline:
                raise BrowserError(f"{url} did not load in {timeout_s:g} s")
            time.sleep(0.02)

    def evaluate(self, expression: str) -> Any:
        """The value of a JavaScript expression in the page (promises are awaited).

        Raises
        ------
        BrowserError
            The expression threw.
        """
        result = self.send("Runtime.evaluate", {"expression": expression,
                                                "returnByValue": True, "awaitPromise": True})
        if "exceptionDetails" in result:
            raise BrowserError(f"{expression}: {result['exceptionDetails']}")
        return result["result"].get("value")

    def wait_for(self, expression: str, timeout_s: float = 30.0, poll_s: float = 0.1) -> Any:
        """Wait until ``expression`` is truthy in the page; return its value.

        Raises
        ------
        BrowserError
            Still falsy after ``timeout_s``.
        """
        deadline = time.monotonic() + timeout_s
        while True:
            value = self.evaluate(expression)
            if value:
                return value
            if time.monotonic() > deadline:
                raise BrowserError(f"still false after {timeout_s:g} s: {expression}")
            time.sleep(poll_s)

    def save_screenshot(self, path: Path) -> Path:
        """Write a PNG of the whole page to ``path``."""
        metrics = self.send("Page.getLayoutMetrics")
        content = metrics.get("cssContentSize") or metrics["contentSize"]
        data = self.send("Page.captureScreenshot", {
            "format": "png", "captureBeyondViewport": True,
            "clip": {"x": 0, "y": 0, "width": content["width"], "height": content["height"],
                     "scale": 1}})["data"]
        path.write_bytes(base64.b64decode(data))
        return path

    def problems(self) -> list[str]:
        """Console errors and warnings, uncaught exceptions, and failed requests so far."""
        found = []
        for event in self.events:
            method, params = event.get("method"), event.get("params", {})
            if method == "Runtime.exceptionThrown":
                found.append(f"exception: {params['exceptionDetails'].get('text')}")
            elif method == "Runtime.consoleAPICalled" and params.get("type") in ("error",
                                                                                  "warning"):
                found.append(f"console {params['type']}: {params.get('args')}")
            elif method == "Log.entryAdded" and params["entry"].get("level") in ("error",
                                                                                   "warning"):
                found.append(f"log: {params['entry'].get('text')} {params['entry'].get('url')}")
            elif method == "Network.loadingFailed":
                found.append(f"request failed: {params.get('errorText')}")
        return found

    def requested_urls(self) -> list[str]:
        """Every URL the page asked for."""
        return [event["params"]["request"]["url"] for event in self.events
                if event.get("method") == "Network.requestWillBeSent"]

    def close(self) -> None:
        """End Chromium."""
        with contextlib.suppress(OSError, BrowserError):
            self.send("Browser.close", session="", timeout_s=5)
        try:
            self.process.wait(timeout=10)
        except subprocess.TimeoutExpired:
            self.process.kill()
            self.process.wait(timeout=10)
        for descriptor in (self._to_browser, self._from_browser):
            with contextlib.suppress(OSError):
                os.close(descriptor)

    def __enter__(self) -> Browser:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
