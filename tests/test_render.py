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
    assert render_main([str(recording), "--video", str(out), "--fps", "4", "--size", "640x480"]) == 0
    line = capsys.readouterr().out
    duration = float(line.split("frames, ")[1].split(" s")[0])
    frames = iio.imread(out, index=None)
    assert frames.shape[1:] == (480, 640, 3)
    # One frame per 1/4 s of the episode, then the last held for 1.5 s with the outcome.
    assert len(frames) == int(np.floor(duration * 4 + 1e-9)) + 1 + round(1.5 * 4) - 1
    assert f"wrote {out}: {len(frames)} frames" in line
    assert all(f.std() > 10 for f in frames[:: max(1, len(frames) // 5)]), "blank frame"
    start, end = _yellow_centroid(frames[0]), _yellow_centroid(frames[-1])
    # The robot drives 19 m from right to left across the top view.
    assert end[0] < start[0] - 100


def test_gif_follow_camera(recording, tmp_path):
    out = tmp_path / "v.gif"
    assert (
        render_main([str(recording), "--video", str(out), "--fps", "4", "--camera", "follow", "--size", "160x120"]) == 0
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
    [
        (["--video", "x.avi"], "must end in .mp4 or .gif"),
        (["--video", "x.gif", "--size", "big"], "bad --size"),
        (["--video", "x.mp4", "--size", "641x480"], "needs an even width and height"),
    ],
)
def test_bad_render_arguments(recording, tmp_path, capsys, argv, message):
    argv = [str(recording), *[a if not a.startswith("x.") else str(tmp_path / a) for a in argv]]
    assert render_main(argv) == 2
    assert message in capsys.readouterr().err


def _near(frame: np.ndarray, color, tol: int = 40) -> np.ndarray:
    return np.abs(frame.astype(int) - np.array(color)).max(axis=2) < tol


def test_frames_explain_themselves(recording, tmp_path):
    """Header, time line, legend, laser dots, the robot's marker, and the outcome at the end."""
    from dynabarn.recording import read_recording
    from dynabarn.render import render_recording
    from dynabarn.render.overlay import LASER, OUTCOME_COLORS, PANEL

    out = tmp_path / "v.mp4"
    rec = read_recording(recording)
    info = render_recording(rec, out, fps=2, width=640, height=480)
    frames = iio.imread(out, index=None)
    assert len(frames) == info.frames
    middle, last = frames[len(frames) // 3], frames[-1]
    for f in (middle, last):
        assert _near(f[:12], PANEL, 30).mean() > 0.7, "no header strip"
        assert (f[:24].max(axis=2) > 200).sum() > 100, "no header text"
        assert _near(f[-12:], PANEL, 30).mean() > 0.5, "no legend strip"
    # The laser's returns: magenta dots on the walls and obstacles.
    assert _near(middle, LASER, 70).sum() > 150
    # The robot is legible from above: its marker disc covers a few hundred pixels.
    blue = (middle[..., 2].astype(int) > 180) & (middle[..., 0].astype(int) < 120) & (middle[..., 1].astype(int) < 160)
    assert blue[30:-30].sum() > 200
    # The outcome, in its colour, on the held last frames.
    outcome = rec.result["outcome"]
    strip = last[26:40]
    assert _near(strip, OUTCOME_COLORS[outcome], 45).mean() > 0.5
    assert not _near(middle[26:40], OUTCOME_COLORS[outcome], 45).mean() > 0.5


def test_projection_puts_world_points_on_their_pixels(recording):
    """The overlay's projection agrees with MuJoCo's rendering: the goal region's centre
    projects onto green, a wall's middle onto the wall's grey."""
    import mujoco

    from dynabarn.recording import read_recording, recorded_world
    from dynabarn.render import place_camera, recorded_model
    from dynabarn.render.overlay import project

    rec = read_recording(recording)
    world = recorded_world(rec)
    model = recorded_model(rec, world)
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    goal_geom = model.geom("goal").id
    model.geom_group[goal_geom] = 0  # drawn (it is in a hidden group in world files)
    model.geom_size[goal_geom, 0] = 1.0
    cam = mujoco.MjvCamera()
    for camera, pose in (("top", (0, 0, 0)), ("follow", (-6.0, 0.0, np.pi))):
        place_camera(cam, camera, pose)
        with mujoco.Renderer(model, 240, 320) as r:
            r.update_scene(data, cam)
            frame = r.render()
            gx, gy = world.layout.goal
            col, row = project(r.scene.camera[0], np.array([[gx, gy, 0.0]]), 320, 240)[0]
            px = frame[int(row), int(col)].astype(int)
            assert px[1] > px[0] + 40 and px[1] > px[2] + 40, (camera, px)


def test_size_is_honoured_exactly(recording, tmp_path):
    out = tmp_path / "v.mp4"
    assert render_main([str(recording), "--video", str(out), "--fps", "1", "--size", "642x362"]) == 0
    assert iio.imread(out, index=None).shape[1:3] == (362, 642)


def test_a_renderer_without_a_display_takes_egl_itself():
    """A library user on a headless machine who did not set MUJOCO_GL (MuJoCo picked GLFW
    when imported, which cannot open a context): the renderer takes EGL itself, as the
    commands do, and draws."""
    from tests.conftest import run_headless

    code = (
        "import mujoco, os\n"
        "from dynabarn.render import offscreen_renderer\n"
        "with offscreen_renderer(mujoco.MjModel.from_xml_string('<mujoco/>'), 48, 64) as r:\n"
        "    print(r.render().shape, os.environ['MUJOCO_GL'])\n"
    )
    out = run_headless(code)
    assert out.returncode == 0, out.stderr
    assert out.stdout.strip() == "(48, 64, 3) egl"


def test_a_render_replaces_a_video_only_when_whole_and_refuses_a_folder(recording, tmp_path):
    """The video is written beside its name and renamed at the end: an earlier video stays
    until the new one is whole, nothing is left behind, and a folder is one line."""
    out = tmp_path / "v.gif"
    out.write_bytes(b"an earlier video")
    assert render_main([str(recording), "--video", str(out), "--fps", "1", "--size", "64x48"]) == 0
    assert out.read_bytes()[:6] == b"GIF89a" and sorted(p.name for p in tmp_path.iterdir()) == ["v.gif"]
    folder = tmp_path / "a_folder.mp4"
    folder.mkdir()
    assert render_main([str(recording), "--video", str(folder)]) == 2


def test_run_with_video_on_a_headless_machine_without_mujoco_gl(tmp_path):
    """The planners' imports load MuJoCo: the command picks EGL before any of them runs."""
    from tests.conftest import run_headless

    out = tmp_path / "v.gif"
    code = (
        "import sys\n"
        "from dynabarn.cli import run_main\n"
        f"sys.exit(run_main(['--world', '0', '--planner', 'straight', '--no-log', '--video', {str(out)!r},"
        " '--size', '64x48', '--fps', '2']))\n"
    )
    proc = run_headless(code)
    assert proc.returncode == 0, proc.stderr
    assert out.read_bytes()[:6] == b"GIF89a"
