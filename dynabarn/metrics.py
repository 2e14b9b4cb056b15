"""Episode metrics (docs/concepts/protocols.md).

All functions are vectorised over the whole episode and run once, after it ends.
"""

from __future__ import annotations

import enum
import math
from collections.abc import Callable
from dataclasses import asdict, dataclass, field

import numpy as np

STALL_SPEED = 0.05
"""Below this forward speed [m/s] (and yaw rate below 0.1 rad/s) the robot counts as stalled."""


class Outcome(enum.StrEnum):
    SUCCESS = "success"
    COLLISION = "collision"
    TIMEOUT = "timeout"
    ERROR = "error"


OUTCOMES = frozenset(o.value for o in Outcome)
"""The outcomes a result may hold, as written in results and recordings."""

INTERRUPTED = "interrupted"
"""The reason of an episode ended by Ctrl-C or SIGTERM (outcome `error`)."""
PLANNER_RAISED = "planner raised"
"""How the reason of an episode whose planner raised begins (outcome `error`)."""
NON_FINITE_COMMAND = "planner returned a non-finite command"
"""How the reason of an episode whose planner returned NaN or infinity begins (outcome `error`)."""


def is_interrupted(result) -> bool:
    """An episode a person or a signal ended, not one the robot or the planner did."""
    return result.outcome == Outcome.ERROR and result.reason == INTERRUPTED


def numbers_ok(result: dict) -> bool:
    """Whether the result's number fields that are present are numbers or null (a result
    read from a file the project did not write)."""
    values = (result[k] for k in RESULT_NUMBERS if k in result)
    return all(v is None or (isinstance(v, int | float) and not isinstance(v, bool)) for v in values)


OUTCOME_MESSAGES = {
    Outcome.SUCCESS: "reached the goal",
    Outcome.COLLISION: "collided",
    Outcome.TIMEOUT: "ran out of time",
    Outcome.ERROR: "stopped by an error",
}


OPTIONAL_FIELDS = ("tracking", "added_metrics")
"""`EpisodeResult` fields only some episodes have (a planner that tracks obstacles,
`Planner.tracks`; metrics added beyond the table, `metric_registry`): left out of `to_dict`
(and the JSON of a run, a results row, a recording) for the rest."""


def _json_number(v):
    """Floats rounded to 6 decimals, and null where no finite number exists (strict JSON)."""
    return (round(v, 6) if np.isfinite(v) else None) if isinstance(v, float) else v


@dataclass(slots=True)
class EpisodeResult:
    """Everything known about one finished episode (the JSON of `dynabarn-run --json`).

    Times in seconds, lengths in metres, compute times in milliseconds.
    """

    world: str
    planner: str
    protocol: str
    seed: int
    outcome: Outcome
    reason: str
    time: float
    """Episode time as the protocol counts it (barn: from the first 0.1 m of motion) [s]."""
    sim_time: float
    """Simulated time from the start to the end of the episode [s]."""
    path_length: float
    score: float
    spl: float
    min_clearance: float
    """Smallest distance between the robot's footprint and any obstacle's surface [m]."""
    mean_abs_jerk: float
    """Mean |d^3 x / dt^3| of the forward motion, from measured speed at the control rate [m/s^3]."""
    sum_abs_dw: float
    """Sum of |change| of the commanded yaw rate between control ticks [rad/s]."""
    time_stalled: float
    planner_ms_mean: float
    planner_ms_p95: float
    rtf: float
    """Real-time factor: simulated seconds per wall-clock second."""
    wall_time: float
    clock_offset: float
    n_ticks: int
    world_file: str = ""
    world_sha256: str = ""
    versions: dict = field(default_factory=dict)
    """Package versions that decide the result (the same under the lock)."""
    machine: dict = field(default_factory=dict)
    """CPU, SIMD targets, BLAS kernels and threads (`provenance.machine`)."""
    planner_config: dict = field(default_factory=dict)
    protocol_version: int = 1
    tracking: dict | None = None
    """How well the planner's tracker saw the obstacles (planners with `Planner.tracks`; left
    out of `to_dict` for the rest): recall, precision, position and velocity errors (median,
    95th percentile) [m, m/s], identity switches, ticks scored (`sim.track_scoring`)."""
    added_metrics: dict | None = None
    """The metrics added beyond the table (`metric_registry.METRIC_REGISTRY`: registered or
    installed), {name: value}; None (left out of `to_dict`) when none is."""

    @property
    def success(self) -> bool:
        return self.outcome is Outcome.SUCCESS

    def to_dict(self) -> dict:
        d = asdict(self)
        d["outcome"] = self.outcome.value
        for name in OPTIONAL_FIELDS:  # without a tracker or added metrics: the row as it always was
            if d[name] is None:
                del d[name]
            else:
                d[name] = {k: _json_number(v) for k, v in d[name].items()}
        # Strict JSON: a value with no finite number (min_clearance in a world without
        # obstacles, rtf of an instant episode) is null, never NaN or Infinity.
        return {k: _json_number(v) for k, v in d.items()}

    def summary(self) -> str:
        """The one-line human summary."""
        head = f"{self.world} | {self.planner} | {self.protocol} | seed {self.seed}: {self.outcome.value.upper()}"
        if self.outcome is Outcome.SUCCESS:
            body = f"in {self.time:.2f} s, score {self.score:.3f}, SPL {self.spl:.2f}"
        else:
            body = f"after {self.time:.2f} s ({self.reason})"
        line = (
            f"{head} {body}; path {self.path_length:.1f} m, min clearance {self.min_clearance:.2f} m, "
            f"planner {self.planner_ms_mean:.2f} ms, {self.rtf:.0f}x real time"
        )
        t = self.tracking
        if t and t.get("recall") is not None and t.get("position_error_median") is not None:
            line += (
                f"; tracking: recall {t['recall']:.2f}, position error {1000 * t['position_error_median']:.1f} mm "
                f"(p95 {1000 * t['position_error_p95']:.0f} mm), velocity error {t['velocity_error_median']:.2f} m/s, "
                f"{t['id_switches']} identity switches"
            )
        return line


