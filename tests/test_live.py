"""Watching an episode while it runs, with the real tools: a WebSocket client speaking
Foxglove's protocol to `dynabarn-run --live foxglove`, a headless rerun (`rerun --save`)
receiving `--live rerun`, and MuJoCo's viewer in an Xvfb window for `--viewer`."""

from __future__ import annotations

import base64
import json
import os
import re
import signal
import socket
import struct
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
from mcap.records import Schema
from mcap_protobuf.decoder import DecoderFactory

from dynabarn.recording import message_digest, read_recording

BIN = Path(sys.executable).parent
RERUN = str(BIN / "rerun")


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def _run(args: str, *paths: Path, **kw) -> subprocess.Popen:
    """dynabarn-run with the options in `args` (split on spaces), then `paths`."""
    command = [str(BIN / "dynabarn-run"), *args.split(), *map(str, paths)]
    return subprocess.Popen(command, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, **kw)


def _foxglove_url(proc: subprocess.Popen) -> str:
    """The server's address, from the line dynabarn-run prints on stderr."""
    deadline = time.monotonic() + 60
    while time.monotonic() < deadline:
        line = proc.stderr.readline()
        if m := re.search(r"(ws://127\.0\.0\.1:\d+)", line):
            return m.group(1)
        if not line and proc.poll() is not None:
            break
    raise AssertionError(f"no server address printed; exit {proc.poll()}")


def _foxglove_client(url: str, topics: set[str], until_topic: str = "/episode/result", timeout: float = 120):
    """Subscribe to `topics` as Foxglove does; returns the advertised channels and, per
    topic, the (receive time, log time, payload) of every message."""
    from tests.conftest import require

    connect = require("websockets.sync.client", "test").connect

    channels: dict[int, dict] = {}
    subscriptions: dict[int, str] = {}
    received: dict[str, list[tuple[float, int, bytes]]] = {}
    with connect(url, subprotocols=["foxglove.sdk.v1", "foxglove.websocket.v1"], open_timeout=30) as ws:
        assert ws.subprotocol in ("foxglove.sdk.v1", "foxglove.websocket.v1")
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            try:
                message = ws.recv(timeout=1)
            except TimeoutError:
                continue
            except Exception:  # the server closed at the episode's end
                break
            if isinstance(message, str):
                op = json.loads(message)
                if op["op"] == "advertise":
                    subs = []
                    for c in op["channels"]:
                        channels[c["id"]] = c
                        if c["topic"] in topics:
                            sid = len(subscriptions) + 1
                            subscriptions[sid] = c["topic"]
                            subs.append({"id": sid, "channelId": c["id"]})
                    if subs:
                        ws.send(json.dumps({"op": "subscribe", "subscriptions": subs}))
            elif message[0] == 1:  # messageData: opcode, subscription id, log time, payload
                sid, log_time = struct.unpack_from("<IQ", message, 1)
                received.setdefault(subscriptions[sid], []).append((time.monotonic(), log_time, bytes(message[13:])))
                if subscriptions[sid] == until_topic:
                    break
    return channels, received


def _decoder(channel: dict):
    assert channel["encoding"] == "protobuf" and channel["schemaEncoding"] == "protobuf"
    schema = Schema(id=1, name=channel["schemaName"], encoding="protobuf", data=base64.b64decode(channel["schema"]))
    return DecoderFactory().decoder_for("protobuf", schema)


def test_foxglove_live_streams_the_episode_with_foxglove_schemas(tmp_path):
    log = tmp_path / "live.mcap"
    rate = 10.0
    proc = _run(f"--world 0 --planner dwa --seed 1 --live foxglove --port 0 --wait 60 --rate {rate} --log", log)
    try:
        url = _foxglove_url(proc)
        topics = {"/scan", "/tf", "/world/static", "/world/metadata", "/episode/result"}
        channels, got = _foxglove_client(url, topics)
        _, err = proc.communicate(timeout=120)
    finally:
        if proc.poll() is None:
            proc.kill()
    assert proc.returncode == 0, err
    by_topic = {c["topic"]: c for c in channels.values()}
    assert by_topic["/scan"]["schemaName"] == "foxglove.LaserScan"
    assert by_topic["/tf"]["schemaName"] == "foxglove.FrameTransforms"
    # Every scan and transform, decoded with the schema the server advertised.
    rec = read_recording(log)
    assert len(got["/scan"]) == len(rec.topic("/scan")) and len(got["/tf"]) == len(rec.topic("/tf"))
    scan = _decoder(by_topic["/scan"])(got["/scan"][5][2])
    assert scan.frame_id == "laser" and len(scan.ranges) == 720
    assert list(scan.ranges) == list(rec.topic("/scan")[5][1].ranges)
    tf = _decoder(by_topic["/tf"])(got["/tf"][-1][2])
    assert [t.child_frame_id for t in tf.transforms] == ["odom", "base_link", "laser"]
    # The world, sent once at the start, reached a client that subscribed after it.
    assert {"/world/static", "/world/metadata"} <= set(by_topic), sorted(by_topic)
    assert {"/world/static", "/world/metadata"} <= set(got), sorted(got)
    result = json.loads(got["/episode/result"][-1][2])
    assert result["outcome"] == rec.result["outcome"]
    # Paced: the scans arrived spread over the episode's time divided by the rate.
    spread = got["/scan"][-1][0] - got["/scan"][0][0]
    assert spread > 0.8 * (rec.topic("/scan")[-1][0] - rec.topic("/scan")[0][0]) / rate


