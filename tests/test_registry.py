"""One registry helper for every named kind: planners, obstacle behaviours, protocols,
profile sets (and shape mixes, static fields) are found the same way: built in,
registered at run time, or installed by another package under an entry-point group. The
installed package here is a real distribution on sys.path, outside this package."""

import sys

import pytest

from dynabarn.errors import DynabarnError, ProfileError, WorldError
from dynabarn.planners.registry import PLANNERS, available_planners, get_planner, planner_spec
from dynabarn.protocol import PROTOCOLS, get_protocol
from dynabarn.registry import Registry
from dynabarn.sim.behaviors import BEHAVIORS, get_behavior
from dynabarn.worlds.profiles import PROFILE_SETS, SHAPE_MIXES, STATIC_FIELDS, get_profile_set
from tests.helpers import GROUPS, install_extension


@pytest.fixture
def installed(tmp_path, monkeypatch):
    install_extension(tmp_path)
    monkeypatch.syspath_prepend(str(tmp_path))
    return tmp_path


def test_every_named_kind_is_one_registry():
    from dynabarn.worlds.importers import IMPORTERS

    for registry in (PLANNERS, BEHAVIORS, PROTOCOLS, PROFILE_SETS, SHAPE_MIXES, STATIC_FIELDS, IMPORTERS):
        assert isinstance(registry, Registry) and registry.builtin <= set(registry.names())
    from dynabarn.perception.trackers import TRACKERS
    from dynabarn.planners.presets import PRESETS

    groups = {PLANNERS.group, BEHAVIORS.group, PROTOCOLS.group, PROFILE_SETS.group, IMPORTERS.group, TRACKERS.group}
    from dynabarn.metric_registry import METRIC_REGISTRY

    groups |= {PRESETS.group, METRIC_REGISTRY.group}
    assert groups | {
        "dynabarn.topics",
        "dynabarn.commands",
    } == set(GROUPS)


def test_an_installed_package_adds_one_of_each_kind(installed):
    assert "ext_planner" in available_planners()
    assert get_planner("ext_planner").act  # the factory loads from the other package
    assert get_behavior("ext_freeze").name == "ext_freeze"
    assert get_protocol("ext_protocol").time_limit == 50.0
    assert get_profile_set("ext_profiles").name == "ext_profiles"
    with pytest.raises(ProfileError, match=r"'broken' failed to load from dynabarn_ext_missing:NOTHING"):
        get_profile_set("broken")
    name, config, label = planner_spec("dwa@ext_preset")  # a preset of another package, by name
    assert (name, config, label) == ("dwa", {"max_vel_x": 0.7}, "dwa@ext_preset")


def test_a_preset_registered_at_run_time_is_used_by_name_and_a_bad_one_refused(tmp_path):
    from dynabarn.planners.presets import PRESETS, Preset

    path = tmp_path / "slow.json"
    path.write_text('{"_extends": "dwa_dynabarn_authors", "max_vel_x": 0.5}')
    PRESETS.register(Preset("slow_authors", path))
    try:
        name, config, _ = planner_spec("dwa@slow_authors")
        assert config["max_vel_x"] == 0.5 and config["vth_samples"] == 40  # the rest from what it extends
        assert get_planner(name, **config).config()["max_vel_x"] == 0.5
        with pytest.raises(DynabarnError, match=r"is not a \.json file"):
            PRESETS.register(Preset("missing", tmp_path / "missing.json"))
        with pytest.raises(DynabarnError, match=r"unknown planner preset 'slow_author'; did you mean 'slow_authors'"):
            planner_spec("dwa@slow_author")
    finally:
        PRESETS.pop("slow_authors", None)


def test_an_installed_import_format_is_offered_and_imports(installed, tmp_path, capsys):
    from dynabarn.cli.worlds import worlds_main
    from dynabarn.worldset import read_index

    with pytest.raises(SystemExit):
        worlds_main(["import", "--help"])
    assert "ext-json, empty arenas" in " ".join(capsys.readouterr().out.split())
    source = tmp_path / "two.json"
    source.write_text('{"count": 2}')
    out = tmp_path / "ext_worlds"
    assert worlds_main(["import", str(source), "--format", "ext-json", "--out", str(out), "--name", "ext"]) == 0
    assert [w["name"] for w in read_index(out)["worlds"]] == ["ext_0", "ext_1"]


def test_unknown_names_are_one_line_listing_what_exists(installed):
    with pytest.raises(DynabarnError, match=r"unknown planner 'nope'; available: .*ext_planner"):
        get_planner("nope")
    with pytest.raises(WorldError, match="unknown obstacle behaviour 'nope'"):
        get_behavior("nope")
    with pytest.raises(DynabarnError, match=r"unknown protocol 'nope'.*ext_protocol.*\(or a \.json file\)"):
        get_protocol("nope")


