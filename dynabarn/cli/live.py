"""`dynabarn-run`'s ways to watch an episode while it runs: `--viewer`, `--live foxglove`,
`--live rerun`, paced by `--rate`."""

from __future__ import annotations

import argparse
import os
import sys

from dynabarn.cli.common import ranged
from dynabarn.errors import DynabarnError
from dynabarn.provenance import has_display

LIVE_TARGETS = ("foxglove", "rerun")


def exit_code(code: int) -> int:
    """A command's exit code, leaving at once once MuJoCo's viewer has been open: everything
    is written and closed by then, and some Mesa GLX drivers crash (or hang) in the
    interpreter's teardown after the viewer's thread has used them (exit 139 for a clean run)."""
    from dynabarn.live.viewer import viewer_was_opened

    if viewer_was_opened():
        sys.stdout.flush()
        sys.stderr.flush()
        os._exit(code)
    return code


def add_live_options(parser: argparse.ArgumentParser) -> None:
    group = parser.add_argument_group("watching it run (paced to --rate times real time)")
    group.add_argument(
        "--viewer",
        action="store_true",
        help="show the episode in MuJoCo's viewer as it runs, following the robot (needs a display or Xvfb); "
        "Space pauses, Escape or closing the window ends the episode (its recording is kept)",
    )
    group.add_argument(
        "--live",
        action="append",
        choices=LIVE_TARGETS,
        default=[],
        help="stream the episode as it runs: foxglove (a WebSocket server on 127.0.0.1:--port; open "
        "ws://127.0.0.1:PORT in Foxglove with the layout assets/foxglove/dynabarn.json, which "
        "`python -m dynabarn.recording.layout` prints from an installed package), rerun (a spawned viewer, or "
        "--connect); may be given twice (default: none)",
    )
    group.add_argument(
        "--rate",
        type=ranged(float, 0.01, 1000.0),
        default=1.0,
        help="simulated seconds per wall-clock second while watched (1: real time)",
    )
    group.add_argument(
        "--port",
        type=ranged(int, 0, 65535),
        default=8765,
        help="--live foxglove: the server's port (0: any free one, printed)",
    )
    group.add_argument(
        "--wait",
        type=ranged(float, 0.0, 3600.0),
        default=30.0,
        help="--live foxglove: seconds to wait for Foxglove to connect before the episode starts (0: start at once)",
    )
    group.add_argument(
        "--connect",
        default=None,
        help="--live rerun: a running viewer's PORT, HOST:PORT or rerun+http://HOST:PORT/proxy (default: spawn one)",
    )


class LiveOutputs:
    """The live outputs one `dynabarn-run` asked for, opened before the episode and closed
    after it whatever happens. `contexts` go to the recorder; `observers` run after it."""

    def __init__(self, args: argparse.Namespace, protocol) -> None:
        self.args, self.protocol = args, protocol
        self.contexts: tuple = ()
        self.observers: tuple = ()
        self._foxglove = self._rerun = self._viewer = None
        self._viewer_process = None  # rerun's native viewer, when we started it
        if args.connect is not None and "rerun" not in args.live:
            raise DynabarnError("--connect is for --live rerun")

    def __enter__(self) -> LiveOutputs:
        try:
            self._open()
        except BaseException:  # close what did open (a Foxglove server before a failed --connect)
            self.__exit__(None, None, None)
            raise
        return self

    def _open(self) -> None:
        args = self.args
        observers = []
        if "foxglove" in args.live:
            from dynabarn.live.foxglove_live import FoxgloveLive

            try:
                self._foxglove = FoxgloveLive(args.port, wait=args.wait)
            except RuntimeError as exc:
                raise DynabarnError(f"--live foxglove: cannot serve on port {args.port} ({exc})") from None
            self.contexts = (self._foxglove.context,)
            observers.append(self._foxglove)
            print(f"Foxglove: open a connection to {self._foxglove.url}", file=sys.stderr, flush=True)
        if "rerun" in args.live:
            observers.append(self._open_rerun())
        if args.viewer:
            self._check_viewer()  # opened on the compiled world: `watch`
        elif args.live:
            from dynabarn.live.pacing import Pacer

            observers.append(Pacer(args.rate))
        self.observers = tuple(observers)

    def attach(self, recorder) -> None:
        if self._foxglove is not None:
            self._foxglove.attach(recorder)

    def _open_rerun(self):
        from dynabarn.live.rerun_live import RerunLive

        if self.args.connect is None:
            if not has_display():
                raise DynabarnError("--live rerun spawns a viewer and needs a display; or --connect to a running one")
            from dynabarn.web_viewer import spawn_native_viewer

            viewer, url = spawn_native_viewer()
            self._viewer_process = viewer
            self._rerun = RerunLive(url, viewer=viewer)
        else:
            from dynabarn.web_viewer import check_reachable, grpc_url

            url = grpc_url(self.args.connect)
            check_reachable(url)
            self._rerun = RerunLive(url)
        return self._rerun

    def _check_viewer(self) -> None:
        if not has_display():
            raise DynabarnError("--viewer needs a display (or Xvfb); none is set")
        if os.environ.get("MUJOCO_GL") not in (None, "", "glfw"):
            raise DynabarnError(f"--viewer needs MuJoCo's windowed GL; MUJOCO_GL={os.environ['MUJOCO_GL']} is set")

    def watch(self, sim, planner) -> tuple:
        """`run_spec`'s `on_built`: with --viewer, MuJoCo's viewer opened on the compiled
        world (an observer after the others), closed when this context ends."""
        if not self.args.viewer:
            return ()
        from dynabarn.live.viewer import MujocoViewer

        sim.reset(self.protocol.spawn)
        self._viewer = MujocoViewer(sim, goal_tolerance=self.protocol.goal_tolerance, rate=self.args.rate)
        self._viewer.open()
        return (self._viewer,)

    def __exit__(self, *exc) -> None:
        if self._viewer is not None:
            self._viewer.close()
        if self._rerun is not None:
            self._rerun.close()
        viewer = self._viewer_process
        if viewer is not None and viewer.poll() is None:
            try:
                if exc[0] is None:  # the run is over; its viewer (which ends with us) stays to be looked at
                    print("the rerun viewer stays open: close it (or Ctrl-C) to finish", file=sys.stderr)
                    viewer.wait()
            except KeyboardInterrupt:
                pass
            finally:
                viewer.terminate()
        if self._foxglove is not None:
            self._foxglove.stop()
