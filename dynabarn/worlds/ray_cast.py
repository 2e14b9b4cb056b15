"""Closed-form ray casts against a world's static geometry, without MuJoCo: standing
cylinders (`circle_ranges`) and axis-aligned wall boxes (`box_ranges`) along a laser's
beams. The laser casts its static field with the first (`sim.laser`); the known map as the
laser would see it alone (`perception.MapScan`) with both."""

from __future__ import annotations

import numpy as np


def circle_ranges(
    ox: float,
    oy: float,
    yaw: float,
    angles: np.ndarray,
    circles: np.ndarray,
    range_max: float,
    directions: tuple[np.ndarray, np.ndarray] | None = None,
) -> np.ndarray:
    """Ranges (n,) along beams at `angles` (evenly spaced, robot frame) from (ox, oy) heading
    `yaw` to the nearest of `circles` (k, 3: x, y, radius); range_max where none is hit.
    `directions`: every beam's (cos, sin) of angle + yaw where the caller has them (None:
    numpy's, of the beams that can hit).

    Each circle is tested only against the beams inside its angular extent
    [theta - alpha, theta + alpha] (np.repeat over the extents: the work is the number of
    beams that can hit, not beams x circles); t = b - sqrt(b^2 - (|c - o|^2 - r^2)),
    b = u . (c - o)."""
    n = len(angles)
    out = np.full(n, range_max)
    d = circles[:, :2] - (ox, oy)
    r = circles[:, 2]
    dist = np.hypot(d[:, 0], d[:, 1])
    near = (dist - r < range_max) & (dist > r)
    d, r, dist = d[near], r[near], dist[near]
    theta = np.arctan2(d[:, 1], d[:, 0]) - yaw
    theta = (theta + np.pi) % (2 * np.pi) - np.pi
    alpha = np.arcsin(r / dist)
    step = (angles[-1] - angles[0]) / (n - 1)
    lo = np.maximum(np.ceil((theta - alpha - angles[0]) / step), 0).astype(np.int64)
    hi = np.minimum(np.floor((theta + alpha - angles[0]) / step), n - 1).astype(np.int64)
    counts = np.maximum(hi - lo + 1, 0)
    total = int(counts.sum())
    if total == 0:
        return out
    which = np.repeat(np.arange(len(counts)), counts)
    beam = lo[which] + np.arange(total) - np.repeat(np.cumsum(counts) - counts, counts)
    if directions is None:
        a = angles[beam] + yaw
        ux, uy = np.cos(a), np.sin(a)
    else:
        ux, uy = directions[0][beam], directions[1][beam]
    dc = d[which]
    b = ux * dc[:, 0] + uy * dc[:, 1]
    disc = b * b - (dist[which] ** 2 - r[which] ** 2)
    hit = disc >= 0
    t = b[hit] - np.sqrt(disc[hit])
    np.minimum.at(out, beam[hit], t)
    return out


def box_ranges(
    ox: float,
    oy: float,
    yaw: float,
    angles: np.ndarray,
    boxes: np.ndarray,
    range_max: float,
    directions: tuple[np.ndarray, np.ndarray] | None = None,
) -> np.ndarray:
    """Ranges (n,) along beams at `angles` from (ox, oy) heading `yaw` to the nearest of the
    axis-aligned `boxes` (k, 4: centre x, centre y, full size x, full size y, as walls are
    given); range_max where none is hit within it. The slab method, every box against every
    beam at once (a world has a handful of walls). `directions` as `circle_ranges`'."""
    if directions is None:
        a = angles + yaw
        ux, uy = np.cos(a), np.sin(a)
    else:
        ux, uy = directions
    half = boxes[:, 2:4] / 2
    lo = boxes[:, :2] - half - (ox, oy)  # (k, 2): the corners seen from the laser
    hi = boxes[:, :2] + half - (ox, oy)
    with np.errstate(divide="ignore", invalid="ignore"):
        tx1, tx2 = lo[:, :1] / ux, hi[:, :1] / ux  # (k, n)
        ty1, ty2 = lo[:, 1:] / uy, hi[:, 1:] / uy
        near = np.maximum(np.fmin(tx1, tx2), np.fmin(ty1, ty2))
        far = np.minimum(np.fmax(tx1, tx2), np.fmax(ty1, ty2))
    hit = (near <= far) & (near > 0)
    t = np.where(hit, near, np.inf).min(axis=0, initial=np.inf)
    return np.minimum(t, range_max)
