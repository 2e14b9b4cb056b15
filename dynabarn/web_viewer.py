"""rerun's web viewer for replays: a saved `.rrd` served over HTTP by the `rerun` command
that ships with rerun-sdk, on loopback unless asked otherwise.

The SDK's `serve_web_viewer` and `serve_grpc` listen on every interface and take no
address; the command's `--bind` does. Serving a file also keeps the data in the server for
as long as it runs, so a browser that connects late (or reloads) still sees the whole run.
"""

from __future__ import annotations

import ipaddress
import socket
import subprocess
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path
from urllib.parse import quote

from dynabarn.errors import DynabarnError
from dynabarn.processes import die_with_parent

DEFAULT_BIND = "127.0.0.1"
DEFAULT_WEB_PORT = 9090
DEFAULT_GRPC_PORT = 9876
"""rerun's own defaults for the web page and for its data server."""


@dataclass
class WebViewer:
    """A running `rerun --serve-web`; `url` opens the run in a browser."""

    process: subprocess.Popen
    url: str
    bind: str
    log: Path

    def wait(self) -> int:
        """Until the server stops (Ctrl-C raises KeyboardInterrupt here)."""
        return self.process.wait()

    def stop(self) -> None:
        if self.process.poll() is None:
            self.process.terminate()
            try:
                self.process.wait(timeout=10)
            except subprocess.TimeoutExpired:
                self.process.kill()
                self.process.wait()


def check_address(bind: str, *ports: int) -> None:
    """One line for an address or port a person may mistype."""
    try:
        ipaddress.ip_address(bind)
    except ValueError:
        raise DynabarnError(
            f"--bind {bind!r}: give an IP address, e.g. 127.0.0.1 (loopback) or 0.0.0.0 (all)"
        ) from None
    for port in ports:
        if not 1 <= port <= 65535:
            raise DynabarnError(f"port {port}: use 1-65535")
    if len(set(ports)) != len(ports):
        raise DynabarnError(f"the web page and the data server need two different ports (got {ports})")


def _browser_host(bind: str) -> str:
    """The host a browser on this machine uses to reach a server bound to `bind`."""
    address = ipaddress.ip_address(bind)
    if address.is_unspecified:
        return "127.0.0.1" if address.version == 4 else "[::1]"
    return bind if address.version == 4 else f"[{bind}]"


def viewer_url(bind: str, port: int, grpc_port: int) -> str:
    host = _browser_host(bind)
    return f"http://{host}:{port}/?url=" + quote(f"rerun+http://{host}:{grpc_port}/proxy", safe="")


def rerun_binary() -> str:
    """The `rerun` program of the installed rerun-sdk (run directly, not through its Python
    wrapper, so that stopping it stops the server)."""
    import os
    import shutil

    override = os.environ.get("RERUN_CLI_PATH")
    if override:
        return override
    import rerun_cli

    bundled = Path(rerun_cli.__file__).resolve().parent / "rerun"
    found = str(bundled) if bundled.is_file() else shutil.which("rerun")
    if found is None:
        raise DynabarnError("rerun's command-line program is missing from the rerun-sdk install")
    return found


def _listening(host: str, port: int) -> bool:
    try:
        with socket.create_connection((host.strip("[]"), port), timeout=0.5):
            return True
    except OSError:
        return False


def serve_web(
    rrd: Path,
    *,
    bind: str = DEFAULT_BIND,
    port: int = DEFAULT_WEB_PORT,
    grpc_port: int = DEFAULT_GRPC_PORT,
    timeout: float = 30.0,
) -> WebViewer:
    """Start serving `rrd` and return once both ports answer (or say why they do not)."""
    check_address(bind, port, grpc_port)
    host = _browser_host(bind)
    for p in (port, grpc_port):
        if _listening(host, p):
            raise DynabarnError(f"port {p} on {bind} is already in use; choose others with --port / --grpc-port")
    log = Path(tempfile.mkstemp(prefix="dynabarn-rerun-", suffix=".log")[1])
    cmd = [rerun_binary(), "--serve-web", "--bind", bind, "--port", str(grpc_port)]
    cmd += ["--web-viewer-port", str(port), str(rrd)]
    with open(log, "wb") as sink:
        process = subprocess.Popen(
            cmd,
            stdin=subprocess.DEVNULL,
            stdout=sink,
            stderr=subprocess.STDOUT,
            preexec_fn=die_with_parent(),
        )
    viewer = WebViewer(process, viewer_url(bind, port, grpc_port), bind, log)
    deadline = time.monotonic() + timeout
    while not (_listening(host, port) and _listening(host, grpc_port)):
        if process.poll() is not None or time.monotonic() > deadline:
            viewer.stop()
            lines = [s for s in log.read_text(errors="replace").splitlines() if s.strip()]
            raise DynabarnError(f"rerun's web viewer did not start: {lines[-1] if lines else 'no output'}")
        time.sleep(0.1)
    return viewer


def spawn_native_viewer(*, timeout: float = 30.0) -> tuple[subprocess.Popen, str]:
    """rerun's native viewer, its data server on loopback at a free port (rerun-sdk's own
    `spawn` listens on every interface), ended with this process; returns the process and
    the gRPC URL to stream to, once the server answers (or one line saying why not)."""
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    log = Path(tempfile.mkstemp(prefix="dynabarn-rerun-", suffix=".log")[1])
    cmd = [rerun_binary(), "--bind", "127.0.0.1", "--port", str(port), "--hide-welcome-screen"]
    with open(log, "wb") as sink:
        process = subprocess.Popen(
            cmd, stdin=subprocess.DEVNULL, stdout=sink, stderr=subprocess.STDOUT, preexec_fn=die_with_parent()
        )
    deadline = time.monotonic() + timeout
    try:
        while not _listening("127.0.0.1", port):
            if process.poll() is not None or time.monotonic() > deadline:
                WebViewer(process, "", "127.0.0.1", log).stop()
                lines = [s for s in log.read_text(errors="replace").splitlines() if s.strip()]
                raise DynabarnError(f"rerun's viewer did not start: {lines[-1].strip() if lines else 'no output'}")
            time.sleep(0.1)
    finally:
        log.unlink(missing_ok=True)
    return process, f"rerun+http://127.0.0.1:{port}/proxy"


def grpc_url(address: str) -> str:
    """`--connect` forms: a port (this machine), host:port, or a full rerun+http(s) URL."""
    text = address.strip()
    if text.startswith(("rerun+http://", "rerun+https://")):
        return text
    host, sep, port = text.rpartition(":")
    if not sep:
        host, port = "127.0.0.1", text
    if not port.isdigit() or not 1 <= int(port) <= 65535 or not host:
        raise DynabarnError(f"--connect {address!r}: give PORT, HOST:PORT or rerun+http://HOST:PORT/proxy")
    return f"rerun+http://{host}:{port}/proxy"


def check_reachable(url: str) -> None:
    """One line when nothing listens at a `--connect` URL (the SDK would retry in silence)."""
    rest = url.split("://", 1)[1].split("/", 1)[0]
    host, _, port = rest.rpartition(":")
    if not _listening(host, int(port)):
        raise DynabarnError(f"no rerun viewer at {url}; start one with `rerun` (native) or `rerun --serve-web`")
