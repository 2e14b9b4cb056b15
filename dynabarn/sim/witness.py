"""A certificate's witness driven in MuJoCo: the proof that the search's way through is one
the Jackal can take.

`WitnessFollower` sends the witness's command of every tick, corrected by a tracking law
(Kanayama et al. 1990: the error to the witness's pose, in the robot's frame) for what the
search's model leaves out. `bench.certify.replay_witness` runs it through the runner as an
episode of the world, with the trial's seed (so the obstacles' clock offset is the one
certified): a certificate stands only if that episode reaches the goal without contact.
"""

from __future__ import annotations

import math

from dynabarn.interfaces.observation import EpisodeInfo, Observation
from dynabarn.interfaces.planner import Planner
from dynabarn.sim.certificate import Witness

ALONG_GAIN = 3.0
"""[1/s] Speed correction per metre of error along the heading."""
ACROSS_GAIN = 4.0
"""[1/m^2 ... per m/s] Yaw-rate correction per metre across the heading, times the speed."""
HEADING_GAIN = 4.0
"""[1/s] Yaw-rate correction per radian of heading error (with the speed)."""


class WitnessFollower(Planner):
    """Drives a witness: its command at each tick plus the tracking correction."""

    name = "witness"

    def __init__(self, witness: Witness) -> None:
        self.witness = witness
        self.largest_error = 0.0
        """[m] The largest distance from the witness's pose at a tick seen so far."""

    def reset(self, info: EpisodeInfo) -> None:
        self.largest_error = 0.0

    def act(self, obs: Observation) -> tuple[float, float]:
        w = self.witness
        k = round(obs.time / w.period)
        if k >= len(w.commands):
            return 0.0, 0.0
        v_ref, w_ref = (float(c) for c in w.commands[k])
        xr, yr, thr = (float(c) for c in w.poses[k])
        x, y, th = (float(c) for c in obs.pose)
        dx, dy = xr - x, yr - y
        self.largest_error = max(self.largest_error, math.hypot(dx, dy))
        c, s = math.cos(th), math.sin(th)
        along, across = c * dx + s * dy, -s * dx + c * dy
        heading = math.atan2(math.sin(thr - th), math.cos(thr - th))
        v = v_ref * math.cos(heading) + ALONG_GAIN * along
        turn = w_ref + ACROSS_GAIN * v_ref * across + HEADING_GAIN * math.sin(heading)
        return v, turn

    def config(self) -> dict:
        return {"ticks": len(self.witness.commands), "arrival": self.witness.arrival}
