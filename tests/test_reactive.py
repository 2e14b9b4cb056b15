"""Reactive obstacles: a yielding obstacle stops short of a robot in its way; a scripted one does not."""

from typing import ClassVar

import numpy as np
import pytest

from dynabarn.errors import WorldError
from dynabarn.metrics import Outcome
from dynabarn.mjcf import read_world, write_world
from dynabarn.planners import get_planner
from dynabarn.protocol import get_protocol
from dynabarn.recording import MACHINE_FIELDS, McapRecorder, read_recording
from dynabarn.sim import Episode, Simulation, run_episode
from dynabarn.sim.behaviors import ObstacleBehavior, Parameter, Surroundings, register_behavior
from dynabarn.worlds.spec import EndBehavior, Interpolation, Obstacle, WorldSpec
from tests.helpers import obstacle


def _world(path, behavior):
    # A cylinder walking at 1 m/s along x = 11 through the robot parked at the barn spawn (11, 0).
    o = obstacle("obstacle_000", [[0, 11, -9], [18, 11, 9]])
    params = {"yield": {"yield_distance": 1.5}, "avoid": {"avoid_distance": 3.0}}.get(behavior, {})
    o = Obstacle(o.name, o.trajectory, behavior=behavior, behavior_params=params)
    world = WorldSpec(
        name=f"walker_{behavior}",
        world_id=None,
        difficulty="easy",
        obstacles=(o,),
        interpolation=Interpolation.LINEAR,
        end_behavior=EndBehavior.HOLD,
    )
    write_world(world, path)
    return path


def test_yielding_obstacle_stops_while_scripted_one_collides(tmp_path):
    protocol = get_protocol("barn")
    scripted = run_episode(_world(tmp_path / "s.xml", "scripted"), get_planner("stop"), protocol, seed=0)
    assert scripted.outcome is Outcome.COLLISION and scripted.reason == "hit obstacle_000"
    path = _world(tmp_path / "y.xml", "yield")
    rec = tmp_path / "y.mcap"
    yielded = run_episode(path, get_planner("stop"), protocol, seed=0, observers=[McapRecorder(rec)])
    assert yielded.outcome is Outcome.TIMEOUT
    # It waited about its yield distance away (centre to centre), minus the robot's size.
    assert 1.5 - 0.5 - 0.3 < yielded.min_clearance < 1.5
    ys = [m.entities[0].cylinders[0].pose.position.y for _, m in read_recording(rec).topic("/world/obstacles")]
    assert max(ys) < -1.2 and ys[-1] == pytest.approx(max(ys), abs=0.05), "it stopped and stayed"


@pytest.mark.parametrize("speed", [0.5, 1.0, 2.0])
def test_avoiding_obstacle_steps_around_the_robot_and_back_onto_its_path(tmp_path, speed):
    o = obstacle("obstacle_000", [[0, 11, -9], [18 / speed, 11, 9]])
    o = Obstacle(o.name, o.trajectory, behavior="avoid", behavior_params={"avoid_distance": 3.0})
    world = WorldSpec(
        name="walker_avoid",
        world_id=None,
        difficulty="easy",
        obstacles=(o,),
        interpolation=Interpolation.LINEAR,
        end_behavior=EndBehavior.HOLD,
    )
    path = tmp_path / "a.xml"
    write_world(world, path)
    rec = tmp_path / "a.mcap"
    result = run_episode(path, get_planner("stop"), get_protocol("barn"), seed=0, observers=[McapRecorder(rec)])
    assert result.outcome is Outcome.TIMEOUT, "it never touched the robot"
    assert result.min_clearance > 0.1
    xy = np.array(
        [
            (c.pose.position.x, c.pose.position.y)
            for _, m in read_recording(rec).topic("/world/obstacles")
            for c in m.entities[0].cylinders
        ]
    )
    side = xy[:, 0] - 11.0
    # It stepped aside by more than the robot's and its own half sizes (0.33 + 0.5) ...
    assert np.abs(side).max() > 0.83
    # ... on one side only (to its left, -x, with the robot dead ahead), passed, and went back onto its path
    # (its sideways speed is on a 1 um/s grid, so the spring's last few micrometres stay: the dead band).
    assert side.max() < 1e-5
    passed = xy[:, 1] > 2.0
    assert passed.any() and abs(side[-1]) < 0.02 and xy[-1, 1] == pytest.approx(9.0)


@pytest.mark.parametrize("behavior", ["yield", "avoid"])
def test_reactive_episodes_are_deterministic(tmp_path, behavior):
    path = _world(tmp_path / "y.xml", behavior)
    a = run_episode(path, get_planner("straight"), get_protocol("barn"), seed=3).to_dict()
    b = run_episode(path, get_planner("straight"), get_protocol("barn"), seed=3).to_dict()
    wall = set(MACHINE_FIELDS)
    assert {k: v for k, v in a.items() if k not in wall} == {k: v for k, v in b.items() if k not in wall}


