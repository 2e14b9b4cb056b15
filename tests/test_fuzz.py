"""Bad inputs and faults against every command: one clear line and exit 2 (or the documented
status), never a traceback, never a silent acceptance, nothing finished lost.

`BAD_INPUTS` is the table: (command, arguments, text the one error line must hold). Files
the arguments name are made by `bad_files`. The fault scenarios below the table kill a
worker, run two writers on one folder, crash a resume mid-rewrite and fill a disk. The
README's "Untrusted input" counts come from this table (a test keeps them equal).
"""

from __future__ import annotations

import json
import os
import re
import signal
import subprocess
import sys
import time
import xml.etree.ElementTree as ET
from pathlib import Path

import pytest

from dynabarn import cli
from dynabarn.provenance import SHIPPED_WORLDS
from tests.conftest import require

REPO = Path(__file__).resolve().parent.parent
WORLD = SHIPPED_WORLDS / "world_000.xml"
MAINS = {name.removesuffix("_main"): getattr(cli, name) for name in cli.__all__}


def _with_metadata(edit) -> bytes:
    """World 0 with its JSON metadata changed by `edit(dict) -> object`."""
    tree = ET.parse(WORLD)
    text = tree.getroot().find("./custom/text[@name='dynabarn_world']")
    text.text = json.dumps(edit(json.loads(text.text)))
    return ET.tostring(tree.getroot())


def _with_keyframes(edit) -> bytes:
    """World 0 with obstacle_000's keyframe numbers changed by `edit(list[str]) -> list[str]`."""
    tree = ET.parse(WORLD)
    numeric = tree.getroot().find("./custom/numeric[@name='obstacle_000_keyframes']")
    numeric.set("data", " ".join(edit(numeric.get("data").split())))
    return ET.tostring(tree.getroot())


def _many_obstacles(n: int) -> bytes:
    tree = ET.parse(WORLD)
    root = tree.getroot()
    text = root.find("./custom/text[@name='dynabarn_world']")
    meta = json.loads(text.text)
    first = meta["obstacles"][0]
    kf = root.find("./custom/numeric[@name='obstacle_000_keyframes']").get("data")
    custom = root.find("./custom")
    meta["obstacles"] = []
    for i in range(n):
        meta["obstacles"].append({**first, "name": f"many_{i}"})
        ET.SubElement(custom, "numeric", name=f"many_{i}_keyframes", data=kf)
    text.text = json.dumps(meta)
    return ET.tostring(root)


def _without_obstacle_bodies() -> bytes:
    text = WORLD.read_text()
    stripped = re.sub(r'<body name="obstacle_\d+".*?</body>\n', "", text, flags=re.S)
    assert stripped != text
    return stripped.encode()


def _xml(replace: str, by: str) -> bytes:
    text = WORLD.read_text()
    assert replace in text
    return text.replace(replace, by, 1).encode()


WORLD_FILES: dict[str, bytes] = {
    "include.xml": _xml("<worldbody>", '<worldbody><include file="/etc/passwd"/>'),
    "include_rel.xml": _xml("<worldbody>", '<worldbody><include file="frag.xml"/>'),
    "mesh.xml": _xml("<asset>", '<asset><mesh name="m" file="../../x.stl"/>'),
    "texture.xml": _xml("<asset>", '<asset><texture name="t" type="2d" file="/etc/hostname"/>'),
    "hfield.xml": _xml("<asset>", '<asset><hfield name="h" file="h.png"/>'),
    "plugin.xml": _xml("<worldbody>", '<extension><plugin plugin="mujoco.elasticity.cable"/></extension><worldbody>'),
    "meshdir.xml": _xml('<compiler angle="radian"/>', '<compiler angle="radian" meshdir="/etc"/>'),
    "second_robot.xml": _xml("<asset>", '<asset><model name="other" file="other.xml"/>'),
    "not_xml.xml": b"this is not xml <",
    "not_mjcf.xml": b"<html><body/></html>",
    "empty.xml": b"",
    "no_metadata.xml": b"<mujoco><worldbody/></mujoco>",
    "nested_json.xml": b'<mujoco><custom><text name="dynabarn_world" data="'
    + b"[" * 100_000
    + b'"/></custom></mujoco>',
    "obstacles_null.xml": _with_metadata(lambda m: {**m, "obstacles": None}),
    "metadata_list.xml": _with_metadata(lambda m: [m]),
    "radius_nan.xml": _with_metadata(lambda m: {**m, "obstacles": [{**m["obstacles"][0], "radius": float("nan")}]}),
    "radius_huge.xml": _with_metadata(lambda m: {**m, "obstacles": [{**m["obstacles"][0], "radius": 1e300}]}),
    "goal_inf.xml": _with_metadata(lambda m: {**m, "layout": {**m["layout"], "goal": [float("inf"), 0]}}),
    "wall_negative.xml": _with_metadata(
        lambda m: {**m, "layout": {**m["layout"], "walls": [{**m["layout"]["walls"][0], "size": [-1, 1, 1]}]}}
    ),
    "keyframes_nan.xml": _with_keyframes(lambda v: ["nan", *v[1:]]),
    "keyframes_inf_xy.xml": _with_keyframes(lambda v: [v[0], "inf", *v[2:]]),
    "keyframes_far.xml": _with_keyframes(lambda v: [v[0], "1e300", *v[2:]]),
    "keyframes_unsorted.xml": _with_keyframes(lambda v: [v[3], v[1], v[2], v[0], *v[4:]]),
    "keyframes_duplicate_time.xml": _with_keyframes(lambda v: [v[0], v[1], v[2], v[0], *v[4:]]),
    "keyframes_negative_time.xml": _with_keyframes(lambda v: ["-5", *v[1:]]),
    "keyframes_text.xml": _with_keyframes(lambda v: ["abc", *v[1:]]),
    "keyframes_pairs.xml": _with_keyframes(lambda v: v[:-1]),
    "many_obstacles.xml": _many_obstacles(501),
    # Few bytes that MuJoCo's compiler would expand into millions of elements, or allocate.
    "replicate.xml": _xml("<worldbody>", '<worldbody><replicate count="100000"><geom size="0.1"/></replicate>'),
    "flexcomp.xml": _xml(
        "<worldbody>", '<worldbody><flexcomp name="f" type="grid" count="1000 1000 1" spacing="0.1 0.1 0.1"/>'
    ),
    "hfield_inline.xml": _xml("<asset>", '<asset><hfield name="h" nrow="100000" ncol="100000" size="1 1 1 1"/>'),
    "texture_huge.xml": _xml('width="512" height="512"', 'width="100000" height="100000"'),
    "many_geoms.xml": _xml("<worldbody>", "<worldbody>" + '<geom size="0.1"/>' * 20_001),
    "joint.xml": _xml("<worldbody>", '<worldbody><body name="j"><joint type="free"/><geom size="0.1"/></body>'),
    "no_obstacle_bodies.xml": _without_obstacle_bodies(),
}

