"""Alg. 1 of the paper: one obstacle's waypoint schedule.

Steps (paper Sec. III-A, with the choices docs/concepts/worlds.md names where the paper is loose):

1. order n ~ U{order_min, order_max};
2. n + 1 points on the integer grid of [-10, 10]^2 with distinct x;
3. the degree-n polynomial through them (Newton's divided differences: exact
   interpolation in plain IEEE arithmetic, so the result is the same on every machine,
   unlike a LAPACK least-squares fit);
4. waypoints at the scheme's x values (every integer x, or the release's ten evenly
   spaced x plus the sample points), plus where the polynomial crosses y = +-10;
   points outside the arena dropped;
5. sorted by x ascending or descending with probability 1/2 each;
6. timing: avg_speed ~ U[speed_min, speed_max] and avg_std ~ U[std_min, std_max] drawn
   once per obstacle (Alg. 1 draws them inside the loop; the released generator draws
   them once, and so do we); per segment s ~ N(avg_speed, avg_std^2) limited to
   [speed_min, speed_max] (and put on the profile's speed grid when it has one);
   t_i = t_{i-1} + d_i / s_i.

Positions and times are rounded to 1 mm and 1 ms so that a world written to MJCF
(6 significant digits) reads back identical. If the polynomial leaves fewer than two
waypoints inside the arena (it barely touches it), the draw is repeated.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from dynabarn.worlds.profiles import ARENA_HALF_SIZE, MotionProfile, WaypointScheme

POSITION_DECIMALS = 3
"""Waypoint positions are stored to 1 mm."""
TIME_DECIMALS = 3
"""Waypoint times are stored to 1 ms."""

_EDGE = ARENA_HALF_SIZE
_RELEASE_X = np.linspace(-_EDGE, _EDGE, 10)
_INTEGER_X = np.arange(-_EDGE, _EDGE + 1.0)
_CROSSING_GRID = np.linspace(-_EDGE, _EDGE, 4001)
_MAX_REDRAWS = 100


@dataclass(frozen=True, slots=True)
class Trajectory:
    """One obstacle's waypoint schedule.

    Attributes:
        times: (N,) waypoint times [s], strictly increasing, times[0] == 0.
        xy: (N, 2) waypoint positions in the world frame [m].
        profile: name of the motion profile it was drawn from.
        order: the polynomial's order (0 when unknown, e.g. imported).
        avg_speed: the per-obstacle mean speed drawn [m/s] (0 when unknown).
        avg_std: the per-obstacle speed standard deviation drawn [m/s].
    """

    times: np.ndarray
    xy: np.ndarray
    profile: str
    order: int = 0
    avg_speed: float = 0.0
    avg_std: float = 0.0

    @property
    def duration(self) -> float:
        return float(self.times[-1])

    def segment_speeds(self) -> np.ndarray:
        """(N-1,) constant speed along each straight segment [m/s]."""
        d = np.hypot(*np.diff(self.xy, axis=0).T)
        return d / np.diff(self.times)

    def __repr__(self) -> str:
        return (
            f"Trajectory(profile={self.profile!r}, n_waypoints={len(self.times)}, "
            f"duration={self.duration:.2f}s, order={self.order})"
        )

    def __eq__(self, other: object) -> bool:
        if not isinstance(other, Trajectory):
            return NotImplemented
        return (
            self.profile == other.profile
            and self.order == other.order
            and self.avg_speed == other.avg_speed
            and self.avg_std == other.avg_std
            and np.array_equal(self.times, other.times)
            and np.array_equal(self.xy, other.xy)
        )

    __hash__ = None  # type: ignore[assignment]


def newton_coefficients(xs: npt.ArrayLike, ys: npt.ArrayLike) -> np.ndarray:
    """Divided-difference coefficients of the polynomial through (xs, ys), distinct xs."""
    x = np.asarray(xs, dtype=np.float64)
    c = np.array(ys, dtype=np.float64)
    for j in range(1, len(x)):
        c[j:] = (c[j:] - c[j - 1 : -1]) / (x[j:] - x[: len(x) - j])
    return c


def newton_eval(xs: np.ndarray, coeffs: np.ndarray, x: npt.ArrayLike) -> np.ndarray:
    """Evaluate the Newton-form polynomial at x (Horner's scheme, vectorised over x)."""
    x = np.asarray(x, dtype=np.float64)
    y = np.full_like(x, coeffs[-1])
    for k in range(len(coeffs) - 2, -1, -1):
        y = y * (x - xs[k]) + coeffs[k]
    return y


def edge_crossings(xs: np.ndarray, coeffs: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(x, y) where the polynomial crosses y = +10 or y = -10, x in [-10, 10].

    Sign changes on a fine grid, then 60 vectorised bisection steps: deterministic to the
    last bit (no eigenvalue solver).
    """
    y = newton_eval(xs, coeffs, _CROSSING_GRID)
    found_x, found_y = [], []
    for level in (_EDGE, -_EDGE):
        f = y - level
        idx = np.nonzero(np.signbit(f[:-1]) != np.signbit(f[1:]))[0]
        if idx.size == 0:
            continue
        lo, hi = _CROSSING_GRID[idx].copy(), _CROSSING_GRID[idx + 1].copy()
        flo = f[idx]
        for _ in range(60):
            mid = 0.5 * (lo + hi)
            fmid = newton_eval(xs, coeffs, mid) - level
            same = np.signbit(fmid) == np.signbit(flo)
            lo = np.where(same, mid, lo)
            flo = np.where(same, fmid, flo)
            hi = np.where(same, hi, mid)
        found_x.append(0.5 * (lo + hi))
        found_y.append(np.full(idx.size, level))
    if not found_x:
        return np.empty(0), np.empty(0)
    return np.concatenate(found_x), np.concatenate(found_y)


def _waypoint_path(rng: np.random.Generator, order: int, scheme: WaypointScheme) -> np.ndarray | None:
    """Steps 2-5 of Alg. 1; None when fewer than two waypoints fall inside the arena."""
    grid = np.arange(-int(_EDGE), int(_EDGE) + 1)
    sample_x = rng.choice(grid, size=order + 1, replace=False).astype(np.float64)
    sample_y = rng.choice(grid, size=order + 1, replace=True).astype(np.float64)
    coeffs = newton_coefficients(sample_x, sample_y)

    x = _INTEGER_X if scheme is WaypointScheme.INTEGER else np.concatenate([_RELEASE_X, sample_x])
    y = newton_eval(sample_x, coeffs, x)
    x_cross, y_cross = edge_crossings(sample_x, coeffs)
    # Crossings first: where a steep curve puts a grid point within 1 mm (in x) of a
    # crossing, de-duplication keeps the crossing, so paths still start on the border.
    x = np.concatenate([x_cross, x])
    y = np.concatenate([y_cross, y])

    xy = np.round(np.stack([x, y], axis=1), POSITION_DECIMALS)
    inside = np.all(np.abs(xy) <= _EDGE, axis=1)
    xy = xy[inside]
    # Distinct x after rounding (a crossing may land on a grid x); keep the first.
    _, keep = np.unique(xy[:, 0], return_index=True)
    xy = xy[np.sort(keep)]
    xy = xy[np.argsort(xy[:, 0], kind="stable")]
    if len(xy) < 2:
        return None
    if rng.random() < 0.5:
        xy = xy[::-1]
    return np.ascontiguousarray(xy)


def _segment_speeds(
    rng: np.random.Generator, profile: MotionProfile, n_segments: int
) -> tuple[np.ndarray, float, float]:
    lo, hi = profile.speed
    avg_speed = float(rng.uniform(lo, hi))
    avg_std = float(rng.uniform(*profile.std))
    s = rng.normal(avg_speed, avg_std, size=n_segments)
    if profile.speed_limit == "redraw":
        for _ in range(1000):  # P(out of range) < 1/2 per draw: 1000 rounds never run out
            bad = (s < lo) | (s >= hi)
            if not bad.any():
                break
            s[bad] = rng.normal(avg_speed, avg_std, size=int(bad.sum()))
    if profile.speed_step > 0:
        # The release's speeds sit on a 0.1 m/s grid inside [min, max): snap to the
        # nearest admissible grid value.
        grid = profile.quantised_speeds()
        s = grid[np.abs(s[:, None] - grid[None, :]).argmin(axis=1)]
    else:
        s = np.clip(s, lo, hi)
    return s, avg_speed, avg_std


def generate_trajectory(
    rng: np.random.Generator, profile: MotionProfile, *, scheme: WaypointScheme = WaypointScheme.INTEGER
) -> Trajectory:
    """Alg. 1: draw one obstacle's trajectory from `profile` using `rng`."""
    for _ in range(_MAX_REDRAWS):
        order = int(rng.integers(profile.order[0], profile.order[1] + 1))
        xy = _waypoint_path(rng, order, WaypointScheme(scheme))
        if xy is None:
            continue
        d = np.hypot(*np.diff(xy, axis=0).T)
        speeds, avg_speed, avg_std = _segment_speeds(rng, profile, len(d))
        times = np.round(np.concatenate([[0.0], np.cumsum(d / speeds)]), TIME_DECIMALS)
        if np.all(np.diff(times) > 0):  # a sub-millisecond segment could round to zero
            break
    else:  # pragma: no cover - needs 100 consecutive degenerate draws
        raise RuntimeError("could not draw a trajectory with two waypoints inside the arena")
    return Trajectory(
        times=times,
        xy=xy,
        profile=profile.name,
        order=order,
        avg_speed=round(avg_speed, 6),
        avg_std=round(avg_std, 6),
    )
