"""`dynabarn-replay`: recordings in the rerun viewer, or saved as .rrd."""

from __future__ import annotations

import argparse
import sys
import time
from collections.abc import Sequence
from pathlib import Path

from dynabarn.cli.common import (
    command,
    make_parser,
    run_command,
)
from dynabarn.errors import DynabarnError
from dynabarn.provenance import has_display


def build_parser() -> argparse.ArgumentParser:
    """`dynabarn-replay`'s parser (its `--help`, and the documentation's page of the command)."""
    parser = make_parser(
        "dynabarn-replay",
        "Show MCAP recordings in rerun: the scene, the scan, the robot's path and the plots on a sim_time "
        "timeline. Several recordings of one world open together for comparison.",
    )
    # Imported once the parser exists: make_parser chose MuJoCo's OpenGL platform, which
    # MuJoCo reads when first imported (these modules import it).
    from dynabarn.web_viewer import DEFAULT_BIND, DEFAULT_GRPC_PORT, DEFAULT_WEB_PORT

    parser.add_argument("recordings", nargs="+", type=Path, help="MCAP recordings (from dynabarn-run)")
    parser.add_argument("--save", type=Path, default=None, help="write an .rrd file instead of opening a viewer")
    where = parser.add_mutually_exclusive_group()
    where.add_argument(
        "--web",
        action="store_true",
        help="serve rerun's web viewer instead of opening the native one; prints the URL and serves until Ctrl-C",
    )
    where.add_argument(
        "--connect",
        metavar="ADDR",
        default=None,
        help="send to a rerun viewer that is already running: PORT, HOST:PORT or rerun+http://HOST:PORT/proxy",
    )
    web = parser.add_argument_group("web viewer (--web)")
    web.add_argument(
        "--bind",
        default=DEFAULT_BIND,
        help="address to listen on: 127.0.0.1 = this machine only, 0.0.0.0 = every interface",
    )
    web.add_argument("--port", type=int, default=DEFAULT_WEB_PORT, help="port of the web page")
    web.add_argument("--grpc-port", type=int, default=DEFAULT_GRPC_PORT, help="port the page loads the data from")
    return parser


@command
def replay_main(argv: Sequence[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    return run_command(_replay, args)


def _replay(args: argparse.Namespace) -> int:

    from dynabarn.recording import read_recording
    from dynabarn.rerun_replay import save_rrd, send_to, spawn_viewer
    from dynabarn.web_viewer import check_reachable, grpc_url

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
    if save is None and not (args.web or args.connect) and not has_display():
        save = args.recordings[0].with_suffix(".rrd")
        print(f"no display: saving to {save} instead (open it with `rerun {save}`, or use --web)", file=sys.stderr)
    t0 = time.perf_counter()
    if args.web:
        return _serve_web(recs, args)
    if save is not None:
        counts = save_rrd(recs, save)
        total = sum(c.scans for c in counts)
        print(f"wrote {save} ({len(recs)} recording(s), {total} scans) in {time.perf_counter() - t0:.2f} s")
        return 0
    if args.connect:
        url = grpc_url(args.connect)
        check_reachable(url)
        counts = send_to(recs, url)
        print(f"sent {len(recs)} recording(s), {sum(c.scans for c in counts)} scans, to {url}")
        return 0
    spawn_viewer(recs)
    return 0


def _serve_web(recs: list, args: argparse.Namespace) -> int:
    """Save the .rrd (to --save, or a temporary folder), serve it, print the URL, wait."""
    import signal
    import tempfile

    from dynabarn.rerun_replay import save_rrd
    from dynabarn.web_viewer import check_address, serve_web

    check_address(args.bind, args.port, args.grpc_port)
    with tempfile.TemporaryDirectory(prefix="dynabarn-replay-") as tmp:
        rrd = args.save or Path(tmp) / "replay.rrd"
        save_rrd(recs, rrd)
        viewer = serve_web(rrd, bind=args.bind, port=args.port, grpc_port=args.grpc_port)
        # `kill` (SIGTERM) stops the server too, as Ctrl-C does: the finally below runs.
        signal.signal(signal.SIGTERM, signal.default_int_handler)
        try:
            scope = "this machine only" if args.bind.startswith("127.") or args.bind == "::1" else "EVERY interface"
            print(viewer.url, flush=True)
            print(
                f"rerun's web viewer: open the URL above; listening on {args.bind} ({scope}); Ctrl-C stops",
                file=sys.stderr,
            )
            code = viewer.wait()
        except KeyboardInterrupt:
            return 0
        finally:
            viewer.stop()
            viewer.log.unlink(missing_ok=True)
    raise DynabarnError(f"rerun's web viewer stopped by itself (exit {code})")