def path_length(xy: np.ndarray) -> float:
    """Length of a polyline (n, 2) [m]."""
    if len(xy) < 2:
        return 0.0
    return float(np.hypot(*np.diff(xy, axis=0).T).sum())


def footprint_clearance(
    robot_pose: np.ndarray, obstacle_xy: np.ndarray, radii: np.ndarray, half_extents: tuple[float, float]
) -> np.ndarray:
    """Distance from a box footprint to circles, per pose: (T,) minimum over obstacles.

    Args:
        robot_pose: (T, 3) x, y, yaw.
        obstacle_xy: (T, n, 2) obstacle centres at the same times.
        radii: (n,) obstacle radii.
        half_extents: (half length, half width) of the footprint.
    """
    if obstacle_xy.shape[1] == 0:
        return np.full(len(robot_pose), np.inf)
    d = obstacle_xy - robot_pose[:, None, :2]
    c, s = np.cos(robot_pose[:, 2])[:, None], np.sin(robot_pose[:, 2])[:, None]
    local = np.stack([c * d[..., 0] + s * d[..., 1], -s * d[..., 0] + c * d[..., 1]], axis=-1)
    outside = np.maximum(np.abs(local) - np.asarray(half_extents), 0.0)
    dist = np.hypot(outside[..., 0], outside[..., 1]) - radii
    return dist.min(axis=1)


def footprint_clearance_at(
    x: float, y: float, yaw: float, obstacle_xy: np.ndarray, radii: np.ndarray, half_extents: tuple[float, float]
) -> float:
    """`footprint_clearance` for one pose (the per-tick case), on Python floats.

    A tick has a dozen obstacles: numpy's per-call cost made this the loop's largest item
    for observers (28 us in the loop, where caches are cold). Every step is the same IEEE
    operation numpy does, but for the distance: `math.hypot` may differ from numpy's
    (libm's) in the last bit, so it only finds the nearest obstacle, and the distance of
    every obstacle within 1e-9 m of it is taken again with `np.hypot`: the same bits as the
    array form (a test compares them)."""
    if obstacle_xy.shape[0] == 0:
        return math.inf
    c, s = math.cos(yaw), math.sin(yaw)
    hx, hy = half_extents
    parts = []
    best = math.inf
    for (px, py), r in zip(obstacle_xy.tolist(), radii.tolist(), strict=True):
        dx, dy = px - x, py - y
        ox = abs(c * dx + s * dy) - hx
        oy = abs(c * dy - s * dx) - hy
        ox, oy = (ox if ox > 0.0 else 0.0), (oy if oy > 0.0 else 0.0)
        d = math.hypot(ox, oy) - r
        parts.append((d, ox, oy, r))
        best = min(best, d)
    near = best + 1e-9
    return float(min(np.hypot(ox, oy) - r for d, ox, oy, r in parts if d <= near))


