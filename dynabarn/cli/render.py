"""`dynabarn-render`: offscreen videos (.mp4, .gif) of recorded episodes."""

from __future__ import annotations

import argparse
import sys
from collections.abc import Sequence
from pathlib import Path

from dynabarn.cli.common import (
    make_parser,
    ranged,
    run_command,
)
from dynabarn.errors import DynabarnError


def render_main(argv: Sequence[str] | None = None) -> int:
    parser = make_parser(
        "dynabarn-render",
        "Render a recorded episode to a video offscreen with MuJoCo (EGL or OSMesa, no GPU needed).",
    )
    parser.add_argument("recording", type=Path, help="MCAP recording (from dynabarn-run)")
    parser.add_argument("--out", type=Path, required=True, help="video file, .mp4 or .gif")
    parser.add_argument("--camera", choices=["top", "follow"], default="top", help="whole arena or behind the robot")
    parser.add_argument("--fps", type=ranged(float, 1.0, 120.0), default=20.0, help="frames per second of the video")
    parser.add_argument("--size", default="640x480", help="frame size WIDTHxHEIGHT")
    args = parser.parse_args(argv)
    return run_command(_render, args)


def _parse_size(text: str) -> tuple[int, int]:
    w, sep, h = text.lower().partition("x")
    if not sep or not w.isdigit() or not h.isdigit() or not (16 <= int(w) <= 4096 and 16 <= int(h) <= 4096):
        raise DynabarnError(f"bad --size {text!r}: use WIDTHxHEIGHT between 16 and 4096 pixels, e.g. 640x480")
    return int(w), int(h)


def render_video(recording: Path, out: Path, camera: str, fps: float, size: str) -> None:
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
    if not args.out.parent.is_dir():
        raise DynabarnError(f"--out {args.out}: the folder {args.out.parent} does not exist")
    try:
        render_video(args.recording, args.out, args.camera, args.fps, args.size)
    except OSError as exc:
        raise DynabarnError(f"cannot write {args.out}: {exc.strerror or exc}") from None
    return 0
