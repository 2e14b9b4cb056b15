"""The third pass on untrusted input and faults: each class the pass found, closed at its root.

`THIRD_PASS` is a table like `test_fuzz.BAD_INPUTS` (command, arguments, the text of the one
error line, exit 2), over files `third_files` makes. Below it, the cases a table cannot say:
a marker file that must not appear (code run from a checkpoint or the current folder), a
link whose target must stay unchanged, a device node or FIFO that must stay what it is, a
second writer to one recording, an interrupted re-run beside a finished recording, a full
disk under a video, listeners that must be on loopback, and the Python API's arguments.
"""

from __future__ import annotations

import json
import os
import re
import stat
import subprocess
import sys
import textwrap
import time
from pathlib import Path

import numpy as np
import pytest

from dynabarn.provenance import SHIPPED_WORLDS
from tests.conftest import require
from tests.test_fuzz import _call, _wait_for, one_clear_line

REPO = Path(__file__).resolve().parent.parent
WORLD = SHIPPED_WORLDS / "world_000.xml"
SCRIPT_BIN = Path(sys.executable).parent


def _world(replace: str, by: str, count: int = 1) -> bytes:
    text = WORLD.read_text()
    assert replace in text, replace
    return text.replace(replace, by, count).encode()


def _world_name(name) -> bytes:
    return _world('"name":"world_000","obstacles"', f'"name":{json.dumps(name)},"obstacles"')


def _many(tag: str, n: int) -> bytes:
    return _world("<worldbody>", "<worldbody>\n" + f'<{tag} pos="0 0 0"/>' * n)


def _nested(tag: str, depth: int) -> bytes:
    return _world("<worldbody>", "<worldbody>\n" + f"<{tag}>" * depth + f"</{tag}>" * depth)


WORLD_FILES = {
    "name_up.xml": _world_name("../../../elsewhere/x"),
    "name_abs.xml": _world_name("/elsewhere/x"),
    "name_empty.xml": _world_name(""),
    "name_newline.xml": _world_name("bar\nn"),
    "world_id_float.xml": _world('"world_id":0}', '"world_id":1.5}'),
    "size_inf.xml": _world('size="0.5 0.5" type="cylinder"', 'size="inf 0.5" type="cylinder"'),
    "size_huge.xml": _world('size="0.5 0.5" type="cylinder"', 'size="1e308 0.5" type="cylinder"'),
    "pos_nan.xml": _world('pos="-10 0 0.5"', 'pos="nan 0 0.5"'),
    "gravity_nan.xml": _world('<option timestep="0.005"', '<option gravity="nan 0 -9.81" timestep="0.005"'),
    "timestep_negative.xml": _world('timestep="0.005"', 'timestep="-0.005"'),
    "iterations_huge.xml": _world('timestep="0.005"', 'timestep="0.005" iterations="1e9"'),
    "sites.xml": _many("site", 20_000),
    "cameras.xml": _many("camera", 1_000),
    "frames_deep.xml": _nested("frame", 990),
    "bodies_deep.xml": _nested("body", 990),
}


@pytest.fixture(scope="module")
def third_files(tmp_path_factory) -> Path:
    d = tmp_path_factory.mktemp("third")
    for name, data in WORLD_FILES.items():
        (d / name).write_bytes(data)
    (d / "protocol_newline.json").write_text(json.dumps({"name": "bar\nn"}))
    (d / "protocol_up.json").write_text(json.dumps({"name": "../../x"}))
    index = d / "nul"
    index.mkdir()
    shipped = json.loads((SHIPPED_WORLDS / "index.json").read_text())
    shipped["worlds"][0]["file"] = "world\u0000.xml"  # a NUL byte: Python's path functions raise on it
    (index / "index.json").write_text(json.dumps(shipped))
    return d


