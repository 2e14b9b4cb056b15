"""`shaped`: the laser tracker for the obstacles the generator makes (boxes, capsules and
cylinders), not only for the paper's cylinders.

The `kalman` tracker (`tracker.py`) fits a circle of the known radius to every segment, so
a box or a capsule's centre lands wherever a 0.5 m circle best meets its visible sides:
158-169 mm median error on the mixed tiers. This one keeps, per track, what the obstacle
looks like, and measures its centre from that:

- an outline: the heading of its sides (fixed: obstacles translate without turning) and
  the half sizes of its bounding rectangle along them. A straight segment tells the
  heading (`shape_fit.fit_headings`); the extent of the returns along a side is the
  obstacle's whole extent when the laser faces that side (beyond 15 degrees for a box's
  sharp sides, within 20 of head-on for a rounded end) and neither end of the returns is
  cut (`shape_fit.Extents`), and a lower bound otherwise; an axis never seen whole takes
  `shape.prior_half`, and `Tracks.half_size_std` says how little is known of it. A segment
  the known-radius circle fits closely is a cylinder, and a track that is mostly that
  (a slow vote) keeps the circle's centre (as `kalman` does);
- a centre measured with the track's own outline (`shape_fit.centre_from_spans`): the side
  facing the laser is where the returns start, and along an axis the scan leaves open the
  measurement keeps the prediction, with a variance that says so (the open width's,
  uniform), so the filter learns only what was seen;
- association by that measured centre, for every track and detection pair, so a box's
  near side is matched with the box; a detection lying inside a box's or capsule's
  outline is a piece of that obstacle cut by something in front of it, not a new track;
- coasting through occlusion as `kalman` does (growing uncertainty; a track is dropped
  only when unseen for `shape.max_coast` (1.2 s: an obstacle hidden for a second comes
  back with its identity) or when the laser sees through its place).

Vectorised over tracks, detections and points; elementwise arithmetic only, and the state
on `STATE_RESOLUTION`'s grid, so the same scans give the same tracks on every CPU.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import ClassVar

import numpy as np
from scipy.optimize import linear_sum_assignment

from dynabarn.determinism import STATE_RESOLUTION, sincos, snap_array
from dynabarn.perception.detect import Detections, ObstacleDetector
from dynabarn.perception.shape_fit import (
    Extents,
    SegmentShapes,
    ShapeConfig,
    centre_from_spans,
    extents,
    fit_headings,
    from_frame,
    group_starts,
    spans,
    to_frame,
)
from dynabarn.perception.tracker import NO_MATCH, ObstacleTracker, TrackerConfig
from dynabarn.perception.tracks import Tracks

_QUARTER = 0.5 * math.pi
_GRAZING_SIDE = math.tan(math.radians(15.0))
"""A straight side seen at less than 15 degrees is seen at a grazing angle: a few beams
catch only its near end."""
_GRAZING_END = math.tan(math.radians(70.0))
"""A rounded end shows its whole width only to a laser almost in front of it (within
20 degrees)."""
_SHARP = 0.01
"""[m] Returns all this close to their rectangle's edges are a box's sharp sides."""
SEEN_EXTENT_STD = 0.05
"""[m] Uncertainty of an extent seen whole: its ends fall between beams (5 cm apart at 8 m)
and a rounded end's tip is seen at a grazing angle."""
EXTENT_STEP = 0.1
"""[m] The most a track's extent grows in one scan."""
ROUNDNESS_GAIN = 0.2
"""How far one vote moves a track's roundness: a cylinder's segment merged with a
neighbour's (a crowd) fits no circle now and then, and must not make it a box."""
HEADING_POINTS = 5
"""Returns a straight segment needs before it tells its track's heading."""
ROUND_VOTE_POINTS = 6
"""Returns a segment needs before its circle fit says whether the obstacle is a cylinder."""
_ROUNDED = 0.15
"""[m] Returns this deep across a side that was never faced are a rounded end's (a
capsule's radius, about), not a box's edge seen at a grazing angle."""


def _wrap_quarter(angle: np.ndarray) -> np.ndarray:
    """Angles to [-pi/4, pi/4): a rectangle's heading is the same a right angle on."""
    return np.mod(angle + 0.25 * math.pi, _QUARTER) - 0.25 * math.pi


