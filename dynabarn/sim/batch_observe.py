"""Many worlds' episodes observed at once: what `Episode.observe` does for one, for a batch
of worlds advancing together (`learn.vector_env.WorldBatch`), vectorised across them.

1. the obstacles of every scripted world placed for the period from one evaluation of all
   their schedules (`ScheduleBatch`: the bits of each world's own player);
2. every world's rays in one closed-form pass (`ray_batch`) where the world is of the
   paper's kind (walls and standing cylinders), `mj_multiRay` otherwise;
3. each world's laser noise from its own generator, then the 1 mm grid: each episode's
   `Observation`, as `Episode.observe` makes it.

The observations agree with `Episode.observe`'s to the laser's 1 mm grid (the closed form
and `mj_multiRay` differ by rounding, 1e-12 m, which can move a range across a grid line
only when it lands within that of one).
"""

from __future__ import annotations

import numpy as np

from dynabarn.interfaces.observation import Observation
from dynabarn.sim.episode import Episode
from dynabarn.sim.ray_batch import BatchCaster, supports
from dynabarn.worlds.schedule_batch import ScheduleBatch, batchable


class BatchObserver:
    """Observes a batch of episodes together, keeping what it built (the caster, the
    schedules) while the batch's worlds stay the same."""

    def __init__(self) -> None:
        self._caster: BatchCaster | None = None
        self._caster_sims: list | None = None
        self._schedule: ScheduleBatch | None = None
        self._players: list | None = None

    def observe(self, episodes: list[Episode]) -> list[Observation]:
        """Each episode's observation now (its obstacles placed, its scan cast and its noise
        drawn from its own generator), in the order given."""
        schedules = self._schedules(episodes)
        for k, ep in enumerate(episodes):
            ep.place_obstacles(schedules.get(k))
        laser = episodes[0].sim.laser
        scans = laser.noisy(self._cast(episodes), [ep.rng for ep in episodes])
        return [ep.observe_scan(scans[k]) for k, ep in enumerate(episodes)]

    def _schedules(self, episodes: list[Episode]) -> dict[int, tuple[np.ndarray, np.ndarray]]:
        """This period's obstacle positions and velocities of every scripted world, by its
        index in `episodes`, in one pass (`ScheduleBatch`)."""
        scripted = [k for k, ep in enumerate(episodes) if ep.reactive is None]
        eps = [episodes[k] for k in scripted]
        players = [ep.player for ep in eps]
        if not players or not batchable(players):
            return {}
        if self._players != players:
            self._schedule, self._players = ScheduleBatch(players), players
        if any(ep.dt != eps[0].dt or not np.array_equal(ep.step_offsets, eps[0].step_offsets) for ep in eps):
            return {}  # worlds of other simulation settings: each reads its own schedule
        # Each world's `period_times()` (time = step x dt, + the steps' offsets), all at once.
        steps = np.array([ep.step for ep in eps], dtype=np.float64)
        times = (steps * eps[0].dt)[None, :] + eps[0].step_offsets[:, None]
        pos, vel = self._schedule.positions_at(times)
        return {k: (p, v) for k, p, v in zip(scripted, pos, vel, strict=True)}

    def _cast(self, episodes: list[Episode]) -> np.ndarray:
        """(len(episodes), beams) noise-free ranges: in closed form, all at once, where the
        world allows it; by `mj_multiRay` otherwise."""
        sims = [ep.sim for ep in episodes]
        out = np.empty((len(sims), sims[0].laser.n))
        closed_form = [supports(s) for s in sims]
        batched = [k for k, ok in enumerate(closed_form) if ok]
        if batched:
            bsims = [sims[k] for k in batched]
            if self._caster_sims != bsims:
                self._caster, self._caster_sims = BatchCaster(bsims), bsims
            origins = np.array([s.data.site_xpos[s.laser.site] for s in bsims])
            yaws = np.array([s.data.qpos[2] for s in bsims])
            centres = np.concatenate([episodes[k].obstacle_centres for k in batched])
            out[batched] = self._caster.cast(origins, yaws, centres)
        for k, s in enumerate(sims):
            if not closed_form[k]:
                out[k] = s.laser.cast(s.model, s.data, float(s.data.qpos[2]))
        return out