def test_watching_does_not_change_the_recording(tmp_path):
    """The live mirror and the resent latched messages go to the server, not the file."""
    watched, plain = tmp_path / "watched.mcap", tmp_path / "plain.mcap"
    proc = _run("--world 0 --planner straight --live foxglove --port 0 --rate 50 --wait 0 --log", watched)
    proc.communicate(timeout=120)
    assert proc.returncode == 0
    subprocess.run([str(BIN / "dynabarn-run"), "--world", "0", "--log", str(plain)], check=True, capture_output=True)
    assert message_digest(watched) == message_digest(plain)


@pytest.mark.slow
def test_rerun_live_stream_is_received(tmp_path):
    port = _free_port()
    rrd = tmp_path / "live.rrd"
    # Its own process group: `rerun` is a Python wrapper around the real binary, and Ctrl-C
    # must reach both.
    server = subprocess.Popen(
        [RERUN, "--port", str(port), "--save", str(rrd)],
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
        start_new_session=True,
    )
    try:
        for _ in range(100):
            with socket.socket() as s:
                if s.connect_ex(("127.0.0.1", port)) == 0:
                    break
            time.sleep(0.1)
        log = tmp_path / "rerun.mcap"
        # A planner that tracks: its tracks stream beside the true obstacles.
        proc = _run(f"--world 0 --planner predictive --live rerun --rate 50 --connect {port} --log", log)
        _, err = proc.communicate(timeout=180)
        assert proc.returncode == 0, err
        time.sleep(1.0)
    finally:
        os.killpg(server.pid, signal.SIGINT)  # Ctrl-C: rerun finishes the file
        try:
            server.wait(timeout=90)
        except subprocess.TimeoutExpired:  # a loaded machine: what was streamed is on disk already
            os.killpg(server.pid, signal.SIGKILL)
            server.wait(timeout=30)
    printed = subprocess.run([RERUN, "rrd", "print", str(rrd)], capture_output=True, text=True, check=True).stdout
    entities = ("/runs/live/scan", "/runs/live/robot", "/runs/live/obstacles", "/world/walls", "/metrics/v/runs/live")
    entities += ("/runs/live/tracks", "/runs/live/track_velocities")
    for entity in entities:
        assert entity in printed, f"{entity} not received"
    scan_rows = r"with (\d+) rows .*? - /runs/live/scan - data columns: \[Points3D:positions"
    scans = sum(int(n) for n in re.findall(scan_rows, printed))
    assert scans == len(read_recording(log).topic("/scan")), "a scan per control tick"


def test_bad_live_options_are_one_line(tmp_path):
    for args, message in (
        (["--connect", "9876"], "--connect is for --live rerun"),
        (["--live", "rerun", "--connect", "1"], "no rerun viewer at"),
    ):
        out = subprocess.run(
            [str(BIN / "dynabarn-run"), "--world", "0", "--no-log", *args], capture_output=True, text=True
        )
        assert out.returncode == 2 and message in out.stderr and "Traceback" not in out.stderr
    env = {k: v for k, v in os.environ.items() if k != "DISPLAY"}
    out = subprocess.run(
        [str(BIN / "dynabarn-run"), "--world", "0", "--no-log", "--viewer"], capture_output=True, text=True, env=env
    )
    assert out.returncode == 2 and "needs a display" in out.stderr


