"""What one scan shows of an obstacle's outline: the heading of its sides and the extent of
its returns along them (for boxes, capsules and cylinders alike).

Every obstacle the generator makes is, in the plane, a rounded rectangle that translates
without turning (`worlds.spec.Obstacle`). The laser sees the sides that face it: one side
(an "I"), two sides meeting at a corner (an "L"), or an arc. Two facts follow:

- the heading of the sides: the one at which the returns lie closest to the edges of their
  own bounding rectangle (`fit_headings`: a search over headings in [0, pi/2), a rectangle
  being the same turned by a right angle; the L-shape fit of Zhang et al., IV 2017, with
  the distance to the nearest edge as its criterion). An arc fits every heading about as
  well, so `straightness` says how much better the best heading is than the average one;
- the extent of the returns along a heading (`spans`): the obstacle's bounding rectangle
  at its own heading contains them, and its side facing the laser is where they start.
  Which sides those are follows from where the laser stands (`centre_from_spans`).

Everything is vectorised over segments (grouped sums and extrema by `ufunc.reduceat` over
the scan-ordered points) and over candidate headings; elementwise arithmetic only, so the
same scan gives the same bits on every CPU.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import ClassVar

import numpy as np

from dynabarn.determinism import sincos
from dynabarn.interfaces.planner import CheckedConfig

COARSE_HEADINGS = 45
"""Headings tried over the quarter turn first (every 2 degrees)."""
FINE_STEPS = 8
"""Headings tried on each side of the best coarse one, a quarter degree apart (to 2 degrees)."""
_QUARTER = 0.5 * math.pi


@dataclass(frozen=True, slots=True)
class SegmentShapes:
    """The outline of every segment of a scan.

    Attributes:
        headings: (m,) the heading of the segment's sides, in [0, pi/2) [rad].
        straightness: (m,) 1 - (edge residual at the best heading / its mean over all
            headings): near 1 for the sides of a box or a capsule, small for an arc.
        edge_rms: (m,) RMS distance of the returns from the nearest edge of their bounding
            rectangle at the best heading [m].
        edge_max: (m,) the largest such distance [m]: a box's sides have every return on
            an edge, a capsule's rounded end has returns well inside.
    """

    headings: np.ndarray
    straightness: np.ndarray
    edge_rms: np.ndarray
    edge_max: np.ndarray


def group_starts(segment: np.ndarray) -> np.ndarray:
    """Index of the first point of every group of a sorted, gap-free group index (k,)."""
    return np.flatnonzero(np.diff(segment, prepend=-1) != 0)


def _frame(points: np.ndarray, cos: np.ndarray, sin: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Coordinates along (u) and across (v) each heading of the points (broadcast)."""
    x, y = points[..., 0], points[..., 1]
    return x * cos + y * sin, y * cos - x * sin


def _edge_distance(u: np.ndarray, v: np.ndarray, segment: np.ndarray, starts: np.ndarray) -> np.ndarray:
    """Distance from each point to the nearest edge of its segment's bounding rectangle,
    per heading row: (rows, k)."""
    lo_u = np.minimum.reduceat(u, starts, axis=-1)[..., segment]
    hi_u = np.maximum.reduceat(u, starts, axis=-1)[..., segment]
    lo_v = np.minimum.reduceat(v, starts, axis=-1)[..., segment]
    hi_v = np.maximum.reduceat(v, starts, axis=-1)[..., segment]
    return np.minimum(np.minimum(u - lo_u, hi_u - u), np.minimum(v - lo_v, hi_v - v))


def _edge_cost(u: np.ndarray, v: np.ndarray, segment: np.ndarray, starts: np.ndarray) -> np.ndarray:
    """Sum of squared distances from each point to the nearest edge of its segment's
    bounding rectangle, per heading row and segment: (rows, m)."""
    edge = _edge_distance(u, v, segment, starts)
    return np.add.reduceat(edge * edge, starts, axis=-1)


