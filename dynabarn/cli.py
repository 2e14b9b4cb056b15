"""Command-line entry points. Each takes `argv` and returns an exit code.

Errors a person can cause (`DynabarnError`) print one line on stderr and exit 2; a
traceback appears only with `--debug`. Ctrl-C exits 130.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from collections.abc import Callable, Sequence
from pathlib import Path

from dynabarn.errors import DynabarnError

EXIT_USAGE = 2
EXIT_INTERRUPTED = 130


def _version() -> str:
    from importlib.metadata import PackageNotFoundError, version

    try:
        return version("dynabarn")
    except PackageNotFoundError:  # pragma: no cover - running from a source tree
        return "0+unknown"


def _parser(prog: str, description: str) -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(
        prog=prog, description=description, formatter_class=argparse.ArgumentDefaultsHelpFormatter
    )
    p.add_argument("--version", action="version", version=f"%(prog)s {_version()}")
    p.add_argument("--debug", action="store_true", help="show full tracebacks on errors")
    return p


def _run(body: Callable[[argparse.Namespace], int], args: argparse.Namespace) -> int:
    try:
        return body(args)
    except DynabarnError as exc:
        if args.debug:
            raise
        print(f"error: {exc}", file=sys.stderr)
        return EXIT_USAGE
    except KeyboardInterrupt:
        print("interrupted", file=sys.stderr)
        return EXIT_INTERRUPTED


def _progress(desc: str, total: int | None = None):
    from tqdm import tqdm

    return lambda it: tqdm(it, desc=desc, total=total, unit="world", disable=None, leave=False)


# -- dynabarn-worlds ---------------------------------------------------------------------


def worlds_main(argv: Sequence[str] | None = None) -> int:
    from dynabarn.provenance import GENERATED_WORLDS
    from dynabarn.sim.behaviors import available_behaviors
    from dynabarn.worlds.generate import DEFAULT_BASE_SEED
    from dynabarn.worlds.profiles import PROFILE_SETS, SHAPE_MIXES, STATIC_FIELDS

    parser = _parser("dynabarn-worlds", "Generate, import and inspect DynaBARN worlds.")
    sub = parser.add_subparsers(dest="command", required=True)

    g = sub.add_parser(
        "generate",
        help="generate the 300 benchmark worlds (what `make worlds` runs)",
        formatter_class=argparse.ArgumentDefaultsHelpFormatter,
    )
    g.add_argument(
        "--out",
        type=Path,
        default=None,
        help=f"output directory (default: {GENERATED_WORLDS.name} for the paper's worlds, "
        "mixed_worlds when --shapes, --static or --behavior is given)",
    )
    g.add_argument(
        "--seed", type=int, default=DEFAULT_BASE_SEED, help="base seed; world i uses SeedSequence([seed, i])"
    )
    g.add_argument(
        "--profiles",
        choices=sorted(PROFILE_SETS),
        default="table1",
        help="motion profile set: table1 = the paper's Table I; release2022 = measured from the 2022 release",
    )
    g.add_argument(
        "--interpolation",
        choices=["linear", "spline"],
        default="linear",
        help="playback between waypoints: linear (the paper) or spline (Gazebo's PoseAnimation)",
    )
    g.add_argument("--end", choices=["loop", "hold"], default="loop", help="after the last waypoint")
    g.add_argument(
        "--shapes",
        choices=sorted(SHAPE_MIXES),
        default="cylinder",
        help="obstacle shapes (beyond the paper): cylinder = the paper's; mixed = cylinders, boxes and "
        "capsules in equal shares, sizes drawn per obstacle",
    )
    g.add_argument(
        "--static",
        choices=["none", *sorted(STATIC_FIELDS)],
        default="none",
        help="static obstacles beside the moving ones (beyond the paper): barn-grid = a BARN-style "
        "cellular-automaton field of r 0.075 m cylinders across the arena's middle, always crossable",
    )
    g.add_argument(
        "--behavior",
        choices=available_behaviors(),
        default="scripted",
        help="every obstacle's behaviour (beyond the paper): scripted = the paper's; yield = pauses while "
        "the robot is within 1.5 m ahead; avoid = steers around the robot (social force) and back",
    )

    im = sub.add_parser(
        "import", help="import worlds from another format", formatter_class=argparse.ArgumentDefaultsHelpFormatter
    )
    im.add_argument("file", type=Path, help="file to import (e.g. ../shared/reference/dynabarn60.json)")
    im.add_argument(
        "--format",
        choices=["dynabarn-release", "barn-static"],
        default="dynabarn-release",
        help="input format: the DynaBARN release's 60 worlds, or the 300 static BARN worlds",
    )
    im.add_argument("--out", type=Path, default=Path("imported_worlds"), help="output directory")
    im.add_argument(
        "--declared-obstacles",
        action="store_true",
        help="use the plugins the world files name instead of `effective_obstacles` (what Gazebo ran)",
    )

    sh = sub.add_parser(
        "show", help="summarise a world and optionally plot it", formatter_class=argparse.ArgumentDefaultsHelpFormatter
    )
    sh.add_argument("world", help="generated world id (0-299) or path of a world .xml")
    sh.add_argument("--plot", type=Path, default=None, help="write a top-down PNG of the trajectories here")

    st = sub.add_parser(
        "stats",
        help="per-difficulty means of a world set's measured difficulty and obstacle motion",
        formatter_class=argparse.ArgumentDefaultsHelpFormatter,
    )
    st.add_argument("folder", nargs="?", type=Path, default=GENERATED_WORLDS, help="a folder of worlds with index.json")
    st.add_argument("--worlds", default=None, help="only these world ids, e.g. 0-19,200-219 (None: all)")

    args = parser.parse_args(argv)
    return _run(_WORLD_COMMANDS[args.command], args)


def _worlds_generate(args: argparse.Namespace) -> int:
    from dynabarn.provenance import GENERATED_WORLDS
    from dynabarn.sim.behaviors import get_behavior
    from dynabarn.worlds.generate import N_WORLDS
    from dynabarn.worlds.profiles import get_profile_set, get_shape_mix, get_static_field
    from dynabarn.worldset import generate_worlds

    variant = args.shapes != "cylinder" or args.static != "none" or args.behavior != "scripted"
    out = args.out or (Path("mixed_worlds") if variant else GENERATED_WORLDS)
    t0 = time.perf_counter()
    index = generate_worlds(
        get_profile_set(args.profiles),
        out,
        base_seed=args.seed,
        interpolation=args.interpolation,
        end_behavior=args.end,
        shapes=get_shape_mix(args.shapes),
        static_field=None if args.static == "none" else get_static_field(args.static),
        behavior=args.behavior,
        behavior_params=get_behavior(args.behavior).defaults(),
        progress=_progress("generating", N_WORLDS),
    )
    print(f"wrote {N_WORLDS} worlds and {index} in {time.perf_counter() - t0:.1f} s")
    return 0


def _worlds_import(args: argparse.Namespace) -> int:
    from dynabarn.worldset import write_worlds

    if args.format == "barn-static":
        from dynabarn.worlds.importers.barn import import_barn_static, load_barn_json

        worlds = import_barn_static(load_barn_json(args.file))
    else:
        from dynabarn.worlds.importers.release import import_release, load_release_json

        worlds = import_release(load_release_json(args.file), use_effective=not args.declared_obstacles)
    sets = {
        "all": [w.world_id for w in worlds],
        "easy": [w.world_id for w in worlds if w.difficulty == "easy"],
        "medium": [w.world_id for w in worlds if w.difficulty == "medium"],
        "hard": [w.world_id for w in worlds if w.difficulty == "hard"],
    }
    meta = {"generator": "dynabarn import", "source_format": args.format, "source_file": args.file.name}
    index = write_worlds(worlds, args.out, meta=meta, sets=sets, progress=_progress("importing", len(worlds)))
    print(f"imported {len(worlds)} worlds into {args.out} (index {index})")
    return 0


def _worlds_show(args: argparse.Namespace) -> int:
    import numpy as np

    from dynabarn.mjcf import load_model, read_world
    from dynabarn.worldset import resolve_world

    path = resolve_world(args.world)
    world = read_world(path)
    model = load_model(path)
    print(f"{world.name}  ({path})")
    print(
        f"  difficulty {world.difficulty.value}  branch {world.count_class and world.count_class.value}"
        f"/{world.motion_class and world.motion_class.value}  profile set {world.profile_set}  seed {world.seed}"
    )
    print(
        f"  playback {world.interpolation.value}/{world.end_behavior.value}  goal {world.layout.goal}  "
        f"MuJoCo: {model.nbody} bodies, {model.nmocap} mocap, {model.nsensor} sensors"
    )
    if world.layout.cylinders:
        print(f"  static cylinders: {len(world.layout.cylinders)}")
    print(
        f"  {'obstacle':<14}{'profile':<9}{'order':>6}{'wpts':>6}{'duration':>10}{'speed min-max':>16}"
        f"  {'shape':<26}{'behavior'}"
    )
    for o in world.obstacles:
        tr = o.trajectory
        s = tr.segment_speeds()
        size = {
            "cylinder": f"cylinder r {o.radius:.2f}",
            "box": f"box {2 * o.half_length:.2f} x {2 * o.half_width:.2f}",
            "capsule": f"capsule r {o.radius:.2f} l {2 * o.half_length:.2f}",
        }[o.shape]
        print(
            f"  {o.name:<14}{tr.profile:<9}{tr.order:>6}{len(tr.times):>6}{tr.duration:>9.1f}s"
            f"{np.min(s):>9.2f}-{np.max(s):.2f}  {size:<26}{o.behavior}"
        )
    if args.plot:
        from dynabarn.worlds.plot import plot_world

        print(f"wrote {plot_world(world, args.plot)}")
    return 0


def _worlds_stats(args: argparse.Namespace) -> int:
    import numpy as np

    from dynabarn.mjcf import read_world
    from dynabarn.worlds.difficulty import world_measures
    from dynabarn.worldset import parse_ids, read_index

    index = read_index(args.folder)
    entries = index["worlds"]
    if args.worlds:
        wanted = set(parse_ids(args.worlds))
        entries = [e for e in entries if e["id"] in wanted]
    if not entries:
        raise DynabarnError(f"{args.folder}: no worlds selected")
    rows: dict[str, list[dict]] = {}
    for e in _progress("measuring", len(entries))(entries):
        world = read_world(Path(args.folder) / e["file"])
        row = {"obstacles": len(world.obstacles), "static": len(world.layout.cylinders)}
        row |= world_measures(world)
        rows.setdefault(e["difficulty"], []).append(row)
    columns = [
        ("obstacles", "obst", 5, 1),
        ("static", "static", 7, 0),
        ("corridor_blocked", "blocked", 8, 2),
        ("corridor_occupancy", "occup.", 7, 2),
        ("crossings_per_minute", "cross/min", 10, 1),
        ("time_in_corridor", "in corr.", 9, 3),
        ("speed", "speed", 6, 2),
        ("loop_duration", "loop s", 7, 1),
        ("y_span", "y span", 7, 1),
        ("y_zero_crossings", "y=0 x", 6, 1),
    ]
    print(f"{args.folder}: means per difficulty (difficulty from the schedules over 60 s; motion per obstacle)")
    print(f"{'difficulty':<11}{'worlds':>7}" + "".join(f"{title:>{width}}" for _, title, width, _ in columns))
    for difficulty in ("easy", "medium", "hard"):
        rs = rows.get(difficulty, [])
        if rs:
            cells = "".join(
                f"{np.mean([r.get(key, np.nan) for r in rs]):>{width}.{digits}f}" for key, _, width, digits in columns
            )
            print(f"{difficulty:<11}{len(rs):>7}" + cells)
    return 0


_WORLD_COMMANDS = {
    "generate": _worlds_generate,
    "import": _worlds_import,
    "show": _worlds_show,
    "stats": _worlds_stats,
}


# -- dynabarn-run ------------------------------------------------------------------------

EXIT_EPISODE_ERROR = 1


def _planner_config(text: str | None) -> dict:
    """--planner-config: a preset name, a JSON file, or inline `key=value,key=value` (values as JSON)."""
    import json

    from dynabarn.planners import planner_presets, read_planner_config

    if not text:
        return {}
    if text in planner_presets() or text.endswith(".json"):
        return read_planner_config(text)
    cfg = {}
    for item in text.split(","):
        key, sep, value = item.partition("=")
        if not sep or not key.strip():
            raise DynabarnError(
                f"bad --planner-config item {item!r}: use key=value[,key=value], a .json file or a preset ("
                + ", ".join(planner_presets())
                + ")"
            )
        try:
            cfg[key.strip()] = json.loads(value)
        except json.JSONDecodeError:
            cfg[key.strip()] = value
    return cfg


def run_main(argv: Sequence[str] | None = None) -> int:
    from dynabarn.planners import available_planners

    parser = _parser(
        "dynabarn-run",
        "Run one episode of a planner in a DynaBARN world, print its outcome and metrics, and record it to MCAP.",
    )
    parser.add_argument("--world", required=True, help="generated world id (0-299) or path of a world .xml")
    parser.add_argument(
        "--planner", default="straight", help=f"planner name; available: {', '.join(available_planners())}"
    )
    parser.add_argument(
        "--planner-config",
        default=None,
        help="planner parameters: key=value[,key=value], a .json file, or a shipped preset "
        "(dwa_barn_challenge = the BARN Challenge's DWA configuration; teb_narrow = TEB for BARN's passages)",
    )
    parser.add_argument(
        "--policy", type=Path, default=None, help="weights for bc/td3 (default: the policy shipped in the package)"
    )
    parser.add_argument("--protocol", default="barn", help="evaluation protocol: barn, paper2022, or a .json file")
    parser.add_argument("--seed", type=int, default=0, help="trial seed: obstacle clock offset and laser noise")
    log = parser.add_mutually_exclusive_group()
    log.add_argument(
        "--log",
        type=Path,
        default=None,
        help="MCAP file to record to (default: runs/<world>_<planner>_<protocol>_s<seed>.mcap)",
    )
    log.add_argument("--no-log", action="store_true", help="do not record")
    parser.add_argument("--runs-dir", type=Path, default=Path("runs"), help="folder of default recordings")
    parser.add_argument("--json", action="store_true", help="print the full result as JSON instead of one line")
    parser.add_argument("--dt", type=float, default=0.005, help="physics step [s], at most 0.01")
    parser.add_argument("--control-rate", type=float, default=10.0, help="planner and laser rate [Hz]")
    parser.add_argument("--video", type=Path, default=None, help="also render the episode to this .mp4 or .gif")
    parser.add_argument("--camera", choices=["top", "follow"], default="top", help="camera of --video")
    args = parser.parse_args(argv)
    return _run(_run_episode, args)


def _run_episode(args: argparse.Namespace) -> int:
    import json

    from dynabarn.metrics import Outcome
    from dynabarn.planners import get_planner
    from dynabarn.protocol import get_protocol
    from dynabarn.recording import McapRecorder, default_run_path
    from dynabarn.sim import SimConfig, Simulation, run_episode
    from dynabarn.worldset import resolve_world

    world_path = resolve_world(args.world)
    protocol = get_protocol(args.protocol)
    config = _planner_config(args.planner_config)
    if args.policy is not None:
        config["policy"] = str(args.policy)
    planner = get_planner(args.planner, **config)
    sim = Simulation(world_path, config=SimConfig(dt=args.dt, control_rate=args.control_rate))
    log_path = None
    observers = []
    if args.video is not None and args.video.suffix.lower() not in (".mp4", ".gif"):
        raise DynabarnError(f"--video must end in .mp4 or .gif, got {args.video.name!r}")
    if not args.no_log:
        log_path = args.log or default_run_path(args.runs_dir, sim.world.name, args.planner, protocol.name, args.seed)
    elif args.video is not None:  # the video is rendered from a recording: keep a temporary one
        import tempfile

        log_path = Path(tempfile.mkdtemp()) / "episode.mcap"
    if log_path is not None:
        observers.append(McapRecorder(log_path))
    try:
        result = run_episode(sim, planner, protocol, seed=args.seed, observers=observers, planner_name=args.planner)
    except KeyboardInterrupt:
        if log_path:
            print(f"interrupted; recording kept: {log_path}", file=sys.stderr)
        raise
    if args.json:
        d = result.to_dict()
        d["recording"] = str(log_path) if log_path and not args.no_log else None
        print(json.dumps(d, indent=1, sort_keys=True))
    else:
        print(result.summary())
        if log_path and not args.no_log:
            print(f"recording: {log_path}")
    if args.video is not None:
        _render_video(log_path, args.video, args.camera, 20.0, "640x480")
        if args.no_log:
            import shutil

            shutil.rmtree(log_path.parent, ignore_errors=True)
    if result.outcome is Outcome.ERROR:
        if not args.json:
            print(f"error: {result.reason}", file=sys.stderr)
        return EXIT_EPISODE_ERROR
    return 0


# -- dynabarn-replay / dynabarn-render ----------------------------------------------------------


def replay_main(argv: Sequence[str] | None = None) -> int:
    parser = _parser(
        "dynabarn-replay",
        "Show MCAP recordings in rerun: the scene, the scan, the robot's path and the plots on a sim_time "
        "timeline. Several recordings of one world open together for comparison.",
    )
    parser.add_argument("recordings", nargs="+", type=Path, help="MCAP recordings (from dynabarn-run)")
    parser.add_argument("--save", type=Path, default=None, help="write an .rrd file instead of opening a viewer")
    parser.add_argument("--web", action="store_true", help="serve rerun's web viewer on loopback instead")
    args = parser.parse_args(argv)
    return _run(_replay, args)


def _replay(args: argparse.Namespace) -> int:
    import os
    import time

    from dynabarn.recording import read_recording
    from dynabarn.replay import open_viewer, save_rrd

    recs = []
    for path in args.recordings:
        rec = read_recording(path)
        if rec.truncated:
            print(f"warning: {path} is truncated ({rec.error}); replaying up to the cut", file=sys.stderr)
        if rec.metadata is None:
            raise DynabarnError(f"{path}: no /world/metadata message; not a dynabarn recording")
        recs.append(rec)
    worlds = {r.metadata["world"]["name"] for r in recs}
    if len(worlds) > 1:
        print(
            f"warning: recordings of different worlds ({', '.join(sorted(worlds))}); walls of the first shown",
            file=sys.stderr,
        )
    save = args.save
    if save is None and not args.web and not (os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY")):
        save = args.recordings[0].with_suffix(".rrd")
        print(f"no display: saving to {save} instead (open it with `rerun {save}`)", file=sys.stderr)
    t0 = time.perf_counter()
    if save is not None:
        counts = save_rrd(recs, save)
        total = sum(c.scans for c in counts)
        print(f"wrote {save} ({len(recs)} recording(s), {total} scans) in {time.perf_counter() - t0:.2f} s")
        return 0
    open_viewer(recs, web=args.web)
    if args.web:
        print("serving rerun's web viewer on loopback; Ctrl-C to stop", file=sys.stderr)
        try:
            while True:
                time.sleep(1.0)
        except KeyboardInterrupt:
            return 0
    return 0


def render_main(argv: Sequence[str] | None = None) -> int:
    parser = _parser(
        "dynabarn-render",
        "Render a recorded episode to a video offscreen with MuJoCo (EGL or OSMesa, no GPU needed).",
    )
    parser.add_argument("recording", type=Path, help="MCAP recording (from dynabarn-run)")
    parser.add_argument("--out", type=Path, required=True, help="video file, .mp4 or .gif")
    parser.add_argument("--camera", choices=["top", "follow"], default="top", help="whole arena or behind the robot")
    parser.add_argument("--fps", type=float, default=20.0, help="frames per second of the video")
    parser.add_argument("--size", default="640x480", help="frame size WIDTHxHEIGHT")
    args = parser.parse_args(argv)
    return _run(_render, args)


def _parse_size(text: str) -> tuple[int, int]:
    w, sep, h = text.lower().partition("x")
    if not sep or not w.isdigit() or not h.isdigit() or int(w) < 16 or int(h) < 16:
        raise DynabarnError(f"bad --size {text!r}: use WIDTHxHEIGHT, e.g. 640x480")
    return int(w), int(h)


def _render_video(recording: Path, out: Path, camera: str, fps: float, size: str) -> None:
    from tqdm import tqdm

    from dynabarn.recording import read_recording
    from dynabarn.render import render_recording

    if fps <= 0:
        raise DynabarnError("--fps must be positive")
    width, height = _parse_size(size)
    rec = read_recording(recording)
    if rec.truncated:
        print(f"warning: {recording} is truncated ({rec.error}); rendering up to the cut", file=sys.stderr)
    info = render_recording(
        rec,
        out,
        camera=camera,
        fps=fps,
        width=width,
        height=height,
        progress=lambda it: tqdm(it, desc="rendering", unit="frame", disable=None, leave=False),
    )
    print(f"wrote {info.path}: {info.frames} frames, {info.duration:.2f} s at {info.fps:g} fps, {width}x{height}")


def _render(args: argparse.Namespace) -> int:
    _render_video(args.recording, args.out, args.camera, args.fps, args.size)
    return 0


# -- dynabarn-teleop / dynabarn-demos ------------------------------------------------------


def teleop_main(argv: Sequence[str] | None = None) -> int:
    parser = _parser(
        "dynabarn-teleop",
        "Drive the Jackal yourself in MuJoCo's viewer and record a demonstration. Keys: Up/Down speed, "
        "Left/Right turn, Space stop, 1 slow mode, 2 fast mode, Escape end. A gamepad works when pygame sees one.",
    )
    parser.add_argument("--world", required=True, help="generated world id (0-299) or path of a world .xml")
    parser.add_argument("--protocol", default="barn", help="barn, paper2022, or a .json file")
    parser.add_argument("--seed", type=int, default=0, help="trial seed: obstacle clock offset and laser noise")
    parser.add_argument("--operator", default="human", help="your name, stored with the demonstration")
    parser.add_argument("--demos-dir", type=Path, default=Path("demos"), help="folder of demonstrations")
    parser.add_argument(
        "--out", type=Path, default=None, help="recording file (default: DEMOS_DIR/<world>_<operator>_<NNN>.mcap)"
    )
    parser.add_argument("--speed", type=float, default=1.0, help="simulated seconds per wall-clock second")
    args = parser.parse_args(argv)
    code = _run(_teleop, args)
    from dynabarn import teleop

    if teleop.viewer_was_opened():
        # Everything is written and closed by now. Some Mesa GLX drivers crash (or hang) in
        # the interpreter's teardown after MuJoCo's viewer thread has used them, which would
        # turn a clean session into exit code 139: leave without that teardown.
        import os

        sys.stdout.flush()
        sys.stderr.flush()
        os._exit(code)
    return code


def _teleop(args: argparse.Namespace) -> int:
    import os

    from dynabarn.metrics import Outcome
    from dynabarn.mjcf import read_world
    from dynabarn.protocol import get_protocol
    from dynabarn.teleop import append_manifest, next_demo_path, run_teleop
    from dynabarn.worldset import resolve_world

    if not os.environ.get("DISPLAY") and not os.environ.get("WAYLAND_DISPLAY"):
        raise DynabarnError("dynabarn-teleop needs a display (or Xvfb); none is set")
    if args.speed <= 0:
        raise DynabarnError("--speed must be positive")
    world_path = resolve_world(args.world)
    protocol = get_protocol(args.protocol)
    world = read_world(world_path)
    out = args.out or next_demo_path(args.demos_dir, world.name, args.operator)
    result, pad = run_teleop(world_path, protocol, out, operator=args.operator, seed=args.seed, speed=args.speed)
    append_manifest(
        out.parent,
        {
            "file": out.name,
            "world": world.name,
            "world_id": world.world_id,
            "protocol": protocol.name,
            "seed": args.seed,
            "outcome": result.outcome.value,
            "reason": result.reason,
            "time": result.time,
            "operator": args.operator,
            "source": "human",
            "gamepad": pad,
        },
    )
    print(result.summary())
    print(f"demonstration: {out} (manifest: {out.parent / 'manifest.jsonl'})")
    operator_stop = result.outcome is Outcome.ERROR and result.reason == "ended by the operator"
    return EXIT_EPISODE_ERROR if result.outcome is Outcome.ERROR and not operator_stop else 0


def demos_main(argv: Sequence[str] | None = None) -> int:
    from dynabarn.demos import DEFAULT_LOOKAHEAD

    parser = _parser("dynabarn-demos", "Collect synthetic demonstrations and export datasets for learning.")
    sub = parser.add_subparsers(dest="command", required=True)
    ex = sub.add_parser(
        "export",
        help="recordings -> dataset.npz of (720 ranges, local goal) -> (v, w) rows",
        formatter_class=argparse.ArgumentDefaultsHelpFormatter,
    )
    ex.add_argument("demos", nargs="+", type=Path, help="recordings or folders of recordings")
    ex.add_argument("--out", type=Path, required=True, help="dataset file (.npz)")
    ex.add_argument("--all", action="store_true", help="keep unsuccessful episodes too")
    ex.add_argument("--lookahead", type=float, default=DEFAULT_LOOKAHEAD, help="local goal distance along the plan [m]")
    co = sub.add_parser(
        "collect",
        help="record oracle demonstrations at scale (synthetic, marked so)",
        formatter_class=argparse.ArgumentDefaultsHelpFormatter,
    )
    co.add_argument("--set", default="paper60", help="world set: paper60, dynabarn300, or a folder with index.json")
    co.add_argument("--worlds", default=None, help="only these world ids, e.g. 0,5,100-119")
    co.add_argument("--trials", type=int, default=1, help="seeds 0..N-1 per world")
    co.add_argument("--protocol", default="barn", help="barn, paper2022, or a .json file")
    co.add_argument("--planner", default="oracle", help="demonstrator planner")
    co.add_argument("--jobs", type=int, default=__import__("os").cpu_count() or 1, help="parallel workers")
    co.add_argument("--out", type=Path, default=Path("demos"), help="folder of demonstrations")
    args = parser.parse_args(argv)
    return _run(_demos_export if args.command == "export" else _demos_collect, args)


def _demos_export(args: argparse.Namespace) -> int:
    from tqdm import tqdm

    from dynabarn.demos import export

    if args.out.suffix != ".npz":
        raise DynabarnError(f"--out must be a .npz file, got {args.out.name!r}")
    meta = export(
        args.demos,
        args.out,
        include_all=args.all,
        lookahead=args.lookahead,
        progress=lambda it: tqdm(it, desc="reading", unit="rec", disable=None, leave=False),
    )
    print(f"wrote {args.out}: {meta['episodes']} episodes, {meta['rows']} rows ({len(meta['skipped'])} skipped)")
    return 0


def _demos_collect(args: argparse.Namespace) -> int:
    from tqdm import tqdm

    from dynabarn import bench, worldset
    from dynabarn.planners import get_planner
    from dynabarn.protocol import get_protocol
    from dynabarn.teleop import MANIFEST, append_manifest

    get_planner(args.planner)
    protocol = get_protocol(args.protocol)
    worlds = worldset.world_set(args.set, worldset.parse_ids(args.worlds))
    jobs = bench.make_jobs([(args.planner, {})], worlds, protocol, args.trials, record="all", recordings_dir=args.out)
    report = bench.run_sweep(
        jobs,
        args.out / ".collect",
        n_workers=args.jobs,
        progress=lambda stream, total: tqdm(stream, total=total, desc="demos", unit="ep", disable=None),
    )
    listed = set()
    if (args.out / MANIFEST).is_file():
        listed = {json.loads(line)["file"] for line in (args.out / MANIFEST).read_text().splitlines() if line}
    for row in sorted(report.rows, key=lambda r: r["key"]):
        name = Path(row.get("recording", "")).name
        if not name or name in listed:
            continue
        append_manifest(
            args.out,
            {
                "file": name,
                "world": row.get("world"),
                "world_id": row["world_id"],
                "protocol": row["protocol"],
                "seed": row["seed"],
                "outcome": row["outcome"],
                "reason": row.get("reason", ""),
                "time": row.get("time"),
                "operator": "",
                "source": "oracle" if args.planner == "oracle" else "planner",
            },
        )
    ok = sum(r["outcome"] == "success" for r in report.rows)
    print(f"{len(report.rows)} demonstrations in {args.out} ({ok} successful); manifest: {args.out / MANIFEST}")
    return 0


# -- dynabarn-train ----------------------------------------------------------------------


def train_main(argv: Sequence[str] | None = None) -> int:
    parser = _parser(
        "dynabarn-train", "Train the learned baselines (needs the learn extra: pip install -e '.[learn]')."
    )
    sub = parser.add_subparsers(dest="command", required=True)
    bc = sub.add_parser(
        "bc", help="behaviour cloning from a dataset", formatter_class=argparse.ArgumentDefaultsHelpFormatter
    )
    bc.add_argument("--data", type=Path, required=True, help="dataset from `dynabarn-demos export`")
    bc.add_argument("--out", type=Path, required=True, help="policy file to write (.pt)")
    bc.add_argument("--epochs", type=int, default=30, help="passes over the data")
    bc.add_argument("--batch-size", type=int, default=256, help="rows per gradient step")
    bc.add_argument("--lr", type=float, default=1e-3, help="Adam learning rate")
    bc.add_argument("--seed", type=int, default=0, help="torch seed")
    td = sub.add_parser(
        "td3", help="TD3 reinforcement learning", formatter_class=argparse.ArgumentDefaultsHelpFormatter
    )
    td.add_argument("--set", default="paper60", help="world set to train in")
    td.add_argument("--difficulty", default="easy", help="easy, medium, hard or all")
    td.add_argument("--protocol", default="barn", help="barn, paper2022 or a .json file")
    td.add_argument("--steps", type=int, default=20_000, help="environment steps in total")
    td.add_argument("--envs", type=int, default=1, help="parallel environments (one process each when > 1)")
    td.add_argument("--eval-every", type=int, default=5_000, help="steps between evaluations and checkpoints")
    td.add_argument("--eval-episodes", type=int, default=10, help="episodes per evaluation")
    td.add_argument("--start-steps", type=int, default=2_000, help="uniformly random actions first")
    td.add_argument("--seed", type=int, default=0, help="seed of torch, the buffer and the environments")
    td.add_argument("--out", type=Path, required=True, help="folder for checkpoints, policy.pt and the learning curve")
    args = parser.parse_args(argv)
    return _run(_train, args)


def _train(args: argparse.Namespace) -> int:
    from tqdm import tqdm

    try:
        import torch  # noqa: F401
    except ImportError:
        raise DynabarnError("dynabarn-train needs the learn extra: pip install -e '.[learn]'") from None
    if args.command == "bc":
        from dynabarn.learn.bc import train_bc

        report = train_bc(
            args.data,
            args.out,
            epochs=args.epochs,
            batch_size=args.batch_size,
            lr=args.lr,
            seed=args.seed,
            progress=lambda it: tqdm(it, desc="epochs", disable=None, leave=False),
        )
        print(
            f"wrote {args.out}: {report.rows} rows, {report.epochs} epochs in {report.seconds:.1f} s, "
            f"loss {report.losses[0]:.4f} -> {report.losses[-1]:.4f}"
        )
        return 0
    from dynabarn.learn.td3 import TD3Config, train_td3

    cfg = TD3Config(
        steps=args.steps,
        envs=args.envs,
        world_set=args.set,
        difficulty=args.difficulty,
        protocol=args.protocol,
        eval_every=args.eval_every,
        eval_episodes=args.eval_episodes,
        start_steps=args.start_steps,
        seed=args.seed,
    )
    if cfg.steps < 1 or cfg.envs < 1:
        raise DynabarnError("--steps and --envs must be positive")
    report = train_td3(cfg, args.out, progress=lambda total: tqdm(total=total, desc="steps", disable=None))
    last = report.evaluations[-1]
    print(
        f"wrote {args.out / 'policy.pt'} after {report.steps} steps ({report.episodes} episodes) in "
        f"{report.seconds:.0f} s; last evaluation: success {last['success']:.2f}, return {last['return']:.1f}; "
        f"curve: {args.out / 'learning_curve.png'}"
    )
    return 0


# -- dynabarn-bench ----------------------------------------------------------------------


def bench_main(argv: Sequence[str] | None = None) -> int:
    import os

    parser = _parser(
        "dynabarn-bench",
        "Run planners over a world set and trials in parallel; resumable; summary table, CSV, Markdown "
        "and a Fig. 5-style PNG in --out.",
    )
    parser.add_argument("--planner", default="dwa", help="planner(s), comma separated, e.g. dwa,teb")
    parser.add_argument(
        "--planner-config",
        default=None,
        help="parameters for every planner: key=value[,...], a .json file, or a shipped preset "
        "(dwa_barn_challenge = the BARN Challenge's DWA configuration; teb_narrow = TEB for BARN's passages)",
    )
    parser.add_argument(
        "--policy", type=Path, default=None, help="weights for bc/td3 (default: the policy shipped in the package)"
    )
    parser.add_argument("--set", default="paper60", help="world set: paper60, dynabarn300, or a folder with index.json")
    parser.add_argument("--worlds", default=None, help="only these world ids, e.g. 0,5,100-119")
    parser.add_argument("--trials", type=int, default=10, help="trials (seeds 0..N-1) per world")
    parser.add_argument("--protocol", default="barn", help="barn, paper2022, or a .json file")
    parser.add_argument("--jobs", type=int, default=os.cpu_count() or 1, help="parallel workers")
    parser.add_argument("--backend", choices=["local", "ray"], default="local", help="where episodes run")
    parser.add_argument("--address", default=None, help="Ray cluster address (ray backend); default: a local Ray")
    parser.add_argument(
        "--record", choices=["none", "failures", "all"], default="none", help="which episodes to keep as MCAP"
    )
    parser.add_argument(
        "--out", type=Path, default=None, help="output folder (results.jsonl, summary, fig5.png); required for a sweep"
    )
    parser.add_argument("--force", action="store_true", help="start over in an --out that holds another sweep")
    golden = parser.add_argument_group(
        "golden set",
        "about 30 committed episodes that must come out the same on every machine (README Reproducibility)",
    )
    golden.add_argument(
        "--verify-golden",
        action="store_true",
        help="re-run the golden set and print every field that differs from the committed results; exit 1 if any",
    )
    golden.add_argument(
        "--update-golden", action="store_true", help="re-run the golden set and rewrite the committed results"
    )
    golden.add_argument(
        "--reference",
        type=Path,
        default=None,
        help="folder with the reference data the imported golden worlds need (dynabarn60.json, barn300_static.json); "
        "default: ../shared/reference beside the repository; cases that need it are skipped without it",
    )
    args = parser.parse_args(argv)
    if args.verify_golden or args.update_golden:
        return _run(_golden, args)
    if args.out is None:
        parser.error("--out is required for a sweep")
    return _run(_bench, args)


def _golden(args: argparse.Namespace) -> int:
    import json

    from tqdm import tqdm

    from dynabarn.bench import golden
    from dynabarn.provenance import machine

    if args.jobs < 1:
        raise DynabarnError("--jobs must be at least 1")
    reference = args.reference or golden.DEFAULT_REFERENCE

    def progress(stream, total):
        return tqdm(stream, total=total, desc="golden episodes", unit="ep", disable=None)

    if args.update_golden:
        path = golden.update(reference, jobs=args.jobs, progress=progress)
        print(f"wrote {len(golden.CASES)} golden episodes to {path}")
        return 0
    t0 = time.perf_counter()
    report = golden.verify(reference, jobs=args.jobs, progress=progress)
    print(f"machine: {json.dumps(machine(), sort_keys=True)}")
    for note in report.version_notes:
        print(f"versions differ: {note}")
    for case in report.skipped:
        print(f"skipped (no reference data under {reference}): {case}")
    for m in report.mismatches:
        print(f"MISMATCH {m}")
    cases = len({m.case for m in report.mismatches})
    verdict = "identical" if report.ok else f"{len(report.mismatches)} fields differ in {cases} episodes"
    print(
        f"golden set: {report.checked} episodes checked, {len(report.skipped)} skipped, {verdict} "
        f"({time.perf_counter() - t0:.1f} s)"
    )
    return 0 if report.ok else 1


def _bench(args: argparse.Namespace) -> int:
    from tqdm import tqdm

    from dynabarn import bench, worldset
    from dynabarn.planners import get_planner
    from dynabarn.protocol import get_protocol

    if args.trials < 1 or args.jobs < 1:
        raise DynabarnError("--trials and --jobs must be at least 1")
    config = _planner_config(args.planner_config)
    if args.policy is not None:
        config["policy"] = str(args.policy.resolve())
    names = [p.strip() for p in args.planner.split(",") if p.strip()]
    for name in names:
        get_planner(name, **config)  # fail fast on an unknown planner or bad configuration
    protocol = get_protocol(args.protocol)
    worlds = worldset.world_set(args.set, worldset.parse_ids(args.worlds))
    jobs = bench.make_jobs(
        [(n, config) for n in names],
        worlds,
        protocol,
        args.trials,
        record=args.record,
        recordings_dir=args.out / "recordings",
    )
    bench.check_or_write_metadata(args.out, bench.metadata(bench.jsonable_args(args), jobs), force=args.force)

    def progress(stream, total):
        return tqdm(stream, total=total, desc="episodes", unit="ep", disable=None, smoothing=0.05)

    try:
        report = bench.run_sweep(
            jobs, args.out, backend=args.backend, n_workers=args.jobs, address=args.address, progress=progress
        )
    except KeyboardInterrupt:
        print(f"interrupted; finished episodes are in {args.out / bench.RESULTS}; rerun to resume", file=sys.stderr)
        raise
    summary = bench.summarise(report.rows)
    title = f"{args.set}, protocol {protocol.name}, {args.trials} trials"
    paths = bench.write_summary(summary, args.out, title=title)
    print(bench.format_table(summary))
    print(
        f"{report.ran} episodes run, {report.skipped} already done, {report.errors} errors, "
        f"{report.wall_time:.1f} s; wrote {paths['csv']}, {paths['md']}, {paths['png']}"
    )
    return 0


if __name__ == "__main__":  # pragma: no cover - `python -m dynabarn.cli run ...` / `... worlds ...`
    if len(sys.argv) > 1 and sys.argv[1] == "run":
        sys.exit(run_main(sys.argv[2:]))
    if len(sys.argv) > 1 and sys.argv[1] == "bench":
        sys.exit(bench_main(sys.argv[2:]))
    if len(sys.argv) > 1 and sys.argv[1] == "teleop":
        sys.exit(teleop_main(sys.argv[2:]))
    sys.exit(worlds_main())