THIRD_PASS: list[tuple[str, list[str], str]] = [
    # Names that would reach a path, a line or nothing at all.
    ("run", ["--world", "{bad}/name_up.xml", "--no-log"], "must be a plain name"),
    ("run", ["--world", "{bad}/name_abs.xml", "--no-log"], "must be a plain name"),
    ("run", ["--world", "{bad}/name_empty.xml", "--no-log"], "must be a non-empty string"),
    ("run", ["--world", "{bad}/name_newline.xml", "--no-log"], "must be a plain name"),
    ("run", ["--world", "0", "--protocol", "{bad}/protocol_newline.json", "--no-log"], "must be a plain name"),
    ("run", ["--world", "0", "--protocol", "{bad}/protocol_up.json", "--no-log"], "must be a plain name"),
    ("teleop", ["--world", "0", "--operator", "../../elsewhere/op"], "must be a plain name"),
    ("run", ["--world", "{bad}/world_id_float.xml", "--no-log"], "world_id 1.5"),
    ("worlds", ["show", "{bad}/name_up.xml"], "must be a plain name"),
    # World values MuJoCo would take: every number finite and bounded, the options in range.
    ("run", ["--world", "{bad}/size_inf.xml", "--no-log"], "holds 'inf'"),
    ("run", ["--world", "{bad}/size_huge.xml", "--no-log"], "holds '1e308'"),
    ("run", ["--world", "{bad}/pos_nan.xml", "--no-log"], "holds 'nan'"),
    ("run", ["--world", "{bad}/gravity_nan.xml", "--no-log"], "holds 'nan'"),
    ("run", ["--world", "{bad}/timestep_negative.xml", "--no-log"], "timestep='-0.005'> is not in"),
    ("run", ["--world", "{bad}/iterations_huge.xml", "--no-log"], "holds '1e9'"),
    # Every element kind counted, and the depth bounded before anything recurses.
    ("run", ["--world", "{bad}/sites.xml", "--no-log"], "<site> elements"),
    ("run", ["--world", "{bad}/cameras.xml", "--no-log"], "<camera> elements"),
    ("run", ["--world", "{bad}/frames_deep.xml", "--no-log"], "nested more than 64 deep"),
    ("run", ["--world", "{bad}/bodies_deep.xml", "--no-log"], "nested more than 64 deep"),
    ("bench", ["--set", "{bad}/nul", "--out", "out"], "must be a file name inside the folder"),
    # Planner configurations: a key the registry takes, keys given twice, fields that cross.
    ("run", ["--world", "0", "--planner", "dwa", "--no-log", "--planner-config", "name=x"], "unknown DWA parameter"),
    ("run", ["--world", "0", "--no-log", "--planner-config", "max_vel_x=1,max_vel_x=2"], "given twice"),
    ("run", ["--world", "0", "--planner", "dwa", "--no-log", "--planner-config", "min_vel_x=3,max_vel_x=1"], "above"),
    (
        "run",
        [
            *("--world", "0", "--planner", "dwa", "--no-log"),
            "--planner-config",
            "costmap.inscribed_radius=1,costmap.inflation_radius=0.5",
        ],
        "inscribed_radius=1 is above inflation_radius=0.5",
    ),
    ("run", ["--world", "0", "--planner", "teb", "--no-log", "--planner-config", "inflation_dist=0.1"], "is above"),
    ("run", ["--world", "0", "--planner", "predictive", "--no-log", "--planner-config", "dt=0.9"], "dt=0.9 is above"),
    (
        "run",
        ["--world", "0", "--planner", "trajectory_planner", "--no-log", "--planner-config", "sim_dt=0.5,sim_time=0.2"],
        "sim_dt=0.5 is above",
    ),
    # Options that were silently read as something else.
    ("bench", ["--worlds", "", "--out", "out"], "--worlds is empty"),
    ("bench", ["--verify-golden", "--planner", "dwa"], "--planner: not for the golden set"),
    ("bench", ["--planner", "ros", "--ros-stack", "move_base_dwa", "--worlds", "0", "--out", "out"], "not built"),
    (
        "bench",
        ["--planner", "ros", "--ros-launch", "x", "--ros-stack", "move_base_dwa", "--worlds", "0", "--out", "out"],
        "not both",
    ),
    ("bench", ["--planner", "ros", "--ros-launch", "roslaunch 'x", "--worlds", "0", "--out", "out"], "No closing"),
]


