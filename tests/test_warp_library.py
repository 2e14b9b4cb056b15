"""A Warp batch of a set's worlds (`learn.warp_library`, `WarpWorlds` with several worlds,
`DynaBARNVectorEnv(backend="warp")`) against MuJoCo's C engine, on Warp's CPU device.

Twenty worlds of the paper's tiers and the four beyond it (static fields, boxes, capsules)
share one padded model; a fixed sequence of commands gives, world by world, the C engine's
pose, scan and ending."""

from __future__ import annotations

import numpy as np
import pytest

from dynabarn.protocol import get_protocol
from dynabarn.sim.episode import Episode
from dynabarn.sim.simulation import Simulation
from dynabarn.worldset import world_set

pytest.importorskip("warp", reason="the Warp backend needs MuJoCo Warp: pip install 'dynabarn[gpu]'")
pytest.importorskip("mujoco_warp", reason="the Warp backend needs MuJoCo Warp: pip install 'dynabarn[gpu]'")
torch = pytest.importorskip("torch")

from dynabarn.learn.warp_library import BELOW, PAD, Padding, WorldLibrary, padded_world  # noqa: E402
from dynabarn.learn.warp_worlds import COLLISION, RUNNING, WarpWorlds  # noqa: E402

POSE_M = 1e-3
"""[m, rad] (measured: 0.006 mm over 12 periods)."""
SCAN_M = 1.5e-3
"""[m] one step of the laser's 1 mm grid."""
GRAZING = 8
"""Beams of one world's scan allowed past SCAN_M: rays grazing an edge, hit in one engine and
missed in the other (float32 directions). Boxes and capsules have more edges than cylinders:
measured at most 3 in a world's 12 scans."""
PERIODS = 12
SETS = (("paper60", 6), ("tier-dense", 3), ("tier-fast", 3), ("tier-mixed", 4), ("tier-combined", 4))


def _twenty_worlds() -> list[tuple[str, int, str]]:
    picks = []
    for name, k in SETS:
        entries = world_set(name)
        step = len(entries) // k
        picks += [(name, int(entries[i * step][0]), str(entries[i * step][1])) for i in range(k)]
    return picks


def _c_ranges(sim: Simulation) -> np.ndarray:
    ranges = sim.laser.cast(sim.model, sim.data, float(sim.data.qpos[2]))
    return np.clip(np.rint(ranges / 1e-3) * 1e-3, 0.1, 30.0)


def _c_episodes(files: list[str], seed: int = 3) -> tuple[list[Simulation], list[Episode]]:
    sims = [Simulation(f) for f in files]
    return sims, [Episode(s, get_protocol("barn"), seed=seed) for s in sims]


def test_twenty_worlds_of_every_tier_in_one_batch_follow_the_c_engine():
    picks = _twenty_worlds()
    files = [p[2] for p in picks]
    assert {"box", "capsule"} <= {s for slot in Padding.covering(WorldLibrary(files[-4:]).worlds).slots for s in slot}
    batch = WarpWorlds(files, len(files), device="cpu", laser_noise=False)
    assert batch.library.padding.n_static > 300  # the static fields of tier-mixed and tier-combined
    sims, episodes = _c_episodes(files)
    n = len(files)
    spawn = np.stack([s.data.qpos[:3] for s in sims])
    batch.reset(np.ones(n, bool), spawn, [e.clock_offset for e in episodes], np.arange(n), world=np.arange(n))
    for period in range(PERIODS):
        command = (1.2, 0.5 * np.sin(period / 6.0))  # one fixed sequence for every world
        scans, poses = batch.scan.numpy(), batch.pose.numpy()[:, :3]
        for i, (sim, episode) in enumerate(zip(sims, episodes, strict=True)):
            if episode.outcome is not None:
                continue
            episode.observe()
            where = f"{picks[i][0]} world {picks[i][1]}, period {period}"
            assert np.abs(poses[i] - sim.data.qpos[:3]).max() <= POSE_M, where
            assert (np.abs(scans[i] - _c_ranges(sim)) > SCAN_M).sum() <= GRAZING, where
            episode.apply(*command)
        batch.step(np.tile(command, (n, 1)))
    outcomes, end_steps = batch.outcome.numpy(), batch.end_step.numpy()
    collided = 0
    for i, episode in enumerate(episodes):
        if episode.outcome is None:
            assert outcomes[i] == RUNNING, picks[i]
        else:  # these commands end only in collisions within 12 periods
            assert episode.outcome.value == "collision" and outcomes[i] == COLLISION, picks[i]
            assert end_steps[i] == episode.step, (picks[i], end_steps[i], episode.step)
            collided += 1
    assert collided >= 2  # measured: tier-dense's hard world 200 and tier-combined's 205


