"""The solvability certificate (issue 43): known answers, and witnesses the simulator drives."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest
from helpers import crafted_world, obstacle

from dynabarn.bench.certify import replay_witness
from dynabarn.mjcf import read_world
from dynabarn.protocol import get_protocol
from dynabarn.sim import Episode, Simulation
from dynabarn.sim.certificate import ROBOT_RADIUS, certify
from dynabarn.sim_config import trial_clock_offset
from dynabarn.worldset import resolve_world

BARN = get_protocol("barn")
STRAIGHT = (20.0 - BARN.goal_tolerance) / 2.0
"""[s] Spawn (11, 0) to the goal disc around (-9, 0) at the Jackal's 2 m/s."""


def _ring(centre=(11.0, 0.0), radius=2.0, n=12, opening_at=None):
    """Parked obstacles in a ring around `centre` (no gap the robot's disc fits through);
    with `opening_at` [s] the one straight ahead (towards -x) leaves then, sideways at 4 m/s."""
    out = []
    for k in range(n):
        a = math.pi + 2 * math.pi * k / n
        x, y = centre[0] + radius * math.cos(a), centre[1] + radius * math.sin(a)
        if k == 0 and opening_at is not None:
            leaves = [[0, x, y], [opening_at, x, y], [opening_at + 2.5, x, y + 10], [200, x, y + 10]]
            out.append(obstacle(f"o{k}", leaves))
        else:
            out.append(obstacle(f"o{k}", [[0, x, y], [200, x, y]]))
    return out


def test_ring_gaps_are_closed():
    gap = 2 * 2.0 * math.sin(math.pi / 12) - 2 * 0.5  # between neighbouring discs
    assert gap < 2 * ROBOT_RADIUS
    opened = 2 * 2.0 * math.sin(2 * math.pi / 12) - 2 * 0.5  # one of them gone
    assert opened > 2 * ROBOT_RADIUS + 0.3


def test_an_empty_arena_is_certified_at_the_straight_line_time(tmp_path):
    path = crafted_world(tmp_path / "empty.xml")
    cert = certify(read_world(path), BARN, clock_offset=0.0)
    assert cert.certified and cert.witness is not None
    # The actuator's lag and the goal region shrunk by the tracking margin (5 cm) cost a
    # substep or two (25 ms each) on top of the straight line.
    assert STRAIGHT <= cert.arrival <= STRAIGHT + 0.1
    result, error = replay_witness(path, cert.witness, BARN, seed=0)
    assert result.outcome.value == "success"
    assert error < 0.05


def test_an_obstacle_parked_on_the_spawn_is_not_certified(tmp_path):
    path = crafted_world(tmp_path / "parked.xml", [obstacle("parked", [[0, 11.0, 0.0], [50, 11.0, 0.0]])])
    cert = certify(read_world(path), BARN, clock_offset=0.0)
    assert not cert.certified and cert.witness is None
    assert "spawn" in cert.reason


def test_a_closed_ring_is_not_certified_and_one_that_opens_is_later(tmp_path):
    closed = crafted_world(tmp_path / "closed.xml", _ring())
    cert = certify(read_world(closed), BARN, clock_offset=0.0)
    assert not cert.certified
    assert "time limit" in cert.reason
    opens = crafted_world(tmp_path / "opens.xml", _ring(opening_at=6.0))
    cert = certify(read_world(opens), BARN, clock_offset=0.0)
    assert cert.certified
    assert cert.arrival > 6.0 + (STRAIGHT - 2.0 / 2.0)  # not through the ring before it opens
    result, _ = replay_witness(opens, cert.witness, BARN, seed=0)
    assert result.outcome.value == "success"
    # The clock offset shifts the opening: 2 s later on the obstacles' clocks is 2 s sooner.
    sooner = certify(read_world(opens), BARN, clock_offset=2.0)
    assert sooner.certified and sooner.arrival == pytest.approx(cert.arrival - 2.0, abs=0.3)