PROTOCOLS: dict[str, str] = {
    "p_time_nan.json": '{"name": "x", "time_limit": NaN}',
    "p_time_inf.json": '{"name": "x", "time_limit": Infinity}',
    "p_time_huge.json": '{"name": "x", "time_limit": 1e9}',
    "p_spawn_nan.json": '{"name": "x", "spawn": [NaN, 0, 3.14]}',
    "p_spawn_far.json": '{"name": "x", "spawn": [1e6, 0, 3.14]}',
    "p_tolerance_zero.json": '{"name": "x", "goal_tolerance": 0}',
    "p_clip_reversed.json": '{"name": "x", "score_clip": [8, 2]}',
    "p_unknown_key.json": '{"name": "x", "speed_of_light": 1}',
    "p_not_object.json": "[1, 2]",
    "p_not_json.json": "{nope",
    "p_nested.json": "[" * 100_000,
    "p_hour.json": '{"name": "x", "time_limit": 3600}',
    "p_reference_yes.json": '{"name": "x", "reference_from_world": "yes"}',
}


@pytest.fixture(scope="module")
def bad_files(tmp_path_factory) -> Path:
    d = tmp_path_factory.mktemp("bad")
    for name, data in WORLD_FILES.items():
        (d / name).write_bytes(data)
    (d / "frag.xml").write_text(
        '<mujoco><worldbody><geom name="HIDDEN_WALL" type="box" size="1 1 1"/></worldbody></mujoco>'
    )
    for name, text in PROTOCOLS.items():
        (d / name).write_text(text)
    # World sets whose index points outside, or is malformed.
    for folder, index in {
        "set_escape": {
            "format": "dynabarn-index",
            "worlds": [{"id": 0, "file": "../../../../etc/passwd", "difficulty": "easy"}],
        },
        "set_abs": {"format": "dynabarn-index", "worlds": [{"id": 0, "file": "/etc/passwd", "difficulty": "easy"}]},
        "set_no_worlds": {"format": "dynabarn-index"},
        "set_bad_entry": {"format": "dynabarn-index", "worlds": [{"file": "w.xml"}]},
        "set_twice": {
            "format": "dynabarn-index",
            "worlds": [
                {"id": 0, "file": "a.xml", "difficulty": "easy"},
                {"id": 0, "file": "b.xml", "difficulty": "easy"},
            ],
        },
        "set_foreign": {"format": "something-else"},
        "set_symlink": {"format": "dynabarn-index", "worlds": [{"id": 0, "file": "w.xml", "difficulty": "easy"}]},
        "set_million": {
            "format": "dynabarn-index",
            "worlds": [{"id": i, "file": f"w{i}.xml", "difficulty": "easy"} for i in range(1_000_000)],
        },
    }.items():
        (d / folder).mkdir()
        (d / folder / "index.json").write_text(json.dumps(index))
    (d / "set_symlink" / "w.xml").symlink_to(WORLD)  # a link out of the folder
    (d / "set_not_json").mkdir()
    (d / "set_not_json" / "index.json").write_text("{")
    # Results folders.
    (d / "a_file").write_text("not a folder")
    (d / "out_empty_meta").mkdir()
    (d / "out_empty_meta" / "metadata.json").write_text("")
    (d / "a_folder").mkdir()
    (d / "a_folder.mp4").mkdir()
    # Files that are not what they claim.
    (d / "not_a_recording.mcap").write_text("hello")
    (d / "not_a_policy.pt").write_bytes(b"\x80\x04K\x01.")
    (d / "bad_config.json").write_text('{"max_vel_x": "fast"}')
    (d / "config_list.json").write_text("[1, 2]")
    _recordings(d)
    _datasets(d)
    return d


def _datasets(d: Path) -> None:
    """Behaviour-cloning datasets that are not what `dynabarn-demos export` writes, and a
    policy file whose pickle would run a command."""
    import pickle

    import numpy as np

    from dynabarn.demos.dataset import DATASET_FORMAT

    meta = json.dumps({"format": DATASET_FORMAT, "lookahead": 2.0})
    n = 8
    good = {
        "scans": np.full((n, 720), 5.0),
        "local_goal": np.ones((n, 2)),
        "actions": np.ones((n, 2)),
        "metadata": meta,
    }
    variants = {
        "ds_nan_actions.npz": {**good, "actions": np.full((n, 2), np.nan)},
        "ds_zero_rows.npz": {
            **good,
            "scans": np.zeros((0, 720)),
            "local_goal": np.zeros((0, 2)),
            "actions": np.zeros((0, 2)),
        },
        "ds_wrong_shapes.npz": {**good, "scans": np.zeros((n, 10))},
        "ds_meta_text.npz": {**good, "metadata": "not json"},
    }
    for name, arrays in variants.items():
        np.savez(d / name, **arrays)

    class Evil:
        def __reduce__(self):
            return (os.system, (f"touch {d / 'EVIL_RAN'}",))

    (d / "evil.pt").write_bytes(pickle.dumps(Evil(), protocol=4))


