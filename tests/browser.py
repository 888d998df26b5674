"""A real headless Chromium driven through its DevTools protocol over a pipe (no Node, no extra package).

Chromium started with ``--remote-debugging-pipe`` reads protocol messages on its file
descriptor 3 and writes them on 4, each a JSON text ended by a NUL byte. :func:`open_page`
loads a page, waits until it says it is ready, and returns what it logged, what it requested
and a screenshot.
"""

from __future__ import annotations

import base64
import fcntl
import json
import os
import select
import shutil
import subprocess
import tempfile
import time
from dataclasses import dataclass, field
from pathlib import Path

CHROMIUM = "/usr/bin/chromium"
# as root, in a container, with no GPU: software WebGL (SwiftShader), nothing started beside the page,
# and every host name unresolvable, so that a request to the network fails rather than leaves
FLAGS = [
    "--headless",
    "--no-sandbox",
    "--disable-gpu",
    "--use-angle=swiftshader",
    "--enable-unsafe-swiftshader",
    "--disable-quic",
    "--no-first-run",
    "--disable-background-networking",
    "--disable-component-update",
    "--disable-sync",
    "--disable-extensions",
    "--hide-scrollbars",
    "--force-device-scale-factor=1",
    "--host-resolver-rules=MAP * ~NOTFOUND",
]


def chromium() -> str | None:
    """The Chromium executable, or None where there is none."""
    if os.access(CHROMIUM, os.X_OK):
        return CHROMIUM
    return shutil.which("chromium")


@dataclass
class PageRun:
    """What a page did in the browser.

    Attributes
    ----------
    errors : list of str
        Uncaught exceptions, ``console.error`` calls and the browser's own error entries
        (a resource that failed, a blocked request).
    requests : list of str
        Every URL the page asked for (its own file included).
    screenshot : bytes
        PNG of the window once the page is ready.
    step_values, step_screenshots : list
        Each step's value and the PNG after it.
    body : dict
        The ``data-*`` attributes of the page's ``<body>`` once ready.
    """

    errors: list = field(default_factory=list)
    requests: list = field(default_factory=list)
    screenshot: bytes = b""
    body: dict = field(default_factory=dict)
    step_values: list = field(default_factory=list)
    step_screenshots: list = field(default_factory=list)


class _Pipe:
    def __init__(self, proc: subprocess.Popen, to_browser: int, from_browser: int):
        self.proc, self.out, self.inp = proc, to_browser, from_browser
        self.buffer = b""
        self.next_id = 0
        self.events: list = []

    def send(self, method: str, params: dict | None = None, session: str | None = None) -> int:
        self.next_id += 1
        message = {"id": self.next_id, "method": method, "params": params or {}}
        if session:
            message["sessionId"] = session
        os.write(self.out, json.dumps(message).encode() + b"\0")
        return self.next_id

    def receive(self, timeout: float) -> dict | None:
        while b"\0" not in self.buffer:
            ready, _, _ = select.select([self.inp], [], [], timeout)
            if not ready:
                return None
            chunk = os.read(self.inp, 1 << 20)
            if not chunk:
                raise RuntimeError("chromium closed its DevTools pipe")
            self.buffer += chunk
        text, self.buffer = self.buffer.split(b"\0", 1)
        return json.loads(text)

    def call(self, method: str, params: dict | None = None, session: str | None = None, timeout: float = 60.0):
        wanted = self.send(method, params, session)
        end = time.monotonic() + timeout
        while time.monotonic() < end:
            message = self.receive(max(0.01, end - time.monotonic()))
            if message is None:
                break
            if message.get("id") == wanted:
                if "error" in message:
                    raise RuntimeError(f"{method}: {message['error']}")
                return message.get("result", {})
            self.events.append(message)
        raise TimeoutError(f"{method}: no answer in {timeout:g} s")


def _record(events: list, run: PageRun) -> None:
    for message in events:
        method, p = message.get("method"), message.get("params", {})
        if method == "Runtime.exceptionThrown":
            d = p["exceptionDetails"]
            run.errors.append((d.get("exception") or {}).get("description") or d.get("text", "exception"))
        elif method == "Runtime.consoleAPICalled" and p.get("type") in ("error", "assert"):
            run.errors.append(" ".join(str(a.get("value", a.get("description", ""))) for a in p.get("args", [])))
        elif method == "Log.entryAdded" and p["entry"].get("level") == "error":
            run.errors.append(f"{p['entry'].get('source')}: {p['entry'].get('text')}")
        elif method == "Network.requestWillBeSent":
            run.requests.append(p["request"]["url"])
    events.clear()