def fit_headings(points: np.ndarray, segment: np.ndarray) -> SegmentShapes:
    """The heading and straightness of every segment.

    Args:
        points: (k, 2) the returns, grouped by segment in order [m].
        segment: (k,) each point's segment index (0, 0, ..., 1, ..., m - 1; no gaps).
    """
    starts = group_starts(segment)
    counts = np.diff(np.append(starts, len(segment)))
    coarse = np.arange(COARSE_HEADINGS) * (_QUARTER / COARSE_HEADINGS)
    s, c = sincos(coarse)
    cost = _edge_cost(*_frame(points[None], c[:, None], s[:, None]), segment, starts)  # (H, m)
    best = np.argmin(cost, axis=0)
    mean_cost = cost.mean(axis=0)
    # Around the best coarse heading, a quarter degree apart.
    offsets = np.arange(-FINE_STEPS, FINE_STEPS + 1) * (_QUARTER / COARSE_HEADINGS / FINE_STEPS)
    fine = coarse[best][None, :] + offsets[:, None]  # (F, m)
    s, c = sincos(fine[:, segment])
    fine_cost = _edge_cost(*_frame(points[None], c, s), segment, starts)
    pick = np.argmin(fine_cost, axis=0)
    m = np.arange(len(starts))
    low = fine_cost[pick, m]
    heading = fine[pick, m]
    s, c = sincos(heading[segment])
    farthest = np.maximum.reduceat(_edge_distance(*_frame(points, c, s), segment, starts), starts)
    return SegmentShapes(
        headings=np.mod(heading, _QUARTER),
        straightness=1.0 - low / np.maximum(mean_cost, 1e-12),
        edge_rms=np.sqrt(low / np.maximum(counts, 1)),
        edge_max=farthest,
    )


CUT_TOLERANCE = 0.03
"""[m] A cut end of a segment is the extreme of its returns along an axis within this."""


def extents(u: np.ndarray, v: np.ndarray, starts: np.ndarray, cut_first: np.ndarray, cut_last: np.ndarray) -> Extents:
    """The extents of every segment's returns given their coordinates u, v (..., k) in some
    frame, with `cut_first` / `cut_last` (m,) saying whether its first or last return (in
    scan order) may not be the obstacle's end: (..., m, 2) arrays."""
    ends = np.append(starts[1:], u.shape[-1]) - 1
    lo = np.stack([np.minimum.reduceat(u, starts, axis=-1), np.minimum.reduceat(v, starts, axis=-1)], axis=-1)
    hi = np.stack([np.maximum.reduceat(u, starts, axis=-1), np.maximum.reduceat(v, starts, axis=-1)], axis=-1)
    first = np.stack([u[..., starts], v[..., starts]], axis=-1)
    last = np.stack([u[..., ends], v[..., ends]], axis=-1)
    cf, cl = cut_first[:, None], cut_last[:, None]
    open_lo = (cf & (first - lo < CUT_TOLERANCE)) | (cl & (last - lo < CUT_TOLERANCE))
    open_hi = (cf & (hi - first < CUT_TOLERANCE)) | (cl & (hi - last < CUT_TOLERANCE))
    return Extents(lo, hi, open_lo, open_hi)


def spans(
    points: np.ndarray, segment: np.ndarray, headings: np.ndarray, cut_first: np.ndarray, cut_last: np.ndarray
) -> Extents:
    """The extents of every segment's returns along and across its own heading (m, 2)."""
    s, c = sincos(headings[segment])
    u, v = _frame(points, c, s)
    return extents(u, v, group_starts(segment), cut_first, cut_last)


def to_frame(xy: np.ndarray, headings: np.ndarray) -> np.ndarray:
    """Points (m, 2) (or one point (2,) for every heading) in each heading's frame: (m, 2)."""
    s, c = sincos(headings)
    u, v = _frame(np.broadcast_to(xy, (len(headings), 2)), c, s)
    return np.column_stack([u, v])


def from_frame(uv: np.ndarray, headings: np.ndarray) -> np.ndarray:
    """Points (m, 2) given in each heading's frame, in the world: (m, 2)."""
    s, c = sincos(headings)
    return np.column_stack([uv[:, 0] * c - uv[:, 1] * s, uv[:, 0] * s + uv[:, 1] * c])