def _json_recording(path: Path, metadata, result=None, world: bytes | None = None) -> None:
    """An MCAP file with a /world/metadata message (and an /episode/result) as given: a
    recording the project did not write."""
    from mcap.writer import Writer

    with path.open("wb") as f:
        writer = Writer(f)
        writer.start()
        schema = writer.register_schema("dynabarn.Json", "jsonschema", b"{}")
        messages = {"/world/metadata": metadata, **({"/episode/result": result} if result is not None else {})}
        for topic, payload in messages.items():
            channel = writer.register_channel(topic, "json", schema)
            writer.add_message(channel, log_time=0, data=json.dumps(payload).encode(), publish_time=0)
        if world is not None:
            writer.add_attachment(0, 0, "world.xml", "application/vnd.mujoco.mjcf+xml", world)
        writer.finish()


def _recordings(d: Path) -> None:
    """Recordings made wrong: metadata of the wrong shape, a chunk corrupted in the middle."""
    from dynabarn.planners import get_planner
    from dynabarn.protocol import get_protocol
    from dynabarn.recording import McapRecorder
    from dynabarn.sim import run_episode

    real = d / "real.mcap"
    run_episode(WORLD, get_planner("straight"), get_protocol("barn"), seed=0, observers=[McapRecorder(real)])
    data = bytearray(real.read_bytes())
    middle = len(data) // 2
    data[middle : middle + 64] = bytes(64)  # a chunk's compressed bytes zeroed
    (d / "rec_corrupt.mcap").write_bytes(bytes(data))
    _json_recording(d / "rec_meta_list.mcap", [1, 2])
    _json_recording(d / "rec_world_string.mcap", {"world": "x", "keyframes": {}, "robot": {}})
    _json_recording(d / "rec_outcome_5.mcap", {}, {"outcome": 5, "time": 1.0})
    _json_recording(d / "rec_time_text.mcap", {}, {"outcome": "success", "time": "abc"})
    _json_recording(d / "rec_attached_include.mcap", {}, world=WORLD_FILES["include.xml"])


WORLD_CASES = [
    ("include.xml", "<include> is not allowed"),
    ("include_rel.xml", "<include> is not allowed"),
    ("mesh.xml", "<mesh file='../../x.stl'> refers to another file"),
    ("texture.xml", "refers to another file"),
    ("hfield.xml", "refers to another file"),
    ("plugin.xml", "is not allowed"),
    ("meshdir.xml", "<compiler meshdir='/etc'> refers to another file"),
    ("second_robot.xml", "<model file='other.xml'> refers to another file"),
    ("not_xml.xml", "not valid XML"),
    ("not_mjcf.xml", "not an MJCF file"),
    ("empty.xml", "not valid XML"),
    ("no_metadata.xml", "not a DynaBARN world"),
    ("nested_json.xml", "not valid JSON"),
    ("obstacles_null.xml", "malformed world description"),
    ("metadata_list.xml", "not a DynaBARN world"),
    ("radius_nan.xml", "radius nan is not in"),
    ("radius_huge.xml", "radius 1e+300 is not in"),
    ("goal_inf.xml", "goal"),
    ("wall_negative.xml", "positive finite sizes"),
    ("keyframes_nan.xml", "NaN or infinite"),
    ("keyframes_inf_xy.xml", "NaN or infinite"),
    ("keyframes_far.xml", "more than 1000 m from the origin"),
    ("keyframes_unsorted.xml", "rise strictly"),
    ("keyframes_duplicate_time.xml", "rise strictly"),
    ("keyframes_negative_time.xml", "start at >= 0 s"),
    ("keyframes_text.xml", "keyframes are not numbers"),
    ("keyframes_pairs.xml", "not [t, x, y] triples"),
    ("many_obstacles.xml", "501 obstacles (at most 500)"),
    ("replicate.xml", "<replicate> is not allowed in a world file"),
    ("flexcomp.xml", "<flexcomp> is not allowed in a world file"),
    ("hfield_inline.xml", "<hfield> is not allowed in a world file"),
    ("texture_huge.xml", "<texture> of 100000 x 100000 pixels is too large"),
    ("many_geoms.xml", "more than 20,000 <geom> elements"),
    ("joint.xml", "<joint> is not allowed in a world file"),
    ("no_obstacle_bodies.xml", "has no body"),
    ("does_not_exist.xml", "world not found"),
]

PROTOCOL_CASES = [
    ("p_time_nan.json", "time_limit nan is not in"),
    ("p_time_inf.json", "time_limit inf is not in"),
    ("p_time_huge.json", "time_limit 1000000000.0 is not in"),
    ("p_spawn_nan.json", "spawn"),
    ("p_spawn_far.json", "within 1000 m"),
    ("p_tolerance_zero.json", "goal_tolerance 0 is not in"),
    ("p_clip_reversed.json", "0 < low < high"),
    ("p_unknown_key.json", "malformed protocol"),
    ("p_not_object.json", "malformed protocol"),
    ("p_not_json.json", "not valid JSON"),
    ("p_nested.json", "not valid JSON"),
    ("p_reference_yes.json", "reference_from_world='yes': expected true or false"),
    ("missing.json", "protocol file not found"),
]

