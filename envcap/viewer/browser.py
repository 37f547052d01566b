"""Headless Chromium driven through the Chrome DevTools Protocol (CDP): the viewer's pages run in a
real browser for tests, screenshots and the WebGL2 benchmark.

:class:`Chromium` starts the system ``chromium`` (Debian package ``chromium``) with
``--headless=new``, WebGL2 on SwiftShader (ANGLE's CPU Vulkan, the same on every machine: no GPU
needed), ``--remote-debugging-port=0`` and a private profile directory; it reads the port Chromium
chose from ``DevToolsActivePort`` and talks to one page target over a WebSocket
(``websocket-client`` from PyPI, the ``viewer`` extra).  Console messages, uncaught exceptions and
failed loads are collected in :attr:`Chromium.errors`.
"""

from __future__ import annotations

import base64
import json
import os
import shutil
import signal
import subprocess
import tempfile
import time
import urllib.request
from pathlib import Path
from typing import Any

CHROMIUM_NAMES = ("chromium", "chromium-browser", "google-chrome", "google-chrome-stable")
"""Executables tried, in order, by :func:`find_chromium`."""

FLAGS = ("--headless=new", "--no-sandbox", "--use-angle=swiftshader", "--enable-unsafe-swiftshader",
         "--ignore-gpu-blocklist", "--no-first-run", "--no-default-browser-check", "--disable-extensions",
         "--disable-background-networking", "--disable-sync", "--mute-audio", "--hide-scrollbars",
         "--remote-allow-origins=*")
"""Command-line flags of every start (``--no-sandbox``: CI runs as root, where Chromium's sandbox refuses)."""
WEBGPU_FLAGS = ("--enable-unsafe-webgpu", "--enable-features=Vulkan", "--use-vulkan=swiftshader",
                "--use-webgpu-adapter=swiftshader")
"""Flags added by ``Chromium(webgpu=True)``: WebGPU on SwiftShader's CPU Vulkan (without
``--use-vulkan=swiftshader`` the adapter is found but ``requestDevice`` fails headless)."""


def find_chromium() -> str | None:
    """Path of the first Chromium executable on ``PATH`` (:data:`CHROMIUM_NAMES`), or ``None``."""
    for name in CHROMIUM_NAMES:
        path = shutil.which(name)
        if path:
            return path
    return None


class BrowserError(RuntimeError):
    """Chromium did not start, a CDP command failed, or page JavaScript threw."""


