"""Crafted worlds with known answers."""

from __future__ import annotations

import textwrap
from pathlib import Path

import numpy as np

from dynabarn.mjcf import write_world
from dynabarn.worlds.spec import EndBehavior, Interpolation, Obstacle, WorldSpec
from dynabarn.worlds.trajectory import Trajectory


def obstacle(name: str, keyframes) -> Obstacle:
    kf = np.asarray(keyframes, dtype=float)
    return Obstacle(name, Trajectory(times=kf[:, 0].copy(), xy=kf[:, 1:].copy(), profile="crafted"))


def crafted_world(path: Path, obstacles=(), *, name="crafted") -> Path:
    world = WorldSpec(
        name=name,
        world_id=None,
        difficulty="easy",
        obstacles=tuple(obstacles),
        profile_set="crafted",
        interpolation=Interpolation.LINEAR,
        end_behavior=EndBehavior.HOLD,
    )
    write_world(world, path)
    return path


def slow_recorded_episode(path: Path, recorder: str, *, say: str) -> str:
    """A script that records a slow `stop`-like episode of world 0 to `path` with
    `recorder` (an expression of `dynabarn.recording`'s names, given `path`) and prints
    "running" at 1 s and `say` (an expression) at 40 s, for a test to kill it midway."""
    return textwrap.dedent(
        f"""
        import time
        from dynabarn.interfaces import Planner
        from dynabarn.protocol import get_protocol
        from dynabarn.recording import McapRecorder
        from dynabarn.recording.background import BackgroundRecorder
        from dynabarn.sim import run_episode
        from dynabarn.worldset import resolve_world

        class Slow(Planner):
            name = "slow"
            def act(self, obs):
                time.sleep(0.004)
                if obs.time == 1.0:
                    print("running", flush=True)
                if abs(obs.time - 40.0) < 1e-9:
                    print({say}, flush=True)
                return 0.0, 0.0

        path = {str(path)!r}
        recorder = {recorder}
        run_episode(resolve_world(0), Slow(), get_protocol("barn"), observers=[recorder])
        """
    )


GROUPS = {
    "dynabarn.planners": "ext_planner = dynabarn_ext:ExtPlanner",
    "dynabarn.behaviors": "ext_freeze = dynabarn_ext:Freeze",
    "dynabarn.protocols": "ext_protocol = dynabarn_ext:PROTOCOL",
    "dynabarn.profile_sets": "ext_profiles = dynabarn_ext:PROFILES\nbroken = dynabarn_ext_missing:NOTHING",
    "dynabarn.topics": "ext_speed = dynabarn_ext:SPEED",
    "dynabarn.commands": "hello = dynabarn_ext:hello_main",
    "dynabarn.importers": "ext-json = dynabarn_ext:IMPORTER",
    "dynabarn.trackers": "ext_tracker = dynabarn_ext:QuietTracker",
    "dynabarn.presets": "ext_preset = dynabarn_ext:PRESET",
    "dynabarn.metrics": "ext_turning = dynabarn_ext:TURNING",
}
"""The entry points of the package `install_extension` installs: one of each kind."""