def open_page(url: str, ready: str, steps: tuple = (), size=(1280, 1000), timeout: float = 90.0) -> PageRun:
    """Load ``url`` in headless Chromium and wait until the page's ``<body>`` has the attribute ``ready``.

    Parameters
    ----------
    url : str
        A file:// URL.
    ready : str
        Name of the ``data-`` attribute (without ``data-``, in the dataset's camelCase) the
        page sets once it has drawn what it draws (``loaded``), or ``error`` if it failed.
    steps : tuple of str
        JavaScript expressions run one after the other once the page is ready (a click), each
        followed by a screenshot; their values are kept.
    size : (int, int)
        Window width and height, CSS pixels (one device pixel each).
    timeout : float
        Seconds to wait for it.

    Returns
    -------
    PageRun
    """
    exe = chromium()
    if exe is None:
        raise FileNotFoundError(CHROMIUM)
    profile = tempfile.mkdtemp(prefix="chromium-profile-")
    to_read, to_browser = os.pipe()  # we write, Chromium reads on its fd 3
    from_browser, to_write = os.pipe()  # Chromium writes on its fd 4, we read

    def descriptors():
        # (copies above 3 and 4 first, so that neither end is overwritten by the other's dup2; dup2 leaves
        # its copy without close-on-exec: Chromium inherits fds 3 and 4 and no other pipe end)
        high = [fcntl.fcntl(fd, fcntl.F_DUPFD, 10) for fd in (to_read, to_write)]
        os.dup2(high[0], 3)
        os.dup2(high[1], 4)

    args = [exe, *FLAGS, f"--window-size={size[0]},{size[1]}", f"--user-data-dir={profile}", "--remote-debugging-pipe"]
    proc = subprocess.Popen(
        args, stdin=subprocess.DEVNULL, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
        preexec_fn=descriptors, close_fds=False,
    )  # fmt: skip
    os.close(to_read)
    os.close(to_write)
    pipe = _Pipe(proc, to_browser, from_browser)
    run = PageRun()
    try:
        target = pipe.call("Target.createTarget", {"url": "about:blank"})["targetId"]
        session = pipe.call("Target.attachToTarget", {"targetId": target, "flatten": True})["sessionId"]
        for domain in ("Runtime", "Log", "Network", "Page"):
            pipe.call(f"{domain}.enable", session=session)
        pipe.call("Page.navigate", {"url": url}, session=session)
        end = time.monotonic() + timeout
        attributes = {}
        while time.monotonic() < end:
            result = pipe.call(
                "Runtime.evaluate",
                {"expression": "JSON.stringify(Object.assign({}, document.body ? document.body.dataset : {}))",
                 "returnByValue": True},
                session=session,
            )  # fmt: skip
            attributes = json.loads(result["result"]["value"])
            if ready in attributes or "error" in attributes:
                break
            time.sleep(0.2)
        run.body = attributes
        run.screenshot = _screenshot(pipe, session)
        for step in steps:
            value = pipe.call("Runtime.evaluate", {"expression": step, "returnByValue": True}, session=session)
            run.step_values.append(value["result"].get("value"))
            run.step_screenshots.append(_screenshot(pipe, session))
        # events still in the pipe
        while (message := pipe.receive(0.3)) is not None:
            pipe.events.append(message)
        _record(pipe.events, run)
        try:
            pipe.send("Browser.close")
            proc.wait(timeout=10)
        except (OSError, subprocess.TimeoutExpired):
            pass
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
        os.close(to_browser)
        os.close(from_browser)
        shutil.rmtree(profile, ignore_errors=True)
    return run


def _screenshot(pipe: _Pipe, session: str) -> bytes:
    """PNG of the window once a frame has been drawn after the last change."""
    frame = "new Promise(r => requestAnimationFrame(() => requestAnimationFrame(() => r(1))))"
    pipe.call("Runtime.evaluate", {"expression": frame, "awaitPromise": True}, session=session)
    shot = pipe.call("Page.captureScreenshot", {"format": "png"}, session=session)
    return base64.b64decode(shot["data"])


def page_url(path: Path) -> str:
    """The file:// URL of a local file."""
    return Path(path).resolve().as_uri()
