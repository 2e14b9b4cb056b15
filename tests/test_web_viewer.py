"""`dynabarn-replay --web` in a real browser: the URL it prints shows the run (the arena's
walls and the red obstacles), not rerun's empty welcome page; it listens on loopback only
and stops with its server on SIGTERM. `--connect` sends to a running viewer."""

from __future__ import annotations

import io
import os
import signal
import socket
import subprocess
import sys
import time

import numpy as np
import pytest

from dynabarn.planners import get_planner
from dynabarn.protocol import get_protocol
from dynabarn.recording import McapRecorder
from dynabarn.sim import run_episode
from dynabarn.web_viewer import rerun_binary
from dynabarn.worldset import resolve_world
from tests.browser import Browser, chromium


def _free_ports(n: int) -> list[int]:
    sockets = [socket.socket() for _ in range(n)]
    for s in sockets:
        s.bind(("127.0.0.1", 0))
    ports = [s.getsockname()[1] for s in sockets]
    for s in sockets:
        s.close()
    return ports


def _listening(host: str, port: int) -> bool:
    try:
        with socket.create_connection((host, port), timeout=1.0):
            return True
    except OSError:
        return False


def _other_address() -> str | None:
    """An address of this machine that is not loopback (None when it has none)."""
    try:
        with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
            s.connect(("192.0.2.1", 9))  # TEST-NET: no packet is sent, the route picks the source
            address = s.getsockname()[0]
    except OSError:
        return None
    return None if address.startswith("127.") else address


def _scene_pixels(png: bytes) -> tuple[int, int]:
    """(obstacle red, wall grey) pixels: the replay's colours (215, 40, 30) and (140, 140, 155)."""
    import imageio.v3 as iio

    a = iio.imread(io.BytesIO(png))[..., :3].astype(int)
    red = (a[..., 0] > 150) & (a[..., 1] < 80) & (a[..., 2] < 80)
    grey = (np.abs(a[..., 0] - a[..., 1]) < 12) & (a[..., 2] - a[..., 0] >= 5) & (a[..., 0] > 100) & (a[..., 0] < 175)
    return int(red.sum()), int(grey.sum())


@pytest.fixture(scope="module")
def recording(tmp_path_factory):
    path = tmp_path_factory.mktemp("web") / "world_137_dwa.mcap"
    run_episode(resolve_world(137), get_planner("dwa"), get_protocol("barn"), seed=0, observers=[McapRecorder(path)])
    return path


@pytest.mark.slow
@pytest.mark.skipif(chromium() is None, reason="needs Debian's chromium: sudo make system-deps")
def test_web_viewer_shows_the_run_in_chromium(recording, tmp_path):
    port, grpc_port = _free_ports(2)
    web_ports = ("--port", str(port), "--grpc-port", str(grpc_port))
    proc = subprocess.Popen(
        [sys.executable, "-m", "dynabarn", "replay", str(recording), "--web", *web_ports],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    try:
        url = proc.stdout.readline().strip()  # printed once both ports answer
        assert url == f"http://127.0.0.1:{port}/?url=rerun%2Bhttp%3A%2F%2F127.0.0.1%3A{grpc_port}%2Fproxy", (
            url + proc.stderr.read() if proc.poll() is not None else url
        )
        assert _listening("127.0.0.1", port) and _listening("127.0.0.1", grpc_port)
        other = _other_address()
        if other is not None:  # loopback only: not reachable on the machine's other address
            assert not _listening(other, port) and not _listening(other, grpc_port)

        with Browser() as browser:
            browser.open(url)
            red = grey = 0
            deadline = time.monotonic() + 120  # WebAssembly compiles in software first
            while time.monotonic() < deadline:
                time.sleep(3.0)
                shot = browser.screenshot()
                red, grey = _scene_pixels(shot)
                if red > 300 and grey > 2000:
                    break
            (tmp_path / "web_viewer.png").write_bytes(shot)
        # The five obstacles of world 137 and the three walls are drawn.
        assert red > 300 and grey > 2000, f"scene not shown (red {red}, grey {grey}); see {tmp_path}/web_viewer.png"

        proc.send_signal(signal.SIGTERM)  # stops the server with it
        assert proc.wait(timeout=20) == 0
        time.sleep(0.5)
        assert not _listening("127.0.0.1", port) and not _listening("127.0.0.1", grpc_port)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()


def test_connect_sends_to_a_running_viewer(recording):
    """A `rerun --serve-grpc` server (what a running viewer listens with) receives the run."""
    (grpc_port,) = _free_ports(1)
    server = subprocess.Popen(
        [rerun_binary(), "--serve-grpc", "--bind", "127.0.0.1", "--port", str(grpc_port)],
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
    )
    try:
        for _ in range(100):
            if _listening("127.0.0.1", grpc_port):
                break
            time.sleep(0.1)
        sent = subprocess.run(
            [sys.executable, "-m", "dynabarn", "replay", str(recording), "--connect", f"127.0.0.1:{grpc_port}"],
            capture_output=True,
            text=True,
            timeout=120,
            env={**os.environ},
        )
        assert sent.returncode == 0, sent.stderr
        assert f"to rerun+http://127.0.0.1:{grpc_port}/proxy" in sent.stdout
        assert "146 scans" in sent.stdout
    finally:
        server.terminate()
        server.wait(timeout=10)


@pytest.mark.parametrize(
    "argv, message",
    [
        (["--web", "--bind", "localhost"], "--bind 'localhost'"),
        (["--web", "--port", "70000"], "port 70000"),
        (["--web", "--port", "9000", "--grpc-port", "9000"], "two different ports"),
        (["--connect", "nowhere:x"], "--connect 'nowhere:x'"),
    ],
)
def test_bad_addresses_give_one_line(recording, argv, message, capsys):
    from dynabarn.cli import replay_main

    assert replay_main([str(recording), *argv]) == 2
    err = capsys.readouterr().err
    assert message in err and err.count("\n") == 1
