"""MCAP recordings -> rerun: the scene, the scan, the path and the plots on `sim_time`.

Entity tree (one per recording; several recordings of one world go under
`runs/<label>/...` and share the walls):

| entity | archetype | when |
|---|---|---|
| world/walls, world/goal | Boxes3D, Cylinders3D | static |
| world/static_obstacles | Cylinders3D (static BARN or mixed worlds) | static |
| <run>/obstacles | Cylinders3D (one per cylinder obstacle) | every obstacle update |
| <run>/obstacle_boxes, <run>/obstacle_capsules | Boxes3D, Capsules3D (other shapes) | every obstacle update |
| <run>/robot | Transform3D (pose) + Boxes3D (footprint, static) | every pose |
| <run>/robot_path | LineStrips3D: the path so far (at most 400 vertices) | every control tick |
| <run>/scan | Points3D: laser returns in the world frame | every scan |
| <run>/scan_beams | LineStrips3D: one beam in four from the laser to its return | every scan |
| <run>/local_plan, <run>/global_plan | LineStrips3D | when the planner recorded them |
| <run>/tracks, <run>/track_velocities | LineStrips3D (circles), Arrows3D (1 s of motion) | each tick, if tracked |
| metrics/<field>/<run> | Scalars: the fields `recording.topics` plots (v, w, clearance, ...) | every control tick |
| description | TextDocument: world, planner, outcome | static |

Everything per-time is sent in bulk with `rr.send_columns`, one call per entity. rerun's
own `rerun mcap convert` leaves LaserScan as raw columns; this module does the mapping.
All `rr.` calls of the package live here, in `rerun_scene` (the entities themselves) and in
`live.rerun_live` (the same entities, tick by tick).
"""

from __future__ import annotations

import contextlib
import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import rerun as rr
import rerun.blueprint as rrb

from dynabarn.errors import DynabarnError
from dynabarn.files import staged_path
from dynabarn.recording import (
    CMD,
    DEBUG,
    POSE,
    SCAN,
    TRACKS,
    Recording,
    obstacle_track,
    recorded_world,
    returns_in_world,
    scan_lasers,
)
from dynabarn.recording.topic_registry import plotted
from dynabarn.rerun_scene import (
    TIMELINE,
    log_obstacles,
    log_robot_body,
    log_robot_poses,
    log_static_world,
    log_tracks,
    time_column,
)

APP_ID = "dynabarn_replay"
PATH_VERTICES = 400
BEAM_STRIDE = 4

COLORS = [(31, 119, 180), (255, 127, 14), (44, 160, 44), (148, 103, 189), (140, 86, 75), (227, 119, 194)]


@dataclass(frozen=True, slots=True)
class ReplayCounts:
    """How many rows of each stream were sent (to check against the MCAP)."""

    scans: int
    poses: int
    obstacle_updates: int
    ticks: int


def _times(msgs: list) -> np.ndarray:
    return np.array([t for t, _ in msgs], dtype=np.float64)


def _log_tracks(stream, run: str, rec: Recording) -> None:
    """The planner's tracks of a recording (`/perception/tracks`), every control tick."""
    msgs = rec.topic(TRACKS.name)
    if not msgs:
        return
    log_tracks(
        stream,
        run,
        _times(msgs),
        [len(m["ids"]) for _, m in msgs],
        np.array([xy for _, m in msgs for xy in m["positions"]], dtype=np.float64).reshape(-1, 2),
        np.array([r for _, m in msgs for r in m["sizes"]], dtype=np.float64),
        np.array([v for _, m in msgs for v in m["velocities"]], dtype=np.float64).reshape(-1, 2),
    )


