"""Many worlds' schedules evaluated at once, with the bits of each world's own player.

`SchedulePlayer` finds every obstacle's segment with one `searchsorted` over its world's
keyframes, each obstacle's times shifted by its index x 1e6 s. Joining worlds would shift
them by more, which rounds differently and could pick the neighbouring segment when a
clock lies within rounding of a keyframe. So here each obstacle's keys keep the shift
its own world gives them, and the segment is counted (keys at or before the clock, the
same comparisons `searchsorted` makes) over the obstacle's own keys only. The rest is
`schedule.interpolate`'s arithmetic on the joined arrays, elementwise: the same
positions and velocities, bit for bit, as each world's player (a test checks).
"""

from __future__ import annotations

import numpy as np

from dynabarn.worlds.schedule import SchedulePlayer, interpolate
from dynabarn.worlds.spec import EndBehavior

WINDOW = 3
"""Keys past a period's first time compared for its later times (a 0.1 s period passes
at most one or two keyframes; more sends it to the full comparison)."""


def batchable(players: list[SchedulePlayer]) -> bool:
    """One interpolation and one end behaviour across the worlds (what one pass computes)."""
    return len({(p.interpolation, p.end_behavior) for p in players}) == 1


class ScheduleBatch:
    """Positions and velocities of every obstacle of `players`' worlds at per-world times."""

    def __init__(self, players: list[SchedulePlayer]) -> None:
        if not batchable(players):
            raise ValueError("players of one interpolation and end behaviour only")
        self.interpolation = players[0].interpolation
        self.loop = players[0].end_behavior is EndBehavior.LOOP
        counts = np.array([p.n_obstacles for p in players], dtype=np.int64)
        self.world_of = np.repeat(np.arange(len(players)), counts)
        ends = np.cumsum(counts).tolist()
        self._rows = [slice(a, b) for a, b in zip([0, *ends[:-1]], ends, strict=True)]  # each world's obstacles
        live = [p for p in players if p.n_obstacles]
        self.n = int(counts.sum())
        if not self.n:
            return
        self.offset = np.concatenate([np.full(p.n_obstacles, p.clock_offset) for p in live])
        self.durations = np.concatenate([p.durations for p in live])
        self.stride = np.concatenate([p.keyframes.stride_offsets for p in live])
        n_key = np.concatenate([p.n_keyframes for p in live])
        self._flat_t = np.concatenate([p.keyframes.flat_t for p in live])
        self._flat_p = np.concatenate([p.keyframes.flat_p for p in live])
        self._flat_m = np.concatenate([p.keyframes.flat_m for p in live])
        start = np.concatenate([[0], np.cumsum(n_key)[:-1]]).astype(np.int64)
        self._start = start
        self._seg_lo = start
        self._seg_hi = start + np.maximum(n_key - 2, 0)
        # Every obstacle's own keys (shifted as its world's player shifts them), +inf padded,
        # with WINDOW more +inf columns so a window past the last key needs no bounds check.
        width = int(n_key.max()) + WINDOW
        keys = np.full((self.n, width), np.inf)
        own = np.concatenate([p.keyframes.flat_key for p in live])
        col = np.arange(len(own)) - np.repeat(start, n_key)
        keys[np.repeat(np.arange(self.n), n_key), col] = own
        self._keys = keys
        self._keys_by_column = np.ascontiguousarray(keys.T)  # a sum over the long axis: numpy's fast case
        self._window = np.arange(self.n)[:, None] * width + np.arange(WINDOW)  # flat indices from column 0

    def positions_at(self, times: np.ndarray) -> tuple[list[np.ndarray], list[np.ndarray]]:
        """times (T, W): world w's T query times. Per world: positions and velocities (T, n_w, 2)."""
        if not self.n:
            empty = np.zeros((times.shape[0], 0, 2))
            return [empty] * len(self._rows), [empty] * len(self._rows)
        tl = times[:, self.world_of] + self.offset  # as SchedulePlayer.local_time: t + clock_offset
        # fmod is np.mod's first step and, for the non-negative clocks here, its result.
        tl = np.fmod(tl, self.durations) if self.loop else np.minimum(tl, self.durations)
        q = tl + self.stride
        seg = self._start + self._keys_at_or_before(q) - 1
        np.clip(seg, self._seg_lo, self._seg_hi, out=seg)
        pos, vel = interpolate(self.interpolation, self._flat_t, self._flat_p, self._flat_m, tl, seg)
        return [pos[:, r] for r in self._rows], [vel[:, r] for r in self._rows]  # views, as np.split gives

    def _keys_at_or_before(self, q: np.ndarray) -> np.ndarray:
        """(T, n) how many of each obstacle's keys are <= q (T, n): the comparisons of all of
        them for the first time only; a period's later times, no earlier than the first (no
        loop wrapped inside it), can only pass the next few keys, so only those are compared.
        The same counts, exactly; all keys compared again when a period passes more."""
        first = (self._keys_by_column <= q[0]).sum(axis=0)  # (n,)
        if len(q) > 1 and (q[1:] >= q[0]).all():
            ahead = np.take(self._keys, self._window + first[:, None])  # (n, WINDOW), +inf beyond the last key
            if (ahead[:, -1] > q[-1]).all():
                count = first + (ahead[:, 0] <= q)
                for w in range(1, WINDOW):  # a sum over a short last axis is numpy's slow case
                    count += ahead[:, w] <= q
                return count
        return (self._keys[None] <= q[..., None]).sum(axis=-1)