def test_registering_at_run_time_is_seen_by_the_registry_only_here():
    PROFILE_SETS.register(get_profile_set("table1"), name="run_time_set")
    try:
        assert get_profile_set("run_time_set") is get_profile_set("table1")
        assert PROFILE_SETS.registered_at_run_time("run_time_set")
        assert not PROFILE_SETS.registered_at_run_time("table1")
    finally:
        del PROFILE_SETS["run_time_set"]


def test_the_older_registration_shape_still_works_and_says_the_one_way():
    with pytest.warns(DeprecationWarning, match=r"use register\(item, name='older_set'\)"):
        PROFILE_SETS.register("older_set", get_profile_set("table1"))
    try:
        assert get_profile_set("older_set") is get_profile_set("table1")
    finally:
        del PROFILE_SETS["older_set"]


def test_an_installed_package_adds_a_recording_topic_and_a_command(installed, tmp_path, capsys, monkeypatch):
    from dynabarn.cli.dispatch import main
    from dynabarn.recording import read_recording
    from dynabarn.recording.topic_registry import plotted
    from dynabarn.runner import EpisodeSpec, run_spec
    from dynabarn.worldset import resolve_world

    # A writer process started before the package was on the path (and kept for the next
    # recording) records its topic too.
    with monkeypatch.context() as m:
        m.setattr(sys, "path", [p for p in sys.path if p != str(installed)])
        run_spec(EpisodeSpec.make(resolve_world(5), "stop", get_protocol("barn")), record_to=tmp_path / "first.mcap")
    rec = tmp_path / "ep.mcap"
    run_spec(EpisodeSpec.make(resolve_world(5), "straight", get_protocol("barn")), record_to=rec)
    speeds = read_recording(rec).topic("/robot/speed")
    assert len(speeds) > 10 and max(m["speed"] for _, m in speeds) > 1.0  # it drove
    assert ("/robot/speed", "speed") in [(t.name, f) for t, f in plotted()]
    assert main(["hello", "world"]) == 0 and capsys.readouterr().out.strip() == "hello world"


def test_every_kind_registers_the_same_way_and_keeps_its_contract():
    """`register(item)` under the item's own name, checked: a planner is a `Planner`
    subclass (or a factory whose product is checked when built), a behaviour an
    `ObstacleBehavior` subclass, a protocol an `EvalProtocol`, a profile set a `ProfileSet`."""
    import dataclasses

    from dynabarn.interfaces import Planner
    from dynabarn.planners.registry import register_planner
    from dynabarn.protocol import register_protocol
    from dynabarn.sim.behaviors import Scripted, register_behavior

    class Mine(Planner):
        name = "mine_contract"

        def act(self, obs):
            return 0.0, 0.0

    class Frozen(Scripted):
        name = "frozen_contract"

    protocol = dataclasses.replace(get_protocol("barn"), name="barn_contract")
    profiles = dataclasses.replace(get_profile_set("table1"), name="table1_contract")
    try:
        assert register_planner(Mine) is Mine and isinstance(get_planner("mine_contract"), Mine)
        assert register_behavior(Frozen) is Frozen and get_behavior("frozen_contract") is Frozen
        register_protocol(protocol)
        assert get_protocol("barn_contract") is protocol
        assert PROFILE_SETS.register(profiles) is profiles and get_profile_set("table1_contract") is profiles
        # What breaks a kind's contract is refused when registered, in one line.
        with pytest.raises(DynabarnError, match=r"'not_a_planner'.*not a subclass of dynabarn.interfaces.Planner"):
            register_planner(dict, name="not_a_planner")
        with pytest.raises(WorldError, match=r"not a subclass of dynabarn.sim.behaviors.ObstacleBehavior"):
            BEHAVIORS.register(Mine, name="not_a_behaviour")
        with pytest.raises(DynabarnError, match=r"not a dynabarn.protocol.EvalProtocol"):
            PROTOCOLS.register(profiles, name="not_a_protocol")
        with pytest.raises(ProfileError, match=r"not a dynabarn.worlds.profiles.ProfileSet"):
            PROFILE_SETS.register(protocol, name="not_a_profile_set")
        with pytest.raises(DynabarnError, match="has no name"):
            PROFILE_SETS.register(object())
        # A factory function may build anything; what it built is checked before it drives.
        register_planner(lambda: object(), name="builds_junk")
        with pytest.raises(DynabarnError, match=r"what planner 'builds_junk'.*not a dynabarn.interfaces.Planner"):
            get_planner("builds_junk")
    finally:
        for registry, name in (
            (PLANNERS, "mine_contract"),
            (PLANNERS, "builds_junk"),
            (BEHAVIORS, "frozen_contract"),
            (PROTOCOLS, "barn_contract"),
            (PROFILE_SETS, "table1_contract"),
        ):
            registry.pop(name, None)


