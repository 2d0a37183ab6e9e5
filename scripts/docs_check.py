"""Open pages of the built documentation site in headless Chromium and check them.

Usage: ``python scripts/docs_check.py [SITE] [--page PATH ...] [--chromium BIN]``

The site (default ``site/``, built by ``make docs``) is served on a local port; each page
(default: the home page and one environment page) is loaded in headless Chromium, driven
over the DevTools protocol through a pipe (``--remote-debugging-pipe``: no extra Python
package). A page fails on an error in the browser's console or an uncaught exception, a
request that fails or answers 400 or more, an image that did not load, or a link into
the site that leads nowhere (a missing page or anchor); links out of the site are counted,
not followed. A screenshot of every page is written to ``SITE/_check/<name>.png``. Exit
status 0 when every page passes, 1 when one fails, 2 on bad input.
"""

from __future__ import annotations

import argparse
import base64
import contextlib
import functools
import http.server
import json
import os
import queue
import re
import shutil
import subprocess
import sys
import tempfile
import threading
import time
import urllib.error
import urllib.request
from pathlib import Path
from typing import Any
from urllib.parse import urldefrag, urlparse

DEFAULT_PAGES = ("index.html", "environments/SRPB-Crowd-v0/index.html")
LOAD_TIMEOUT = 30.0  # s, for a page to load
SETTLE = 1.5  # s after the load event, for scripts and late requests
JS_IMAGES = ("Array.from(document.images).filter(i => !i.complete || i.naturalWidth === 0)"
             ".map(i => i.currentSrc || i.src)")  # fmt: skip
JS_LINKS = "Array.from(document.querySelectorAll('a[href]')).map(a => a.href)"


class DocsCheckError(Exception):
    """Bad input: one line for the user."""


class Browser:
    """Headless Chromium driven over the DevTools protocol on a pipe."""

    def __init__(self, binary: str) -> None:
        self.profile = tempfile.mkdtemp(prefix="docs-check-")
        to_browser_r, self._to_browser = os.pipe()
        self._from_browser, from_browser_w = os.pipe()
        command = (f'exec "$0" --headless --no-sandbox --disable-gpu --no-first-run '
                   f"--disable-extensions --hide-scrollbars --mute-audio "
                   f"--remote-debugging-pipe --user-data-dir={self.profile} about:blank "
                   f"3<&{to_browser_r} 4>&{from_browser_w}")  # fmt: skip
        quiet = subprocess.DEVNULL
        self.process = subprocess.Popen(["bash", "-c", command, binary],
                                        pass_fds=(to_browser_r, from_browser_w),
                                        stdout=quiet, stderr=quiet)  # fmt: skip
        os.close(to_browser_r)
        os.close(from_browser_w)
        self._next_id = 0
        self._replies: dict[int, dict[str, Any]] = {}
        self.events: queue.Queue[dict[str, Any]] = queue.Queue()
        self._lock = threading.Condition()
        threading.Thread(target=self._read, daemon=True).start()

    def _read(self) -> None:
        buffer = b""
        while chunk := os.read(self._from_browser, 1 << 16):
            buffer += chunk
            *messages, buffer = buffer.split(b"\0")
            for raw in messages:
                message = json.loads(raw)
                if "id" in message:
                    with self._lock:
                        self._replies[message["id"]] = message
                        self._lock.notify_all()
                else:
                    self.events.put(message)

    def send(
        self, method: str, params: dict[str, Any] | None = None,
        session: str | None = None, timeout: float = LOAD_TIMEOUT,
    ) -> dict[str, Any]:  # fmt: skip
        """Send one command and wait for its result."""
        self._next_id += 1
        message: dict[str, Any] = {"id": self._next_id, "method": method, "params": params or {}}
        if session:
            message["sessionId"] = session
        os.write(self._to_browser, json.dumps(message).encode() + b"\0")
        deadline = time.monotonic() + timeout
        with self._lock:
            while self._next_id not in self._replies:
                left = deadline - time.monotonic()
                if left <= 0 or self.process.poll() is not None:
                    raise RuntimeError(f"Chromium did not answer {method}")
                self._lock.wait(min(left, 0.5))
            reply = self._replies.pop(self._next_id)
        if "error" in reply:
            raise RuntimeError(f"{method}: {reply['error'].get('message')}")
        return reply.get("result", {})

    def close(self) -> None:
        with contextlib.suppress(RuntimeError, OSError):
            self.send("Browser.close", timeout=5)
        try:
            self.process.wait(timeout=10)
        except subprocess.TimeoutExpired:
            self.process.kill()
        shutil.rmtree(self.profile, ignore_errors=True)


def serve(site: Path) -> tuple[http.server.ThreadingHTTPServer, str]:
    """Serve ``site`` on a free local port; (server, base URL)."""

    class Quiet(http.server.SimpleHTTPRequestHandler):
        def log_message(self, format: str, *args: Any) -> None:
            pass

    handler = functools.partial(Quiet, directory=str(site))
    server = http.server.ThreadingHTTPServer(("127.0.0.1", 0), handler)
    threading.Thread(target=server.serve_forever, daemon=True).start()
    return server, f"http://127.0.0.1:{server.server_address[1]}/"


