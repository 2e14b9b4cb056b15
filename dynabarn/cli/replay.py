"""`dynabarn-replay`: recordings in the rerun viewer, or saved as .rrd."""

from __future__ import annotations

import argparse
import sys
import time
from collections.abc import Sequence
from pathlib import Path

from dynabarn.cli.common import (
    make_parser,
    run_command,
)
from dynabarn.errors import DynabarnError


def replay_main(argv: Sequence[str] | None = None) -> int:
    parser = make_parser(
        "dynabarn-replay",
        "Show MCAP recordings in rerun: the scene, the scan, the robot's path and the plots on a sim_time "
        "timeline. Several recordings of one world open together for comparison.",
    )
    parser.add_argument("recordings", nargs="+", type=Path, help="MCAP recordings (from dynabarn-run)")
    parser.add_argument("--save", type=Path, default=None, help="write an .rrd file instead of opening a viewer")
    parser.add_argument("--web", action="store_true", help="serve rerun's web viewer on loopback instead")
    args = parser.parse_args(argv)
    return run_command(_replay, args)


def _replay(args: argparse.Namespace) -> int:
    import os

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