def test_padding_gives_every_world_one_structure_with_its_stand_ins_below_the_floor():
    mixed = [str(e[1]) for e in world_set("tier-mixed")[:2]]
    plain = str(world_set("paper60")[0][1])
    library = WorldLibrary([plain, *mixed])
    worlds = library.worlds
    assert library.padding.n_static == max(len(w.layout.cylinders) for w in worlds)
    assert len(library.padding.slots) == max(len(w.obstacles) for w in worlds)
    model = library.model  # the paper's world: its whole static field is stand-ins
    names = [model.geom(g).name for g in range(model.ngeom)]
    pos = library.fields["geom_pos"]
    for g, name in enumerate(names):
        if name.startswith((PAD, "static_")):
            assert pos[0, g, 2] < BELOW + 1.0, name
    # Slot by slot, each world's own obstacle stands on the floor and the other shapes' stand-ins under it.
    body_of = {int(model.body_mocapid[b]): b for b in range(model.nbody) if model.body_mocapid[b] >= 0}
    for k, world in enumerate(worlds):
        padded = padded_world(world, library.padding).obstacles
        assert len(padded) == library.n_obstacles == model.nmocap
        heights = np.array([pos[k, model.body_geomadr[body_of[j]], 2] for j in range(len(padded))])
        own = np.array([not o.name.startswith(PAD) for o in padded])
        assert own.sum() == len(world.obstacles)
        assert (heights[own] > -1.0).all() and (heights[~own] < BELOW + 1.0).all(), k
    assert library.keys["durations"].shape == (3 * library.n_obstacles,)


def test_a_batch_world_restarted_in_another_world_sees_that_worlds_static_field():
    """Static geoms are placed once when MuJoCo Warp makes its data: a batch world moved to
    another library world takes that world's placement with it (the scan is the C engine's)."""
    files = [str(world_set("paper60")[0][1]), str(world_set("tier-mixed")[0][1]), str(world_set("tier-combined")[0][1])]
    batch = WarpWorlds(files, 2, device="cpu", laser_noise=False)
    assert list(batch.world_of.numpy()) == [0, 1]
    sims, episodes = _c_episodes(files)
    spawn = np.tile(sims[0].data.qpos[:3], (2, 1))
    offsets = [episodes[2].clock_offset, episodes[0].clock_offset]
    batch.reset(np.ones(2, bool), spawn, offsets, [0, 1], world=[2, 0])  # world 0 -> the combined, 1 -> the paper's
    assert list(batch.world_of.numpy()) == [2, 0]
    scans = batch.scan.numpy()
    for row, k in ((0, 2), (1, 0)):
        episodes[k].observe()
        assert (np.abs(scans[row] - _c_ranges(sims[k])) > SCAN_M).sum() <= GRAZING, (row, k)
    with pytest.raises(Exception, match="indices into the batch's 3 worlds"):
        batch.reset(np.ones(2, bool), spawn, offsets, [0, 1], world=[0, 3])


def test_the_vector_environment_gives_the_warp_backend_over_a_sets_worlds():
    from dynabarn.learn.env import DynaBARNEnv
    from dynabarn.learn.vector_env import DynaBARNVectorEnv
    from dynabarn.learn.warp_env import WarpVectorEnv

    env = DynaBARNVectorEnv(4, backend="warp", device="cpu", world_set="tier-mixed", difficulty="hard", seed=5)
    assert isinstance(env, WarpVectorEnv) and len(env.world_files) == 20
    obs, info = env.reset()
    assert obs.shape == (4, 722) and obs.dtype == torch.float32
    worlds = info["world"].numpy()
    assert np.array_equal(worlds, env.trial_worlds[:, 0])
    assert env.single_observation_space.shape == (722,)
    # Environment 0's first episode is the C environment's in that world and trial.
    single = DynaBARNEnv(world_set="tier-mixed", difficulty="hard")
    index = [str(e[1]) for e in single.entries].index(env.world_files[worlds[0]])
    expected, _ = single.reset(seed=0, options={"world_index": index, "trial_seed": int(env.trials[0, 0])})
    assert np.abs(obs[0, 720:].numpy() - expected[720:]).max() <= 5e-3
    assert (np.abs(obs[0, :720].numpy() - expected[:720]) > 6e-3).sum() <= GRAZING
    obs, reward, terminated, truncated, _ = env.step(torch.zeros((4, 2)))
    assert obs.shape == (4, 722) and reward.shape == (4,) and not (terminated | truncated).any()
    single.close()
    env.close()
    with pytest.raises(ValueError, match="backend 'jax'"):
        DynaBARNVectorEnv(2, backend="jax")
    with pytest.raises(ValueError, match="the C engine runs on the CPU"):
        DynaBARNVectorEnv(2, device="cuda")
    with pytest.raises(ValueError, match="workers"):
        DynaBARNVectorEnv(2, backend="warp", workers=1, worlds=[137])