def install_extension(folder: Path) -> Path:
    """A real distribution, `dynabarn-ext`, outside this package in `folder` (put it on
    sys.path, or PYTHONPATH for a child process): one planner, behaviour, protocol, profile
    set, recording topic, command, world import format, tracker, planner preset and metric
    under their entry-point groups."""
    tmp_path = folder
    folder.mkdir(parents=True, exist_ok=True)
    (tmp_path / "dynabarn_ext.py").write_text(
        textwrap.dedent(
            """
            import dataclasses
            import numpy as np
            from dynabarn.planners.simple import StraightPlanner
            from dynabarn.protocol import get_protocol
            from dynabarn.sim.behaviors import ObstacleBehavior
            from dynabarn.worlds.profiles import get_profile_set

            class ExtPlanner(StraightPlanner):
                name = "ext_planner"

            class Freeze(ObstacleBehavior):
                name = "ext_freeze"
                def rates(self, s):
                    return np.zeros(len(self.members))

            PROTOCOL = dataclasses.replace(get_protocol("barn"), name="ext_protocol", time_limit=50.0)

            from dynabarn.recording.topics import Topic
            SPEED = Topic(
                "/robot/speed", "ext.Speed", "10 Hz", "measured |v| [m/s]",
                json_schema={"type": "object", "properties": {"speed": {"type": "number"}}},
                per_tick=lambda tick: {"speed": abs(float(tick.velocity[0]))},
                plots=("speed",),
            )

            def hello_main(argv):
                print("hello", *argv)
                return 0
            PROFILES = dataclasses.replace(get_profile_set("table1"), name="ext_profiles")

            import json
            from dynabarn.worlds.importers import WorldImporter
            from dynabarn.worlds.spec import WorldSpec
            IMPORTER = WorldImporter(
                "ext-json",
                "empty arenas, as many as the file's count",
                lambda path: json.loads(path.read_text()),
                lambda data, name, declared: [
                    WorldSpec(f"{name}_{i}", i, "easy", ()) for i in range(int(data["count"]))
                ],
            )

            from dynabarn.perception import ObstacleTracker
            class QuietTracker(ObstacleTracker):
                # The Kalman tracker, counting its scans (a tracker of another package).
                scans = 0
                def update(self, time, scan, pose):
                    QuietTracker.scans += 1
                    return super().update(time, scan, pose)

            from pathlib import Path
            from dynabarn.planners.presets import Preset
            PRESET = Preset("ext_preset", Path(__file__).with_name("ext_preset.json"))

            from dynabarn.metrics import Metric
            TURNING = Metric(
                "ext_turning", "rad/s", "mean |commanded yaw rate|",
                lambda f: float(np.abs(f.tick_w_cmd).mean()) if len(f.tick_w_cmd) else 0.0, "mean",
            )
            """
        )
    )
    (tmp_path / "ext_preset.json").write_text('{"_source": "a package of its own", "max_vel_x": 0.7}')
    dist = tmp_path / "dynabarn_ext-0.1.dist-info"
    dist.mkdir()
    (dist / "METADATA").write_text("Metadata-Version: 2.1\nName: dynabarn-ext\nVersion: 0.1\n")
    (dist / "entry_points.txt").write_text("".join(f"[{g}]\n{lines}\n\n" for g, lines in GROUPS.items()))
    return folder


def page_outside_scripts(page: str) -> str:
    """A report's HTML without its script blocks (plotly.js carries URLs in its strings, and
    the data block is checked as data: `report_data`)."""
    import re

    return re.sub(r"<script\b[^>]*>.*?</script>", "", page, flags=re.S)


def report_data(page: str) -> dict:
    """The JSON block a report's script reads (its episodes, recordings and charts)."""
    import json
    import re

    match = re.search(r'<script type="application/json" id="report-data">(.*?)</script>', page, re.S)
    assert match, "the report has no data block"
    return json.loads(match[1])


def assert_urls_stay_inside(page: str) -> None:
    """Every URL of a report is an anchor, a quoted relative path inside its folder, or an
    image inside the page; the policy admits no inline code."""
    import re

    assert "'unsafe-inline'" not in page and "'unsafe-eval'" not in page
    for url in re.findall(r'(?:href|src)="([^"]*)"', page_outside_scripts(page)):
        assert url.startswith(("#", "./", "data:image/")), url
    for recording in report_data(page)["recordings"]:
        assert recording["href"].startswith("./") and ":" not in recording["href"].split("/", 1)[0], recording
        assert recording["still"] is None or recording["still"].startswith("data:image/png;base64,")


def goal_distance_message(tick) -> dict:
    """A topic's `per_tick` registered at run time by the tests: at a module's top level, so
    the recording's writer process imports it (`recording.topic_registry`)."""
    return {"distance": round(float(tick.distance_to_goal), 6)}