CONFIG_CASES = [
    ("dwa", "max_vel_x=abc", "max_vel_x='abc': expected a number"),
    ("dwa", "costmap=null", "costmap=None: expected an object of costmap parameters"),
    ("dwa", "max_vel_x=" + "1" * 5000, "bad --planner-config value for 'max_vel_x'"),
    ("dwa", "max_vel_x=-1", "max_vel_x=-1: out of range"),
    ("dwa", "max_vel_x=Infinity", "expected a finite number"),
    ("dwa", "sim_time=NaN", "expected a finite number"),
    ("dwa", "vx_samples=100000000", "vx_samples=100000000: out of range"),
    ("dwa", "vx_samples=2.5", "expected a whole number"),
    ("dwa", "vx_samples=true", "expected a whole number"),
    ("dwa", "costmap.resolution=0", "resolution=0: out of range"),
    ("dwa", "costmap.size=1e9", "size=1000000000.0: out of range"),
    ("dwa", "bogus=1", "unknown DWA parameter"),
    ("dwa", "novalue", "bad --planner-config item"),
    ("dwa", "{bad}/bad_config.json", "max_vel_x='fast'"),
    ("dwa", "{bad}/config_list.json", "must be a JSON object"),
    ("dwa", "{bad}/missing.json", "planner config file not found"),
    ("teb", "n_poses=100000", "n_poses=100000: out of range"),
    ("teb", "max_iterations=0", "max_iterations=0: out of range"),
    ("oracle", "dt=0", "dt=0: out of range"),
    ("predictive", "tracker.gate=-1", "predictive tracker gate=-1: out of range"),
    ("predictive", "tracker=null", "tracker=None: expected an object of tracker parameters"),
    ("predictive", "tracker.detector.min_points=0", "tracker detector min_points=0: out of range"),
    ("predictive", "tracker.bogus=1", "unknown predictive tracker parameter"),
    ("teb", "include_dynamic_obstacles=1", "include_dynamic_obstacles=1: expected true or false"),
    ("straight", "speed=1e9", "speed=1000000000.0: out of range"),
]

