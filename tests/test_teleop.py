"""dynabarn-teleop in a real MuJoCo viewer window on Xvfb, driven with xdotool."""

import json
import os
import subprocess
import sys
import time

import pytest

from dynabarn.recording import read_recording
from tests.xwindow import find_window, no_window, xdotool


@pytest.mark.slow
def test_keyboard_drives_the_robot_and_escape_ends_cleanly(display, tmp_path):
    env = {**os.environ, "DISPLAY": display}
    env.pop("MUJOCO_GL", None)  # the viewer uses GLFW on the X display
    demos = tmp_path / "demos"
    proc = subprocess.Popen(
        [
            sys.executable,
            "-m",
            "dynabarn.cli",
            "teleop",
            "--world",
            "0",
            "--demos-dir",
            str(demos),
            "--operator",
            "tester",
        ],
        env=env,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    try:
        wid = find_window(env, process=proc)
        if not wid:
            pytest.fail(no_window(proc))
        wid = str(wid)
        time.sleep(1.5)
        for _ in range(6):  # slow mode: 6 x 0.1 m/s
            xdotool(env, "key", "--window", wid, "Up")
            time.sleep(0.15)
        xdotool(env, "key", "--window", wid, "Left")
        time.sleep(2.5)
        xdotool(env, "key", "--window", wid, "Escape")
        out, err = proc.communicate(timeout=60)
    finally:
        if proc.poll() is None:
            proc.kill()
    assert proc.returncode == 0, err
    assert "ended by the operator" in out
    files = sorted(demos.glob("*.mcap"))
    assert [f.name for f in files] == ["world_000_tester_001.mcap"]
    rec = read_recording(files[0])
    assert not rec.truncated and rec.result["reason"] == "ended by the operator"
    keys = [k for _, m in rec.topic("/teleop/input") for k in m["keys"]]
    assert keys.count("up") == 6 and "left" in keys and keys[-1] == "escape"
    assert rec.metadata["source"] == "human" and rec.metadata["operator"] == "tester"
    poses = rec.topic("/robot/pose")
    moved = 11.0 - poses[-1][1].pose.position.x
    assert moved > 0.5, f"robot moved only {moved:.2f} m"
    cmds = [m["v"] for _, m in rec.topic("/cmd_vel")]
    assert max(cmds) == pytest.approx(0.6)
    manifest = [json.loads(line) for line in (demos / "manifest.jsonl").read_text().splitlines()]
    assert manifest[0]["file"] == files[0].name and manifest[0]["operator"] == "tester"


def test_teleop_without_display_says_so(monkeypatch, capsys):
    from dynabarn.cli import teleop_main

    monkeypatch.delenv("DISPLAY", raising=False)
    monkeypatch.delenv("WAYLAND_DISPLAY", raising=False)
    assert teleop_main(["--world", "0"]) == 2
    assert "needs a display" in capsys.readouterr().err