# Over 80 lines on purpose: one short section per rerun entity (poses, scan, obstacles, path,
# plan, tracks, plots), each one batched send; apart, they would pass the same ten locals around.
def log_recording(
    rec: Recording, stream: rr.RecordingStream, *, run: str = "run", color_index: int = 0
) -> ReplayCounts:
    """Send one recording's time series under entity `run` (and `metrics/run`)."""
    meta = rec.metadata or {}
    color = COLORS[color_index % len(COLORS)]
    robot = meta.get("robot", {})
    length, width = robot.get("footprint", [0.508, 0.430])

    # Robot pose: Transform3D columns, footprint box static under it.
    poses = rec.topic(POSE.name)
    pt = _times(poses)
    pxy = np.array([[m.pose.position.x, m.pose.position.y] for _, m in poses]).reshape(-1, 2)
    pyaw = np.array([2.0 * math.atan2(m.pose.orientation.z, m.pose.orientation.w) for _, m in poses])
    if len(pt):
        log_robot_poses(stream, run, pt, pxy, pyaw)
    log_robot_body(stream, run, (length, width), color)

    # Scans: returns (not max-range) as points in the world, every fourth beam as a line.
    # The scan is in the `laser` frame, placed by the robot's pose and the laser's mounting
    # (recordings before /tf carried the laser's world pose in the scan itself).
    scans = rec.topic(SCAN.name)
    st, lasers = scan_lasers(rec)
    laser_z = robot.get("laser_z", 0.3)
    pts_all, beams_all, n_pts, n_beams = [], [], [], []
    if scans:
        first = scans[0][1]
        angles = np.linspace(first.start_angle, first.end_angle, len(first.ranges))
        ranges = np.array([np.asarray(m.ranges) for _, m in scans])
        hits = returns_in_world(ranges, angles, lasers, robot.get("laser_range", [0.1, 30.0])[1])
    for (ox, oy, _), xy in zip(lasers.tolist(), hits if scans else [], strict=True):
        pts_all.append(np.column_stack([xy, np.full(len(xy), laser_z)]))
        n_pts.append(len(xy))
        bxy = xy[::BEAM_STRIDE]
        origin = np.array([ox, oy, laser_z])
        beams_all.append(
            np.stack(
                [np.broadcast_to(origin, (len(bxy), 3)), np.column_stack([bxy, np.full(len(bxy), laser_z)])], axis=1
            )
        )
        n_beams.append(len(bxy))
    if len(st):
        stream.send_columns(
            f"{run}/scan",
            indexes=[time_column(st)],
            columns=rr.Points3D.columns(positions=np.concatenate(pts_all)).partition(n_pts),
        )
        strips = [b for per_scan in beams_all for b in per_scan]
        stream.send_columns(
            f"{run}/scan_beams",
            indexes=[time_column(st)],
            columns=rr.LineStrips3D.columns(strips=strips).partition(n_beams),
        )
        stream.log(f"{run}/scan", rr.Points3D.from_fields(colors=[color], radii=[0.04]), static=True)
        stream.log(f"{run}/scan_beams", rr.LineStrips3D.from_fields(colors=[(*color, 60)], radii=[0.005]), static=True)

    # Obstacles: one row per update, each shape kind as its archetype, sizes fixed.
    world = recorded_world(rec)
    ot, oxy = obstacle_track(rec, world)
    if len(ot):
        log_obstacles(stream, run, world, ot, oxy)

    # The path so far, at the control ticks, decimated to PATH_VERTICES.
    ticks = rec.topic(CMD.name)
    tt = _times(ticks)
    if len(tt) and len(pt):
        strips = []
        for t in tt:
            k = int(np.searchsorted(pt, t, side="right"))
            idx = np.unique(np.linspace(0, max(k - 1, 0), min(k, PATH_VERTICES)).astype(int))
            strips.append(np.column_stack([pxy[idx], np.full(len(idx), 0.02)]))
        stream.send_columns(
            f"{run}/robot_path", indexes=[time_column(tt)], columns=rr.LineStrips3D.columns(strips=strips)
        )
        stream.log(f"{run}/robot_path", rr.LineStrips3D.from_fields(colors=[color], radii=[0.03]), static=True)

    # Local and global plans, when the planner recorded them.
    for key, plan_color, z in (("local_plan", (250, 200, 0), 0.05), ("global_plan", (50, 115, 255), 0.03)):
        plans = [(t, m[key]) for t, m in rec.topic(DEBUG.name) if m.get(key)]
        if not plans:
            continue
        stream.send_columns(
            f"{run}/{key}",
            indexes=[time_column(np.array([t for t, _ in plans]))],
            columns=rr.LineStrips3D.columns(
                strips=[np.column_stack([np.asarray(p)[:, :2], np.full(len(p), z)]) for _, p in plans]
            ),
        )
        stream.log(f"{run}/{key}", rr.LineStrips3D.from_fields(colors=[plan_color], radii=[0.04]), static=True)

    _log_tracks(stream, run, rec)

    # Time series: every field the topic table marks for plotting.
    for topic, name in plotted():
        msgs = rec.topic(topic.name)
        if not msgs:
            continue
        values = np.array([np.nan if m.get(name) is None else m[name] for _, m in msgs], dtype=np.float64)
        stream.send_columns(
            f"metrics/{name}/{run}", indexes=[time_column(_times(msgs))], columns=rr.Scalars.columns(scalars=values)
        )
        stream.log(f"metrics/{name}/{run}", rr.SeriesLines(colors=[color], names=[f"{run} {name}"]), static=True)
    return ReplayCounts(scans=len(st), poses=len(pt), obstacle_updates=len(ot), ticks=len(tt))