@pytest.mark.slow
def test_viewer_shows_the_robot_and_obstacles_and_closing_ends_cleanly(display, tmp_path):
    from tests.xwindow import close_window, find_window, no_window, screenshot, xdotool

    env = {k: v for k, v in os.environ.items() if k != "MUJOCO_GL"}
    env["DISPLAY"] = display
    log = tmp_path / "viewer.mcap"
    proc = _run("--world 0 --planner dwa --viewer --rate 1 --log", log, env=env)
    try:
        window = find_window(env, process=proc)
        if not window:
            pytest.fail(no_window(proc))
        time.sleep(4.0)  # a few seconds of the episode, at real time
        shot = screenshot(display).astype(int)
        r, g, b = shot[..., 0], shot[..., 1], shot[..., 2]
        obstacles = (r > 150) & (g < 80) & (b < 80)
        robot = (r > 180) & (g > 150) & (b < 80)  # the Jackal's yellow top plate
        assert obstacles.sum() > 2000, "no obstacles in the viewer"
        assert robot.sum() > 100, "no robot in the viewer"
        xs = np.nonzero(robot)[1]
        # The camera follows the robot: it stays near the window's middle.
        w = np.nonzero(shot.sum(axis=2) > 0)[1]
        assert abs(xs.mean() - (w.min() + w.max()) / 2) < 0.25 * (w.max() - w.min())
        # Space pauses: the picture stands still; running, the obstacles move.
        time.sleep(1.0)
        moving = np.abs(screenshot(display).astype(int) - shot).sum(axis=2) > 60
        xdotool(env, "key", "--window", str(window), "space")
        time.sleep(1.0)
        paused = screenshot(display).astype(int)
        time.sleep(1.5)
        still = np.abs(screenshot(display).astype(int) - paused).sum(axis=2) > 60
        assert moving.sum() > 20 * max(1, still.sum()), (moving.sum(), still.sum())
        xdotool(env, "key", "--window", str(window), "space")
        close_window(display, window)
        out, err = proc.communicate(timeout=60)
    finally:
        if proc.poll() is None:
            proc.kill()
    assert proc.returncode == 0, err
    assert "the viewer window was closed" in out
    rec = read_recording(log)
    assert not rec.truncated and rec.result["reason"] == "the viewer window was closed"
    assert 2.0 < rec.result["sim_time"] < 30.0


def test_a_paused_pacer_holds_the_episode_until_resumed():
    """Space in the viewer pauses: the episode waits between ticks, and the pause does not
    count as time to catch up afterwards."""
    import threading
    from types import SimpleNamespace

    from dynabarn.live.pacing import Pacer

    waited = []
    pacer = Pacer(rate=1000.0, while_waiting=lambda: waited.append(1))
    pacer.on_start(None)
    pacer.toggle_pause()
    ticking = threading.Thread(target=pacer.on_tick, args=(SimpleNamespace(time=0.1),))
    ticking.start()
    ticking.join(timeout=0.5)
    assert ticking.is_alive() and waited, "a paused episode went on"
    pacer.toggle_pause()
    ticking.join(timeout=10)
    assert not ticking.is_alive()
    done = threading.Event()
    threading.Thread(target=lambda: (pacer.on_tick(SimpleNamespace(time=0.2)), done.set())).start()
    assert done.wait(10), "after the pause the clock restarts from the paused tick"
    with pytest.raises(ValueError):
        Pacer(rate=0.0)


def test_the_spawned_rerun_viewer_listens_on_loopback_or_says_why_it_cannot_start(display, monkeypatch):
    """`--live rerun` starts rerun's native viewer itself, its data server on 127.0.0.1
    (rerun-sdk's spawn listens on every interface). Where the graphics cannot run it (here:
    software GL without the formats the viewer needs) that is one line, not a wait."""
    import subprocess

    from dynabarn.errors import DynabarnError
    from dynabarn.web_viewer import spawn_native_viewer

    monkeypatch.setenv("DISPLAY", display)
    monkeypatch.delenv("MUJOCO_GL", raising=False)
    try:
        process, url = spawn_native_viewer(timeout=60)
    except DynabarnError as exc:
        assert str(exc).startswith("rerun's viewer did not start: ") and "\n" not in str(exc)
        return
    try:
        port = url.split(":")[-1].split("/")[0]
        assert url.startswith("rerun+http://127.0.0.1:")
        ss = subprocess.run(["ss", "-ltnpH"], capture_output=True, text=True).stdout.splitlines()
        mine = [line for line in ss if f"pid={process.pid}," in line]
        assert mine and all(line.split()[3].startswith("127.0.0.1:") for line in mine), mine
        assert any(line.split()[3] == f"127.0.0.1:{port}" for line in mine)
    finally:
        process.terminate()
        process.wait(timeout=30)
