"""The compiled models stepped as MuJoCo Menagerie steps its models: in sampled worlds of
every shipped set and tier (and the release's 60 where the reference data is here), the
Jackal driven by pseudo-random commands for a few simulated seconds among the moving
obstacles, failing on any MuJoCo warning or non-finite state. A known answer first: a
state blown up on purpose is caught."""

from __future__ import annotations

import json
from dataclasses import replace
from pathlib import Path

import mujoco
import numpy as np
import pytest

from dynabarn.interfaces import Planner
from dynabarn.protocol import get_protocol
from dynabarn.sim import Simulation, run_episode

ROOT = Path(__file__).resolve().parent.parent
SEED = 20261128
SECONDS = 6.0
"""Simulated seconds a world is driven for (or until the robot touches something)."""
PER_SET = 2
"""Worlds sampled from each difficulty of the shipped set, and from each tier."""


class RandomCommands(Planner):
    """A new command every control period, uniform within the robot's limits, from a
    generator of its own seeded by the episode (the same commands on every machine)."""

    name = "random_commands"

    def reset(self, info) -> None:
        self.rng = np.random.default_rng([SEED, info.seed])
        self.v_limits, self.w_max = info.v_limits, info.w_max

    def act(self, obs) -> tuple[float, float]:
        return float(self.rng.uniform(*self.v_limits)), float(self.rng.uniform(-self.w_max, self.w_max))


def stepping_problems(sim: Simulation) -> list[str]:
    """MuJoCo's warnings raised since the last reset, and any non-finite state."""
    problems = [
        f"MuJoCo warning {mujoco.mjtWarning(i).name} ({sim.data.warning[i].number} times)"
        for i in range(len(sim.data.warning))
        if sim.data.warning[i].number
    ]
    for name in ("qpos", "qvel", "qacc", "mocap_pos", "xpos"):
        if not np.isfinite(getattr(sim.data, name)).all():
            problems.append(f"data.{name} is not finite")
    return problems


def drive(world: Path, seed: int) -> tuple[object, list[str]]:
    sim = Simulation(world)
    protocol = replace(get_protocol("barn"), time_limit=SECONDS)
    result = run_episode(sim, RandomCommands(), protocol, seed=seed, planner_name=RandomCommands.name)
    return result, stepping_problems(sim)


def _shipped_sample() -> list[tuple[str, int]]:
    index = json.loads((ROOT / "generated_worlds" / "index.json").read_text())
    rng = np.random.default_rng(SEED)
    picks = []
    for difficulty in ("easy", "medium", "hard"):
        files = sorted(e["file"] for e in index["worlds"] if e["difficulty"] == difficulty)
        picks += [(f, k) for k, f in enumerate(rng.choice(files, PER_SET, replace=False))]
    return picks


def test_a_blown_up_state_is_caught(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)  # MuJoCo logs the warning to MUJOCO_LOG.TXT here, not in the checkout
    sim = Simulation(ROOT / "generated_worlds" / "world_000.xml")
    mujoco.mj_resetData(sim.model, sim.data)
    assert stepping_problems(sim) == []
    sim.data.qvel[:] = 1e30  # what an unstable contact or a bad command would leave
    mujoco.mj_step(sim.model, sim.data)
    problems = stepping_problems(sim)
    assert any(p.startswith("MuJoCo warning mjWARN_BADQ") for p in problems), problems
    assert "unstable" in (tmp_path / "MUJOCO_LOG.TXT").read_text()


@pytest.mark.parametrize(("file", "seed"), _shipped_sample())
def test_shipped_worlds_step_cleanly_under_random_commands(file, seed):
    result, problems = drive(ROOT / "generated_worlds" / file, seed)
    assert problems == []
    assert result.outcome.value != "error", result.reason
    assert result.sim_time > 0.5  # it drove


@pytest.mark.parametrize("tier", ["tier-dense", "tier-fast", "tier-mixed", "tier-combined"])
def test_tier_worlds_step_cleanly_under_random_commands(tier):
    from dynabarn.worlds.tiers import get_tier
    from dynabarn.worldset.tiers import tier_worlds

    folder = tier_worlds(tier)
    rng = np.random.default_rng([SEED, len(tier)])
    for world_id in rng.choice(list(get_tier(tier).ids), PER_SET, replace=False):
        world = folder / f"world_{int(world_id):03d}.xml"
        result, problems = drive(world, int(world_id))
        assert problems == [], world.name
        assert result.outcome.value != "error", (world.name, result.reason)


def test_release_worlds_step_cleanly_under_random_commands(release_path, tmp_path):
    from dynabarn.cli.worlds import worlds_main

    assert worlds_main(["import", str(release_path), "--name", "release", "--out", str(tmp_path)]) == 0
    files = sorted(tmp_path.glob("release_*.xml"))
    rng = np.random.default_rng(SEED)
    for world in rng.choice(files, 3, replace=False):
        result, problems = drive(Path(world), 0)
        assert problems == [], Path(world).name
        assert result.outcome.value != "error", result.reason