def shape_clearance(
    robot_pose: np.ndarray,
    obstacle_xy: np.ndarray,
    yaws: np.ndarray,
    core_half_extents: np.ndarray,
    radii: np.ndarray,
    half_extents: tuple[float, float],
) -> np.ndarray:
    """Distance from a box footprint to rounded rectangles (cylinders, boxes, capsules), per pose.

    Each obstacle is a core rectangle (half sizes `core_half_extents` along and across its
    yaw; zero for a cylinder, zero width for a capsule) grown by `radii`. Two convex
    polygons apart are nearest at a vertex of one of them, so the core distance is the
    smallest distance from either shape's corners to the other rectangle; overlapping
    cores (separating-axis test) count as distance 0. Equals `footprint_clearance` for
    cylinders (negative when overlapping).

    Args:
        robot_pose: (T, 3) x, y, yaw.
        obstacle_xy: (T, n, 2) obstacle centres.
        yaws: (n,) fixed obstacle yaws.
        core_half_extents: (n, 2) half sizes of the cores.
        radii: (n,) rounding radii.
        half_extents: (half length, half width) of the robot's footprint.
    Returns: (T,) minimum over obstacles.
    """
    if obstacle_xy.shape[1] == 0:
        return np.full(len(robot_pose), np.inf)
    signs = np.array([[1.0, 1.0], [1.0, -1.0], [-1.0, 1.0], [-1.0, -1.0]])
    rh = np.asarray(half_extents, dtype=np.float64)
    c, s = np.cos(robot_pose[:, 2]), np.sin(robot_pose[:, 2])  # (T,)
    co, so = np.cos(yaws), np.sin(yaws)  # (n,)
    # Obstacle core corners in the world: (T, n, 4, 2).
    loc = signs[None] * core_half_extents[:, None, :]  # (n, 4, 2)
    corner_o = obstacle_xy[:, :, None, :] + np.stack(
        [co[:, None] * loc[..., 0] - so[:, None] * loc[..., 1], so[:, None] * loc[..., 0] + co[:, None] * loc[..., 1]],
        axis=-1,
    )
    # Robot corners in the world: (T, 4, 2).
    rl = signs * rh
    corner_r = robot_pose[:, None, :2] + np.stack(
        [c[:, None] * rl[:, 0] - s[:, None] * rl[:, 1], s[:, None] * rl[:, 0] + c[:, None] * rl[:, 1]], axis=-1
    )
    # Obstacle corners against the robot's rectangle, in the robot's frame.
    d = corner_o - robot_pose[:, None, None, :2]
    cx, sx = c[:, None, None], s[:, None, None]
    out = np.maximum(np.abs(np.stack([cx * d[..., 0] + sx * d[..., 1], cx * d[..., 1] - sx * d[..., 0]], -1)) - rh, 0)
    dist = np.hypot(out[..., 0], out[..., 1]).min(axis=2)  # (T, n)
    # Robot corners against each obstacle's core, in the obstacle's frame.
    d = corner_r[:, None, :, :] - obstacle_xy[:, :, None, :]  # (T, n, 4, 2)
    cy, sy = co[None, :, None], so[None, :, None]
    local = np.stack([cy * d[..., 0] + sy * d[..., 1], cy * d[..., 1] - sy * d[..., 0]], -1)
    out = np.maximum(np.abs(local) - core_half_extents[None, :, None, :], 0)
    dist = np.minimum(dist, np.hypot(out[..., 0], out[..., 1]).min(axis=2))
    # Separating axes: the robot's two and the obstacle's two.
    delta = obstacle_xy - robot_pose[:, None, :2]  # (T, n, 2)
    separated = np.zeros(dist.shape, dtype=bool)
    axes = (
        (c[:, None], s[:, None]),
        (-s[:, None], c[:, None]),
        (co[None, :], so[None, :]),
        (-so[None, :], co[None, :]),
    )
    for ux, uy in axes:
        r_robot = rh[0] * np.abs(ux * c[:, None] + uy * s[:, None]) + rh[1] * np.abs(-ux * s[:, None] + uy * c[:, None])
        r_obst = core_half_extents[None, :, 0] * np.abs(ux * co[None] + uy * so[None]) + core_half_extents[
            None, :, 1
        ] * np.abs(-ux * so[None] + uy * co[None])
        separated |= np.abs(ux * delta[..., 0] + uy * delta[..., 1]) > r_robot + r_obst
    dist = np.where(separated, dist, 0.0)
    return (dist - radii).min(axis=1)


def mean_abs_jerk(v: np.ndarray, dt: float) -> float:
    """Mean |third derivative of position| from forward speed samples v (k,) at period dt."""
    if len(v) < 3:
        return 0.0
    return float(np.mean(np.abs(np.diff(v, n=2))) / dt**2)


def sum_abs_change(x: np.ndarray) -> float:
    return float(np.abs(np.diff(x)).sum()) if len(x) > 1 else 0.0


def stalled_time(v: np.ndarray, w: np.ndarray, dt: float) -> float:
    """Time [s] with |v| < STALL_SPEED and |w| < 0.1 rad/s, from samples at period dt."""
    return float(np.count_nonzero((np.abs(v) < STALL_SPEED) & (np.abs(w) < 0.1)) * dt)


def spl(success: bool, optimal_length: float, actual_length: float) -> float:
    """Success weighted by (normalised inverse) Path Length (Anderson et al. 2018)."""
    if not success:
        return 0.0
    return optimal_length / max(actual_length, optimal_length, 1e-9)