class Chromium:
    """One headless Chromium with one page, driven over CDP.

    ``width`` x ``height``: the window (CSS px); ``webgpu``: start with :data:`WEBGPU_FLAGS`.  Use as a context manager or call :meth:`close`.
    ``errors``: console errors / warnings-as-errors, uncaught exceptions and failed network
    loads seen so far (strings); ``console``: every console message ``(level, text)``."""

    def __init__(self, width: int = 800, height: int = 600, executable: str | None = None,
                 timeout: float = 20.0, webgpu: bool = False) -> None:
        import websocket  # websocket-client; imported here: serving pages needs no driver

        exe = executable or find_chromium()
        if exe is None:
            raise BrowserError(f"no Chromium executable found (tried {', '.join(CHROMIUM_NAMES)})")
        self.timeout = timeout
        self.errors: list[str] = []
        self.console: list[tuple[str, str]] = []
        self._profile = tempfile.TemporaryDirectory(prefix="envcap-chromium-")
        self._proc = subprocess.Popen(
            [exe, *FLAGS, *(WEBGPU_FLAGS if webgpu else ()), f"--window-size={width},{height}", "--remote-debugging-port=0",
             f"--user-data-dir={self._profile.name}", "about:blank"],
            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
            start_new_session=True)   # its own process group: close() stops its helper processes too
        try:
            port = self._wait_port(Path(self._profile.name) / "DevToolsActivePort")
            with urllib.request.urlopen(f"http://127.0.0.1:{port}/json/list", timeout=timeout) as r:
                targets = json.load(r)
            page = next(t for t in targets if t.get("type") == "page")
            self._ws = websocket.create_connection(page["webSocketDebuggerUrl"], timeout=timeout,
                                                   suppress_origin=True)
        except BaseException:
            self.close()
            raise
        self._id = 0
        for domain in ("Page", "Runtime", "Log"):
            self.send(f"{domain}.enable")
        # the page's viewport is exactly width x height CSS px (the window's chrome is not subtracted)
        self.send("Emulation.setDeviceMetricsOverride", width=width, height=height, deviceScaleFactor=1, mobile=False)

    def _wait_port(self, path: Path) -> int:
        end = time.monotonic() + self.timeout
        while time.monotonic() < end:
            if self._proc.poll() is not None:
                raise BrowserError(f"chromium exited with status {self._proc.returncode} at start")
            if path.is_file():
                text = path.read_text().split()
                if text:
                    return int(text[0])
            time.sleep(0.05)
        raise BrowserError(f"chromium wrote no DevToolsActivePort within {self.timeout} s")

    def _event(self, msg: dict[str, Any]) -> None:
        method, p = msg.get("method"), msg.get("params", {})
        if method == "Runtime.consoleAPICalled":
            text = " ".join(str(a.get("value", a.get("description", ""))) for a in p.get("args", []))
            self.console.append((p.get("type", ""), text))
            if p.get("type") in ("error", "assert"):
                self.errors.append(f"console.{p.get('type')}: {text}")
        elif method == "Runtime.exceptionThrown":
            d = p.get("exceptionDetails", {})
            self.errors.append("exception: " + str(d.get("exception", {}).get("description", d.get("text"))))
        elif method == "Log.entryAdded":
            e = p.get("entry", {})
            if e.get("level") == "error":
                self.errors.append(f"log: {e.get('text')} {e.get('url', '')}".strip())

    def send(self, method: str, **params: Any) -> dict[str, Any]:
        """Send one CDP command and return its ``result`` (events seen meanwhile are recorded)."""
        self._id += 1
        mid = self._id
        self._ws.send(json.dumps({"id": mid, "method": method, "params": params}))
        while True:
            msg = json.loads(self._ws.recv())
            if msg.get("id") == mid:
                if "error" in msg:
                    raise BrowserError(f"{method}: {msg['error']}")
                return msg.get("result", {})
            self._event(msg)

    def goto(self, url: str) -> None:
        """Load ``url`` and wait for its ``load`` event."""
        self.send("Page.navigate", url=url)
        end = time.monotonic() + self.timeout
        while time.monotonic() < end:
            if self.evaluate("document.readyState") == "complete":
                return
            time.sleep(0.02)
        raise BrowserError(f"{url} did not finish loading within {self.timeout} s")

    def evaluate(self, expression: str, await_promise: bool = True) -> Any:
        """The JSON value of JavaScript ``expression`` in the page (a promise is awaited)."""
        r = self.send("Runtime.evaluate", expression=expression, awaitPromise=await_promise,
                      returnByValue=True, timeout=int(self.timeout * 1000))
        if "exceptionDetails" in r:
            d = r["exceptionDetails"]
            raise BrowserError("page JavaScript threw: " + str(d.get("exception", {}).get("description", d.get("text"))))
        return r.get("result", {}).get("value")

    def screenshot(self, path: str | Path) -> Path:
        """Save a PNG screenshot of the page to ``path``; returns it."""
        data = self.send("Page.captureScreenshot", format="png")["data"]
        out = Path(path)
        out.write_bytes(base64.b64decode(data))
        return out

    def close(self) -> None:
        """Close the connection, stop Chromium (this process only) and remove its profile."""
        ws = getattr(self, "_ws", None)
        if ws is not None:
            try:
                ws.close()
            except OSError:
                pass
        if self._proc.poll() is None:
            self._signal_group(signal.SIGTERM)
            try:
                self._proc.wait(5)
            except subprocess.TimeoutExpired:
                self._signal_group(signal.SIGKILL)
                self._proc.wait(5)
        # Chromium's renderer and utility processes outlive the browser process by a moment and
        # may still write into the profile (its Cache): stop the rest of the group, then remove it
        self._signal_group(signal.SIGKILL)
        for attempt in range(20):
            try:
                self._profile.cleanup()
                return
            except OSError:
                if attempt == 19:
                    raise
                time.sleep(0.05)

    def _signal_group(self, sig: int) -> None:
        """Send ``sig`` to Chromium's process group (started for it alone), if it still exists."""
        try:
            os.killpg(self._proc.pid, sig)
        except (ProcessLookupError, PermissionError):
            pass

    def __enter__(self) -> "Chromium":
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
