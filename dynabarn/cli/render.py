"""`dynabarn-render`: offscreen videos (.mp4, .gif) of recorded episodes."""

from __future__ import annotations

import argparse
import sys
from collections.abc import Sequence
from pathlib import Path

from dynabarn.cli.common import (
    add_renamed,
    command,
    make_parser,
    ranged,
    run_command,
)
from dynabarn.errors import DynabarnError


def build_parser() -> argparse.ArgumentParser:
    """`dynabarn-render`'s parser (its `--help`, and the documentation's page of the command)."""
    parser = make_parser(
        "dynabarn-render",
        "Render a recorded episode to a video offscreen with MuJoCo (EGL or OSMesa, no GPU needed).",
    )
    parser.add_argument("recording", type=Path, help="MCAP recording (from dynabarn-run)")
    parser.add_argument("--video", type=Path, required=True, help="video file to write, .mp4 or .gif")
    add_renamed(parser, "--out", "--video", "video", type=Path)
    add_video_options(parser)
    return parser


@command
def render_main(argv: Sequence[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    return run_command(_render, args)


def add_video_options(parser: argparse.ArgumentParser, prefix: str = "") -> None:
    """--camera, --fps, --size, --quality (dynabarn-run's --video takes the same)."""
    from dynabarn.render import CAMERAS, QUALITIES

    parser.add_argument(
        "--camera", choices=CAMERAS, default="top", help=f"{prefix}whole arena from above, or behind the robot"
    )
    parser.add_argument(
        "--fps", type=ranged(float, 1.0, 120.0), default=20.0, help=f"{prefix}frames per second of the video"
    )
    parser.add_argument(
        "--size", default="640x480", help=f"{prefix}frame size WIDTHxHEIGHT, 16 to 4096 px (even for .mp4)"
    )
    parser.add_argument(
        "--quality",
        choices=QUALITIES,
        default=QUALITIES[0],
        help=f"{prefix}fast: no multisampling, coarse round shapes; high: MuJoCo's defaults, about 3x slower",
    )


def _parse_size(text: str) -> tuple[int, int]:
    w, sep, h = text.lower().partition("x")
    if not sep or not w.isdigit() or not h.isdigit() or not (16 <= int(w) <= 4096 and 16 <= int(h) <= 4096):
        raise DynabarnError(f"bad --size {text!r}: use WIDTHxHEIGHT between 16 and 4096 pixels, e.g. 640x480")
    return int(w), int(h)


def video_settings(args: argparse.Namespace, out: Path) -> dict:
    """The video options checked before anything runs: one line for a bad one."""
    from dynabarn.render import check_video

    width, height = _parse_size(args.size)
    check_video(out, width, height)
    return {"camera": args.camera, "fps": args.fps, "width": width, "height": height, "quality": args.quality}


def render_video(recording: Path, out: Path, settings: dict) -> None:
    from tqdm import tqdm

    from dynabarn.recording import read_recording
    from dynabarn.render import render_recording

    rec = read_recording(recording)
    if rec.truncated:
        print(f"warning: {recording} is truncated ({rec.error}); rendering up to the cut", file=sys.stderr)
    info = render_recording(
        rec,
        out,
        **settings,
        progress=lambda it: tqdm(it, desc="rendering", unit="frame", disable=None, leave=False),
    )
    print(
        f"wrote {info.path}: {info.frames} frames, {info.duration:.2f} s at {info.fps:g} fps, "
        f"{info.width}x{info.height}"
    )


def _render(args: argparse.Namespace) -> int:
    if not args.video.parent.is_dir():
        raise DynabarnError(f"--video {args.video}: the folder {args.video.parent} does not exist")
    settings = video_settings(args, args.video)
    try:
        render_video(args.recording, args.video, settings)
    except OSError as exc:
        raise DynabarnError(f"cannot write {args.video}: {exc.strerror or exc}") from None
    return 0