# (command, arguments, what the one error line must hold); exit status 2 for all.
BAD_INPUTS: list[tuple[str, list[str], str]] = [
    # Worlds are data.
    *[("run", ["--world", "{bad}/" + name, "--no-log"], msg) for name, msg in WORLD_CASES],
    ("worlds", ["show", "{bad}/include.xml"], "<include> is not allowed"),
    ("worlds", ["show", "{bad}/keyframes_nan.xml"], "NaN or infinite"),
    ("worlds", ["show", "300"], "unknown world id 300"),
    ("worlds", ["show", "world_9999"], "unknown world id world_9999"),
    ("worlds", ["show", "137", "--plot", "{bad}/p.xyz"], "use a .png, .pdf or .svg"),
    ("worlds", ["show", "137", "--plot", "{bad}/a_file/p.png"], "error:"),
    ("worlds", ["stats", "{bad}/set_escape"], "must be a file name inside the folder"),
    ("worlds", ["stats", "{bad}/set_abs"], "must be a file name inside the folder"),
    ("worlds", ["stats", "{bad}/set_no_worlds"], "index has no list of worlds"),
    ("worlds", ["stats", "{bad}/set_bad_entry"], "integer id"),
    ("worlds", ["stats", "{bad}/set_twice"], "appears twice"),
    ("worlds", ["stats", "{bad}/set_foreign"], "not a dynabarn world index"),
    ("worlds", ["stats", "{bad}/set_not_json"], "not valid JSON"),
    ("worlds", ["show", "{bad}/no_obstacle_bodies.xml"], "has no body"),
    ("worlds", ["stats", "{bad}/set_symlink"], "is a symbolic link; worlds are plain files"),
    ("worlds", ["stats", "{bad}/set_million"], "1,000,000 worlds; an index holds at most 100,000"),
    ("run", ["--world", "{bad}/two\nlines.xml", "--no-log"], "world not found"),
    ("worlds", ["stats", "--worlds", "5-2"], "ranges go upwards"),
    ("worlds", ["generate", "--out", "{bad}/a_file/sub"], "error:"),
    ("worlds", ["generate", "--seed", "abc"], "--seed"),
    ("worlds", ["generate", "--seed", "-1"], "--seed: -1 is not in [0, 4294967295]"),
    ("worlds", ["import", "{bad}/nope.json"], "import file not found"),
    # Protocols.
    *[("run", ["--world", "0", "--no-log", "--protocol", "{bad}/" + name], msg) for name, msg in PROTOCOL_CASES],
    ("run", ["--world", "0", "--no-log", "--protocol", "nope"], "unknown protocol 'nope'"),
    # Planner configurations.
    *[
        ("run", ["--world", "0", "--no-log", "--planner", planner, "--planner-config", cfg], msg)
        for planner, cfg, msg in CONFIG_CASES
    ],
    ("run", ["--world", "0", "--no-log", "--planner", "nope"], "unknown planner 'nope'"),
    (
        "run",
        ["--world", "0", "--no-log", "--planner", "bc", "--policy", "{bad}/not_a_policy.pt"],
        "not a loadable policy",
    ),
    ("run", ["--world", "0", "--no-log", "--planner", "bc", "--policy", "{bad}/missing.pt"], "policy file not found"),
    ("run", ["--world", "0", "--no-log", "--planner", "bc", "--policy", "{bad}/evil.pt"], "not a loadable policy"),
    # Numbers on the command line.
    ("run", ["--world", "0", "--no-log", "--seed", "-1"], "--seed: -1 is not in [0, 4294967295]"),
    ("run", ["--world", "0", "--no-log", "--seed", "1e3"], "is not a whole number"),
    ("run", ["--world", "0", "--no-log", "--dt", "1e-7"], "--dt: 1e-7 is not in"),
    ("run", ["--world", "0", "--no-log", "--dt", "nan"], "--dt: nan is not in"),
    ("run", ["--world", "0", "--no-log", "--control-rate", "nan"], "--control-rate: nan is not in"),
    ("run", ["--world", "0", "--no-log", "--control-rate", "7"], "whole number of physics steps"),
    ("run", ["--world", "0", "--no-log", "--dt", "0.0001", "--protocol", "{bad}/p_hour.json"], "at most 5,000,000"),
    ("run", ["--world", "0", "--log", "{bad}/a_folder"], "a folder, not a recording file"),
    ("run", ["--world", "0", "--log", "{bad}/a_file/r.mcap"], "cannot record to"),
    ("run", ["--world", "0", "--no-log", "--video", "{bad}/v.avi"], "video must end in .mp4 or .gif"),
    ("run", ["--no-log"], "--world"),
    ("bench", ["--out", "{bad}/a_file", "--worlds", "0", "--trials", "1"], "exists and is not a folder"),
    ("bench", ["--out", "{bad}/o1", "--jobs", "0"], "--jobs: 0 is not in [1, 256]"),
    ("bench", ["--out", "{bad}/o1", "--jobs", "100000"], "--jobs: 100000 is not in [1, 256]"),
    ("bench", ["--out", "{bad}/o1", "--trials", "0"], "--trials: 0 is not in"),
    ("bench", ["--out", "{bad}/o1", "--worlds", "5-2"], "ranges go upwards"),
    ("bench", ["--out", "{bad}/o1", "--worlds", "50"], "is in set 'paper60'"),
    ("bench", ["--out", "{bad}/o1", "--worlds", "x"], "bad --worlds item 'x'"),
    ("bench", ["--out", "{bad}/o1", "--planner", ","], "name at least one planner"),
    ("bench", ["--out", "{bad}/o1", "--set", "{bad}/set_escape"], "must be a file name inside the folder"),
    ("bench", ["--out", "{bad}/o1", "--set", "{bad}/nowhere"], "unknown world set"),
    ("bench", ["--out", "{bad}/out_empty_meta", "--worlds", "0", "--trials", "1"], "is not a sweep's metadata"),
    ("bench", ["--out", "{bad}/o1", "--backend", "ray", "--address", "not-an-address"], "--address 'not-an-address'"),
    ("bench", ["--worlds", "0"], "--out is required"),
    ("render", ["{bad}/not_a_recording.mcap", "--video", "{bad}/v.mp4"], "error:"),
    ("render", ["{bad}/missing.mcap", "--video", "{bad}/v.mp4"], "recording not found"),
    ("render", ["{bad}/not_a_recording.mcap", "--video", "{bad}/no/such/v.mp4"], "does not exist"),
    ("render", ["{bad}/not_a_recording.mcap", "--video", "{bad}/a_folder.mp4"], "is a folder, not a video file"),
    ("render", ["{bad}/real.mcap", "--video", "/proc/self/v.gif"], "cannot write a video into /proc/self"),
    ("render", ["{bad}/not_a_recording.mcap", "--video", "{bad}/v.mp4", "--fps", "100000"], "--fps: 100000 is not in"),
    ("render", ["{bad}/not_a_recording.mcap", "--video", "{bad}/v.mp4", "--fps", "0"], "--fps: 0 is not in"),
    ("render", ["{bad}/not_a_recording.mcap", "--video", "{bad}/v.mp4", "--size", "100000x100000"], "bad --size"),
    ("replay", ["{bad}/not_a_recording.mcap", "--save", "{bad}/x.rrd"], "error:"),
    ("replay", ["{bad}/missing.mcap"], "recording not found"),
    ("replay", ["{bad}/real.mcap", "--save", "{bad}/a_folder"], "is a folder, not an .rrd file"),
    ("replay", ["{bad}/rec_meta_list.mcap", "--save", "{bad}/x.rrd"], "a /world/metadata message is list"),
    ("replay", ["{bad}/rec_world_string.mcap", "--save", "{bad}/x.rrd"], "field 'world' is not a JSON dict"),
    ("render", ["{bad}/rec_world_string.mcap", "--video", "{bad}/v.gif"], "field 'world' is not a JSON dict"),
    ("demos", ["export", "{bad}/rec_meta_list.mcap", "--dataset", "{bad}/d.npz"], "a /world/metadata message is list"),
    ("demos", ["export", "{bad}/rec_outcome_5.mcap", "--dataset", "{bad}/d.npz"], "no outcome the runner gives"),
    ("demos", ["export", "{bad}/rec_time_text.mcap", "--dataset", "{bad}/d.npz"], "a metric that is not a number"),
    ("demos", ["export", "{bad}/rec_attached_include.mcap", "--dataset", "{bad}/d.npz"], "<include> is not allowed"),
    ("demos", ["collect", "--jobs", "0"], "--jobs: 0 is not in"),
    ("demos", ["collect", "--trials", "-3"], "--trials: -3 is not in"),
    ("demos", ["export", "{bad}/missing", "--dataset", "{bad}/d.npz"], "error:"),
    ("demos", ["export", "{bad}/a_folder", "--dataset", "{bad}/d.npz", "--lookahead", "inf"], "--lookahead: inf"),
    ("train", ["td3", "--out", "{bad}/t", "--steps", "0"], "--steps: 0 is not in"),
    ("train", ["td3", "--out", "{bad}/t", "--set", "nope"], "unknown world set 'nope'"),
    (
        "train",
        ["td3", "--out", "{bad}/t", "--difficulty", "nope"],
        "--difficulty 'nope': use easy, medium, hard or all",
    ),
    ("train", ["bc", "--data", "{bad}/missing.npz", "--out", "{bad}/p", "--epochs", "-1"], "--epochs: -1"),
    ("train", ["bc", "--data", "{bad}/ds_nan_actions.npz", "--out", "{bad}/p"], "actions holds NaN or infinite"),
    ("train", ["bc", "--data", "{bad}/ds_zero_rows.npz", "--out", "{bad}/p"], "the dataset has no rows"),
    ("train", ["bc", "--data", "{bad}/ds_wrong_shapes.npz", "--out", "{bad}/p"], "10 ranges per row, not"),
    ("train", ["bc", "--data", "{bad}/ds_meta_text.npz", "--out", "{bad}/p"], "not a dynabarn"),
    ("teleop", ["--world", "0", "--speed", "1e9"], "--speed: 1e9 is not in"),
]


def _call(command: str, argv: list[str]) -> tuple[int, str]:
    """Run a command in this process; (exit status, what it printed on stderr)."""
    import contextlib
    import io

    err = io.StringIO()
    with contextlib.redirect_stderr(err), contextlib.redirect_stdout(io.StringIO()):
        try:
            code = MAINS[command](argv)
        except SystemExit as exc:  # argparse's usage errors
            code = exc.code
    return code, err.getvalue()