@pytest.mark.parametrize("command, argv, message", THIRD_PASS, ids=[f"{c} {' '.join(a)}" for c, a, _ in THIRD_PASS])
def test_third_pass_bad_input_gives_one_clear_line(command, argv, message, third_files, monkeypatch, tmp_path):
    monkeypatch.chdir(tmp_path)
    monkeypatch.setenv("DYNABARN_NAV_WS", str(tmp_path / "no_workspace"))  # move_base is never built there
    line = one_clear_line(command, [a.replace("{bad}", str(third_files)) for a in argv])
    assert message in line, line
    assert not (tmp_path / "out").exists() or not any((tmp_path / "out").rglob("*.jsonl")), "nothing may run"


def test_the_documentation_counts_the_third_pass():
    page = (REPO / "docs" / "faults.md").read_text()
    match = re.search(r"(\d+) cases of the third pass", page)
    assert match and int(match[1]) == len(THIRD_PASS), "update docs/faults.md's count of the third pass's cases"


# -- names ------------------------------------------------------------------------------------


def test_recording_names_from_data_never_leave_their_folder(tmp_path):
    from dynabarn.demos.teleop import next_demo_path
    from dynabarn.recording import default_run_path

    runs = tmp_path / "runs"
    for world in ("../../../elsewhere/x", "/elsewhere/x", "a\nb", "..", ""):
        path = default_run_path(runs, world, "dwa", "bar\nn", 0)
        assert path.parent == runs and "\n" not in path.name and not path.name.startswith("."), path
        demo = next_demo_path(tmp_path / "demos", world, "../op")
        assert demo.parent == tmp_path / "demos", demo
    assert default_run_path(runs, "world_137", "dwa", "barn", 0).name == "world_137_dwa_barn_s0.mcap"


# -- no code runs from a checkpoint or the current folder ------------------------------------------


class _RunsACommand:
    def __init__(self, marker: Path) -> None:
        self.marker = marker

    def __reduce__(self):
        return (os.system, (f"touch {self.marker}",))


def test_a_td3_checkpoint_whose_pickle_runs_a_command_is_refused_and_runs_nothing(tmp_path):
    require("torch", "learn")
    from dataclasses import asdict

    import torch

    from dynabarn.errors import DynabarnError
    from dynabarn.learn.configs import TD3Config
    from dynabarn.learn.td3 import STATE, train_td3

    out, marker = tmp_path / "out", tmp_path / "MARKER"
    out.mkdir()
    cfg = TD3Config(steps=10)
    (out / "config.json").write_text(json.dumps(asdict(cfg)))
    torch.save({"actor": _RunsACommand(marker)}, out / STATE)  # a zip with a pickle that calls os.system
    with pytest.raises(DynabarnError, match="cannot resume from its checkpoint"):
        train_td3(cfg, out)
    assert not marker.exists(), "the checkpoint ran a command"
    # Damaged training folders are one line too.
    (out / "config.json").write_text("{not json")
    with pytest.raises(DynabarnError, match="not JSON"):
        train_td3(cfg, out)
    (out / "config.json").write_text(json.dumps(asdict(cfg)))
    (out / STATE).write_bytes((out / STATE).read_bytes()[:100])  # truncated
    with pytest.raises(DynabarnError, match="cannot resume"):
        train_td3(cfg, out)


