"""What every frame of a video shows, computed for all frames at once from a recording:
robot poses, obstacle positions and trails, the last scan's returns in the world, speeds.

A recording holds everything needed: the world (attached file or metadata and keyframes),
the obstacles' clock offset, the robot's 50 Hz poses, the 10 Hz scans and metrics. The
obstacles are replayed from their schedules at each frame time (exact, not interpolated
from the 10 Hz updates) unless they react to the robot; the robot is put at its recorded
pose (interpolated between the 50 Hz poses).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from dynabarn.errors import DynabarnError
from dynabarn.recording import (
    METRICS,
    SCAN,
    Recording,
    obstacle_track,
    pose_track,
    returns_in_world,
    scan_lasers,
)
from dynabarn.worlds.schedule import SchedulePlayer
from dynabarn.worlds.spec import WorldSpec

TRAIL_SECONDS = 2.0
TRAIL_STEP = 0.25
"""Obstacle trails: where each obstacle was over the last 2 s, every 0.25 s."""
SCAN_STRIDE = 2
"""One return in two is drawn (360 dots at 0.375 degree spacing)."""


@dataclass(frozen=True, slots=True)
class FrameTracks:
    """Per-frame arrays (K frames)."""

    times: np.ndarray  # (K,) [s]
    robot: np.ndarray  # (K, 3) x, y, yaw
    obstacles: np.ndarray  # (K, n, 2)
    trails: np.ndarray  # (K, steps, n, 2), oldest first
    speed: np.ndarray  # (K,) measured forward speed [m/s] at the last control tick
    scan_index: np.ndarray  # (K,) the last scan at or before each frame (-1: none yet)
    scan_points: list[np.ndarray]  # per scan, (m, 2) returns in the world


def _interpolate(t: np.ndarray, xy: np.ndarray, at: np.ndarray) -> np.ndarray:
    """Recorded centres (T, n, 2) at times t, linearly interpolated to `at` (K,): (K, n, 2)."""
    if len(t) == 0:
        raise DynabarnError("the recording holds no obstacle updates")
    k = np.clip(np.searchsorted(t, at, side="right") - 1, 0, len(t) - 1)
    k1 = np.minimum(k + 1, len(t) - 1)
    span = np.where(k1 > k, t[k1] - t[k], 1.0)
    u = np.clip((at - t[k]) / span, 0.0, 1.0)[:, None, None]
    return xy[k] + (xy[k1] - xy[k]) * u


def _last_at_or_before(t: np.ndarray, at: np.ndarray) -> np.ndarray:
    return np.searchsorted(t, at + 1e-9, side="right") - 1


def scan_returns(rec: Recording) -> tuple[np.ndarray, list[np.ndarray]]:
    """Times (S,) of the scans and each scan's returns (m, 2) in the world, every
    SCAN_STRIDE-th beam, placed by the laser's pose as `/tf` gives it."""
    t, lasers = scan_lasers(rec)
    if not len(t):
        return t, []
    scans = rec.topic(SCAN.name)
    first = scans[0][1]
    ranges = np.array([np.asarray(m.ranges)[::SCAN_STRIDE] for _, m in scans])  # (S, B)
    angles = np.linspace(first.start_angle, first.end_angle, len(first.ranges))[::SCAN_STRIDE]
    range_max = ((rec.metadata or {}).get("robot", {}).get("laser_range") or [0.1, 30.0])[1]
    return t, returns_in_world(ranges, angles, lasers, range_max)


def frame_tracks(rec: Recording, world: WorldSpec, frame_times: np.ndarray) -> FrameTracks:
    """Everything the frames at `frame_times` draw."""
    t_pose, track = pose_track(rec)
    trail_steps = np.arange(-TRAIL_SECONDS, 1e-4, TRAIL_STEP)
    trail_times = np.clip(frame_times[:, None] + trail_steps, 0, None).ravel()
    if any(o.reactive for o in world.obstacles):
        # Reactive obstacles went where the robot made them go: play what was recorded.
        t_obs, xy_obs = obstacle_track(rec, world)
        obstacles, trails = _interpolate(t_obs, xy_obs, frame_times), _interpolate(t_obs, xy_obs, trail_times)
    else:  # scripted ones exactly, from their schedules
        player = SchedulePlayer(world, clock_offset=float((rec.metadata or {}).get("clock_offset", 0.0)))
        obstacles, _ = player.positions_at(frame_times)
        trails, _ = player.positions_at(trail_times)
    robot = np.column_stack([np.interp(frame_times, t_pose, track[:, k]) for k in range(3)])
    metrics = rec.topic(METRICS.name)
    if metrics:
        t_m = np.array([t for t, _ in metrics])
        v = np.array([m.get("v", 0.0) for _, m in metrics], dtype=np.float64)
        k = _last_at_or_before(t_m, frame_times)
        speed = np.where(k >= 0, v[np.maximum(k, 0)], 0.0)
    else:
        speed = np.zeros(len(frame_times))
    t_scan, points = scan_returns(rec)
    return FrameTracks(
        times=frame_times,
        robot=robot,
        obstacles=obstacles,
        trails=trails.reshape(len(frame_times), len(trail_steps), -1, 2),
        speed=speed,
        scan_index=_last_at_or_before(t_scan, frame_times) if len(t_scan) else np.full(len(frame_times), -1),
        scan_points=points,
    )
