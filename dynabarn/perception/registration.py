"""How far each obstacle moved between two scans, from its returns alone: translation-only
point-to-line registration (ICP) of the returns of this scan onto those of an earlier one.

An obstacle of the generator never turns (its yaw is fixed) and is rigid, so the same
sides seen twice differ by a translation, whatever the shape: a box's flat faces and
corners, a capsule's ends. A centre fitted to each scan with the wrong shape (a circle of
the known radius round a box) moves as the laser's view of the outline changes, and its
differences are the velocity errors of the fitted-centre tracker; the translation that
lays one scan's returns onto the other's does not depend on the shape model.

Per pair of point sets, at most `iterations` Gauss-Newton steps from a guess (the track's
predicted motion): every current point is matched to its nearest earlier point, measured
along that point's normal (the earlier returns' local direction turned a right angle),
and points farther than `trim` from their match (`coarse_trim` in the first step, halved
at each step down to `trim`, so that the guess may be off by more than the trim) (sides that came into view, or went out
of it) are left out. The translation's covariance is sigma^2 H^-1, H the summed outer
products of the matched normals plus `prior` on the diagonal: along a flat face seen
without its ends the data say nothing, and the variance there is large (sigma^2 / prior).

Vectorised over pairs (points padded to the longest set of each side); elementwise
arithmetic and reductions over fixed axes only.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True, slots=True)
class Registration:
    """Translations of m point sets, each onto its earlier set.

    Attributes:
        shift: (m, 2) translation of each obstacle [m].
        variance: (m, 2) variance of the shift along x and y [m^2] (the diagonal of its
            covariance).
        matched: (m,) current points matched within the trim (0: no measurement).
    """

    shift: np.ndarray
    variance: np.ndarray
    matched: np.ndarray


def padded(points: np.ndarray, group: np.ndarray, wanted: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The points of each group in `wanted`, in their order: (m, L, 2) padded with zeros and
    the (m, L) mask of real points (L: the largest group's count, at least 1)."""
    m = len(wanted)
    if not len(points) or not m:
        return np.zeros((m, 1, 2)), np.zeros((m, 1), dtype=bool)
    slot = np.full(int(max(group.max(), wanted.max())) + 1, -1, dtype=np.int64)
    slot[wanted] = np.arange(m)
    row = slot[group]
    keep = row >= 0
    row, pts = row[keep], points[keep]
    counts = np.bincount(row, minlength=m)
    start = np.cumsum(counts) - counts
    order = np.argsort(row, kind="stable")
    row, pts = row[order], pts[order]
    column = np.arange(len(row)) - start[row]
    out = np.zeros((m, max(int(counts.max()), 1), 2))
    mask = np.zeros(out.shape[:2], dtype=bool)
    out[row, column] = pts
    mask[row, column] = True
    return out, mask


def normals(points: np.ndarray, mask: np.ndarray) -> np.ndarray:
    """(m, L, 2) unit normals of padded point sets in scan order: the direction between each
    point's neighbours (one-sided at the ends) turned a right angle; a lone point's normal
    is zero, so it constrains nothing."""
    before = np.concatenate([points[:, :1], points[:, :-1]], axis=1)
    before_ok = np.concatenate([np.zeros_like(mask[:, :1]), mask[:, :-1]], axis=1)
    after = np.concatenate([points[:, 1:], points[:, -1:]], axis=1)
    after_ok = np.concatenate([mask[:, 1:], np.zeros_like(mask[:, :1])], axis=1)
    tangent = np.where(after_ok[..., None], after, points) - np.where(before_ok[..., None], before, points)
    length = np.sqrt(tangent[..., 0] ** 2 + tangent[..., 1] ** 2)
    unit = np.where(length[..., None] > 1e-9, tangent / np.maximum(length, 1e-9)[..., None], 0.0)
    return np.stack([-unit[..., 1], unit[..., 0]], axis=-1) * mask[..., None]


def register(
    current: np.ndarray,
    current_mask: np.ndarray,
    earlier: np.ndarray,
    earlier_mask: np.ndarray,
    guess: np.ndarray,
    *,
    sigma: float,
    trim: float,
    coarse_trim: float,
    prior: float,
    iterations: int,
) -> Registration:
    """Translation of each padded `current` set (m, P, 2) onto its `earlier` set (m, Q, 2)
    from `guess` (m, 2); see the module's description."""
    m = len(current)
    shift = guess.astype(np.float64, copy=True)
    n_earlier = normals(earlier, earlier_mask)
    rows = np.arange(m)[:, None]
    h = np.zeros((m, 2, 2))
    matched = np.zeros(m, dtype=np.int64)
    for step in range(iterations):
        # Coarse to fine: an obstacle that turned since the guess is found from farther away.
        limit = max(trim, coarse_trim * 0.5**step)
        moved = earlier + shift[:, None, :]  # (m, Q, 2)
        dx = current[:, :, None, 0] - moved[:, None, :, 0]  # (m, P, Q)
        dy = current[:, :, None, 1] - moved[:, None, :, 1]
        d2 = np.where(earlier_mask[:, None, :], dx * dx + dy * dy, np.inf)
        nearest = np.argmin(d2, axis=2)  # (m, P)
        close = current_mask & (np.take_along_axis(d2, nearest[..., None], axis=2)[..., 0] <= limit * limit)
        n = n_earlier[rows, nearest] * close[..., None]  # (m, P, 2)
        q = moved[rows, nearest]
        residual = ((current - q) * n).sum(axis=2)  # along the normal
        h[:, 0, 0] = (n[..., 0] * n[..., 0]).sum(axis=1) + prior
        h[:, 1, 1] = (n[..., 1] * n[..., 1]).sum(axis=1) + prior
        h[:, 0, 1] = h[:, 1, 0] = (n[..., 0] * n[..., 1]).sum(axis=1)
        g0, g1 = (n[..., 0] * residual).sum(axis=1), (n[..., 1] * residual).sum(axis=1)
        det = h[:, 0, 0] * h[:, 1, 1] - h[:, 0, 1] ** 2
        shift[:, 0] += (h[:, 1, 1] * g0 - h[:, 0, 1] * g1) / det
        shift[:, 1] += (h[:, 0, 0] * g1 - h[:, 0, 1] * g0) / det
        matched = close.sum(axis=1)
    det = h[:, 0, 0] * h[:, 1, 1] - h[:, 0, 1] ** 2
    variance = sigma * sigma * np.stack([h[:, 1, 1] / det, h[:, 0, 0] / det], axis=1)
    return Registration(shift=shift, variance=variance, matched=matched)
