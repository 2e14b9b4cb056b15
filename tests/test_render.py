"""Offscreen videos: real frames decoded back from the files."""

import imageio.v3 as iio
import numpy as np
import pytest

from dynabarn.cli import render_main, run_main
from dynabarn.planners import get_planner
from dynabarn.protocol import get_protocol
from dynabarn.recording import McapRecorder
from dynabarn.sim import run_episode
from dynabarn.worldset import resolve_world


def _yellow_centroid(frame: np.ndarray) -> np.ndarray:
    """Pixel centroid of the Jackal's yellow top plate."""
    r, g, b = (frame[..., k].astype(int) for k in range(3))
    mask = (r > 150) & (g > 110) & (b < 90) & (r - b > 90)
    assert mask.sum() > 3, "robot not visible"
    ys, xs = np.nonzero(mask)
    return np.array([xs.mean(), ys.mean()])


@pytest.fixture(scope="module")
def recording(tmp_path_factory):
    p = tmp_path_factory.mktemp("r") / "straight.mcap"
    run_episode(resolve_world(0), get_planner("straight"), get_protocol("barn"), seed=0, observers=[McapRecorder(p)])
    return p


def test_mp4_frames_count_content_and_motion(recording, tmp_path, capsys):
    out = tmp_path / "v.mp4"
    assert render_main([str(recording), "--out", str(out), "--fps", "4", "--size", "640x480"]) == 0
    line = capsys.readouterr().out
    duration = float(line.split("frames, ")[1].split(" s")[0])
    frames = iio.imread(out, index=None)
    assert frames.shape[1:] == (480, 640, 3)
    assert len(frames) == int(np.floor(duration * 4 + 1e-9)) + 1
    assert all(f.std() > 10 for f in frames[:: max(1, len(frames) // 5)]), "blank frame"
    start, end = _yellow_centroid(frames[0]), _yellow_centroid(frames[-1])
    # The robot drives 19 m from right to left across the top view.
    assert end[0] < start[0] - 100


def test_gif_follow_camera(recording, tmp_path):
    out = tmp_path / "v.gif"
    assert (
        render_main([str(recording), "--out", str(out), "--fps", "4", "--camera", "follow", "--size", "160x120"]) == 0
    )
    frames = iio.imread(out, index=None)
    assert len(frames) > 10 and frames[0].shape[:2] == (120, 160)


@pytest.mark.slow
def test_run_with_video(tmp_path, capsys):
    out = tmp_path / "run.gif"
    assert run_main(["--world", "0", "--no-log", "--video", str(out)]) == 0
    assert out.is_file() and "wrote" in capsys.readouterr().out


@pytest.mark.parametrize(
    "argv, message",
    [(["--out", "x.avi"], "must end in .mp4 or .gif"), (["--out", "x.gif", "--size", "big"], "bad --size")],
)
def test_bad_render_arguments(recording, tmp_path, capsys, argv, message):
    argv = [str(recording), *[a if not a.startswith("x.") else str(tmp_path / a) for a in argv]]
    assert render_main(argv) == 2
    assert message in capsys.readouterr().err