_OUTLINE_FIELDS = ("headings", "half_sizes", "half_size_std")
"""What `Tracks` says of outlines (a circle-only tracker leaves them None)."""
OCCLUDER_GAP = 0.05
"""[m] A neighbouring beam this much shorter than a segment's end ended on something in
front of it: the obstacle may go on behind."""


@dataclass(frozen=True, slots=True)
class _Segments:
    """One scan's detections as outlines: their returns, fits and cut ends."""

    points: np.ndarray  # (k, 2) returns of the kept segments, in scan order
    segment: np.ndarray  # (k,) detection index of each
    starts: np.ndarray  # (m,) first return of each detection
    cut_first: np.ndarray  # (m,) its first / last return may not be the obstacle's end
    cut_last: np.ndarray
    outline: SegmentShapes
    is_round: np.ndarray  # (m,) the known-radius circle fits it: a cylinder
    straight: np.ndarray  # (m,) straight enough, with returns enough, to tell a heading
    circles: np.ndarray  # (m, 2) the known-radius circles' centres
    residuals: np.ndarray  # (m,) and their RMS residuals
    sizes: np.ndarray  # (m,)
    n_points: np.ndarray  # (m,)

    @classmethod
    def of(cls, det: Detections, scan: np.ndarray, shape: ShapeConfig) -> _Segments:
        inside = det.segment_of_point >= 0
        points, segment, beams = det.points[inside], det.segment_of_point[inside], det.beams[inside]
        starts = group_starts(segment)
        ends = np.append(starts[1:], len(segment)) - 1
        first, last, n_beams = beams[starts], beams[ends], len(scan)
        # Cut where the next beam out ended in front (or the field of view ends).
        cut_first = (first == 0) | (scan[np.maximum(first - 1, 0)] < scan[first] - OCCLUDER_GAP)
        cut_last = (last == n_beams - 1) | (scan[np.minimum(last + 1, n_beams - 1)] < scan[last] - OCCLUDER_GAP)
        outline = fit_headings(points, segment)
        # A rectangle fits three or four returns exactly: a few returns on the known circle
        # count as round without the comparison.
        few = det.n_points < ROUND_VOTE_POINTS
        is_round = (det.residuals < shape.round_rms) & (few | (det.residuals <= outline.edge_rms))
        straight = (outline.straightness >= shape.min_straightness) & ~is_round & (det.n_points >= HEADING_POINTS)
        return cls(points, segment, starts, cut_first, cut_last, outline, is_round, straight,
                   det.centres, det.residuals, det.sizes, det.n_points)  # fmt: skip


@dataclass
class ShapeTrackerConfig(TrackerConfig):
    """The `shaped` tracker's configuration: the Kalman tracker's, and the outlines' (`shape`)."""

    shape: ShapeConfig = field(default_factory=ShapeConfig)
    """Outlines: how boxes, capsules and cylinders are fitted and kept."""

    RECORDED_WHEN_SET: ClassVar[dict[str, tuple[str, ...]]] = {"kind": ("kind", "shape")}