def test_a_policy_file_with_a_flipped_byte_is_refused(tmp_path):
    require("torch", "learn")
    from dynabarn.errors import DynabarnError
    from dynabarn.planners.learned.models import read_blob

    data = bytearray((REPO / "dynabarn" / "policies" / "bc.pt").read_bytes())
    data[len(data) // 2] ^= 0xFF  # inside a tensor's bytes: PyTorch alone loaded it and drove
    bad = tmp_path / "flipped.pt"
    bad.write_bytes(bytes(data))
    with pytest.raises(DynabarnError, match="CRC"):
        read_blob(bad, "anything")


PLANTED = {
    "numpy.py": "open({marker!r}, 'w').write('numpy')\n",
    "struct.py": "open({marker!r}, 'w').write('struct')\n",
    "multiprocessing.py": "open({marker!r}, 'w').write('multiprocessing')\n",
    "runpy.py": "open({marker!r}, 'w').write('runpy')\n",
}


def _plant(folder: Path, marker: Path) -> None:
    for name, text in PLANTED.items():
        (folder / name).write_text(text.format(marker=str(marker)))
    (folder / "dynabarn").mkdir()
    (folder / "dynabarn" / "__init__.py").write_text(f"open({str(marker)!r}, 'w').write('dynabarn')\n")


def test_the_recording_writer_never_imports_from_the_current_folder(tmp_path):
    """`dynabarn-run --log` in a folder holding a numpy.py, struct.py, runpy.py and a dynabarn/
    package: none is imported by the writer process, and the recording is whole."""
    from dynabarn.recording import read_recording

    marker = tmp_path / "MARKER"
    work = tmp_path / "work"
    work.mkdir()
    _plant(work, marker)
    script = SCRIPT_BIN / "dynabarn-run"
    done = subprocess.run(
        [str(script), "--world", "0", "--planner", "straight", "--log", "r.mcap"],
        cwd=work,
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert done.returncode in (0, 1), done.stderr
    assert not marker.exists(), f"imported from the current folder: {marker.read_text()}"
    assert read_recording(work / "r.mcap").result is not None


def test_spawned_workers_never_import_from_the_current_folder(tmp_path):
    """multiprocessing's spawn starts `python -c ...`, which puts the current folder first: a
    planted multiprocessing.py ran in every worker of the vector environment."""
    require("gymnasium", "learn")
    marker = tmp_path / "MARKER"
    work = tmp_path / "work"
    work.mkdir()
    _plant(work, marker)
    script = tmp_path / "vector.py"  # outside the planted folder: this process imports the real ones
    script.write_text(
        textwrap.dedent(
            """
            from dynabarn.learn.vector_env import DynaBARNVectorEnv

            if __name__ == "__main__":
                env = DynaBARNVectorEnv(2, workers=2, worlds=[0, 1])
                env.reset(seed=0)
                env.step([[0.0, 0.0], [0.0, 0.0]])
                env.close()
                print("stepped")
            """
        )
    )
    env = dict(os.environ, PYTHONPATH=str(REPO))
    env.pop("PYTHONSAFEPATH", None)
    done = subprocess.run([sys.executable, str(script)], cwd=work, capture_output=True, text=True, timeout=300, env=env)
    assert done.returncode == 0 and "stepped" in done.stdout, done.stderr
    assert not marker.exists(), f"a worker imported from the current folder: {marker.read_text()}"


# -- nothing written through a link or over a device ---------------------------------------------


def _run_to(log: Path) -> tuple[int, str]:
    return _call("run", ["--world", "0", "--planner", "straight", "--log", str(log)])


def test_a_link_at_the_staging_name_is_never_written_through(tmp_path):
    target = tmp_path / "precious"
    target.write_bytes(b"precious")
    log = tmp_path / "r.mcap"
    (tmp_path / "r.mcap.part").symlink_to(target)
    code, err = _run_to(log)
    assert code == 2 and "symbolic link" in err and "Traceback" not in err, err
    assert target.read_bytes() == b"precious" and not log.exists()


def test_a_link_at_a_results_folders_lock_is_never_written_through(tmp_path):
    target = tmp_path / "precious"
    target.write_bytes(b"precious")
    out = tmp_path / "out"
    out.mkdir()
    (out / ".lock").symlink_to(target)
    code, err = _call("bench", ["--planner", "straight", "--no-floor", "--worlds", "0", "--out", str(out)])
    assert code == 2 and "symbolic link" in err, err
    assert target.read_bytes() == b"precious"


def test_staged_files_are_new_files_under_unpredictable_names(tmp_path):
    """What writers that take a name (ffmpeg, rerun) write into: created here, exclusively."""
    from dynabarn.files import staged_path, write_atomically

    names = set()
    for _ in range(3):
        with staged_path(tmp_path / "v.mp4") as part:
            assert part.exists() and not part.is_symlink() and part.parent == tmp_path
            names.add(part.name)
            part.write_bytes(b"video")
    assert len(names) == 3 and (tmp_path / "v.mp4").read_bytes() == b"video"
    write_atomically(tmp_path / "x.json", "{}")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["v.mp4", "x.json"]


def _special_files(tmp_path: Path) -> list[Path]:
    fifo = tmp_path / "fifo.mcap"
    os.mkfifo(fifo)
    found = [fifo]
    if os.geteuid() == 0:  # a character device node like /dev/null, made here (root only)
        node = tmp_path / "null.mcap"
        os.mknod(node, stat.S_IFCHR | 0o666, os.makedev(1, 3))
        found.append(node)
    return found


def test_a_device_or_fifo_is_never_replaced(tmp_path):
    from dynabarn.files import write_atomically

    for special in _special_files(tmp_path):
        kind = stat.S_IFMT(special.lstat().st_mode)
        code, err = _run_to(special)
        assert code == 2 and "not a regular file" in err, err
        with pytest.raises(OSError, match="not a regular file"):
            write_atomically(special, "x")
        assert stat.S_IFMT(special.lstat().st_mode) == kind, f"{special} was replaced"


# -- one writer per recording; an interrupted re-run keeps the finished one ------------------------


def test_a_second_run_to_the_same_recording_is_refused_while_the_first_records(tmp_path):
    from dynabarn.recording import read_recording
    from tests.helpers import slow_recorded_episode

    log = tmp_path / "r.mcap"
    script = slow_recorded_episode(log, "BackgroundRecorder(path)", say='"halfway"')
    first = subprocess.Popen([sys.executable, "-c", script], stdout=subprocess.PIPE, text=True, cwd=REPO)
    try:
        assert first.stdout.readline().strip() == "running"
        code, err = _run_to(log)
        assert code == 2 and "another run is recording to this file" in err, err
    finally:
        first.wait(timeout=300)
    assert first.returncode == 0
    rec = read_recording(log)
    assert not rec.truncated and rec.result["outcome"] == "timeout"  # the first run's, whole
    # A killed writer's leftover is taken over by the next run, not refused.
    (tmp_path / "s.mcap.part").write_bytes(b"a killed run's start")
    code, err = _run_to(tmp_path / "s.mcap")
    assert code in (0, 1) and (tmp_path / "s.mcap").is_file(), err


def test_an_interrupted_episode_never_replaces_a_finished_recording(tmp_path):
    """Ctrl-C keeps the interrupted episode beside a finished recording of the same name
    (NAME.interrupted.mcap); with none there, it takes the name itself."""
    from dynabarn.files import kept_beside, publish

    finished, part = tmp_path / "r.mcap", tmp_path / "r.mcap.part"
    finished.write_bytes(b"finished")
    part.write_bytes(b"interrupted")
    kept = publish(part, finished, replace=False)
    assert kept == kept_beside(finished) == tmp_path / "r.interrupted.mcap"
    assert finished.read_bytes() == b"finished" and kept.read_bytes() == b"interrupted" and not part.exists()
    part.write_bytes(b"alone")
    assert publish(part, tmp_path / "new.mcap", replace=False) == tmp_path / "new.mcap"


# -- full disks ---------------------------------------------------------------------------------


def test_a_video_the_encoder_did_not_finish_is_not_whole(tmp_path):
    """ffmpeg reports a failed trailer only in its output: an MP4 without its index is not
    taken for a video (before, `dynabarn-render` printed `wrote` and renamed it over a good one)."""
    from dynabarn.render.video import mp4_is_whole

    def box(kind: bytes, body: bytes) -> bytes:
        return (8 + len(body)).to_bytes(4, "big") + kind + body

    whole = box(b"ftyp", b"isom" * 4) + box(b"mdat", b"\0" * 100) + box(b"moov", b"\1" * 20)
    (tmp_path / "whole.mp4").write_bytes(whole)
    (tmp_path / "cut.mp4").write_bytes(whole[:-10])
    (tmp_path / "no_index.mp4").write_bytes(whole[: -len(box(b"moov", b"\1" * 20))])
    assert mp4_is_whole(tmp_path / "whole.mp4")
    assert not mp4_is_whole(tmp_path / "cut.mp4") and not mp4_is_whole(tmp_path / "no_index.mp4")


def test_a_failed_pytorch_write_is_one_oserror(tmp_path, monkeypatch):
    require("torch", "learn")
    import torch

    from dynabarn.planners.learned.models import save_tensors

    def full_disk(obj, f):
        raise RuntimeError("[enforce fail at inline_container.cc:603] . unexpected pos 64 vs 0\nmore lines")

    monkeypatch.setattr(torch, "save", full_disk)
    with pytest.raises(OSError, match="PyTorch could not write it"):
        save_tensors(tmp_path / "p.pt", {"x": 1})
    assert not list(tmp_path.iterdir())


# -- the Python API's arguments -------------------------------------------------------------------


def test_the_environments_check_their_arguments_like_the_commands():
    require("gymnasium", "learn")
    from dynabarn.learn.env import DynaBARNEnv
    from dynabarn.learn.vector_env import DynaBARNVectorEnv

    with pytest.raises(ValueError, match="worlds must be a list"):
        DynaBARNEnv(worlds=[True])
    with pytest.raises(ValueError, match="workers"):
        DynaBARNVectorEnv(2, workers=True, worlds=[0, 1])
    env = DynaBARNEnv(worlds=[0])
    env.reset(seed=0)
    for bad, match in (([np.nan, 0.0], "NaN"), ([0.0, 0.0, 0.0], "shape"), ("go", "expected numbers")):
        with pytest.raises(ValueError, match=match):
            env.step(bad)
    env.step([0.0, 0.0])
    env.close()
    with pytest.raises(RuntimeError, match="closed"):
        env.step([0.0, 0.0])
    venv = DynaBARNVectorEnv(2, workers=0, worlds=[0, 1])
    venv.reset(seed=0)
    with pytest.raises(ValueError, match="NaN"):
        venv.step([[np.inf, 0.0], [0.0, 0.0]])
    with pytest.raises(ValueError, match="shape"):
        venv.step([0.0, 0.0])
    venv.close()
    with pytest.raises(RuntimeError, match="closed"):
        venv.step([[0.0, 0.0], [0.0, 0.0]])


def test_a_dagger_run_is_checked_where_it_is_configured_and_resumed(tmp_path):
    require("torch", "learn")
    from dynabarn.errors import DynabarnError
    from dynabarn.learn.configs import DaggerConfig
    from dynabarn.learn.dagger import Dataset

    with pytest.raises(DynabarnError, match="unknown protocol"):
        DaggerConfig(protocol="nope")
    with pytest.raises(DynabarnError, match="unknown profile set"):
        DaggerConfig(profile_sets=["nope"])
    data = Dataset(tmp_path)
    np.savez(tmp_path / "iteration_000.npz", x=np.full((4, 3), np.nan, np.float16), y=np.zeros((4, 2), np.float32))
    with pytest.raises(ValueError, match="NaN"):
        data.load(1)
    np.savez(tmp_path / "iteration_000.npz", x=np.zeros((4, 3), np.float16), y=np.zeros((5, 2), np.float32))
    with pytest.raises(ValueError, match="do not fit"):
        Dataset(tmp_path).load(1)


def test_a_damaged_demos_manifest_is_one_line(tmp_path):
    from dynabarn.demos.teleop import MANIFEST

    (tmp_path / MANIFEST).write_text('{"file": "a.mcap"}\n{not json\n')
    code, err = _call("demos", ["collect", "--worlds", "0", "--out", str(tmp_path), "--planner", "straight"])
    assert code == 2 and f"{MANIFEST}:2: not a manifest entry" in err and "Traceback" not in err, err


def test_the_gl_environment_is_checked_before_mujoco_is_imported():
    env = dict(os.environ, MUJOCO_GL="garbage")
    done = subprocess.run(
        [sys.executable, "-m", "dynabarn", "worlds", "show", "0"], capture_output=True, text=True, env=env, cwd=REPO
    )
    assert done.returncode == 2 and done.stderr.strip() == (
        "error: MUJOCO_GL='garbage' is not one of glfw, glx, egl, osmesa (or unset)"
    ), done.stderr
    env = dict(os.environ, MUJOCO_GL="egl", PYOPENGL_PLATFORM="garbage")
    done = subprocess.run(
        [sys.executable, "-m", "dynabarn", "worlds", "show", "0"], capture_output=True, text=True, env=env, cwd=REPO
    )
    assert done.returncode == 2 and "PYOPENGL_PLATFORM='garbage' contradicts MUJOCO_GL=egl" in done.stderr


# -- recordings as someone else's files -----------------------------------------------------------


@pytest.fixture(scope="module")
def a_recording(tmp_path_factory) -> Path:
    from dynabarn.cli import run_main

    path = tmp_path_factory.mktemp("rec") / "r.mcap"
    assert run_main(["--world", "0", "--planner", "straight", "--log", str(path)]) in (0, 1)
    return path


def _rewritten(src: Path, dst: Path, edit) -> Path:
    """A copy of `src` whose decoded messages pass through `edit(topic, log_time, message)`
    (returning (log_time, message) or None to keep them), written with the same schemas."""
    from mcap.reader import make_reader
    from mcap.writer import Writer

    with open(src, "rb") as f, open(dst, "wb") as out:
        reader = make_reader(f)
        writer = Writer(out)
        writer.start(profile="", library="test")
        schemas, channels = {}, {}
        summary = reader.get_summary()
        for sid, schema in summary.schemas.items():
            schemas[sid] = writer.register_schema(schema.name, schema.encoding, schema.data)
        for cid, channel in summary.channels.items():
            channels[cid] = writer.register_channel(
                channel.topic, channel.message_encoding, schemas.get(channel.schema_id, 0)
            )
        for _schema, channel, message in reader.iter_messages():
            log_time, data = edit(channel.topic, message.log_time, message.data)
            writer.add_message(channels[channel.id], log_time=log_time, data=data, publish_time=log_time)
        writer.finish()
    return dst


def test_recordings_with_impossible_motion_are_one_line(a_recording, tmp_path):
    from dynabarn.recording import read_recording
    from dynabarn.recording.reader import RecordingError
    from dynabarn.recording.topics import POSE, SCAN

    last = max(m.log_time for m in _messages(a_recording))

    def far_future(topic, t, data):
        return (t + 10**15 if t == last else t), data

    with pytest.raises(RecordingError, match="logged outside"):
        read_recording(_rewritten(a_recording, tmp_path / "future.mcap", far_future))
    from dynabarn.recording.reader import _check_motion

    rec = read_recording(a_recording)
    scans = rec.messages[SCAN.name]
    scans[1][1].ranges.pop()  # one beam fewer
    with pytest.raises(RecordingError, match="different numbers of beams"):
        _check_motion(rec)
    rec = read_recording(a_recording)
    rec.messages[POSE.name][3][1].pose.position.x = float("nan")
    with pytest.raises(RecordingError, match="not finite"):
        _check_motion(rec)
    code, err = _call("render", [str(tmp_path / "future.mcap"), "--out", str(tmp_path / "v.mp4")])
    assert code == 2 and "logged outside" in err and "Traceback" not in err, err


def _messages(path: Path):
    from mcap.reader import make_reader

    with open(path, "rb") as f:
        return [m for _s, _c, m in make_reader(f).iter_messages()]


# -- what listens, and what outlives its parent ---------------------------------------------------


@pytest.mark.slow
def test_a_local_ray_cluster_listens_on_loopback_only_and_imports_nothing_from_here(tmp_path):
    """Its GCS, raylets, workers and this process's own server on 127.0.0.1; and no worker
    imports the planted modules of the folder the sweep runs from (Ray puts the driver's
    folder on its workers' path itself)."""
    require("ray", "ray")
    marker = tmp_path / "MARKER"
    work = tmp_path / "work"
    work.mkdir()
    _plant(work, marker)
    script = tmp_path / "sweep.py"
    script.write_text(
        textwrap.dedent(
            """
            import os, subprocess
            from dynabarn.bench.backends import run_jobs
            from dynabarn.bench.jobs import make_jobs
            from dynabarn.protocol import get_protocol
            from dynabarn.worldset import world_set

            jobs = make_jobs([("straight", {})], world_set("dynabarn300", [0]), get_protocol("barn"), 1)
            rows = run_jobs(jobs, backend="ray", n_workers=1)
            first = next(rows)  # the cluster is up and has run an episode: see what listens
            session = subprocess.run(["pgrep", "-s", str(os.getsid(0))], capture_output=True, text=True).stdout
            ss = subprocess.run(["ss", "-ltnpH"], capture_output=True, text=True).stdout.splitlines()
            print("ROW", first["outcome"])
            print("SESSION", " ".join(session.split()))
            for line in ss:
                print("LISTEN", line)
            list(rows)
            """
        )
    )
    env = dict(os.environ, PYTHONPATH=str(REPO))
    done = subprocess.run(
        [sys.executable, str(script)],
        capture_output=True,
        text=True,
        timeout=300,
        cwd=work,
        env=env,
        start_new_session=True,
    )
    assert "ROW " in done.stdout, done.stdout + done.stderr
    assert not marker.exists(), f"a Ray worker imported from the sweep's folder: {marker.read_text()}"
    session = {int(p) for line in done.stdout.splitlines() if line.startswith("SESSION") for p in line.split()[1:]}
    ours = [line for line in done.stdout.splitlines() if line.startswith("LISTEN") and _pids(line) & session]
    assert any("gcs_server" in line for line in ours), done.stdout  # the cluster's servers are seen
    wide = [line for line in ours if not re.search(r"\s(127\.0\.0\.1|\[::ffff:127\.0\.0\.1\]|\[::1\]):\d+\s", line)]
    assert not wide, "listening beyond loopback:\n" + "\n".join(wide)


def _pids(line: str) -> set[int]:
    return {int(p) for p in re.findall(r"pid=(\d+)", line)}


@pytest.mark.slow
def test_a_killed_dagger_run_takes_its_collection_workers_with_it(tmp_path):
    """SIGKILL to a DAgger run: its spawned collection workers (and multiprocessing's
    resource tracker) end too, instead of holding the caller's pipes."""
    require("torch", "learn")
    from tests.conftest import cmdline, processes_carrying, tagged_environment

    script = tmp_path / "dagger.py"
    script.write_text(
        textwrap.dedent(
            f"""
            from pathlib import Path
            from dynabarn.learn.configs import DaggerConfig
            from dynabarn.learn.dagger import train_dagger

            if __name__ == "__main__":
                cfg = DaggerConfig(iterations=50, episodes=4, validation_episodes=1, updates=2, workers=2)
                train_dagger(cfg, Path({str(tmp_path / "out")!r}))
            """
        )
    )
    token, env = tagged_environment()
    env["PYTHONPATH"] = str(REPO)
    proc = subprocess.Popen(
        [sys.executable, str(script)], env=env, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL
    )
    try:
        assert _wait_for(lambda: len(processes_carrying(token)) >= 3, 120), "the workers never started"
        time.sleep(1.0)  # collecting
    finally:
        proc.kill()
        proc.wait()
    assert _wait_for(lambda: not processes_carrying(token), 30), [cmdline(p) for p in processes_carrying(token)]