@dataclass(frozen=True, slots=True)
class Extents:
    """The extent of segments' returns in some frame, and which of their ends may be cut.

    Attributes:
        lo, hi: (..., 2) smallest and largest coordinate along u and v [m].
        open_lo, open_hi: (..., 2) the returns at that end may not be the obstacle's end:
            the scan's neighbouring beam ended in front of them (something hides the rest)
            or the field of view ends there.
    """

    lo: np.ndarray
    hi: np.ndarray
    open_lo: np.ndarray
    open_hi: np.ndarray

    def __getitem__(self, index) -> Extents:
        return Extents(self.lo[index], self.hi[index], self.open_lo[index], self.open_hi[index])

    def reshape(self, *shape: int) -> Extents:
        return Extents(*(a.reshape(*shape, 2) for a in (self.lo, self.hi, self.open_lo, self.open_hi)))

    @property
    def whole(self) -> np.ndarray:
        """(..., 2) neither end cut."""
        return ~(self.open_lo | self.open_hi)


def centre_from_spans(
    extents: Extents, half: np.ndarray, sensor: np.ndarray, prior: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Centres of bounding rectangles of half sizes `half` that hold the returns, in each
    segment's frame, and how far each axis is left open: (centres (m, 2), slack (m, 2)).

    Along each axis the rectangle holds [lo, hi], so its centre lies in [hi - half, lo +
    half]. Where the laser stands below lo it sees the low side (the centre is lo + half),
    above hi the high side (hi - half), unless that end is cut (something in front of it);
    otherwise the centre is the one of the interval nearest `prior` (the track's predicted
    centre: what this scan cannot say, the prediction keeps). `slack` is the width of the
    interval the scan left open (0 where it fixed the centre).
    """
    lo, hi = extents.lo, extents.hi
    low_end, high_end = hi - half, lo + half
    low_end, high_end = np.minimum(low_end, high_end), np.maximum(low_end, high_end)
    centre = np.clip(prior, low_end, high_end)
    faces_lo = (sensor < lo) & ~extents.open_lo
    faces_hi = (sensor > hi) & ~extents.open_hi
    centre = np.where(faces_lo, lo + half, np.where(faces_hi, hi - half, centre))
    slack = np.where(faces_lo | faces_hi, 0.0, high_end - low_end)
    return centre, slack


@dataclass
class ShapeConfig(CheckedConfig):
    """The `shaped` tracker's parameters for outlines (`tracker.shape.KEY=...`)."""

    prior_half: float = 0.4
    """Half size assumed along an axis whose whole extent the laser has not yet seen [m]
    (the generator's boxes: 0.2-0.6, capsules' radii 0.25-0.45)."""
    max_half: float = 1.3
    """A half extent beyond this is two obstacles seen as one, not one obstacle [m] (the
    generator's longest capsule: 1.25)."""
    max_edge_rms: float = 0.03
    """Returns farther than this (RMS) from the edges of their bounding rectangle are not
    one box or capsule seen cleanly: its extents are not learned from them [m]."""
    round_rms: float = 0.004
    """A segment the known-radius circle fits this closely (and better than a rectangle)
    is a cylinder: its centre is the circle's [m]."""
    min_straightness: float = 0.5
    """A segment this much straighter than an arc tells its sides' heading."""
    heading_gain: float = 0.3
    """How far a straight segment moves its track's heading towards its own (times its
    straightness; the first one sets it)."""
    max_coast: float = 1.2
    """Seconds a track is kept without a detection (this tracker's `tracker.max_coast`,
    which stays the circle tracker's)."""
    extent_sigmas: float = 1.0
    """Planners that read outlines cover each one grown by this many standard deviations
    of its half sizes (`Tracks.covering_circles`): what the tracker has not seen of an
    obstacle is kept clear of too."""
    birth_margin: float = 0.15
    """A detection within a track's outline grown by this is part of that obstacle (a side
    cut in two by something in front of it), not a new one [m]."""

    LIMITS: ClassVar[dict[str, tuple[float, float]]] = {
        "prior_half": (0.01, 5.0),
        "max_half": (0.05, 20.0),
        "max_edge_rms": (0.0, 1.0),
        "round_rms": (0.0, 1.0),
        "min_straightness": (0.0, 1.0),
        "heading_gain": (0.0, 1.0),
        "birth_margin": (0.0, 5.0),
        "extent_sigmas": (0.0, 10.0),
        "max_coast": (0.0, 60.0),
    }