class ShapeTracker(ObstacleTracker):
    """Tracks boxes, capsules and cylinders from scans and odometry (world frame).

    Args:
        cfg: the tracker's parameters (`cfg.shape` for outlines, `cfg.detector` for segments).
        detector: the episode's detector (its known map and laser).
    """

    name = "shaped"
    Config = ShapeTrackerConfig

    PER_TRACK: ClassVar[tuple[str, ...]] = (
        *ObstacleTracker.PER_TRACK, "heading", "heading_known", "seen_half", "visible_half", "roundness",
    )  # fmt: skip

    def __init__(self, cfg: ShapeTrackerConfig, detector: ObstacleDetector) -> None:
        super().__init__(cfg, detector)
        self.heading = np.zeros(0)
        self.heading_known = np.zeros(0, dtype=bool)
        self.seen_half = np.zeros((0, 2))  # whole extents seen (0: never)
        self.visible_half = np.zeros((0, 2))  # the largest extents of returns seen
        self.roundness = np.zeros(0)  # running share of detections that were cylinders

    def max_coast(self) -> float:
        return self.cfg.shape.max_coast

    # -- outlines -----------------------------------------------------------------------------
    def half_sizes(self) -> np.ndarray:
        """(n, 2) half sizes of each track's bounding rectangle, along and across its heading."""
        prior = self.cfg.shape.prior_half
        # An axis never seen whole: the prior, or a rounded end's depth (the visible
        # returns of a capsule's side and end reach its radius deep: half its width).
        depth = 2.0 * self.visible_half
        # Only across a long side (the other axis longer than the prior): seen end on, a
        # capsule's cap is as deep as a side view's, but its length is what is hidden.
        long_other = self.visible_half[:, ::-1] > prior
        rounded = (depth > _ROUNDED) & (depth < prior) & long_other
        unseen = np.maximum(self.visible_half, np.where(rounded, depth, prior))
        half = np.where(self.seen_half > 0, np.maximum(self.seen_half, self.visible_half), unseen)
        radius = self.detector.cfg.radius
        return np.where(self._round()[:, None], radius, half)

    def _round(self) -> np.ndarray:
        return self.roundness > 0.5

    def _measure(self, scan: _Segments, sensor: np.ndarray) -> tuple[np.ndarray, np.ndarray, Extents]:
        """Every detection's centre as each track's outline measures it: centres (n, m, 2)
        and per-axis variances (n, m, 2) in the world, and the returns' extents (n, m, 2)
        in each track's frame."""
        s, c = sincos(self.heading)
        s, c = s[:, None], c[:, None]
        x, y = scan.points[None, :, 0], scan.points[None, :, 1]
        seen = extents(x * c + y * s, y * c - x * s, scan.starts, scan.cut_first, scan.cut_last)  # (n, m, 2)
        n, m = seen.lo.shape[:2]
        rows = np.repeat(np.arange(n), m)
        circles = np.broadcast_to(scan.circles, (n, m, 2)).reshape(-1, 2)
        fits = np.broadcast_to(scan.residuals, (n, m)).reshape(-1)
        centres, var = self._centres(rows, seen.reshape(-1), sensor, circles, fits)
        return centres.reshape(n, m, 2), var.reshape(n, m, 2), seen

    def _centres(
        self, rows: np.ndarray, seen: Extents, sensor: np.ndarray, circles: np.ndarray, fits: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray]:
        """Centres (p, 2) and their per-axis variances (p, 2) in the world measured by the
        outlines of tracks `rows` (p,) from returns of extents `seen` (p, 2) in each one's
        frame; a round track's is its detection's known-radius circle, `circles` (p, 2), of
        RMS residual `fits` (p,)."""
        s, c = sincos(self.heading[rows])
        half = self.half_sizes()[rows]
        headings = self.heading[rows]
        uv, slack = centre_from_spans(seen, half, to_frame(sensor, headings), to_frame(self.x[rows], headings))
        world = from_frame(uv, headings)
        # An axis whose whole extent was never seen stands on the prior: as uncertain as it.
        unknown = self.seen_half[rows] <= 0
        var_uv = slack * slack / 12.0 + np.where(unknown, self.cfg.shape.prior_half**2 / 3.0, 0.0)
        cc, ss = c * c, s * s
        var = np.column_stack([cc * var_uv[:, 0] + ss * var_uv[:, 1], ss * var_uv[:, 0] + cc * var_uv[:, 1]])
        round_track = self._round()[rows][:, None]
        # A cylinder's segment the circle does not fit (merged with a neighbour's) says
        # little of where it is: the prediction keeps it.
        off_circle = (fits > 3.0 * self.cfg.shape.round_rms)[:, None]
        circle_var = np.where(off_circle, 1.0, 0.0)
        return np.where(round_track, circles, world), np.where(round_track, circle_var, var)

    # -- one scan -----------------------------------------------------------------------------
    def update(self, time: float, scan: np.ndarray, pose: np.ndarray) -> Tracks:
        """Take one scan (and the robot's pose at it); the tracks at `time`."""
        cfg = self.cfg
        det, dt, var = self._next_scan(time, scan, pose)
        sensor = self.detector.laser_origin(pose)
        rows = cols = np.zeros(0, dtype=np.int64)
        segments = _Segments.of(det, scan, cfg.shape) if len(det) else None
        claimed = np.zeros(len(det), dtype=bool)
        if segments is not None and len(self.ids):
            centres, _, seen = self._measure(segments, sensor)
            rows, cols = self._associate_measured(centres)
            # Learn the outline first; where it changed, the same returns put the centre
            # elsewhere, and the track moves with it (a shape learned is not a velocity).
            before = centres[rows, cols]
            matched = seen[rows, cols]
            self._learn_outline(rows, cols, segments, matched, sensor)
            after, after_var = self._centres(rows, matched, sensor, det.centres[cols], det.residuals[cols])
            self.x[rows] += after - before
            self._correct(rows, after, var[cols][:, None] + after_var)
            self.seen[rows] = time
            self.unseen_in_view[rows] = 0.0
            claimed = self._within_outlines(seen)
        unmatched = np.ones(len(self.ids), dtype=bool)
        unmatched[rows] = False
        self._age_unmatched(np.flatnonzero(unmatched), scan, pose, dt)
        claimed[cols] = True
        born = np.flatnonzero(~claimed)
        if len(born):
            self._birth_outlines(segments, born, sensor, var[born], time)
        snap_array(self.x, STATE_RESOLUTION, out=self.x)
        snap_array(self.v, STATE_RESOLUTION, out=self.v)
        self.size = np.hypot(*self.half_sizes().T) if len(self.ids) else np.zeros(0)
        return self.tracks()

    def _associate_measured(self, centres: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The Hungarian method on the distances from predicted to measured centres, gated."""
        d = np.sqrt(((self.x[:, None, :] - centres) ** 2).sum(axis=-1))
        gate = self.cfg.gate + 3.0 * np.sqrt(self.p_xx.max(axis=1))
        cost = np.where(d <= gate[:, None], d, NO_MATCH)
        rows, cols = linear_sum_assignment(cost)
        ok = cost[rows, cols] < NO_MATCH
        return rows[ok], cols[ok]

    def _within_outlines(self, seen: Extents) -> np.ndarray:
        """(m,) detections whose returns all lie inside some track's outline (grown by
        `birth_margin`) about its predicted centre: pieces of a tracked obstacle."""
        centre_uv = to_frame(self.x, self.heading)
        reach = self.half_sizes() + self.cfg.shape.birth_margin
        low, high = (centre_uv - reach)[:, None, :], (centre_uv + reach)[:, None, :]
        inside = ((seen.lo >= low) & (seen.hi <= high)).all(axis=-1)
        return (inside & ~self._round()[:, None]).any(axis=0)  # a cylinder's pieces fit its circle

    def _learn_outline(
        self, rows: np.ndarray, cols: np.ndarray, segments: _Segments, seen: Extents, sensor: np.ndarray
    ) -> None:
        """Matched tracks learn from their detections: roundness, heading, extents."""
        shape = self.cfg.shape
        outline, is_round, n_points = segments.outline, segments.is_round[cols], segments.n_points[cols]
        # A few returns fit any circle: only a segment of `ROUND_VOTE_POINTS` votes.
        votes = n_points >= ROUND_VOTE_POINTS
        self.roundness[rows] += np.where(votes, ROUNDNESS_GAIN * (is_round - self.roundness[rows]), 0.0)
        straight = segments.straight[cols]
        turn = _wrap_quarter(outline.headings[cols] - self.heading[rows])
        gain = np.where(self.heading_known[rows], shape.heading_gain * outline.straightness[cols], 1.0)
        self.heading[rows] += np.where(straight, gain * turn, 0.0)
        self.heading_known[rows] |= straight
        # Extents from clean outlines only: returns that fit no rectangle (two obstacles in
        # one segment, a cylinder's arc) would make a box of them.
        clean = (outline.edge_rms[cols] <= shape.max_edge_rms) & ~is_round
        self._learn_extents(rows[clean], seen[clean], sensor, outline.edge_max[cols][clean])

    def _learn_extents(self, rows: np.ndarray, seen: Extents, sensor: np.ndarray, edge_max: np.ndarray) -> None:
        """The returns' extents (p, 2) in each track's frame: lower bounds of its outline,
        and the whole of it along an axis when the laser faces the side along it and
        nothing cuts its ends."""
        s, c = sincos(self.heading[rows])
        su, sv = sensor[0] * c + sensor[1] * s, sensor[1] * c - sensor[0] * s
        lo, hi = seen.lo, seen.hi
        half = 0.5 * (hi - lo)
        plausible = half <= self.cfg.shape.max_half
        # A side is seen end to end when the laser stands in front of it, not at a grazing
        # angle (where a few beams catch only its near end): its extent along the side is then whole.
        off_u = np.maximum(np.maximum(lo[:, 0] - su, su - hi[:, 0]), 0.0)  # how far beside the extent
        off_v = np.maximum(np.maximum(lo[:, 1] - sv, sv - hi[:, 1]), 0.0)
        # Sharp sides (the returns on their rectangle's edges): seen whole from 15 degrees;
        # rounded ends (a capsule's) show their whole width only from the front.
        grazing = np.where(edge_max <= _SHARP, _GRAZING_SIDE, _GRAZING_END)
        facing = np.column_stack([off_v > grazing * off_u, off_u > grazing * off_v])
        whole = facing & plausible & seen.whole
        # Grown by at most `EXTENT_STEP` a scan: the whole of an extent is seen over a few
        # scans, while a segment that merged two obstacles for one scan adds little.
        visible, known = self.visible_half[rows], self.seen_half[rows]
        grown = np.minimum(half, np.where(visible > 0, visible + EXTENT_STEP, half))
        self.visible_half[rows] = np.where(plausible, np.maximum(visible, grown), visible)
        grown = np.minimum(half, np.where(known > 0, known + EXTENT_STEP, half))
        self.seen_half[rows] = np.where(whole, np.maximum(known, grown), known)

    def _birth_outlines(
        self, segments: _Segments, born: np.ndarray, sensor: np.ndarray, var: np.ndarray, time: float
    ) -> None:
        """New tracks for detections no track claimed, each with its own outline."""
        first = len(self.ids)
        outline = segments.outline
        headings = outline.headings[born]
        seen = spans(segments.points, segments.segment, outline.headings, segments.cut_first, segments.cut_last)[born]
        round_now = segments.is_round[born]
        self._birth(from_frame(0.5 * (seen.lo + seen.hi), headings), segments.sizes[born], var, time)
        n = len(born)
        self.heading = np.concatenate([self.heading, headings])
        self.heading_known = np.concatenate([self.heading_known, segments.straight[born]])
        self.seen_half = np.concatenate([self.seen_half, np.zeros((n, 2))])
        self.visible_half = np.concatenate([self.visible_half, np.zeros((n, 2))])
        # A segment too short to vote starts undecided, taken for the larger outline until
        # its first vote (a cylinder's makes it round at once).
        undecided = segments.n_points[born] < ROUND_VOTE_POINTS
        start = np.where(undecided, 0.5, round_now.astype(np.float64))
        self.roundness = np.concatenate([self.roundness, start])
        new = np.arange(first, first + n)
        self._learn_extents(new, seen, sensor, segments.outline.edge_max[born])
        # Where its outline says the centre is (the returns' middle was a start).
        self.x[new], centre_var = self._centres(new, seen, sensor, segments.circles[born], segments.residuals[born])
        self.p_xx[new] = var[:, None] + centre_var

    def tracks(self) -> Tracks:
        """The current tracks (copies), with each one's outline."""
        base = super().tracks()
        if not len(self.ids):
            return base
        return Tracks(
            **{
                name: getattr(base, name)
                for name in Tracks.__slots__
                if name not in ("headings", "half_sizes", "half_size_std", "extent_sigmas")
            },
            headings=self.heading.copy(),
            half_sizes=self.half_sizes(),
            half_size_std=self.half_size_std(),
            extent_sigmas=self.cfg.shape.extent_sigmas,
        )

    def half_size_std(self) -> np.ndarray:
        """(n, 2) uncertainty of each half size: an extent never seen whole could be up to
        the generator's largest (`shape.max_half`) from what was seen: that range, as a
        uniform's standard deviation; a seen one, `SEEN_EXTENT_STD`; a cylinder's, none."""
        unseen = np.maximum(self.cfg.shape.max_half - self.half_sizes(), 0.0) / math.sqrt(12.0)
        std = np.where(self.seen_half > 0, SEEN_EXTENT_STD, unseen)
        return np.where(self._round()[:, None], 0.0, std)
