"""Speed benchmarks (`make bench`): figures measured in one run, printed as a table.

Measures, on one core:
1. the bare loop: mj_step + obstacle schedules + 720-ray scans at 10 Hz, nothing else;
2. the runner with `straight` and `stop` on a hard world, without and with MCAP recording,
   and where a recorded episode spends its time (`recording_cost.py`);
3. world generation (300 worlds) and MCAP recovery;
4. every shipped planner's compute time per call over six worlds of all difficulties, where
   the search planners' time goes (`planner_breakdown.py`: each part their `act` calls),
   and a fixed 60-episode sweep per planner with 2 workers (`sweep_speed.py`: wall time
   and x real time);
5. converting a 60 s recording to a rerun .rrd (and its ratio to the recording's length);
6. the Gymnasium environment's control steps per second (with the learn extra);
7. the speed-up of a 2-worker benchmark sweep over 1 worker;
   the laser tracker's time per scan on a hard world (every obstacle in play), and the
   planners that use it;
8. video frames per second, the default renderer against `--quality high` (MuJoCo's
   defaults, what every video used before).
Each figure is the best of `--repeat` runs (the least disturbed by other processes); the
bare loop and the runner rows are taken in turns, so their ratios hold.
"""

from __future__ import annotations

import argparse
import math
import os
import tempfile
import time
from functools import partial
from pathlib import Path

if "MUJOCO_GL" not in os.environ and not os.environ.get("DISPLAY"):
    os.environ["MUJOCO_GL"] = "egl"  # before mujoco is imported: it picks its OpenGL platform then

import mujoco
import numpy as np
from planner_breakdown import print_breakdown
from planner_scaling import planner_compute
from recording_cost import fixed_costs, recording_breakdown
from sweep_speed import SHIPPED, print_sweep_speeds

from dynabarn.planners import get_planner
from dynabarn.planners.learned.policy import SHIPPED as SHIPPED_POLICIES
from dynabarn.protocol import get_protocol
from dynabarn.recording import McapRecorder, read_recording
from dynabarn.runner import EpisodeSpec, run_spec
from dynabarn.sim import Laser, Simulation
from dynabarn.worlds.schedule import SchedulePlayer
from dynabarn.worldset import resolve_world

HARD_WORLD = 250


def bare_loop(world: int | Path, sim_seconds: float) -> float:
    """Real-time factor of mj_step + schedules + scans and nothing else."""
    sim = Simulation(resolve_world(world))
    model, data, laser = sim.model, sim.data, sim.laser
    player = SchedulePlayer(sim.world, clock_offset=1.0)
    k = sim.config.steps_per_tick
    dt = sim.config.dt
    offsets = np.arange(k) * dt
    n_ticks = round(sim_seconds / sim.config.control_period)
    sim.reset((11.0, 0.0, math.pi))
    n_obs = sim.radii.size
    t0 = time.perf_counter()
    step = 0
    poses = np.empty((k, 3))
    for _ in range(n_ticks):
        xy, _ = player.positions_at(step * dt + offsets)
        data.mocap_pos[:n_obs, :2] = xy[0]
        mujoco.mj_kinematics(model, data)
        laser.cast(model, data, data.qpos[2])
        step += sim.physics.run(xy, poses)[0]  # the period in one call into MuJoCo, as the runner steps it
    return sim_seconds / (time.perf_counter() - t0)


def runner(world_id: int, planner: str, seeds: range, *, record: bool, in_process: bool = False) -> tuple[float, float]:
    """(real-time factor over all episodes, simulated seconds) for the full runner (`run_spec`,
    as every command runs an episode): recording as it does by default (a writer process),
    or with `in_process` the recorder in the episode's process."""
    sim_time = 0.0
    wall = 0.0
    with tempfile.TemporaryDirectory() as tmp:
        for seed in seeds:
            path = Path(tmp) / f"{seed}.mcap"
            observers = [McapRecorder(path)] if record and in_process else []
            t0 = time.perf_counter()
            spec = EpisodeSpec.make(resolve_world(world_id), planner, get_protocol("barn"), seed=seed)
            r = run_spec(spec, record_to=path if record and not in_process else None, observers=observers).result
            wall += time.perf_counter() - t0
            sim_time += r.sim_time
    return sim_time / wall, sim_time


