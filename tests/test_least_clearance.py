"""The least-clearance metric evaluated where it can be the least equals it evaluated
everywhere, bit for bit, on every kind of world; the bounds it rests on hold."""

import dataclasses

import numpy as np
import pytest

from dynabarn.mjcf import read_world, write_world
from dynabarn.planners import get_planner
from dynabarn.protocol import get_protocol
from dynabarn.provenance import SHIPPED_WORLDS
from dynabarn.sim import Simulation, run_episode
from dynabarn.sim import least_clearance as lc
from dynabarn.sim.episode import Episode
from dynabarn.worlds.generate import generate_world
from dynabarn.worlds.profiles import SHAPE_MIXES, STATIC_FIELDS, get_profile_set
from dynabarn.worlds.schedule import SchedulePlayer
from dynabarn.worlds.spec import EndBehavior, Interpolation, WorldSpec
from tests.helpers import crafted_world, obstacle

VARIANTS = {
    "paper": {},
    "spline loop": {"interpolation": Interpolation.SPLINE},
    "linear hold": {"end_behavior": EndBehavior.HOLD},
    "spline hold": {"interpolation": Interpolation.SPLINE, "end_behavior": EndBehavior.HOLD},
    "shapes and a static field": {"shapes": SHAPE_MIXES["mixed"], "static_field": STATIC_FIELDS["barn-grid"]},
}


def _variant(tmp_path, world_id: int, variant: str):
    kw = dict(VARIANTS[variant])
    motion = {k: kw.pop(k) for k in ("interpolation", "end_behavior") if k in kw}
    world = dataclasses.replace(generate_world(world_id, get_profile_set("table1"), **kw), **motion)
    path = tmp_path / f"{world_id}_{variant.replace(' ', '_')}.xml"
    write_world(world, path)
    return Simulation(path)


def _random_walk(rng, n_steps: int, start, speed: float) -> np.ndarray:
    """Poses (n, 3) wandering at up to `speed` [m per step], turning freely (yaw unwrapped)."""
    steps = rng.normal(0.0, speed, (n_steps - 1, 3))
    steps[:, 2] *= 10.0
    return np.vstack([start, start + np.cumsum(steps, axis=0)])


@pytest.mark.parametrize("variant", list(VARIANTS))
def test_pruned_equals_full_on_every_kind_of_world(tmp_path, variant):
    rng = np.random.default_rng(7)
    for world_id in (40, 160, 250):
        sim = _variant(tmp_path, world_id, variant)
        dt = sim.config.dt
        for offset in (0.0, 2.5):
            player = SchedulePlayer(sim.world, clock_offset=offset)
            # Wander among the obstacles (slow and fast: few stretches opened, and many).
            for speed in (0.002, 0.02):
                traj = _random_walk(rng, 6001, [-1.0, 6.0, 0.3], speed)
                full = lc.full_clearance(sim, player, traj, dt)
                assert lc.least_clearance(sim, player, traj, dt) == full


def test_pruned_equals_full_on_episodes_and_evaluates_few_steps(monkeypatch):
    sim = Simulation(SHIPPED_WORLDS / "world_250.xml")
    dt = sim.config.dt
    for planner in ("dwa", "stop"):
        episode = Episode(sim, get_protocol("barn"), seed=3)
        p = get_planner(planner)
        p.reset(episode.info)
        while episode.outcome is None:
            v, w = p.act(episode.observe())
            episode.apply(v, w)
        traj = episode.poses[: episode.step + 1]
        full = lc.full_clearance(sim, episode.player, traj, dt)
        evaluated = []
        clearance = Simulation.clearance

        def counted(self, poses, xy, clearance=clearance, evaluated=evaluated, **kw):
            evaluated.append(len(poses))
            return clearance(self, poses, xy, **kw)

        with monkeypatch.context() as m:
            m.setattr(Simulation, "clearance", counted)
            assert lc.least_clearance(sim, episode.player, traj, dt) == full
        # One step in SAMPLE_STRIDE, and the stretches near the least value: far from every step.
        assert len(traj) > 1000 and sum(evaluated) < 0.25 * len(traj), (sum(evaluated), len(traj))
        # The runner's result is the same number.
        result = run_episode(sim, get_planner(planner), get_protocol("barn"), seed=3)
        assert result.min_clearance == full


def test_the_least_value_inside_a_stretch_is_found(tmp_path):
    """An obstacle crossing in front of a parked robot between two evaluated steps: the least
    value is at neither of them, and is found all the same."""
    path = crafted_world(tmp_path / "crossing.xml", [obstacle("obstacle_000", [[0, 5.0, -10.0], [1, 5.0, 10.0]])])
    sim = Simulation(path)
    dt = 0.005
    player = SchedulePlayer(sim.world)
    # It moves at 20 m/s and passes the robot at steps 105-109, between two evaluated steps
    # where its clearance is 0.31 and 0.76 m.
    traj = np.tile([5.9, 0.7, 0.0], (401, 1))
    c = lc.full_clearance(sim, player, traj, dt)
    at = sim.clearance(traj, player.positions_at(np.arange(401) * dt)[0])
    least = int(np.argmin(at))
    assert 100 < least < 120 and at[least] < min(at[100], at[120]) - 0.1
    assert lc.least_clearance(sim, player, traj, dt) == c == at[least]


def test_max_speed_bounds_every_velocity_and_wraps_are_found():
    for interpolation in Interpolation:
        world = WorldSpec.from_dict(
            {**read_world(SHIPPED_WORLDS / "world_250.xml").to_dict(), "interpolation": interpolation.value}
        )
        player = SchedulePlayer(world, clock_offset=1.3)
        t = np.arange(0, 20000) * 0.005
        xy, vel = player.positions_at(t)
        bound = player.max_speed()
        assert np.hypot(vel[..., 0], vel[..., 1]).max() <= bound
        # Between consecutive steps no obstacle moves further than the bound allows, except
        # where its clock wraps.
        moved = np.hypot(*np.moveaxis(np.diff(xy, axis=0), -1, 0)).max(axis=1)
        wraps = player.clock_wraps(t[:-1], t[1:])
        assert wraps.any() and not wraps.all()
        assert (moved[~wraps] <= bound * 0.005 * (1 + 1e-9)).all()
        assert (moved[wraps] > bound * 0.005).any()  # the paper's paths jump back where they wrap
    held = SchedulePlayer(dataclasses.replace(world, end_behavior=EndBehavior.HOLD))
    assert not held.clock_wraps(t[:-1], t[1:]).any()