def test_a_topic_registered_at_run_time_is_recorded_by_the_writer_process_too(tmp_path):
    """`TOPIC_REGISTRY.register(topic)` as every kind registers: recorded by the default
    recorder (its writer process is handed the topic by reference) and by one in this
    process, the same bytes; a per_tick the writer could not import is refused in one line."""
    from dynabarn.recording import McapRecorder, message_digest, read_recording
    from dynabarn.recording.topic_registry import TOPIC_REGISTRY, recorded_topics
    from dynabarn.recording.topics import Topic
    from dynabarn.runner import EpisodeSpec, run_spec
    from dynabarn.worldset import resolve_world
    from tests.helpers import goal_distance_message

    schema = {"type": "object", "properties": {"distance": {"type": "number"}}}
    topic = Topic("/robot/goal_distance", "x.GoalDistance", "10 Hz", "distance to the goal [m]",
                  json_schema=schema, per_tick=goal_distance_message, plots=("distance",))  # fmt: skip
    TOPIC_REGISTRY.register(topic)
    try:
        assert recorded_topics()[-1] is topic and TOPIC_REGISTRY.registered_at_run_time(topic.name)
        spec = EpisodeSpec.make(resolve_world(5), "straight", get_protocol("barn"))
        run_spec(spec, record_to=tmp_path / "writer.mcap")  # the default: a writer process
        run_spec(spec, observers=[McapRecorder(tmp_path / "here.mcap")])  # this process
        distances = read_recording(tmp_path / "writer.mcap").topic(topic.name)
        assert len(distances) > 10 and distances[0][1]["distance"] > distances[-1][1]["distance"]
        assert message_digest(tmp_path / "writer.mcap") == message_digest(tmp_path / "here.mcap")
        with pytest.raises(DynabarnError, match="is already recorded"):
            TOPIC_REGISTRY.register(topic)
        odd = Topic("/robot/odd", "x.Odd", "10 Hz", "odd", json_schema={}, per_tick=lambda tick: {})
        with pytest.raises(DynabarnError, match=r"/robot/odd: its per_tick cannot be handed to the recording's writer"):
            TOPIC_REGISTRY.register(odd)
        assert "/robot/odd" not in TOPIC_REGISTRY and TOPIC_REGISTRY.group == "dynabarn.topics"
    finally:
        TOPIC_REGISTRY.pop(topic.name, None)
    assert topic not in recorded_topics()


def test_the_loop_refuses_what_is_not_a_planner():
    from dynabarn.sim import run_episode
    from dynabarn.worldset import resolve_world

    class DuckTyped:  # the methods, not the declared contract
        name, privileged = "duck", False

        def reset(self, info): ...

        def act(self, obs):
            return 0.0, 0.0

    with pytest.raises(DynabarnError, match=r"DuckTyped, not a dynabarn.interfaces.Planner"):
        run_episode(resolve_world(0), DuckTyped(), get_protocol("barn"))


def test_the_tracker_a_planner_uses_is_chosen_by_its_configuration():
    from dynabarn.perception import ObstacleTracker
    from dynabarn.perception.trackers import TRACKERS
    from dynabarn.sim import run_episode
    from dynabarn.worldset import resolve_world

    updates = []

    class Counting(ObstacleTracker):
        def update(self, time, scan, pose):
            updates.append(time)
            return super().update(time, scan, pose)

    TRACKERS.register(Counting, name="counting")
    try:
        default = get_planner("dwa", include_dynamic_obstacles=True)
        assert "kind" not in default.config()["tracker"]  # the default is recorded as before the choice
        chosen = get_planner("dwa", include_dynamic_obstacles=True, **{"tracker.kind": "counting"})
        assert chosen.config()["tracker"]["kind"] == "counting"
        result = run_episode(resolve_world(3), chosen, get_protocol("barn"))
        assert len(updates) == result.n_ticks > 0
        with pytest.raises(DynabarnError, match="unknown tracker 'nope'"):
            get_planner("predictive", **{"tracker.kind": "nope"})
        with pytest.raises(DynabarnError, match=r"not a subclass of dynabarn\.interfaces\.tracker\.Tracker"):
            TRACKERS.register(dict, name="not_a_tracker")

        class Unconfigured(ObstacleTracker):
            Config = dict  # not a tracker configuration

        with pytest.raises(DynabarnError, match="is not a dataclass subclassing BaseTrackerConfig"):
            TRACKERS.register(Unconfigured, name="unconfigured")
    finally:
        TRACKERS.pop("counting", None)