def test_behavior_round_trips_and_is_validated(tmp_path):
    path = _world(tmp_path / "y.xml", "yield")
    assert read_world(path).obstacles[0].behavior == "yield"
    o = obstacle("obstacle_000", [[0, 0, 0], [1, 1, 1]])
    with pytest.raises(WorldError, match="must be a name"):
        Obstacle(o.name, o.trajectory, behavior="../x")
    with pytest.raises(WorldError, match="finite number"):
        Obstacle(o.name, o.trajectory, behavior="yield", behavior_params={"yield_distance": float("nan")})
    with pytest.raises(WorldError, match="scripted obstacle takes no"):
        Obstacle(o.name, o.trajectory, behavior_params={"yield_distance": 1.0})
    assert np.all(read_world(tmp_path / "y.xml").obstacles[0].trajectory.xy[:, 0] == 11)
    avoid = read_world(_world(tmp_path / "a.xml", "avoid")).obstacles[0]
    assert (avoid.behavior, dict(avoid.behavior_params)) == ("avoid", {"avoid_distance": 3.0})
    # Names and parameters are checked against the registry when the world is loaded to run.
    for behavior, params, message in [
        ("dance", {}, "unknown obstacle behaviour 'dance'; available: avoid, "),
        ("yield", {"speed": 1.0}, "yield has no parameter 'speed'"),
        ("avoid", {"avoid_distance": -1.0}, r"avoid_distance = -1.0 outside \[0, inf\]"),
    ]:
        bad = Obstacle(o.name, o.trajectory, behavior=behavior, behavior_params=params)
        world = WorldSpec(name="bad", world_id=None, difficulty="easy", obstacles=(bad,))
        write_world(world, tmp_path / "bad.xml")
        with pytest.raises(WorldError, match=message):
            Simulation(tmp_path / "bad.xml")


class Freeze(ObstacleBehavior):
    """The README's example: stops dead while the robot is within `freeze_distance`."""

    name = "freeze"
    parameters: ClassVar = {"freeze_distance": Parameter(2.0, "[m] centre to centre")}

    def rates(self, s: Surroundings) -> np.ndarray:
        return np.where(self.members & (s.dist < self.params["freeze_distance"]), 0.0, 1.0)


def test_a_new_behaviour_is_one_class(tmp_path):
    register_behavior(Freeze)
    o = obstacle("obstacle_000", [[0, 11, -9], [18, 11, 9]])
    o = Obstacle(o.name, o.trajectory, behavior="freeze", behavior_params=Freeze.defaults())
    world = WorldSpec(name="freeze", world_id=None, difficulty="easy", obstacles=(o,), end_behavior=EndBehavior.HOLD)
    write_world(world, tmp_path / "f.xml")
    result = run_episode(tmp_path / "f.xml", get_planner("stop"), get_protocol("barn"), seed=0)
    assert result.outcome is Outcome.TIMEOUT, "it froze before touching the parked robot"
    assert 2.0 - 0.5 - 0.4 < result.min_clearance < 2.0


def test_privileged_prediction_extrapolates_reactive_obstacles(tmp_path):
    # Scripted: the schedule, exactly; reactive: the present velocity, extrapolated.
    for behavior in ("scripted", "avoid"):
        sim = Simulation(_world(tmp_path / f"{behavior}.xml", behavior))
        episode = Episode(sim, get_protocol("barn"), seed=0, privileged=True)
        for _ in range(5):
            obs = episode.observe()
            episode.apply(0.0, 0.0)
        state = obs.obstacles
        future = state.predict(obs.time + np.array([0.5, 1.0]))
        if behavior == "avoid":
            expected = state.positions + np.array([0.5, 1.0])[:, None, None] * state.velocities
        else:
            expected, _ = episode.player.positions_at(obs.time + np.array([0.5, 1.0]))
        assert np.allclose(future, expected)
        assert future[1, 0, 1] > future[0, 0, 1], "it keeps walking along +y"


def test_generated_worlds_can_make_every_obstacle_reactive(tmp_path):
    from dynabarn.cli import worlds_main
    from dynabarn.worlds.generate import generate_world
    from dynabarn.worlds.profiles import get_profile_set
    from dynabarn.worldset import read_index

    plain = generate_world(137, get_profile_set("table1"))
    avoid = generate_world(137, get_profile_set("table1"), behavior="avoid", behavior_params={"avoid_distance": 3.0})
    assert {o.behavior for o in avoid.obstacles} == {"avoid"} and avoid.provenance["behavior"] == "avoid"
    assert [o.trajectory for o in avoid.obstacles] == [o.trajectory for o in plain.obstacles]
    out = tmp_path / "yield"
    assert worlds_main(["generate", "--behavior", "yield", "--out", str(out)]) == 0
    assert read_index(out)["behavior"] == "yield"
    assert {o.behavior for o in read_world(out / "world_250.xml").obstacles} == {"yield"}