def tracker_cost(world_id: int = HARD_WORLD, n_scans: int = 300) -> tuple[float, float, int]:
    """(mean, p95 [ms], obstacles) of `ObstacleTracker.update` on the scans of a robot
    driving blind through a hard world (the scans gathered first, then tracked alone)."""
    from dynabarn.interfaces import Planner
    from dynabarn.perception import ObstacleTracker, TrackerConfig

    scans: list = []

    class Gather(Planner):
        name = "gather"

        def reset(self, info):
            self.info = info
            self.inner = get_planner("straight")
            self.inner.reset(info)

        def act(self, obs):
            scans.append((obs.time, obs.scan.copy(), obs.pose.copy()))
            return self.inner.act(obs)

    gather = Gather()
    seed = 0
    while len(scans) < n_scans:
        run_spec(
            EpisodeSpec.make(resolve_world(world_id), gather.name, get_protocol("barn"), seed=seed), planner=gather
        )
        seed += 1
    tracker = ObstacleTracker.for_episode(TrackerConfig(), gather.info)
    times = []
    for t, scan, pose in scans[:n_scans]:
        t0 = time.perf_counter()
        tracker.update(t, scan, pose)
        times.append((time.perf_counter() - t0) * 1e3)
    arr = np.array(times)
    return float(arr.mean()), float(np.percentile(arr, 95)), len(Simulation(resolve_world(world_id)).radii)


def recovery_speed() -> float:
    """MB/s at which a recording is read back (100 s, ~1000 scans)."""
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "r.mcap"
        run_spec(EpisodeSpec.make(resolve_world(HARD_WORLD), "stop", get_protocol("barn")), record_to=path)
        t0 = time.perf_counter()
        read_recording(path)
        return path.stat().st_size / 1e6 / (time.perf_counter() - t0)


def replay_conversion() -> tuple[float, float]:
    """(seconds to convert a 60 s recording to .rrd, its length in simulated seconds)."""
    from dynabarn.protocol import EvalProtocol
    from dynabarn.rerun_replay import save_rrd

    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "r.mcap"
        spec = EpisodeSpec.make(resolve_world(HARD_WORLD), "stop", EvalProtocol("sixty", time_limit=60.0))
        result = run_spec(spec, record_to=path).result
        t0 = time.perf_counter()
        save_rrd([read_recording(path)], Path(tmp) / "r.rrd")
        return time.perf_counter() - t0, result.sim_time


def video_speed(quality: str, seconds: float = 10.0) -> tuple[float, float]:
    """(frames per wall second, frames per CPU second) of `dynabarn-render` at 640x480, 20 fps,
    top camera, on a DWA episode of world 137 cut to its first `seconds`."""
    from dynabarn.protocol import EvalProtocol
    from dynabarn.render import render_recording

    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "r.mcap"
        run_spec(EpisodeSpec.make(resolve_world(137), "dwa", EvalProtocol("cut", time_limit=seconds)), record_to=path)
        rec = read_recording(path)
        w0, c0 = time.perf_counter(), time.process_time()
        info = render_recording(rec, Path(tmp) / "v.mp4", quality=quality)
        return info.frames / (time.perf_counter() - w0), info.frames / (time.process_time() - c0)


def env_steps_per_second(n_steps: int = 3000) -> float | None:
    """Control steps per second of DynaBARN-v0 on one core (None without the learn extra)."""
    try:
        import gymnasium

        import dynabarn.learn  # noqa: F401
    except ImportError:
        return None
    env = gymnasium.make("DynaBARN-v0", world_set="paper60")
    env.reset(seed=0)
    action = np.array([0.2, 0.0], dtype=np.float32)
    t0 = time.perf_counter()
    for _ in range(n_steps):
        _, _, term, trunc, _ = env.step(action)
        if term or trunc:
            env.reset()
    return n_steps / (time.perf_counter() - t0)