def test_what_a_package_installs_is_in_help_a_sweep_and_a_generated_set(installed, tmp_path, capsys):
    """One of each kind from outside the package, used as a user would: offered by `--help`,
    run in a sweep under its own protocol, drawn into worlds with its profiles and behaviour."""
    import json

    from dynabarn.cli.bench import bench_main
    from dynabarn.cli.dispatch import main
    from dynabarn.cli.run import run_main
    from dynabarn.cli.worlds import worlds_main

    for command, args in ((run_main, ["--help"]), (worlds_main, ["generate", "--help"]), (main, ["--help"])):
        with pytest.raises(SystemExit) if command is not main else _nothing():
            command(args)
    shown = " ".join(capsys.readouterr().out.split())
    assert "ext_planner" in shown and "ext_profiles" in shown and "ext_freeze" in shown and "hello" in shown
    out = tmp_path / "sweep"
    argv = ["--planner", "ext_planner", "--protocol", "ext_protocol", "--worlds", "3", "--jobs", "1", "--out", str(out)]
    assert bench_main([*argv, "--trials", "1", "--no-floor"]) == 0
    rows = [json.loads(line) for line in (out / "results.jsonl").read_text().splitlines()]
    assert [(r["planner"], r["protocol"]) for r in rows] == [("ext_planner", "ext_protocol")]
    # Its metric, computed in the episode and aggregated by the summary.
    assert rows[0]["added_metrics"]["ext_turning"] >= 0.0
    assert "ext_turning" in (out / "summary.csv").read_text().splitlines()[0].split(",")
    # Its tracker, chosen by a planner's configuration, tracks in a sweep's episode.
    tracked = tmp_path / "tracked"
    argv = ["--planner", "predictive", "--planner-config", "tracker.kind=ext_tracker", "--worlds", "3"]
    assert bench_main([*argv, "--trials", "1", "--no-floor", "--jobs", "1", "--out", str(tracked)]) == 0
    (row,) = [json.loads(line) for line in (tracked / "results.jsonl").read_text().splitlines()]
    assert row["planner_config"]["tracker"]["kind"] == "ext_tracker" and row["tracking"]["ticks"] > 0
    assert sys.modules["dynabarn_ext"].QuietTracker.scans == row["n_ticks"]
    worlds = tmp_path / "ext_worlds"
    gen = ["generate", "--profiles", "ext_profiles", "--behavior", "ext_freeze", "--out", str(worlds)]
    assert worlds_main(gen) == 0
    index = json.loads((worlds / "index.json").read_text())
    assert "ext_profiles" in json.dumps(index) and "ext_freeze" in (worlds / "world_000.xml").read_text()


class _nothing:
    def __enter__(self):
        return self

    def __exit__(self, *exc):
        return False


def test_a_metric_registered_at_run_time_is_in_the_result_and_a_clash_refused():
    from dynabarn.metric_registry import METRIC_REGISTRY
    from dynabarn.metrics import Metric
    from dynabarn.runner import EpisodeSpec, run_spec
    from dynabarn.worldset import resolve_world

    ticks = Metric("ticks_per_second", "1/s", "control periods per simulated second",
                   lambda f: len(f.tick_v) / f.sim_time if f.sim_time else 0.0, "mean")  # fmt: skip
    METRIC_REGISTRY.register(ticks)
    try:
        result = run_spec(EpisodeSpec.make(resolve_world(0), "straight", get_protocol("barn"))).result
        assert result.to_dict()["added_metrics"] == {"ticks_per_second": pytest.approx(10.0, abs=0.2)}
        with pytest.raises(DynabarnError, match="metric 'score': metric score is already a field of every result"):
            METRIC_REGISTRY.register(Metric("score", "", "again", lambda f: 0.0))
        with pytest.raises(DynabarnError, match="summary 'median'"):
            METRIC_REGISTRY.register(Metric("odd", "", "odd", lambda f: 0.0, "median"))
    finally:
        METRIC_REGISTRY.pop("ticks_per_second", None)
    plain = run_spec(EpisodeSpec.make(resolve_world(0), "straight", get_protocol("barn"))).result
    assert "added_metrics" not in plain.to_dict()  # without added metrics: the row as it always was
