"""Demonstration datasets: recordings -> the paper's behaviour-cloning state and action.

`export` reads MCAP recordings (human teleoperation, oracle or any planner) and writes one
row per control tick: the state of the paper's BC policy (Sec. IV-b) - the 720 laser
ranges and the local goal (g_x, g_y) in the robot frame, taken `lookahead` metres along
the Dijkstra global plan on the static map - and the action (v, w) the robot was sent.
Rows carry their episode, world and time; episodes carry their outcome, source (human,
oracle, planner) and operator. Only successful episodes by default.

The dataset is one `.npz` (numpy, no pickle):

| array | shape | dtype | meaning |
|---|---|---|---|
| scans | (N, 720) | float32 | laser ranges [m] |
| local_goal | (N, 2) | float32 | (g_x, g_y) in the robot frame [m] |
| actions | (N, 2) | float32 | (v [m/s], w [rad/s]) sent to the robot |
| time | (N,) | float64 | simulated time of the tick [s] |
| episode | (N,) | int32 | index into the episode arrays |
| episode_world, episode_source, episode_outcome, episode_operator, episode_file | (E,) | str | per episode |
| episode_world_id, episode_seed | (E,) | int32 | per episode |
| metadata | () | str | JSON: format, lookahead, counts, version |
"""

from __future__ import annotations

import json
import sys
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from dynabarn.errors import DynabarnError
from dynabarn.files import save_atomically
from dynabarn.planners.global_planner import GlobalPlanner
from dynabarn.recording import CMD, SCAN, Recording, read_recording, scan_lasers
from dynabarn.robot import JACKAL, mounted_pose, to_robot_frame

DATASET_FORMAT = "dynabarn-demos-v1"
DEFAULT_LOOKAHEAD = 2.0


@dataclass
class DemoEpisode:
    file: str
    world: str
    world_id: int
    seed: int
    source: str
    outcome: str
    operator: str
    scans: np.ndarray
    local_goal: np.ndarray
    actions: np.ndarray
    time: np.ndarray


def find_recordings(inputs: list[Path]) -> list[Path]:
    files: list[Path] = []
    for p in inputs:
        if p.is_dir():
            files.extend(sorted(p.glob("*.mcap")))
        elif p.is_file():
            files.append(p)
        else:
            raise DynabarnError(f"no such recording or folder: {p}")
    if not files:
        raise DynabarnError("no .mcap recordings found in " + ", ".join(map(str, inputs)))
    return files


def episode_rows(rec: Recording, *, lookahead: float = DEFAULT_LOOKAHEAD) -> DemoEpisode:
    """The BC rows of one recording, one per control tick with both a scan and a command."""
    meta = rec.metadata
    if not meta:
        raise DynabarnError(f"{rec.path}: not a dynabarn recording (no metadata)")
    layout = meta["world"]["layout"]
    walls = np.array([[w["centre"][0], w["centre"][1], w["size"][0], w["size"][1]] for w in layout["walls"]], float)
    goal = np.array(layout["goal"], dtype=float)
    planner = GlobalPlanner.for_robot(
        walls.reshape(-1, 4),
        goal,
        tuple(meta["robot"]["footprint"]),
        np.array(layout.get("cylinders", []), dtype=float).reshape(-1, 3),
    )
    offset = np.array(meta["robot"]["laser_offset"], dtype=float)
    cmds = {round(t, 6): m for t, m in rec.topic(CMD.name)}
    scans, goals, actions, times = [], [], [], []
    scan_msgs = rec.topic(SCAN.name)
    # The robot when each scan was cast: the laser's pose then, less its mounting.
    robot = mounted_pose(scan_lasers(rec)[1], -offset).tolist()
    for k, (t, scan) in enumerate(scan_msgs):
        cmd = cmds.get(round(t, 6))
        if cmd is None:
            continue  # the tick the recording was cut in
        x, y, yaw = robot[k]
        lg, _ = planner.local_goal(x, y, lookahead)
        goals.append(to_robot_frame(lg[None], np.array([x, y, yaw]))[0])
        scans.append(np.asarray(scan.ranges, dtype=np.float32))
        actions.append((cmd["v"], cmd["w"]))
        times.append(t)
    result = rec.result or {}
    world = meta["world"]
    return DemoEpisode(
        file=str(rec.path),
        world=world["name"],
        world_id=-1 if world.get("world_id") is None else int(world["world_id"]),
        seed=int(meta.get("seed", 0)),
        source=str(meta.get("source", "planner")),
        outcome=str(result.get("outcome", "unfinished")),
        operator=str(meta.get("operator", "")),
        scans=np.array(scans, dtype=np.float32).reshape(-1, len(scans[0]) if scans else 720),
        local_goal=np.array(goals, dtype=np.float32).reshape(-1, 2),
        actions=np.array(actions, dtype=np.float32).reshape(-1, 2),
        time=np.array(times, dtype=np.float64),
    )


