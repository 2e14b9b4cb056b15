"""Foxglove-native recordings: every message decodes with foxglove-sdk's own schema classes,
every JSON message validates against its channel's JSON Schema, the frame tree places the
scan where the world's surfaces are, plans are line strips, the MCAP metadata records and
the attached world file let `dynabarn-render` and `dynabarn-replay` work from the file alone."""

import itertools
import json
import math
import shutil
import subprocess
import sys

import numpy as np
import pytest
from foxglove import messages as fm
from mcap.reader import make_reader
from mcap.records import Schema
from mcap_protobuf.decoder import DecoderFactory

from dynabarn.planners import get_planner
from dynabarn.protocol import get_protocol
from dynabarn.recording import McapRecorder, read_recording, returns
from dynabarn.recording.layout import LAYOUT_FILE, layout_json, referenced_topics
from dynabarn.recording.topics import FRAMES, TOPICS
from dynabarn.sim import run_episode
from dynabarn.worldset import resolve_world
from tests.conftest import require

BARN = get_protocol("barn")
SDK_TYPES = {f"foxglove.{name}": getattr(fm, name) for name in ("LaserScan", "PoseInFrame", "SceneUpdate")}
SDK_TYPES["foxglove.FrameTransforms"] = fm.FrameTransforms


@pytest.fixture(scope="module")
def dwa_recording(tmp_path_factory):
    folder = tmp_path_factory.mktemp("fox")
    world = folder / "world_000.xml"
    shutil.copy(resolve_world(0), world)
    path = folder / "dwa.mcap"
    result = run_episode(world, get_planner("dwa"), BARN, seed=1, observers=[McapRecorder(path)])
    return path, result, world


@pytest.fixture(scope="module")
def predictive_recording(tmp_path_factory):
    """A planner with a tracker: the tracks topics too."""
    path = tmp_path_factory.mktemp("fox") / "predictive.mcap"
    run_episode(resolve_world(0), get_planner("predictive"), BARN, seed=1, observers=[McapRecorder(path)])
    return path


def _sdk_decoder(schema_name: str):
    s = SDK_TYPES[schema_name].get_schema()
    return DecoderFactory().decoder_for("protobuf", Schema(id=1, name=s.name, encoding=s.encoding, data=s.data))


def test_every_message_decodes_with_foxglove_schemas_and_json_schemas(dwa_recording, predictive_recording):
    jsonschema = require("jsonschema", "test")
    decoders = {name: _sdk_decoder(name) for name in SDK_TYPES}
    counts: dict[str, int] = {}
    for path in (dwa_recording[0], predictive_recording):
        _check_messages(path, decoders, counts, jsonschema)
    assert set(counts) == {t.name for t in TOPICS}


def _check_messages(path, decoders, counts, jsonschema) -> None:
    with path.open("rb") as f:
        reader = make_reader(f)
        for schema, channel, message in reader.iter_messages():
            counts[channel.topic] = counts.get(channel.topic, 0) + 1
            if channel.message_encoding == "protobuf":
                sdk = SDK_TYPES[schema.name].get_schema()
                assert schema.data == sdk.data, f"{channel.topic}: not foxglove-sdk's schema"
                decoders[schema.name](message.data)  # raises on anything malformed
            else:
                assert channel.message_encoding == "json" and schema.encoding == "jsonschema"
                doc = json.loads(schema.data)
                assert doc.get("title") == schema.name and doc.get("properties"), f"{channel.topic}: a placeholder"
                jsonschema.Draft202012Validator.check_schema(doc)  # a valid schema itself
                jsonschema.Draft202012Validator(doc).validate(json.loads(message.data))


def test_the_frame_tree_is_complete_at_every_time_and_places_the_scan(dwa_recording):
    rec = read_recording(dwa_recording[0])
    tf = rec.topic("/tf")
    poses = rec.topic("/robot/pose")
    assert len(tf) == len(poses)
    chain = list(itertools.pairwise(FRAMES))
    for (t, m), (_, p) in zip(tf, poses, strict=True):
        assert [(x.parent_frame_id, x.child_frame_id) for x in m.transforms] == chain
        assert all(x.timestamp.seconds + x.timestamp.nanos * 1e-9 == pytest.approx(t, abs=1e-9) for x in m.transforms)
        robot = m.transforms[1]
        assert (robot.translation.x, robot.translation.y) == (p.pose.position.x, p.pose.position.y)
    tf_times = np.array([t for t, _ in tf])
    scans = rec.topic("/scan")
    # Every scan is covered by a transform at its own time (the tree is never stale).
    assert all(s.frame_id == "laser" for _, s in scans)
    assert np.isin(np.round([t for t, _ in scans], 9), np.round(tf_times, 9)).all()

    # Placed by the tree, the scan's returns lie on the world's surfaces: walls and
    # obstacles (the obstacles where the same tick's update puts them).
    meta = rec.metadata
    offset = meta["robot"]["laser_offset"]
    walls = np.array([[*w["centre"], *w["size"][:2]] for w in meta["world"]["layout"]["walls"]])
    radii = np.array([o["radius"] for o in meta["world"]["obstacles"]])
    tf_at = {round(t, 9): m for t, m in tf}
    obstacles = {round(t, 9): m for t, m in rec.topic("/world/obstacles")}
    gaps = []
    for t, s in scans[::5]:
        robot = tf_at[round(t, 9)].transforms[1]
        yaw = 2 * math.atan2(robot.rotation.z, robot.rotation.w)
        lx = robot.translation.x + math.cos(yaw) * offset[0]
        ly = robot.translation.y + math.sin(yaw) * offset[0]
        r = np.asarray(s.ranges)
        a = np.linspace(s.start_angle, s.end_angle, len(r)) + yaw
        hit = returns(r, meta["robot"]["laser_range"][1])
        pts = np.column_stack([lx + r[hit] * np.cos(a[hit]), ly + r[hit] * np.sin(a[hit])])
        centres = np.array(
            [[c.pose.position.x, c.pose.position.y] for c in obstacles[round(t, 9)].entities[0].cylinders]
        )
        to_obstacles = np.abs(np.hypot(*(pts[:, None] - centres[None]).transpose(2, 0, 1)) - radii).min(axis=1)
        d = np.abs(pts[:, None] - walls[None, :, :2]) - walls[None, :, 2:] / 2
        to_walls = np.abs(np.where((d > 0).any(axis=2), np.hypot(*np.maximum(d, 0).transpose(2, 0, 1)), d.max(axis=2)))
        gaps.append(np.minimum(to_obstacles, to_walls.min(axis=1)))
    gaps = np.concatenate(gaps)
    assert len(gaps) > 1000
    assert np.median(gaps) < 0.02 and np.quantile(gaps, 0.99) < 0.1, "the scan is not where /tf puts the laser"