def describe(recs: list[tuple[str, Recording]]) -> str:
    lines = ["# DynaBARN replay", ""]
    for run, rec in recs:
        meta, res = rec.metadata or {}, rec.result or {}
        outcome = res.get("outcome", "unfinished (truncated recording)")
        lines.append(
            f"- **{run}**: {meta.get('world', {}).get('name', '?')}, planner `{meta.get('planner', '?')}`, protocol "
            f"`{meta.get('protocol', {}).get('name', '?')}`, seed {meta.get('seed', '?')}: **{outcome}**"
            + (f" after {res['time']:.2f} s ({res.get('reason', '')})" if "time" in res else "")
        )
    return "\n".join(lines)


def blueprint(runs: list[str]) -> rrb.Blueprint:
    """Top-down 3D scene beside the scan and the plots."""
    plots = [rrb.TimeSeriesView(name=name, origin=f"/metrics/{name}") for _, name in plotted()]
    # Looking down on the arena from above its centre, +x to the right.
    top_down = rrb.EyeControls3D(position=[0.5, -6.0, 30.0], look_target=[0.5, 0.0, 0.0], eye_up=[0.0, 0.0, 1.0])
    scene = rrb.Spatial3DView(name="world", origin="/", eye_controls=top_down)
    scans = rrb.Spatial3DView(
        name="scan",
        origin="/",
        contents=[f"/{r}/scan/**" for r in runs] + [f"/{r}/robot/**" for r in runs],
        eye_controls=rrb.EyeControls3D(tracking_entity=f"/{runs[0]}/robot") if runs else None,
    )
    return rrb.Blueprint(
        rrb.Horizontal(
            rrb.Vertical(scene, rrb.TextDocumentView(origin="/description", name="episode"), row_shares=[4, 1]),
            rrb.Vertical(scans, rrb.Grid(*plots), row_shares=[2, 3]),
            column_shares=[3, 2],
        ),
        rrb.TimePanel(timeline=TIMELINE, state="collapsed", play_state="following"),
        collapse_panels=True,
    )


def run_label(rec: Recording, taken: set[str]) -> str:
    meta = rec.metadata or {}
    base = f"runs/{meta.get('planner', 'run')}_s{meta.get('seed', 0)}"
    label, k = base, 2
    while label in taken:
        label, k = f"{base}_{k}", k + 1
    return label


def build_stream(recs: list[Recording], stream: rr.RecordingStream) -> list[ReplayCounts]:
    """Log several recordings (of one world) into one stream; returns their counts."""
    labels: list[str] = []
    for rec in recs:
        labels.append(run_label(rec, set(labels)))
    if recs and recs[0].metadata:
        log_static_world(recs[0].metadata, stream)
    counts = [
        log_recording(rec, stream, run=label, color_index=i)
        for i, (label, rec) in enumerate(zip(labels, recs, strict=True))
    ]
    stream.log(
        "description",
        rr.TextDocument(describe(list(zip(labels, recs, strict=True))), media_type="text/markdown"),
        static=True,
    )
    stream.send_blueprint(blueprint(labels))
    return counts


def save_rrd(recs: list[Recording], path: Path) -> list[ReplayCounts]:
    """Write an .rrd file with the recordings and the blueprint: beside `path` first, renamed
    when complete, so an .rrd already there is replaced only by a whole one."""
    path = Path(path)
    if path.is_dir():
        raise DynabarnError(f"{path} is a folder, not an .rrd file")
    path.parent.mkdir(parents=True, exist_ok=True)
    stream = rr.RecordingStream(APP_ID, make_default=False, make_thread_default=False)
    with staged_path(path) as part:
        stream.save(str(part))
        try:
            counts = build_stream(recs, stream)
            stream.flush()
        except RuntimeError as exc:  # rerun's file writer stopped (a full disk): it says so only here
            with contextlib.suppress(Exception):
                stream.disconnect()
            first = (str(exc).strip().splitlines() or [type(exc).__name__])[0]
            raise DynabarnError(f"cannot write {path}: {first} (a full disk?)") from None
        stream.disconnect()
        if not part.stat().st_size:  # rerun's sink writes in its own thread and reports nothing
            raise DynabarnError(f"cannot write {path} (nothing was written; is the folder writable?)")
    return counts


def spawn_viewer(recs: list[Recording]) -> list[ReplayCounts]:
    """Start rerun's native viewer and stream the recordings to it."""
    stream = rr.RecordingStream(APP_ID, make_default=False, make_thread_default=False)
    stream.spawn()
    return build_stream(recs, stream)


def send_to(recs: list[Recording], url: str) -> list[ReplayCounts]:
    """Stream the recordings to a viewer that is already running (`rerun+http://...`)."""
    stream = rr.RecordingStream(APP_ID, make_default=False, make_thread_default=False)
    stream.connect_grpc(url)
    counts = build_stream(recs, stream)
    stream.flush()
    stream.disconnect()
    return counts