def _describe(event: dict[str, Any]) -> str | None:
    """A problem the event reports, or None."""
    method, params = event.get("method"), event.get("params", {})
    if method == "Runtime.exceptionThrown":
        details = params.get("exceptionDetails", {})
        text = details.get("exception", {}).get("description") or details.get("text")
        return f"uncaught exception: {text}"
    if method == "Runtime.consoleAPICalled" and params.get("type") in ("error", "assert"):
        args = " ".join(str(a.get("value", a.get("description", ""))) for a in params["args"])
        return f"console error: {args}"
    if method == "Log.entryAdded" and params.get("entry", {}).get("level") == "error":
        entry = params["entry"]
        return f"console error: {entry.get('text')} ({entry.get('url', '')})"
    if method == "Network.loadingFailed" and not params.get("canceled"):
        return f"request failed: {params.get('errorText')} ({params.get('requestId')})"
    if method == "Network.responseReceived" and params["response"]["status"] >= 400:
        response = params["response"]
        return f"HTTP {response['status']}: {response['url']}"
    return None


@functools.cache
def _fetch(url: str) -> str | None:
    """The text at ``url``, or None when it cannot be fetched."""
    try:
        with urllib.request.urlopen(url, timeout=10) as response:
            return response.read().decode("utf-8", errors="replace")
    except (urllib.error.URLError, OSError):
        return None


def dead_links(links: list[str], base: str) -> tuple[list[str], int]:
    """(links into the site that lead nowhere, the number of links out of it)."""
    dead, outside = [], 0
    for link in sorted(set(links)):
        if not link.startswith(base):
            outside += urlparse(link).scheme in ("http", "https")
            continue
        url, fragment = urldefrag(link)
        text = _fetch(url)
        anchor = rf"""id=["']?{re.escape(fragment)}["'\s>]"""
        if text is None or (fragment and not re.search(anchor, text)):
            dead.append(link)
    return dead, outside


def check_page(browser: Browser, base: str, page: str, shots: Path) -> list[str]:
    """Load one page; its problems (empty: it passes). Writes its screenshot."""
    target = browser.send("Target.createTarget", {"url": "about:blank"})["targetId"]
    session = browser.send("Target.attachToTarget", {"targetId": target, "flatten": True})
    sid = session["sessionId"]
    for domain in ("Page", "Runtime", "Log", "Network"):
        browser.send(f"{domain}.enable", session=sid)
    browser.send("Emulation.setDeviceMetricsOverride",
                 {"width": 1280, "height": 900, "deviceScaleFactor": 1, "mobile": False},
                 session=sid)  # fmt: skip
    while not browser.events.empty():
        browser.events.get_nowait()
    browser.send("Page.navigate", {"url": base + page}, session=sid)
    problems: list[str] = []
    loaded_at = None
    deadline = time.monotonic() + LOAD_TIMEOUT
    while time.monotonic() < deadline:
        if loaded_at is not None and time.monotonic() > loaded_at + SETTLE:
            break
        try:
            event = browser.events.get(timeout=0.2)
        except queue.Empty:
            continue
        if event.get("sessionId") != sid:
            continue
        if event.get("method") == "Page.loadEventFired":
            loaded_at = time.monotonic()
        if (problem := _describe(event)) is not None:
            problems.append(problem)
    if loaded_at is None:
        problems.append(f"the page did not load within {LOAD_TIMEOUT:g} s")

    def evaluate(expression: str) -> Any:
        result = browser.send("Runtime.evaluate", {"expression": expression,
                                                   "returnByValue": True}, session=sid)  # fmt: skip
        return result.get("result", {}).get("value")

    problems += [f"image not loaded: {src}" for src in evaluate(JS_IMAGES) or []]
    dead, outside = dead_links(evaluate(JS_LINKS) or [], base)
    problems += [f"dead link: {link}" for link in dead]
    shot = browser.send("Page.captureScreenshot", {"format": "png"}, session=sid)
    name = page.removesuffix("index.html").strip("/").replace("/", "-") or "home"
    (shots / f"{name}.png").write_bytes(base64.b64decode(shot["data"]))
    print(f"{page}: {len(problems)} problem(s), {outside} link(s) out of the site not "
          f"followed, screenshot {shots / (name + '.png')}")  # fmt: skip
    browser.send("Target.closeTarget", {"targetId": target})
    return problems


def main(argv: list[str] | None = None) -> int:
    """Check the pages; print each problem."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("site", nargs="?", default="site", help="the built site (make docs)")
    parser.add_argument("--page", action="append", help="a page's path in the site "
                        "(repeatable; default: the home page and SRPB-Crowd-v0's)")  # fmt: skip
    parser.add_argument("--chromium", default=None, help="the browser (default: chromium)")
    args = parser.parse_args(argv)
    try:
        site = Path(args.site)
        if not (site / "index.html").is_file():
            raise DocsCheckError(f"{site}: no index.html; build the site first (make docs)")
        pages = args.page or list(DEFAULT_PAGES)
        for page in pages:
            if not (site / page).is_file():
                raise DocsCheckError(f"--page: {site / page} does not exist")
        binary = args.chromium or shutil.which("chromium") or shutil.which("chromium-browser")
        if binary is None or shutil.which(binary) is None:
            raise DocsCheckError("no chromium found (apt-get install chromium, or --chromium)")
    except DocsCheckError as error:
        print(f"docs_check: error: {error}", file=sys.stderr)
        return 2
    shots = site / "_check"
    shots.mkdir(exist_ok=True)
    server, base = serve(site)
    browser = Browser(binary)
    failed = False
    try:
        for page in pages:
            problems = check_page(browser, base, page, shots)
            for problem in problems:
                print(f"  {page}: {problem}")
            failed |= bool(problems)
    finally:
        browser.close()
        server.shutdown()
    print("docs_check: FAIL" if failed else "docs_check: every page passes")
    return 1 if failed else 0


if __name__ == "__main__":
    raise SystemExit(main())