def vector_env_speed(num_envs: int = 32, seconds: float = 8.0) -> tuple[float, float, float] | None:
    """Control steps per second with random actions on paper60: one DynaBARN-v0, the vector
    environment in this process (one core), and with 2 worker processes (None without the
    learn extra). The same action distribution for all three (episodes end and reset)."""
    try:
        from dynabarn.learn.env import DynaBARNEnv
        from dynabarn.learn.shared_worlds import shared_world
        from dynabarn.learn.vector_env import DynaBARNVectorEnv
    except ImportError:
        return None
    rng = np.random.default_rng(0)

    def timed(step_batch, n_per_call: int) -> float:
        calls, t0 = 0, time.perf_counter()
        while time.perf_counter() - t0 < seconds:
            step_batch()
            calls += 1
        return calls * n_per_call / (time.perf_counter() - t0)

    env = DynaBARNEnv(world_set="paper60")
    for _, file, _ in env.entries:  # every world compiled before the clock starts, as the vector env does
        shared_world(file)
    env.reset(seed=0)

    def single():
        _, _, term, trunc, _ = env.step(rng.uniform(-1, 1, 2).astype(np.float32))
        if term or trunc:
            env.reset()

    out = [timed(single, 1)]
    for workers in (0, 2):
        vec = DynaBARNVectorEnv(num_envs, workers=workers, world_set="paper60")
        vec.reset(seed=0)
        for _ in range(30):  # past the first episodes' starts (the worlds are compiled at construction)
            vec.step(rng.uniform(-1, 1, (num_envs, 2)).astype(np.float32))
        out.append(timed(lambda v=vec: v.step(rng.uniform(-1, 1, (num_envs, 2)).astype(np.float32)), num_envs))
        vec.close()
    return out[0], out[1], out[2]


def sweep_speedup(workers: int = 2) -> tuple[float, float]:
    """(wall seconds with 1 worker, with `workers`) for the same 40 DWA episodes of paper60."""
    from dynabarn import bench, worldset

    worlds = worldset.world_set("paper60", [0, 1, 2, 3, 100, 101, 150, 151, 200, 201])
    jobs = bench.make_jobs([("dwa", {})], worlds, get_protocol("barn"), 4)
    times = []
    for n in (1, workers):
        with tempfile.TemporaryDirectory() as tmp:
            t0 = time.perf_counter()
            bench.run_sweep(jobs, Path(tmp), n_workers=n, folder=False)
            times.append(time.perf_counter() - t0)
    return times[0], times[1]


def scan_cost(world: Path, n: int = 300, *, closed_form: bool = True) -> float:
    """Mean milliseconds of one 720-beam scan from just before the middle of the arena (where
    a mixed world's static field begins), facing it. `closed_form=False` leaves the static
    cylinders to mj_multiRay too (what the runner did before)."""
    sim = Simulation(world)
    if not closed_form:  # a laser told of no static cylinders casts them with mj_multiRay
        sim.laser = Laser(sim.model)
    sim.reset((2.6, 0.0, math.pi))
    mujoco.mj_kinematics(sim.model, sim.data)
    t0 = time.perf_counter()
    for _ in range(n):
        sim.laser.cast(sim.model, sim.data, math.pi)
    return (time.perf_counter() - t0) / n * 1e3


def variant_worlds(tmp: Path) -> list[tuple[str, Path]]:
    """World 250 as the paper's, with mixed shapes, and with shapes and a static BARN field."""
    from dynabarn.mjcf import write_world
    from dynabarn.worlds.generate import generate_world
    from dynabarn.worlds.profiles import SHAPE_MIXES, STATIC_FIELDS, get_profile_set

    out = []
    for label, kw in (
        ("cylinders (the paper's)", {}),
        ("mixed shapes", {"shapes": SHAPE_MIXES["mixed"]}),
        (
            "mixed shapes + static barn-grid field",
            {"shapes": SHAPE_MIXES["mixed"], "static_field": STATIC_FIELDS["barn-grid"]},
        ),
    ):
        world = generate_world(HARD_WORLD, get_profile_set("table1"), **kw)
        path = tmp / f"{len(out)}.xml"
        write_world(world, path)
        out.append((f"{label}, {len(world.layout.cylinders)} static", path))
    return out


def ros_lockstep(world_id: int = 137, stack: str | None = None) -> tuple[float, float, float] | None:
    """dynabarn-ros in lockstep with the tests' rospy stack (or `stack`, one of ours: real
    move_base): (x real time after the boot, bridge ms per control period, round trip ms);
    None without Debian's ROS packages (or without the built move_base)."""
    from dynabarn.planners import get_planner
    from dynabarn.protocol import get_protocol
    from dynabarn.ros.bridge import bridge_overhead
    from dynabarn.ros.nav_build import built, default_workspace
    from dynabarn.worldset import resolve_world

    test_stack = Path(__file__).resolve().parent.parent / "tests" / "ros_stack.py"
    if stack is not None and built(default_workspace()) is None:
        return None
    try:
        planner = (
            get_planner("ros", stack=stack) if stack else get_planner("ros", launch=f"/usr/bin/python3 {test_stack}")
        )
    except Exception:
        return None
    result = run_spec(EpisodeSpec.make(resolve_world(world_id), "ros", get_protocol("barn")), planner=planner).result
    if planner.steady_since is None:
        return None
    # From the first control period after the boot: simulated over wall time, in lockstep.
    steady = (result.sim_time - planner.steady_sim_time) / (time.perf_counter() - planner.steady_since)
    return steady, bridge_overhead(planner), float(np.median(planner.round_trip_ms))