def test_plans_are_line_strips(dwa_recording):
    path, result, _ = dwa_recording
    rec = read_recording(path)
    plans = rec.topic("/planner/plans")
    assert len(plans) == result.n_ticks
    debug = dict(rec.topic("/planner/debug"))
    drawn = 0
    for t, update in plans:
        entities = {e.id: e for e in update.entities}
        assert set(entities) == {"local_plan", "global_plan"} and all(e.frame_id == "world" for e in update.entities)
        for key, entity in entities.items():
            if key in debug[t]:
                points = [(p.x, p.y) for p in entity.lines[0].points]
                assert points == [tuple(p[:2]) for p in debug[t][key]]
                drawn += 1
    assert drawn > result.n_ticks  # both plans on most ticks


def test_metadata_records_and_the_attached_world(dwa_recording):
    path, result, world = dwa_recording
    with path.open("rb") as f:
        reader = make_reader(f)
        records = {m.name: m.metadata for m in reader.iter_metadata()}
        attachments = {a.name: a for a in reader.iter_attachments()}
    assert set(records) == {"dynabarn.episode", "dynabarn.result", "dynabarn.machine"}
    episode, outcome = records["dynabarn.episode"], records["dynabarn.result"]
    assert episode["world"] == "world_000" and episode["planner"] == "dwa" and episode["seed"] == "1"
    assert episode["protocol"] == "barn" and "mujoco" in json.loads(episode["versions"])
    assert outcome["outcome"] == result.outcome.value and float(outcome["time"]) == pytest.approx(result.time)
    assert "rtf" not in outcome and "wall_time" not in outcome
    attached = attachments["world_000.xml"]
    assert attached.data == world.read_bytes() and attached.media_type == "application/vnd.mujoco.mjcf+xml"


def test_render_and_replay_work_from_the_recording_alone(dwa_recording, tmp_path):
    path, _, world = dwa_recording
    alone = tmp_path / "alone"
    alone.mkdir()
    shutil.copy(path, alone / "run.mcap")
    bin_dir = f"{sys.prefix}/bin"
    env_free_of_project = {"PATH": bin_dir, "HOME": str(tmp_path), "MUJOCO_GL": "egl"}
    # The world file the episode ran in is not beside the recording; the attachment is.
    assert not (alone / world.name).exists()
    out = subprocess.run(
        [f"{bin_dir}/dynabarn-render", "run.mcap", "--video", "run.gif", "--fps", "2", "--size", "160x120"],
        cwd=alone, env=env_free_of_project, capture_output=True, text=True, timeout=300,
    )  # fmt: skip
    assert out.returncode == 0, out.stderr
    assert (alone / "run.gif").stat().st_size > 1000
    out = subprocess.run(
        [f"{bin_dir}/dynabarn-replay", "run.mcap", "--save", "run.rrd"],
        cwd=alone, env=env_free_of_project, capture_output=True, text=True, timeout=300,
    )  # fmt: skip
    assert out.returncode == 0, out.stderr
    assert (alone / "run.rrd").stat().st_size > 10_000


def test_a_tampered_world_attachment_is_refused(dwa_recording):
    from dynabarn.errors import DynabarnError
    from dynabarn.recording import recorded_world

    rec = read_recording(dwa_recording[0])
    assert recorded_world(rec).name == "world_000"
    name = next(iter(rec.attachments))
    rec.attachments[name] = rec.attachments[name].replace(b"world_000", b"world_001")
    with pytest.raises(DynabarnError, match="does not match"):
        recorded_world(rec)


def test_the_shipped_foxglove_layout_is_current_and_names_recorded_topics():
    shipped = LAYOUT_FILE.read_text()
    regenerate = "python -m dynabarn.recording.layout --out assets/foxglove/dynabarn.json"
    assert shipped == layout_json(), f"regenerate it: {regenerate}"
    layout = json.loads(shipped)
    names = referenced_topics(layout)
    assert {"/scan", "/world/obstacles", "/planner/plans", "/episode/result", "/cmd_vel"} <= names
    assert names <= {t.name for t in TOPICS}
    assert '"followTf": "base_link"' in shipped