def one_clear_line(command: str, argv: list[str]) -> str:
    """Run a command that must refuse its input: exit 2 and one line, never a traceback;
    that line."""
    code, err = _call(command, argv)
    lines = [line for line in err.splitlines() if line.strip()]
    assert code == 2, f"exit {code}: {err}"
    assert len(lines) == 1 and "Traceback" not in err, err
    return lines[0]


@pytest.mark.parametrize("command, argv, message", BAD_INPUTS, ids=[f"{c} {' '.join(a)}" for c, a, _ in BAD_INPUTS])
def test_bad_input_gives_one_clear_line(command, argv, message, bad_files, monkeypatch, tmp_path):
    monkeypatch.chdir(tmp_path)  # nothing may depend on (or write to) the repository folder
    if {"bc", "td3"} & set(argv):
        require("torch", "learn")  # without it, the one line says to install the extra
    if "ray" in argv:
        require("ray", "ray")
    line = one_clear_line(command, [a.replace("{bad}", str(bad_files)) for a in argv])
    assert message.replace("{bad}", str(bad_files)) in line, line


def test_the_documentation_counts_the_table():
    page = (REPO / "docs" / "faults.md").read_text()
    match = re.search(r"(\d+) bad inputs", page)
    assert match and int(match[1]) == len(BAD_INPUTS), "update docs/faults.md's count of bad inputs"


def test_a_world_file_cannot_pull_in_a_hidden_wall(bad_files, tmp_path):
    """The issue's proof of concept: the fragment beside the world is never read."""
    code, err = _call("run", ["--world", str(bad_files / "include_rel.xml"), "--no-log"])
    assert code == 2 and "<include>" in err


def test_relative_references_do_not_depend_on_the_current_folder(tmp_path, monkeypatch):
    """The same world file gives the same episode from any folder (it reads nothing else)."""
    import shutil

    from dynabarn.planners import get_planner
    from dynabarn.protocol import get_protocol
    from dynabarn.sim import run_episode

    copy = tmp_path / "elsewhere" / "w.xml"
    copy.parent.mkdir()
    shutil.copy(WORLD, copy)  # its ../assets/jackal/jackal.xml does not exist here
    results = []
    for folder in (tmp_path, copy.parent, REPO):
        monkeypatch.chdir(folder)
        r = run_episode(copy, get_planner("straight"), get_protocol("barn"), seed=0)
        results.append((r.outcome, r.time, r.world_sha256))
    assert len(set(results)) == 1


# -- fault scenarios -------------------------------------------------------------------------


def _run_job_or_die(job):
    """A pool worker's job that kills its own process in one episode, every time (a crash in
    native code, the OOM killer); module level, so the pool can send it to its workers."""
    from dynabarn.bench.jobs import run_job

    if job.world_id == 1 and job.spec.seed == 0:
        os.kill(os.getpid(), signal.SIGKILL)
    return run_job(job)


def _sweep_jobs(ids, trials=1, planner="straight", **kwargs):
    from dynabarn import bench, worldset
    from dynabarn.protocol import get_protocol

    worlds = worldset.world_set("dynabarn300", ids)
    return bench.make_jobs([(planner, {})], worlds, get_protocol("barn"), trials, **kwargs)


@pytest.mark.slow
def test_a_killed_worker_is_noticed_and_its_episodes_run_again(tmp_path, monkeypatch):
    """`kill -9` of a pool worker: the sweep neither hangs nor loses rows; the episodes of
    the dead pool run again, and one that kills its worker every time ends as a retry row."""
    from dynabarn import bench
    from dynabarn.bench import backends

    real_run_job = backends.run_job
    monkeypatch.setattr(backends, "run_job", _run_job_or_die)
    jobs = _sweep_jobs([0, 1, 2, 3], trials=2)
    report = bench.run_sweep(jobs, tmp_path / "out", n_workers=2)
    rows = {r["key"]: r for r in report.rows}
    assert len(rows) == len(jobs) == 8
    dead = [r for r in rows.values() if r["outcome"] == "error"]
    assert len(dead) == 1 and dead[0]["world_id"] == 1 and dead[0]["seed"] == 0 and dead[0]["retry"] is True
    assert "worker process died" in dead[0]["reason"]
    assert all(r["outcome"] in ("success", "collision") for r in rows.values() if r is not dead[0])
    # On resume only the retry row runs again (and now its worker survives).
    monkeypatch.setattr(backends, "run_job", real_run_job)
    again = bench.run_sweep(jobs, tmp_path / "out", n_workers=2)
    assert again.ran == 1 and again.skipped == 7
    assert all(r["outcome"] != "error" and not r.get("retry") for r in again.rows) and len(again.rows) == 8


def test_a_second_writer_is_refused_while_the_first_holds_the_folder(tmp_path):
    from dynabarn import bench

    out = tmp_path / "out"
    out_arg = ("--trials", "1", "--out", str(out))
    with bench.locked(out):
        proc = subprocess.run(
            [
                sys.executable,
                "-m",
                "dynabarn",
                "bench",
                "--planner",
                "straight",
                "--worlds",
                "0",
                "--trials",
                "1",
                *out_arg,
            ],
            capture_output=True,
            text=True,
            timeout=120,
        )
    assert proc.returncode == 2
    assert f"is being written by another dynabarn-bench or -demos (pid {os.getpid()})" in proc.stderr
    assert not (out / "results.jsonl").exists()
    # Released, the lock leaves nothing behind, and the folder can be written again.
    assert not (out / ".lock").exists()
    code, err = _call("bench", ["--planner", "straight", "--worlds", "0", *out_arg])
    assert code == 0, err
    assert (out / "results.jsonl").is_file() and not [p.name for p in out.iterdir() if p.name.startswith(".")]


