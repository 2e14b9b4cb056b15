"""`dynabarn-run`: one episode of a planner in a world, recorded to MCAP."""

from __future__ import annotations

import argparse
from collections.abc import Sequence
from pathlib import Path

from dynabarn.cli.common import (
    EXIT_EPISODE_ERROR,
    add_protocol,
    add_recording,
    add_sim_settings,
    add_trial_seed,
    add_world,
    command,
    make_parser,
    planner_config,
    run_command,
    sim_settings,
)
from dynabarn.cli.episode import exit_status, print_result
from dynabarn.cli.live import LiveOutputs, add_live_options, exit_code
from dynabarn.cli.render import add_video_options, render_video, video_settings
from dynabarn.errors import DynabarnError


def build_parser() -> argparse.ArgumentParser:
    """`dynabarn-run`'s parser (its `--help`, and the documentation's page of the command)."""
    parser = make_parser(
        "dynabarn-run",
        "Run one episode of a planner in a DynaBARN world, print its outcome and metrics, and record it to MCAP.",
    )
    # Imported once the parser exists: make_parser chose MuJoCo's OpenGL platform, which
    # MuJoCo reads when first imported (these modules import it).
    from dynabarn.planners import available_planners, planner_presets

    add_world(parser)
    parser.add_argument(
        "--planner",
        default="straight",
        help="planner name, NAME@PRESET for a named preset (shipped or installed), or a planner from its "
        "code, unpackaged: MODULE:CLASS "
        f"(the current folder is searched too) or FILE.py:CLASS; available: {', '.join(available_planners())}",
    )
    parser.add_argument(
        "--planner-config",
        default=None,
        help="planner parameters: key=value[,key=value], a .json file, or a named preset "
        + f"({', '.join(planner_presets())}; each file in dynabarn/planners/presets/ says its source)",
    )
    parser.add_argument(
        "--policy",
        type=Path,
        default=None,
        help="weights for bc, td3, dagger or ppo (default: the policy shipped in the package; ppo ships none)",
    )
    add_protocol(parser)
    add_trial_seed(parser)
    add_recording(parser)
    add_sim_settings(parser)
    parser.add_argument("--video", type=Path, default=None, help="also render the episode to this .mp4 or .gif")
    add_video_options(parser, prefix="--video: ")
    add_live_options(parser)
    return parser


@command
def run_main(argv: Sequence[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    return exit_code(run_command(_run_episode, args))


def _run_episode(args: argparse.Namespace) -> int:

    from dynabarn.planners import planner_spec
    from dynabarn.protocol import get_protocol
    from dynabarn.runner import EpisodeSpec, run_spec
    from dynabarn.worldset import resolve_world

    world_path = resolve_world(args.world, args.set)
    protocol = get_protocol(args.protocol)
    name, preset, _ = planner_spec(args.planner)
    config = preset | planner_config(args.planner_config)
    if args.policy is not None:
        config["policy"] = str(args.policy)
    settings = sim_settings(args)
    spec = EpisodeSpec.make(world_path, name, protocol, config=config, seed=args.seed, sim=settings, label=args.planner)
    log_path = None
    video = video_settings(args, args.video) if args.video is not None else None
    if not args.no_log:
        log_path = args.log  # else the default name in --runs-dir (run_spec names it)
    elif args.video is not None:  # the video is rendered from a recording: keep a temporary one
        import tempfile

        log_path = Path(tempfile.mkdtemp()) / "episode.mcap"
    # The runner checks the configuration, then opens the live outputs: a bad one is one
    # line before a server starts.
    run = run_spec(
        spec,
        record_to=log_path,
        record_in=None if args.no_log else args.runs_dir,
        live=LiveOutputs(args, protocol),
    )
    result = run.result
    # Where the recording is now: None when its writer died (run_spec said so on stderr).
    kept = run.recording
    print_result(result, as_json=args.json, recording=None if args.no_log else kept)
    if args.video is not None and kept is None:
        raise DynabarnError(f"no recording to render {args.video} from: its writer ended early")
    if args.video is not None:
        render_video(kept, args.video, video)
        if args.no_log:
            import shutil

            shutil.rmtree(log_path.parent, ignore_errors=True)
    from dynabarn.live.viewer import CLOSED, ESCAPED

    if result.reason in (CLOSED, ESCAPED):  # the person watching ended it: not a failure
        return 0
    from dynabarn.recording.topics import stopped_by_a_topic

    if stopped_by_a_topic(run.recording_problem):  # what was asked to be recorded is not (run_spec said why)
        return EXIT_EPISODE_ERROR
    return exit_status(result, as_json=args.json)
