"""Watching an episode in MuJoCo's own viewer as it runs: `MujocoViewer`, an `EpisodeObserver`.

MuJoCo's passive viewer shows the simulation's model and data; the episode loop steps the
physics and the viewer is synced after every control tick, paced to `rate` times real
time. The camera follows the robot (drag to orbit, as in MuJoCo's viewer); the goal region
is drawn. Space pauses and resumes; Escape or closing the window ends the episode like any
planner error would (outcome `error`, the reason says why), so the recording is closed
complete and the result printed.

Needs a display (or Xvfb). MuJoCo must not be told to render offscreen (`MUJOCO_GL=egl`);
`dynabarn-run --viewer` and `dynabarn-teleop` take care of both.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from dynabarn.errors import EndEpisode
from dynabarn.interfaces.events import EpisodeObserver
from dynabarn.live.pacing import Pacer

KEY_SPACE, KEY_ESCAPE = 32, 256
"""GLFW key codes."""
CLOSED = "the viewer window was closed"
ESCAPED = "ended from the viewer (Escape)"

_opened = False


class ViewerClosed(EndEpisode):
    """The person watching ended the episode (closed the window or pressed Escape)."""


def viewer_was_opened() -> bool:
    """Whether this process has opened MuJoCo's viewer (its commands leave without the
    interpreter's teardown then: some Mesa GLX drivers crash in it after the viewer's thread)."""
    return _opened


class MujocoViewer(EpisodeObserver):
    """MuJoCo's passive viewer on a `Simulation`, following the robot, paced to `rate`.

    Args:
        sim: the simulation the episode runs in (its model and data are shown).
        goal_tolerance: radius of the goal region drawn [m].
        rate: simulated seconds per wall-clock second.
        key_callback: further handling of GLFW key codes (teleop's driving keys); Space and
            Escape are the viewer's own unless `own_keys` is False.
        closed_reason: the episode's reason when the window is closed.
    """

    def __init__(
        self,
        sim,
        *,
        goal_tolerance: float,
        rate: float = 1.0,
        key_callback: Callable[[int], None] | None = None,
        own_keys: bool = True,
        closed_reason: str = CLOSED,
    ) -> None:
        self.sim = sim
        self.goal_tolerance = goal_tolerance
        self.key_callback = key_callback
        self.own_keys = own_keys
        self.closed_reason = closed_reason
        self.pacer = Pacer(rate, while_waiting=self._keep_alive)
        self.viewer = None
        self._escaped = False

    # -- the window -------------------------------------------------------------------
    def _key(self, keycode: int) -> None:
        if self.own_keys and keycode == KEY_SPACE:
            self.pacer.toggle_pause()
        elif self.own_keys and keycode == KEY_ESCAPE:
            self._escaped = True
        if self.key_callback is not None:
            self.key_callback(keycode)

    def open(self) -> None:
        """Open the window on the simulation (after its reset, so the robot is at the spawn)."""
        global _opened
        import mujoco
        import mujoco.viewer

        _opened = True
        sim = self.sim
        mujoco.mj_forward(sim.model, sim.data)
        self.viewer = mujoco.viewer.launch_passive(
            sim.model, sim.data, key_callback=self._key, show_left_ui=False, show_right_ui=False
        )
        cam = self.viewer.cam
        cam.type = mujoco.mjtCamera.mjCAMERA_TRACKING
        cam.trackbodyid = sim.model.body("jackal/base_link").id
        cam.distance, cam.elevation, cam.azimuth = 6.0, -35.0, 180.0
        with self.viewer.lock():
            scn = self.viewer.user_scn
            mujoco.mjv_initGeom(
                scn.geoms[0],
                mujoco.mjtGeom.mjGEOM_CYLINDER,
                np.array([self.goal_tolerance, 0.01, 0]),
                np.array([sim.goal[0], sim.goal[1], 0.01]),
                np.eye(3).ravel(),
                np.array([0.1, 0.9, 0.2, 0.5], np.float32),
            )
            scn.ngeom = 1

    def close(self) -> None:
        if self.viewer is not None:
            self.viewer.close()
            self.viewer = None

    def _keep_alive(self) -> None:
        """Between ticks (paused or ahead of time): keep the picture current, notice an end."""
        self._check()
        self.viewer.sync()

    def _check(self) -> None:
        if self._escaped:
            raise ViewerClosed(ESCAPED)
        if not self.viewer.is_running():
            raise ViewerClosed(self.closed_reason)

    # -- EpisodeObserver --------------------------------------------------------------
    def on_start(self, start) -> None:
        if self.viewer is None:
            self.open()
        self.pacer.on_start(start)

    def on_tick(self, tick) -> None:
        self._check()
        self.viewer.sync()
        self.pacer.on_tick(tick)

    def on_poses(self, times, poses) -> None: ...

    def on_end(self, result) -> None:
        if self.viewer is not None and self.viewer.is_running():
            self.viewer.sync()
