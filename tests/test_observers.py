"""Observer hooks are declared: a misspelt one is refused when the observer is attached."""

from __future__ import annotations

import pytest

from dynabarn.errors import DynabarnError
from dynabarn.interfaces import EpisodeObserver
from dynabarn.interfaces.events import check_hooks, listens
from dynabarn.planners import get_planner
from dynabarn.protocol import get_protocol
from dynabarn.sim import run_episode
from dynabarn.worldset import resolve_world


class Counting(EpisodeObserver):
    def __init__(self) -> None:
        self.ticks = 0

    def on_tick(self, tick) -> None:
        self.ticks += 1


class Misspelt(Counting):
    def on_ticks(self, tick) -> None:  # not a hook: would never be called
        raise AssertionError("never")


def test_declared_hooks_are_called_and_a_misspelt_one_is_refused():
    world, planner, protocol = resolve_world(0), get_planner("straight"), get_protocol("barn")
    counting = Counting()
    result = run_episode(world, planner, protocol, seed=0, observers=[counting])
    assert counting.ticks == result.n_ticks > 0
    with pytest.raises(DynabarnError, match="on_ticks is not a hook"):
        run_episode(world, get_planner("straight"), protocol, seed=0, observers=[Misspelt()])


def test_an_observer_is_an_episode_observer_and_gets_periods_only_for_what_it_overrides():
    world, protocol = resolve_world(0), get_protocol("barn")

    class DuckTyped:  # the hooks' names, but not the declared contract
        def on_tick(self, tick) -> None: ...

    with pytest.raises(DynabarnError, match=r"not a dynabarn.interfaces.EpisodeObserver"):
        run_episode(world, get_planner("straight"), protocol, observers=[DuckTyped()])

    class EndsOnly(EpisodeObserver):
        ended = None

        def on_end(self, result) -> None:
            self.ended = result

    class PosesOnly(EpisodeObserver):
        poses = 0

        def on_poses(self, times, poses) -> None:
            self.poses += len(times)

    assert listens(EndsOnly()) == (False, False) and listens(PosesOnly()) == (False, True)
    assert listens(Counting()) == (True, False)
    ends, poses, counting = EndsOnly(), PosesOnly(), Counting()
    result = run_episode(world, get_planner("straight"), protocol, observers=[ends, poses, counting])
    assert ends.ended == result and counting.ticks == result.n_ticks and poses.poses > result.n_ticks


def test_every_hook_the_loop_calls_is_declared():
    assert {"on_start", "on_tick", "on_poses", "on_end", "on_tick_period", "on_poses_period"} == set(
        EpisodeObserver.HOOKS
    )
    check_hooks(EpisodeObserver())
    from dynabarn.recording.background import BackgroundRecorder  # the writer-process recorder's period hooks

    check_hooks(BackgroundRecorder.__new__(BackgroundRecorder))  # its on_tick_period, on_poses_period


def test_the_loop_step_is_the_one_run_episode_takes():
    """Driven period by period through `EpisodeLoop` (as the Gymnasium environments drive
    it), the straight planner's commands give run_episode's result and its observers' ticks."""
    from dynabarn.provenance import versions
    from dynabarn.sim import Episode, EpisodeLoop, Simulation
    from dynabarn.sim.loop import episode_start

    world, protocol = resolve_world(3), get_protocol("barn")
    counted = Counting()
    reference = run_episode(world, get_planner("straight"), protocol, seed=4, observers=[counted])
    planner, episode = get_planner("straight"), Episode(Simulation(world), protocol, seed=4)
    start = episode_start(episode, protocol, planner="straight", planner_config=planner.config(), versions=versions())
    stepped = Counting()
    loop = EpisodeLoop(episode, start, [stepped])
    planner.reset(episode.info)
    while episode.outcome is None:
        loop.period(*planner.act(episode.observe()))
    result = loop.result()
    clocks = {"wall_time": 0, "rtf": 0, "planner_ms_mean": 0, "planner_ms_p95": 0, "machine": 0}
    assert result.to_dict() | clocks == reference.to_dict() | clocks
    assert stepped.ticks == counted.ticks == result.n_ticks > 0