def compute_percentiles(ms: np.ndarray) -> tuple[float, float]:
    if len(ms) == 0:
        return 0.0, 0.0
    return float(np.mean(ms)), float(np.percentile(ms, 95))


@dataclass(frozen=True)
class EpisodeFacts:
    """What an ended episode's metrics are computed from (`sim.result` gathers it)."""

    success: bool
    time: float
    """Episode time as the protocol counts it [s]."""
    sim_time: float
    path_length: float
    optimal_length: float
    """SPL's shortest path [m]."""
    score: float
    """The protocol's score (`EvalProtocol.score`)."""
    min_clearance: float
    tick_v: np.ndarray
    """Measured forward speed at each control tick [m/s]."""
    tick_w: np.ndarray
    tick_w_cmd: np.ndarray
    """Commanded yaw rate at each control tick [rad/s]."""
    control_period: float
    planner_ms: np.ndarray
    wall_time: float
    clock_offset: float


@dataclass(frozen=True)
class Metric:
    """One number of every result, defined once: its name (an `EpisodeResult` field, a
    results column, a key of the recording's `/episode/result`), unit, meaning, how it is
    computed from an ended episode's facts, and how a sweep's summary aggregates it
    (`mean` over episodes, `successes`: the mean over successful episodes, as NAME_success;
    None: not summarised). The result's schema, the summary and the docs' table read it."""

    name: str
    unit: str
    doc: str
    compute: Callable[[EpisodeFacts], float]
    summary: str | None = None
    when_missing: float | None = None
    """What a results row without it counts as in a summary (None: left out); a score is 0
    for an episode whose row has none (it ended in an error before it was judged)."""


def _percentile(f: EpisodeFacts, which: int) -> float:
    return compute_percentiles(f.planner_ms)[which]


METRICS: tuple[Metric, ...] = (
    Metric("time", "s", "episode time as the protocol counts it (barn: from the first 0.1 m of motion)",
           lambda f: f.time, "successes"),
    Metric("sim_time", "s", "simulated time from the start to the end of the episode", lambda f: f.sim_time),
    Metric("path_length", "m", "length of the path the robot drove", lambda f: f.path_length),
    Metric("score", "", "the protocol's score (BARN: success x OT / clip(AT, 2 OT, 8 OT))",
           lambda f: f.score, "mean", 0.0),
    Metric("spl", "", "success weighted by path length: optimal / max(path, optimal) on success",
           lambda f: spl(f.success, f.optimal_length, f.path_length), "mean", 0.0),
    Metric("min_clearance", "m", "smallest distance between the footprint and any obstacle's surface (every step)",
           lambda f: f.min_clearance, "mean"),
    Metric("mean_abs_jerk", "m/s^3", "mean |d^3 x / dt^3| of the forward motion, from measured speed per tick",
           lambda f: mean_abs_jerk(f.tick_v, f.control_period)),
    Metric("sum_abs_dw", "rad/s", "sum of |change| of the commanded yaw rate between ticks",
           lambda f: sum_abs_change(f.tick_w_cmd)),
    Metric("time_stalled", "s", f"time with |v| < {STALL_SPEED} m/s and |w| < 0.1 rad/s",
           lambda f: stalled_time(f.tick_v, f.tick_w, f.control_period)),
    Metric("planner_ms_mean", "ms", "the planner's compute per call, mean", lambda f: _percentile(f, 0)),
    Metric("planner_ms_p95", "ms", "the planner's compute per call, 95th percentile", lambda f: _percentile(f, 1)),
    Metric("rtf", "", "real-time factor: simulated seconds per wall-clock second",
           lambda f: f.sim_time / f.wall_time if f.wall_time > 0 else math.inf),
    Metric("wall_time", "s", "wall-clock time of the episode", lambda f: f.wall_time),
    Metric("clock_offset", "s", "the obstacles' clock offset the trial's seed drew", lambda f: f.clock_offset),
)  # fmt: skip
"""Every number of a result, in the order `EpisodeResult` holds them."""

RESULT_NUMBERS = tuple(m.name for m in METRICS)
"""The fields of a result that are numbers (or null when no finite value exists)."""


def metrics_table() -> str:
    """The metric table of docs/concepts/protocols.md (`tests/test_docs.py` keeps it there)."""
    rows = ["| metric | unit | what it is | in a sweep's summary |", "|---|---|---|---|"]
    summary = {"mean": "mean over episodes", "successes": "mean over successes", None: "-"}
    for m in METRICS:
        rows.append(f"| `{m.name}` | {m.unit or '-'} | {m.doc.replace('|', chr(92) + '|')} | {summary[m.summary]} |")
    return "\n".join(rows)