def test_a_lock_whose_file_was_removed_meanwhile_is_taken_anew(tmp_path):
    """A writer that waited on a lock file its holder then removed must not think it holds
    the folder: it locks the file that is at the path now."""
    import fcntl

    from dynabarn import bench

    out = tmp_path / "out"
    out.mkdir()
    stale = os.open(out / ".lock", os.O_RDWR | os.O_CREAT)
    fcntl.flock(stale, fcntl.LOCK_EX)
    (out / ".lock").unlink()  # as a finishing holder does, still holding it
    with bench.locked(out):  # not refused: the removed file's lock guards nothing
        assert (out / ".lock").is_file()
        assert os.stat(out / ".lock").st_ino != os.fstat(stale).st_ino
    os.close(stale)
    assert not (out / ".lock").exists()


def test_duplicate_jobs_run_once(tmp_path):
    from dynabarn import bench

    jobs = _sweep_jobs([0]) * 3
    report = bench.run_sweep(jobs, tmp_path / "out")
    assert report.ran == 1 and len(report.rows) == 1
    code, err = _call(
        "bench", ["--planner", "straight,straight", "--worlds", "0,0,0", "--trials", "1", "--out", str(tmp_path / "o2")]
    )
    assert code == 0, err
    assert len((tmp_path / "o2" / "results.jsonl").read_text().splitlines()) == 1


def test_a_crash_during_the_resume_rewrite_loses_nothing(tmp_path, monkeypatch):
    """Resuming rewrites results.jsonl (dropping a torn line) through a temporary file: a
    crash before the rename leaves the old file whole."""
    from dynabarn import bench
    from dynabarn.bench.results import prepare_resume

    out = tmp_path / "out"
    report = bench.run_sweep(_sweep_jobs([0, 1, 2]), out)
    path = out / "results.jsonl"
    with path.open("a") as f:
        f.write('{"key": "torn')  # a kill mid-write
    f.close()
    before = path.read_bytes()

    def crash(*args):
        raise KeyboardInterrupt  # the process dies between writing and renaming

    monkeypatch.setattr("dynabarn.files.os.replace", crash)
    with pytest.raises(KeyboardInterrupt):
        prepare_resume(path)
    assert path.read_bytes() == before and [p.name for p in out.iterdir() if ".part" in p.name] == []
    monkeypatch.undo()
    rows = prepare_resume(path)
    assert [r["key"] for r in rows] == [r["key"] for r in report.rows]
    assert path.read_text().count("\n") == 3 and "torn" not in path.read_text()


def test_foreign_lines_in_results_are_skipped(tmp_path):
    from dynabarn import bench

    out = tmp_path / "out"
    out.mkdir()
    (out / "results.jsonl").write_text('{}\nnull\n[1]\n"text"\n{"key": 5}\n')
    report = bench.run_sweep(_sweep_jobs([0]), out)
    assert report.ran == 1 and len(report.rows) == 1


@pytest.fixture
def small_disk(tmp_path):
    """A 16 MB tmpfs (root only; skipped where mounting is not allowed)."""
    mnt = tmp_path / "disk"
    mnt.mkdir()
    if os.geteuid() != 0 or subprocess.run(["mount", "-t", "tmpfs", "-o", "size=16m", "tmpfs", str(mnt)]).returncode:
        pytest.skip("needs root to mount a small tmpfs")
    yield mnt
    subprocess.run(["umount", "-l", str(mnt)], check=False)


def _fill(disk: Path, leave: int) -> Path:
    """Fill the disk but for `leave` bytes; returns the filler file."""
    filler = disk / "filler"
    st = os.statvfs(disk)
    free = st.f_bavail * st.f_frsize
    with filler.open("ab") as f:
        f.write(b"\0" * max(0, free - leave))
    return filler


