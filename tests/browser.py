"""Headless Chromium (Debian's `chromium`, installed by `make system-deps`) driven over the
DevTools protocol: open a page, let it run in real time, take screenshots.

`chromium --screenshot` alone shoots at load time (rerun's viewer is still compiling its
WebAssembly then), so the page is opened with a remote-debugging port and screenshots are
taken while it runs. Software WebGPU/WebGL (SwiftShader): no GPU needed.
"""

from __future__ import annotations

import base64
import contextlib
import json
import os
import shutil
import signal
import subprocess
import tempfile
import time
import urllib.request
from pathlib import Path

FLAGS = (
    "--headless",
    "--no-sandbox",  # tests run as root in CI
    "--disable-quic",
    "--no-first-run",
    "--disable-background-networking",  # this machine's network is closed; no calls home
    "--disable-component-update",
    "--disable-sync",
    "--use-angle=swiftshader",
    "--enable-unsafe-swiftshader",
    "--ignore-gpu-blocklist",
    "--window-size=1280,800",
)


def chromium() -> str | None:
    return shutil.which("chromium") or shutil.which("chromium-browser")


class Browser:
    """One headless Chromium with one page; use as a context manager."""

    def __init__(self) -> None:
        from tests.conftest import require

        connect = require("websockets.sync.client", "test").connect

        exe = chromium()
        if exe is None:
            raise RuntimeError("chromium is not installed (make system-deps)")
        self._profile = Path(tempfile.mkdtemp(prefix="dynabarn-chromium-"))
        # Its own session, so that closing reaches the renderer, GPU and crash-handler children
        # too: they write into the profile after the main process is gone.
        self._proc = subprocess.Popen(
            [exe, *FLAGS, f"--user-data-dir={self._profile}", "--remote-debugging-port=0", "about:blank"],
            stdout=subprocess.DEVNULL,
            stderr=subprocess.DEVNULL,
            start_new_session=True,
        )
        port_file = self._profile / "DevToolsActivePort"
        deadline = time.monotonic() + 30
        while not (port_file.is_file() and port_file.read_text().strip()):
            if time.monotonic() > deadline or self._proc.poll() is not None:
                self.close()
                raise RuntimeError("chromium did not start its DevTools endpoint")
            time.sleep(0.1)
        port = int(port_file.read_text().split()[0])
        with urllib.request.urlopen(f"http://127.0.0.1:{port}/json/list", timeout=10) as response:
            page = next(t for t in json.load(response) if t["type"] == "page")
        self._ws = connect(page["webSocketDebuggerUrl"], max_size=64_000_000, open_timeout=10).__enter__()
        self._id = 0
        self.events: list[dict] = []
        """Every event the page sent (after `Network.enable`: each request it made)."""
        self.call("Page.enable")

    def call(self, method: str, **params) -> dict:
        self._id += 1
        self._ws.send(json.dumps({"id": self._id, "method": method, "params": params}))
        while True:
            message = json.loads(self._ws.recv(timeout=60))
            if "method" in message:
                self.events.append(message)
            if message.get("id") == self._id:
                if "error" in message:
                    raise RuntimeError(f"{method}: {message['error']}")
                return message.get("result", {})

    def open(self, url: str) -> None:
        self.call("Page.navigate", url=url)

    def evaluate(self, expression: str):
        """The value of a JavaScript expression in the page."""
        return self.call("Runtime.evaluate", expression=expression, returnByValue=True).get("result", {}).get("value")

    def requests(self) -> list[str]:
        """The URLs of every request the page made since `Network.enable` (collected while
        calls waited for their answers; one more call collects the latest)."""
        self.evaluate("0")
        return [e["params"]["request"]["url"] for e in self.events if e["method"] == "Network.requestWillBeSent"]

    def screenshot(self) -> bytes:
        return base64.b64decode(self.call("Page.captureScreenshot", format="png")["data"])

    def close(self) -> None:
        ws = getattr(self, "_ws", None)
        if ws is not None:
            ws.close()
        self._signal_group(signal.SIGTERM)
        with contextlib.suppress(subprocess.TimeoutExpired):
            self._proc.wait(timeout=10)
        self._signal_group(signal.SIGKILL)
        self._proc.wait()
        self._remove_profile()

    def _signal_group(self, sig: int) -> None:
        with contextlib.suppress(ProcessLookupError):  # the whole group has gone
            os.killpg(self._proc.pid, sig)

    def _remove_profile(self) -> None:
        # A child killed a moment ago may still be flushing a file into the profile (under load it
        # has been seen as "Directory not empty"); try again for a while, never fail a test for it.
        deadline = time.monotonic() + 10
        while self._profile.exists():
            try:
                shutil.rmtree(self._profile)
            except OSError:
                if time.monotonic() > deadline:
                    shutil.rmtree(self._profile, ignore_errors=True)
                    return
                time.sleep(0.2)

    def __enter__(self) -> Browser:
        return self

    def __exit__(self, *exc) -> None:
        self.close()
