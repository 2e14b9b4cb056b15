"""`dynabarn.check_planner` and `check_tracker`: every shipped planner and tracker keeps the
contract in behaviour, and each mistake a plugin author can make is caught, named in one
line (known answers: planners and trackers built to break one rule each)."""

from __future__ import annotations

import random

import numpy as np
import pytest

import dynabarn
from dynabarn import CheckFailed, Planner, check_planner, check_tracker
from dynabarn.perception import ObstacleTracker
from dynabarn.perception.trackers import TRACKERS
from dynabarn.planners import available_planners
from dynabarn.planners.registry import PLANNERS, register_planner

NEEDS_A_STACK = {"ros": "drives a ROS stack it starts with --launch; tests/test_ros.py runs it with one"}


@pytest.mark.parametrize("name", [n for n in available_planners() if n not in NEEDS_A_STACK])
def test_every_shipped_planner_keeps_the_contract(name, tmp_path):
    config = {}
    if name in ("bc", "td3", "dagger", "ppo"):
        from tests.conftest import require

        require("torch", "learn")
    if name == "ppo":  # none is shipped: an untrained actor of its kind, as dynabarn-train ppo writes one
        from dynabarn.planners.learned.models import Actor, save_policy

        config["policy"] = str(save_policy(Actor(), tmp_path / "ppo.pt", kind="ppo", lookahead=2.0))
    report = check_planner(name, config=config)  # raises CheckFailed, listing every problem
    assert report.passed and report.calls > 10 and report.ms_per_call > 0


@pytest.mark.parametrize("kind", sorted(TRACKERS.builtin))
def test_every_shipped_tracker_keeps_the_contract(kind):
    report = check_tracker(kind)
    assert report.passed and report.calls > 100 and np.isfinite(report.ms_per_call_p95)


class _Breaks(Planner):
    """Steers at the goal, keeping every rule but the one a subclass breaks."""

    name = "breaks"

    def act(self, obs):
        return 0.8, float(np.clip(obs.goal_in_robot[1], -1.0, 1.0))


class _TooFast(_Breaks):
    def act(self, obs):
        return 3.5, 0.0  # the Jackal's limit is 2 m/s: the loop clips it


class _Random(_Breaks):
    def act(self, obs):
        return 0.8, random.uniform(-1.0, 1.0)  # the global generator: no two runs alike


class _Remembers(_Breaks):
    """Its turn rate depends on how many ticks it has driven in all episodes."""

    ticks = 0

    def act(self, obs):
        _Remembers.ticks += 1
        return 0.8, 0.5 if _Remembers.ticks % 7 == 0 else 0.0


class _ConfigNotJson(_Breaks):
    def config(self) -> dict:
        return {"weights": np.ones(3)}


class _Raises(_Breaks):
    def act(self, obs):
        if obs.time > 1.0:
            raise ValueError("index out of range")
        return super().act(obs)


@pytest.mark.parametrize(
    ("planner", "problem"),
    [
        (_TooFast(), "v leaves the robot's limits [-0.5, 2] m/s (up to 3.5)"),
        (_Remembers(), "reset(info) leaves state of the earlier episodes behind"),
        (_ConfigNotJson(), "config() is not JSON data"),
        (_Raises(), "planner raised ValueError: index out of range"),
    ],
    ids=["too-fast", "remembers", "config-not-json", "raises"],
)
def test_each_broken_rule_is_named(planner, problem):
    with pytest.raises(CheckFailed) as info:
        check_planner(planner, seconds=4.0)
    assert problem in str(info.value)
    report = check_planner(planner, seconds=4.0, raise_on_problem=False)
    assert not report.passed and len(report.problems) == 1, report.problems
    assert check_planner(_Breaks(), seconds=4.0).passed  # the same planner keeping every rule


@pytest.fixture
def registered():
    names = []

    def register(factory, name):
        register_planner(factory, name=name)
        names.append(name)

    yield register
    for name in names:
        PLANNERS.pop(name, None)


def test_a_planner_that_draws_from_the_global_generator_is_caught_by_name(registered):
    registered(_Random, "random_turns")
    report = check_planner("random_turns", seconds=4.0, raise_on_problem=False)
    assert any("two planners built alike give other commands" in p for p in report.problems), report.problems


class _Rate(_Breaks):
    """Takes a rate, records it doubled: its recorded configuration builds another planner."""

    def __init__(self, rate: float = 0.5) -> None:
        self.rate = rate

    def config(self) -> dict:
        return {"rate": self.rate * 2}


def test_a_configuration_that_does_not_rebuild_the_planner_is_caught(registered):
    registered(_Rate, "rate")
    report = check_planner("rate", config={"rate": 0.5}, seconds=4.0, raise_on_problem=False)
    assert report.problems == ("the planner built from its recorded config() records another configuration",)


class _LeakyTracker(ObstacleTracker):
    """The Kalman tracker, with every identity shifted by the scans seen in all episodes."""

    scans = 0

    def update(self, time, scan, pose):
        from dataclasses import replace

        _LeakyTracker.scans += 1
        tracks = super().update(time, scan, pose)
        return replace(tracks, ids=tracks.ids + _LeakyTracker.scans)


class _BadShapes(ObstacleTracker):
    def update(self, time, scan, pose):
        from dataclasses import replace

        tracks = super().update(time, scan, pose)
        return replace(tracks, velocities=tracks.velocities[:, :1])


def test_a_tracker_that_keeps_state_between_episodes_or_misshapes_its_tracks_is_caught():
    leaky = check_tracker(_LeakyTracker, seconds=4.0, raise_on_problem=False)
    assert any("state is kept outside the tracker" in p for p in leaky.problems), leaky.problems
    bad = check_tracker(_BadShapes, seconds=4.0, raise_on_problem=False)
    assert any(p.startswith("velocities has shape") for p in bad.problems), bad.problems
    with pytest.raises(CheckFailed, match=r"not a subclass of dynabarn\.interfaces\.tracker\.Tracker"):
        check_tracker(type("NotATracker", (), {"for_episode": classmethod(lambda cls, cfg, info: cls())}))


def test_the_checks_are_the_public_surface():
    assert {"check_planner", "check_tracker", "CheckReport", "CheckFailed"} <= set(dynabarn.__all__)