def world_generation() -> float:
    from dynabarn.worlds.profiles import get_profile_set
    from dynabarn.worldset import generate_worlds

    with tempfile.TemporaryDirectory() as tmp:
        t0 = time.perf_counter()
        generate_worlds(get_profile_set("table1"), Path(tmp))
        return time.perf_counter() - t0


def in_turns(measures: dict, repeat: int) -> dict:
    """The best (real-time factor, simulated seconds) of `repeat` runs of each measure, the
    measures taken in turns: a machine slowed for a while slows them alike, so their ratios
    hold (one after the other, a slow spell lowered one measure alone by up to 5 %)."""
    fastest: dict = {}
    for _ in range(repeat):
        for name, measure in measures.items():
            value = measure()
            if name not in fastest or value[0] > fastest[name][0]:
                fastest[name] = value
    return fastest


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--repeat", type=int, default=5, help="runs per figure; the best counts (default: 5)")
    args = parser.parse_args(argv)

    def best(fn, *a, **kw):
        return max((fn(*a, **kw) for _ in range(args.repeat)), key=lambda v: v if not isinstance(v, tuple) else v[0])

    runner(HARD_WORLD, "stop", range(1), record=True)  # the writer process started before the clock runs
    measures = {"bare loop: mj_step + schedules + scans": lambda: (bare_loop(HARD_WORLD, 100.0), 100.0)}
    for planner, seeds in (("stop", range(1)), ("straight", range(20))):
        for record, in_process in ((False, False), (True, False), (True, True)):
            how = "off" if not record else "in this process" if in_process else "on (writer process)"
            measures[(planner, len(seeds), how)] = partial(
                runner, HARD_WORLD, planner, seeds, record=record, in_process=in_process
            )
    fastest = in_turns(measures, args.repeat)
    bare = fastest.pop("bare loop: mj_step + schedules + scans")[0]
    rows = [("bare loop: mj_step + schedules + scans", bare, 1.0)]
    for (planner, n, how), (rtf, sim_s) in fastest.items():
        rows.append((f"runner, {planner} ({n} ep, {sim_s:.0f} s sim), recording {how}", rtf, rtf / bare))
    print(f"world_{HARD_WORLD:03d} (hard), dt 0.005 s, 10 Hz control, one core")
    print(f"{'measure':<66}{'x real time':>12}{'/ bare':>9}")
    for label, rtf, ratio in rows:
        print(f"{label:<66}{rtf:>12.0f}{ratio:>9.2f}")
    print(f"{'where one recorded 100 s episode of `stop` spends its time [ms]':<66}{'ms':>12}{'/ alone':>9}")
    parts = recording_breakdown(HARD_WORLD, args.repeat)
    for label, ms in parts.items():
        print(f"{'  ' + label:<66}{ms:>12.1f}{ms / parts['runner alone']:>9.2f}")
    for label, ms in fixed_costs(HARD_WORLD).items():
        print(f"{label:<66}{ms:>12.2f}")
    print(f"{'generate 300 worlds [s]':<66}{world_generation():>12.2f}")
    with tempfile.TemporaryDirectory() as tmp:
        variants = variant_worlds(Path(tmp))
        print(f"{'world_250 variants':<52}{'scan [ms]':>11}{'bare x RT':>11}{'/ plain':>9}")
        plain = None
        for label, path in variants:
            rtf = best(bare_loop, path, 30.0)
            plain = plain or rtf
            print(f"{label:<52}{scan_cost(path):>11.2f}{rtf:>11.0f}{rtf / plain:>9.2f}")
        label, path = variants[-1]
        slow, fast = scan_cost(path, closed_form=False), scan_cost(path)
        print(f"{'  its scan with every cylinder in mj_multiRay [ms]':<52}{slow:>11.2f}{'':>11}{slow / fast:>8.1f}x")
    print(f"{'planner compute per call':<44}{'mean [ms]':>11}{'p95 [ms]':>11}{'calls':>8}")
    for planner in SHIPPED[1:]:
        mean, p95, calls = planner_compute(planner)
        print(f"{planner:<44}{mean:>11.2f}{p95:>11.2f}{calls:>8}")
    # The student that sees the map (issue 57): the map's closed-form cast on top of its call.
    mean, p95, calls = planner_compute("dagger", policy=str(SHIPPED_POLICIES / "dagger_map.pt"))
    print(f"{'dagger, policy dagger_map.pt':<44}{mean:>11.2f}{p95:>11.2f}{calls:>8}")
    # The tracker that registers returns (issue 57): its registrations on top of predictive's call.
    mean, p95, calls = planner_compute("predictive@registered_tracker")
    print(f"{'predictive@registered_tracker':<44}{mean:>11.2f}{p95:>11.2f}{calls:>8}")
    # TEB against tracks grown by their uncertainty (issue 57): a std per pose and track per evaluation.
    mean, p95, calls = planner_compute("teb@teb_dynamic_uncertain")
    print(f"{'teb@teb_dynamic_uncertain':<44}{mean:>11.2f}{p95:>11.2f}{calls:>8}")
    print_breakdown(("oracle", "predictive", "dwa@dwa_dynabarn_authors", "teb", "dagger"))
    print_sweep_speeds()
    mean, p95, n_obstacles = min(tracker_cost() for _ in range(args.repeat))
    label = f"laser tracker, one scan of world_{HARD_WORLD:03d} ({n_obstacles} obstacles)"
    print(f"{label:<44}{mean:>11.2f}{p95:>11.2f}{300:>8}")
    print(f"{'read back a recording [MB/s]':<66}{recovery_speed():>12.1f}")
    sps = env_steps_per_second()
    if sps is not None:
        print(f"{'DynaBARN-v0 control steps per second (720-ray scan)':<66}{sps:>12.0f}")
    speeds = vector_env_speed()
    if speeds is not None:
        single, batch, two = speeds
        print(f"{'random actions, paper60 [control steps/s]':<66}{'steps/s':>12}{'/ single':>9}")
        print(f"{'  DynaBARN-v0, one environment':<66}{single:>12.0f}{1.0:>9.2f}")
        print(f"{'  DynaBARNVectorEnv, 32 worlds in this process (one core)':<66}{batch:>12.0f}{batch / single:>9.2f}")
        print(f"{'  DynaBARNVectorEnv, 32 worlds in 2 worker processes':<66}{two:>12.0f}{two / single:>9.2f}")
        wide = vector_env_speed(num_envs=64)
        if wide is not None:
            label = "  DynaBARNVectorEnv, 64 worlds in 2 worker processes (aim 10,000)"
            print(f"{label:<66}{wide[2]:>12.0f}{wide[2] / single:>9.2f}")
    one, two = sweep_speedup()
    print(f"{'bench sweep, 40 DWA episodes: 1 worker / 2 workers [s]':<66}{one:>6.1f} /{two:>5.1f}{one / two:>9.2f}x")
    fast, high = best(video_speed, "fast"), best(video_speed, "high")
    label = "video 640x480 (frames/s wall, /s CPU): fast (default) vs --quality high"
    print(f"{label:<66}{fast[0]:>6.1f} /{fast[1]:>5.1f}{fast[0] / high[0]:>8.1f}x")
    print(f"{'  --quality high: MuJoCo defaults, the renderer before issue 19':<66}{high[0]:>6.1f} /{high[1]:>5.1f}")
    conv, length = min(replay_conversion() for _ in range(args.repeat))
    print(f"{f'convert a {length:.0f} s recording to .rrd [s]':<66}{conv:>12.2f}{conv / length:>9.3f}")
    for stack, name in ((None, "rospy test stack"), ("move_base_dwa", "real move_base (make ros-nav)")):
        ros = ros_lockstep(stack=stack)
        if ros is None:
            continue
        rtf, bridge_ms, round_trip_ms = ros
        print(f"{f'dynabarn-ros lockstep, world 137, {name} (x real time)':<66}{rtf:>12.1f}")
        label = "  bridge overhead / full round trip per control period [ms]"
        print(f"{label:<66}{bridge_ms:>6.2f} /{round_trip_ms:>5.2f}")
    return 0


if __name__ == "__main__":  # pragma: no cover
    raise SystemExit(main())