def test_full_disk_while_recording_keeps_the_result_and_a_readable_recording(small_disk):
    from dynabarn.recording import read_recording
    from dynabarn.recording.writer import CHUNK_SIZE, SPACE_RESERVE

    _fill(small_disk, SPACE_RESERVE + 2 * CHUNK_SIZE + 200_000)  # room for about 200 kB of recording
    log = small_disk / "r.mcap"
    proc = subprocess.run(
        [sys.executable, "-m", "dynabarn", "run", "--world", "137", "--planner", "dwa", "--log", str(log)],
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert proc.returncode == 0, proc.stderr
    assert "SUCCESS in 14.27 s" in proc.stdout  # the episode ran to its end
    assert "the disk was nearly full" in proc.stderr and proc.stderr.count("\n") == 1
    rec = read_recording(log)
    assert not rec.truncated and 0 < len(rec.topic("/scan")) < 143


def test_full_disk_in_a_sweep_loses_no_row_and_resumes(small_disk):
    """Results on a full disk: one line, exit 2, the rows written stay; recordings cut by a
    nearly full disk are rows to run again; after freeing space the same command finishes."""
    out = small_disk / "out"
    argv = ["--planner", "straight", "--worlds", "0-5", "--trials", "1", "--jobs", "1", "--record", "all"]
    argv += ["--out", str(out)]
    code, err = _call("bench", argv)  # metadata and the first rows fit
    assert code == 0, err
    first = (out / "results.jsonl").read_text()
    assert first.count("\n") == 6
    (out / "results.jsonl").write_text(first.splitlines(keepends=True)[0])  # 5 episodes to run again
    filler = _fill(small_disk, 0)  # now nothing fits
    code, err = _call("bench", argv)
    assert code == 2 and "No space left on device" in err and err.count("\n") == 1, err
    assert (out / "results.jsonl").read_text() == first.splitlines(keepends=True)[0]  # the finished row stays
    assert not list((out / "recordings").glob("*.part"))
    filler.unlink()
    code, err = _call("bench", argv)
    assert code == 0, err
    rows = [json.loads(line) for line in (out / "results.jsonl").read_text().splitlines()]
    assert len(rows) == 6 and "error" not in {r["outcome"] for r in rows} and not any(r.get("retry") for r in rows)
    assert rows[0] == json.loads(first.splitlines()[0])  # the row finished before the full disk, untouched


@pytest.mark.parametrize(
    "reference",
    [
        "<model file='{robot}' name='jackal'/>",  # another attribute order, single quotes
        '<model name="jackal" file="{robot}" />',  # a space before />
        '<model\n  name="jackal"\n  file="{robot}"></model>',
        '<model name="jackal" file="/etc/passwd"/>',
    ],
    ids=["reordered", "spaced", "split", "etc-passwd"],
)
def test_the_jackal_reference_takes_the_packages_robot_however_it_is_spelled(reference, tmp_path):
    """The check works on the parsed document and MuJoCo compiles that document: a robot
    file named by the world is never read, however the reference is written."""
    from dynabarn.mjcf import load_model
    from dynabarn.robot import JACKAL_XML

    smuggled = tmp_path / "smuggled.xml"  # a Jackal with one more geom, beside the world
    smuggled.write_text(
        JACKAL_XML.read_text().replace(
            "<body name=", '<body name="holder"><geom name="SMUGGLED" size="0.1"/></body><body name=', 1
        )
    )
    text = WORLD.read_text()
    original = '<model name="jackal" file="../assets/jackal/jackal.xml"/>'
    assert original in text
    world = tmp_path / "world.xml"
    world.write_text(text.replace(original, reference.format(robot=smuggled.name)))
    model = load_model(world)
    names = {model.geom(i).name for i in range(model.ngeom)}
    assert not any("SMUGGLED" in n for n in names)
    assert model.nsensor == 720 and "jackal/laser" in {model.site(i).name for i in range(model.nsite)}


def _wait_for(condition, timeout: float = 60.0) -> bool:
    deadline = time.monotonic() + timeout
    while not condition():
        if time.monotonic() > deadline:
            return False
        time.sleep(0.1)
    return True


def test_sigterm_ends_a_run_as_ctrl_c_does_with_its_recording_whole(tmp_path):
    """SIGTERM: the episode is judged as interrupted, the recording closed whole, one line,
    exit 143; a finished recording already at its name is never replaced by an interrupted
    one: that is kept beside it (NAME.interrupted.mcap)."""
    from dynabarn.recording import read_recording

    log = tmp_path / "keep.mcap"
    log.write_bytes(b"an earlier, finished recording")
    proc = subprocess.Popen(
        [
            sys.executable,
            "-m",
            "dynabarn",
            "run",
            "--world",
            "0",
            "--planner",
            "stop",
            "--log",
            str(log),
            *("--live", "foxglove", "--port", "0", "--wait", "0", "--rate", "1"),  # paced: 100 s of episode
        ],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    part = tmp_path / "keep.mcap.part"
    assert _wait_for(lambda: part.is_file() and part.stat().st_size > 0), "the recording never started"
    time.sleep(1.0)  # paced at real time: a second of episode
    assert log.read_bytes() == b"an earlier, finished recording"  # untouched while the new one runs
    proc.send_signal(signal.SIGTERM)
    _, err = proc.communicate(timeout=60)
    assert proc.returncode == 143, (proc.returncode, err)
    kept = tmp_path / "keep.interrupted.mcap"
    assert err.strip().splitlines()[-1] == f"terminated; recording kept: {kept}", err  # after Foxglove's address
    assert log.read_bytes() == b"an earlier, finished recording"
    rec = read_recording(kept)
    assert not rec.truncated and rec.result["outcome"] == "error" and rec.result["reason"] == "interrupted"
    assert not part.exists()


def test_a_killed_sweep_takes_its_workers_with_it(tmp_path):
    """SIGKILL to dynabarn-bench: its pool workers end too (they held the results folder's
    lock and the caller's pipe), and the same command then runs and finishes."""
    from tests.conftest import cmdline, processes_carrying, tagged_environment

    out = tmp_path / "sweep"
    argv = [sys.executable, "-m", "dynabarn", "bench", "--planner", "stop", "--worlds", "0-19", "--trials", "2"]
    argv += ["--jobs", "2", "--no-floor", "--out", str(out)]
    token, env = tagged_environment()
    proc = subprocess.Popen(argv, env=env, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    results = out / "results.jsonl"
    assert _wait_for(lambda: results.is_file() and results.read_text().count("\n") >= 2), "no episode finished"
    assert len(processes_carrying(token)) >= 3  # the sweep and its two workers
    proc.kill()
    proc.wait()
    assert _wait_for(lambda: not processes_carrying(token), 30), [cmdline(p) for p in processes_carrying(token)]
    again = subprocess.run(argv, env=env, capture_output=True, text=True, timeout=600)
    assert again.returncode == 0, again.stderr
    assert results.read_text().count("\n") == 40 and not (out / ".lock").exists()


@pytest.mark.parametrize(
    "command, argv, verb",
    [
        ("replay", ["{bad}/rec_corrupt.mcap", "--save", "{out}/x.rrd"], "replaying"),
        ("render", ["{bad}/rec_corrupt.mcap", "--video", "{out}/v.gif", "--size", "64x48", "--fps", "1"], "rendering"),
        ("demos", ["export", "{bad}/rec_corrupt.mcap", "--dataset", "{out}/d.npz", "--all"], "exporting"),
    ],
    ids=["replay", "render", "demos-export"],
)
def test_a_corrupted_chunk_is_read_up_to_the_corruption_with_a_warning(command, argv, verb, bad_files, tmp_path):
    """zstd's error on a broken chunk was a traceback: now the file is cut there, as a
    killed recording is, and every reader says so in one line."""
    argv = [a.replace("{bad}", str(bad_files)).replace("{out}", str(tmp_path)) for a in argv]
    code, err = _call(command, argv)
    assert code == 0, err
    lines = [line for line in err.splitlines() if line.strip() and not line.startswith("\r")]
    assert len(lines) == 1 and "is truncated (ZstdError" in lines[0] and f"{verb} up to the cut" in lines[0], err


def test_a_policy_whose_pickle_runs_a_command_is_refused_and_runs_nothing(bad_files):
    require("torch", "learn")
    code, err = _call("run", ["--world", "0", "--no-log", "--planner", "bc", "--policy", str(bad_files / "evil.pt")])
    assert code == 2 and err.count("\n") == 1 and "not a loadable policy" in err, err
    assert not (bad_files / "EVIL_RAN").exists()