def export(
    inputs: list[Path], out: Path, *, include_all: bool = False, lookahead: float = DEFAULT_LOOKAHEAD, progress=None
) -> dict:
    """Write the dataset; returns a summary (episodes kept and skipped, rows)."""
    files = find_recordings(inputs)
    episodes: list[DemoEpisode] = []
    skipped: list[tuple[str, str]] = []
    for f in progress(files) if progress else files:
        rec = read_recording(f)
        if rec.truncated:  # as replay and render say it: the rows end at the cut
            print(f"warning: {f} is truncated ({rec.error}); exporting up to the cut", file=sys.stderr)
        ep = episode_rows(rec, lookahead=lookahead)
        if not include_all and ep.outcome != "success":
            skipped.append((f.name, ep.outcome))
            continue
        if len(ep.time):
            episodes.append(ep)
    if not episodes:
        raise DynabarnError(f"no episodes to export ({len(skipped)} skipped as unsuccessful; --all keeps them)")
    n = [len(e.time) for e in episodes]
    meta = {
        "format": DATASET_FORMAT,
        "lookahead": lookahead,
        "episodes": len(episodes),
        "rows": int(sum(n)),
        "skipped": skipped,
        "state": "720 laser ranges + local goal (g_x, g_y) in the robot frame (paper Sec. IV-b)",
        "action": "(v [m/s], w [rad/s]) sent to the robot",
    }
    out.parent.mkdir(parents=True, exist_ok=True)
    arrays = dict(
        scans=np.concatenate([e.scans for e in episodes]),
        local_goal=np.concatenate([e.local_goal for e in episodes]),
        actions=np.concatenate([e.actions for e in episodes]),
        time=np.concatenate([e.time for e in episodes]),
        episode=np.repeat(np.arange(len(episodes), dtype=np.int32), n),
        episode_world=np.array([e.world for e in episodes]),
        episode_world_id=np.array([e.world_id for e in episodes], dtype=np.int32),
        episode_seed=np.array([e.seed for e in episodes], dtype=np.int32),
        episode_source=np.array([e.source for e in episodes]),
        episode_outcome=np.array([e.outcome for e in episodes]),
        episode_operator=np.array([e.operator for e in episodes]),
        episode_file=np.array([Path(e.file).name for e in episodes]),
        metadata=np.array(json.dumps(meta)),
    )
    save_atomically(out, lambda f: np.savez_compressed(f, **arrays))
    return meta


def load_dataset(path: Path) -> dict[str, np.ndarray]:
    """Read a dataset written by `export` (no pickle)."""
    try:
        with np.load(path, allow_pickle=False) as z:
            data = {k: z[k] for k in z.files}
    except (OSError, ValueError, EOFError) as exc:
        raise DynabarnError(f"{path}: not a readable dataset ({exc})") from None
    try:
        meta = json.loads(str(data.get("metadata", "{}")))
    except (ValueError, RecursionError):
        meta = None
    if not isinstance(meta, dict) or meta.get("format") != DATASET_FORMAT:
        raise DynabarnError(f"{path}: not a {DATASET_FORMAT} dataset")
    lookahead = meta.get("lookahead")
    if isinstance(lookahead, bool) or not isinstance(lookahead, int | float) or not 0 < lookahead < 100:
        raise DynabarnError(f"{path}: the dataset's metadata has no usable lookahead ({lookahead!r})")
    _check_arrays(path, data)
    return data


N_BEAMS = JACKAL.laser_beams


def _check_arrays(path: Path, data: dict[str, np.ndarray]) -> None:
    """The training arrays as `export` writes them: shapes that agree, numbers, finite."""
    shapes = {"scans": 2, "local_goal": 2, "actions": 2}
    for name, ndim in shapes.items():
        a = data.get(name)
        if a is None or a.ndim != ndim or a.dtype.kind not in "fiu":
            raise DynabarnError(f"{path}: {name} is missing or not a {ndim}-d array of numbers")
        if not np.isfinite(a).all():
            raise DynabarnError(f"{path}: {name} holds NaN or infinite values")
    n, width = data["scans"].shape
    if width != N_BEAMS:
        raise DynabarnError(f"{path}: scans have {width} ranges per row, not the laser's {N_BEAMS}")
    if n == 0:
        raise DynabarnError(f"{path}: the dataset has no rows")
    if data["local_goal"].shape != (n, 2) or data["actions"].shape != (n, 2):
        raise DynabarnError(
            f"{path}: scans, local_goal and actions must have one row each per tick, (n, 2) for the last two"
        )