def test_a_spent_budget_says_so_and_claims_nothing(tmp_path):
    """The ring that opens at 6 s needs the search past 6 s: a budget it spends before
    then stops it, uncertified, with the reason; a budget it does not reach changes nothing."""
    opens = crafted_world(tmp_path / "opens.xml", _ring(opening_at=6.0))
    full = certify(read_world(opens), BARN, clock_offset=0.0)
    spent = certify(read_world(opens), BARN, clock_offset=0.0, budget=full.expanded // 4)
    assert not spent.certified and spent.witness is None
    assert "budget" in spent.reason and spent.expanded < full.expanded
    ample = certify(read_world(opens), BARN, clock_offset=0.0, budget=full.expanded + 1)
    assert ample.certified and ample.arrival == full.arrival


@pytest.mark.parametrize("world_id, seed", [(299, 0), (250, 1)])
def test_a_witness_replayed_in_the_simulator_is_collision_free(world_id, seed):
    path = resolve_world(world_id)
    cert = certify(read_world(path), BARN, clock_offset=trial_clock_offset(seed))
    assert cert.certified
    result, error = replay_witness(path, cert.witness, BARN, seed=seed)
    assert result.outcome.value == "success"
    assert result.min_clearance > 0.0
    assert error < 0.05  # inside the search's tracking margin
    # The episode ends within a tick of the witness's arrival (its clock starts at 0.1 m).
    assert result.time <= cert.arrival + 0.1


def test_certificates_are_the_same_bits_every_time():
    world = read_world(resolve_world(250))
    a = certify(world, BARN, clock_offset=trial_clock_offset(3))
    b = certify(world, BARN, clock_offset=trial_clock_offset(3))
    assert a.arrival == b.arrival and a.expanded == b.expanded
    assert np.array_equal(a.witness.commands, b.witness.commands)
    assert np.array_equal(a.witness.poses, b.witness.poses)


def test_the_trial_clock_offset_is_the_episodes(tmp_path):
    sim = Simulation(crafted_world(tmp_path / "w.xml"))
    for seed in (0, 7, 123):
        assert Episode(sim, BARN, seed=seed).clock_offset == trial_clock_offset(seed)


def test_reactive_obstacles_are_not_certified():
    world = read_world(resolve_world(0))
    reactive = dataclasses.replace(
        world, obstacles=tuple(dataclasses.replace(o, behavior="yield") for o in world.obstacles)
    )
    cert = certify(reactive, BARN, clock_offset=0.0)
    assert not cert.certified and "reactive" in cert.reason


def _passage_world(tmp_path, gap: float):
    """A wall of standing cylinders (r = 0.25) across the arena at x = 0, with one passage
    `gap` metres wide between two of them at y = 0, on the straight line to the goal."""
    from dynabarn.mjcf import write_world

    world = read_world(crafted_world(tmp_path / "empty.xml"))
    r, pitch = 0.25, 0.45  # neighbours 0.05 m apart elsewhere: closed to the robot
    upper = [(0.0, gap / 2 + r + k * pitch, r) for k in range(30)]
    lower = [(0.0, -(gap / 2 + r + k * pitch), r) for k in range(30)]
    half = world.layout.arena_half_size
    cylinders = tuple(c for c in upper + lower if abs(c[1]) < half)
    world = dataclasses.replace(world, layout=dataclasses.replace(world.layout, cylinders=cylinders))
    path = tmp_path / f"passage_{gap:.2f}.xml"
    write_world(world, path)
    return path, world


@pytest.mark.parametrize(
    ("gap", "disc", "footprint"),
    [
        (1.20, True, True),  # wide: both
        (0.72, False, True),  # narrower than the search's disc (0.84 with margins), wider than the Jackal
        (0.40, False, False),  # narrower than the Jackal (0.43 wide): neither
    ],
)
def test_the_footprint_search_certifies_passages_the_jackal_fits_and_its_disc_does_not(tmp_path, gap, disc, footprint):
    from dynabarn.sim.certificate import CertificateConfig
    from dynabarn.sim.certificate_occupancy import HALF_FOOTPRINT

    assert 2 * HALF_FOOTPRINT[1] < 0.72 < 2 * ROBOT_RADIUS + 0.2
    path, world = _passage_world(tmp_path, gap)
    budget = 2_000_000
    by_disc = certify(world, BARN, clock_offset=0.0, budget=budget)
    by_footprint = certify(world, BARN, clock_offset=0.0, budget=budget, config=CertificateConfig(footprint=True))
    assert by_disc.certified is disc
    assert by_footprint.certified is footprint, by_footprint.reason
    if footprint:  # and MuJoCo drives the witness through without touching a cylinder
        result, error = replay_witness(path, by_footprint.witness, BARN, seed=0)
        assert result.outcome.value == "success", result.reason
        assert error < 0.05


def test_the_footprint_resolution_is_recorded_as_version_3_and_the_disc_as_before():
    from dynabarn.sim.certificate import CertificateConfig

    assert CertificateConfig().to_dict()["version"] == 2
    assert "footprint" not in CertificateConfig().to_dict()  # version 2's records unchanged
    assert CertificateConfig(footprint=True).to_dict()["version"] == 3


def test_the_goal_guided_search_certifies_within_a_budget_the_breadth_first_search_spends_elsewhere(tmp_path):
    """Version 4 (`beam`): the passage on the straight line to the goal, narrower than the
    disc. Breadth-first, the search fills the open arena and spends half a million states
    before it gets there; keeping the 100 states nearest the goal along the static map, it
    drives straight through, arriving when an empty arena's search does, and MuJoCo drives
    its witness without touching a cylinder."""
    from dynabarn.sim.certificate import CertificateConfig

    path, world = _passage_world(tmp_path, 0.72)
    budget = 500_000
    wide = certify(world, BARN, clock_offset=0.0, budget=budget, config=CertificateConfig(footprint=True))
    assert not wide.certified and "budget" in wide.reason
    guided = certify(world, BARN, clock_offset=0.0, budget=budget, config=CertificateConfig(footprint=True, beam=100))
    assert guided.certified, guided.reason
    from dynabarn.bench.certify import unobstructed_arrival

    assert guided.arrival == pytest.approx(unobstructed_arrival(BARN), abs=0.2)
    result, error = replay_witness(path, guided.witness, BARN, seed=0)
    assert result.outcome.value == "success", result.reason
    assert error < 0.05


@pytest.mark.parametrize(
    ("gap", "footprint", "reachable"), [(0.72, True, True), (0.72, False, False), (0.40, True, False)]
)
def test_the_cost_to_go_runs_through_the_passages_the_robot_fits(tmp_path, gap, footprint, reachable):
    """The goal guidance's distances: through the gap along y = 0 the spawn is 20 m from the
    goal (the grid's straight steps are exact); where the robot does not fit at any heading
    (or its disc does not, without the footprint), the spawn is cut off."""
    from dynabarn.sim.certificate import CertificateConfig
    from dynabarn.sim.certificate_occupancy import Occupancy
    from dynabarn.worlds.schedule import SchedulePlayer

    _, world = _passage_world(tmp_path, gap)
    config = CertificateConfig(footprint=footprint, beam=100)
    occupancy = Occupancy.of_search(world, SchedulePlayer(world, clock_offset=0.0), BARN, config)
    cost = occupancy.cost_to_go((float(world.layout.goal[0]), float(world.layout.goal[1])))
    at_spawn = occupancy.lookup(cost, np.array([BARN.spawn[0]]), np.array([BARN.spawn[1]]))[0]
    if reachable:
        assert at_spawn == pytest.approx(20.0, abs=0.06)
    else:
        assert np.isinf(at_spawn)


def test_each_resolution_is_recorded_with_its_version_and_read_back_as_it_was():
    from dynabarn.sim.certificate import CertificateConfig

    for config, version in (
        (CertificateConfig(), 2),
        (CertificateConfig(footprint=True), 3),
        (CertificateConfig(footprint=True, beam=1000), 4),
        (CertificateConfig(beam=50), 4),
    ):
        d = config.to_dict()
        assert d["version"] == version
        assert ("beam" in d) is (version == 4)
        assert CertificateConfig.from_dict(d) == config
    with pytest.raises(ValueError, match="version"):
        CertificateConfig.from_dict({**CertificateConfig(footprint=True).to_dict(), "version": 2})
