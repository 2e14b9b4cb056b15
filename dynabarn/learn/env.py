"""`DynaBARN-v0`: the benchmark as a Gymnasium environment.

## Description
A Clearpath Jackal must cross a DynaBARN world (Nair et al. 2022) from its spawn to the goal among moving cylinders,
with the observation of the paper's learned baselines: the 720-beam laser scan and the local goal from the Dijkstra
global planner (Sec. IV-b, Fig. 4). One step is one control period (0.1 s: 20 MuJoCo steps at 5 ms).

## Action space
`Box(-1, 1, (2,), float32)`, normalised; mapped linearly onto the paper's command ranges:

| num | action | min | max | unit after mapping |
|---|---|---|---|---|
| 0 | forward speed v = -0.5 + 1.25 (a0 + 1) | -1 | 1 | v in [-0.5, 2.0] m/s |
| 1 | turn rate w = 3.14 a1 | -1 | 1 | w in [-3.14, 3.14] rad/s |

## Observation space
`Box((722,), float32)`: 720 laser ranges [m] in [0.1, 30] (right to left over +-2.356 rad),
then the local goal (g_x, g_y) [m] in the robot frame, `lookahead` metres (default 2)
along the global plan (closer near the goal).

## Rewards
After the TD3 navigation work of the paper's group (progress, collision and success terms):
- `reward_progress` = 1.0 x (decrease of the cost-to-go to the goal on the static map) [per m];
- `reward_time` = -0.01 per step;
- `reward_collision` = -10 when the robot touches an obstacle or a wall;
- `reward_success` = +20 when the protocol judges the goal reached.
Each term is in `info`.

## Starting state
World drawn uniformly from the chosen set (and difficulty); trial seed from the environment's generator (the
obstacles' clock offset, the laser noise); robot at the protocol's spawn ((11, 0, yaw pi) for `barn`).
`reset(options=...)`: `world_index` (an index into the chosen worlds), `trial_seed`, and `privileged=True` (the
obstacles' true states in `env.unwrapped.observation`, for a demonstrator such as the oracle; the policy's
observation is unchanged).

## Episode end
Terminated on success or collision; truncated on the protocol's time limit (100 s of simulated time once the robot
has moved 0.1 m, about 1,000 steps) or an error. `info["is_success"]` says whether the goal was reached
(Stable-Baselines3 logs it as the success rate). The registered `spec.max_episode_steps` (2,000 for `barn`) is the
longest an episode can last under the protocol (its clock may start up to one time limit late), so the protocol
always truncates first and Gymnasium's `TimeLimit` is only a safety net.

## Rendering
`render_mode="rgb_array"`: `render()` returns an (height, width, 3) uint8 frame from MuJoCo's renderer (without a
display and MUJOCO_GL, on EGL, chosen itself), so `gymnasium.wrappers.RecordVideo` and `check_env` work.
`render_mode="human"`: MuJoCo's viewer window, paced to real time (needs a display). `camera`: `top` or `follow`.

## Arguments
| parameter | type | default | description |
|---|---|---|---|
| world_set | str | "paper60" | paper60, dynabarn300, a tier, or a folder with index.json |
| split | str or None | None | "train" or "validation": worlds drawn on the fly |
| split_seed | int | 0 | the split's seed (the same worlds for the same seed) |
| split_profile_sets | tuple[str] | ("table1", "release2022") | profile sets of the split |
| difficulty | str or None | None | easy, medium, hard, or all |
| worlds | list[int] or None | None | explicit world ids (overrides difficulty) |
| protocol | str | "barn" | barn, paper2022 or a .json file |
| lookahead | float | 2.0 | local goal distance along the plan [m] |
| render_mode | str or None | None | None, "rgb_array" or "human" |
| camera | str | "top" | top or follow (rendering) |
| width, height | int | 640, 480 | frame size [px] (rendering) |
| observers | callable or None | None | `f(info)`: each episode's observers, e.g. a recorder (`learn.observed`) |

`worlds` picks ids from the whole folder of `world_set` (with `paper60`, any of the 300). Registered as
`dynabarn/DynaBARN-v0` (and `DynaBARN-v0`) by importing `dynabarn.learn` (or `dynabarn` once gymnasium is).

`split` draws worlds from Alg. 1 and 2 (`dynabarn.learn.split`), never a shipped one, in place of `world_set`.
With it, `reset(options={"world_index": k})` picks the split's world k (any k >= 0); `info["fingerprint"]` names it.

## Version history
- v0: first version (rendering, `is_success`, the time-limit spec, `privileged`, `split` and `observers` added
  without changing dynamics, observations or rewards).
"""

from __future__ import annotations

import math
import shutil
import tempfile
import threading
from functools import cache
from pathlib import Path
from typing import Any, ClassVar

import gymnasium
import numpy as np

from dynabarn.errors import DynabarnError
from dynabarn.interfaces.observation import Observation
from dynabarn.learn.gym_spaces import ACTION_SPACE, observation_space
from dynabarn.learn.observed import ObservedEpisodes, ObserverFactory
from dynabarn.learn.shared_worlds import forget_world, shared_world
from dynabarn.learn.split import DEFAULT_PROFILE_SETS, ProceduralWorlds, reserved_fingerprints
from dynabarn.metrics import Outcome
from dynabarn.planners.global_planner import GlobalPlanner
from dynabarn.planners.learned.spaces import action_to_command, checked_actions, policy_input
from dynabarn.protocol import get_protocol
from dynabarn.provenance import has_display
from dynabarn.render import CAMERAS, offscreen_renderer, place_camera
from dynabarn.robot import JACKAL
from dynabarn.sim import Episode, SimConfig, Simulation
from dynabarn.worlds.profiles import Difficulty
from dynabarn.worldset import world_set as resolve_world_set

REWARD_PROGRESS = 1.0
REWARD_TIME = -0.01
REWARD_COLLISION = -10.0
REWARD_SUCCESS = 20.0
PAPER_SETS = ("paper60", "dynabarn300")


@cache
def shipped_fingerprints() -> frozenset[str]:
    """The shipped 300 worlds' fingerprints, once per process (a training world never is one)."""
    return reserved_fingerprints()


def episode_step_limit(protocol: str = "barn") -> int:
    """The most control steps an episode can take under `protocol` (`longest_episode`)."""
    return math.ceil(get_protocol(protocol).longest_episode / SimConfig().control_period - 1e-9)


class DynaBARNEnv(gymnasium.Env):
    """DynaBARN navigation among moving obstacles (see the module docstring)."""

    # "human" only where a window can open: MuJoCo's viewer ends the process without one.
    metadata: ClassVar[dict] = {
        "render_modes": ["rgb_array", "human"] if has_display() else ["rgb_array"],
        "render_fps": 10,
    }

    # Over 80 lines on purpose: every argument checked at the edge, each with its own line.
    def __init__(
        self,
        world_set: str = "paper60",
        split: str | None = None,
        split_seed: int = 0,
        split_profile_sets: tuple[str, ...] = DEFAULT_PROFILE_SETS,
        difficulty: str | None = None,
        worlds: list[int] | None = None,
        protocol: str = "barn",
        lookahead: float = 2.0,
        render_mode: str | None = None,
        camera: str = "top",
        width: int = 640,
        height: int = 480,
        observers: ObserverFactory | None = None,
    ) -> None:
        self._closed = False
        self._observed = ObservedEpisodes(observers)
        self.batched = False  # True in a `vector_env` batch, which observes its worlds together
        if render_mode == "human" and not has_display():
            raise ValueError("render_mode 'human' needs a display (DISPLAY is not set); use 'rgb_array'")
        if render_mode not in (None, *self.metadata["render_modes"]):
            raise ValueError(f"render_mode {render_mode!r}: use None, 'rgb_array' or 'human'")
        if camera not in CAMERAS:
            raise ValueError(f"camera {camera!r}: use one of {', '.join(CAMERAS)}")
        if not (isinstance(width, int) and isinstance(height, int) and 16 <= width <= 4096 and 16 <= height <= 4096):
            raise ValueError(f"width and height must be whole numbers of pixels in [16, 4096], got {width}x{height}")
        if not (isinstance(lookahead, int | float) and math.isfinite(lookahead) and 0.1 <= lookahead <= 30.0):
            raise ValueError(f"lookahead must be a number of metres in [0.1, 30], got {lookahead!r}")
        difficulties = [d.value for d in Difficulty]
        if difficulty not in (None, "all", *difficulties):
            raise ValueError(f"difficulty {difficulty!r}: use None, 'all' or one of {', '.join(difficulties)}")
        if worlds is not None:
            if difficulty not in (None, "all"):
                raise ValueError("give worlds or difficulty, not both (worlds picks the exact ids)")
            if isinstance(worlds, str | bytes) or not all(
                isinstance(i, int | np.integer) and not isinstance(i, bool) for i in worlds
            ):
                raise ValueError(f"worlds must be a list of world ids, got {worlds!r}")
            worlds = [int(i) for i in worlds]
            if not worlds:
                raise ValueError("worlds is empty")
        self.procedural: ProceduralWorlds | None = None
        if split is not None:
            if worlds is not None or difficulty not in (None, "all"):
                raise ValueError("a procedural split draws its own worlds: give split or worlds/difficulty, not both")
            try:
                self.procedural = ProceduralWorlds(
                    Path(tempfile.mkdtemp(prefix=f"dynabarn-{split}-")),
                    split=split,
                    seed=int(split_seed),
                    profile_sets=tuple(split_profile_sets),
                    reserved=shipped_fingerprints(),
                )
            except DynabarnError as exc:
                raise ValueError(str(exc)) from None
        # Explicit ids choose from the whole folder: paper60's ids are a subset of the 300.
        set_name = "dynabarn300" if worlds is not None and world_set in PAPER_SETS else world_set
        try:
            entries = resolve_world_set(set_name, worlds)
            self.protocol = get_protocol(protocol)
        except DynabarnError as exc:
            raise ValueError(str(exc)) from None
        if difficulty not in (None, "all"):
            entries = [e for e in entries if e[2] == difficulty]
        if not entries:
            raise ValueError(f"no {difficulty} worlds in set {world_set!r}")
        self.entries = entries
        self.lookahead = float(lookahead)
        self.render_mode = render_mode
        self.camera, self.width, self.height = camera, width, height
        self.observation_space, self.action_space = observation_space(self.lookahead), ACTION_SPACE
        self._sims: dict[str, Simulation] = {}
        self._planners: dict[str, GlobalPlanner] = {}
        self.episode: Episode | None = None
        self._file: str | None = None
        self._renderers: dict[str, Any] = {}
        self._viewer = None
        self._viewer_thread: threading.Thread | None = None
        self._viewer_file: str | None = None
        self._wall_next = 0.0
        self._observation = None

    @property
    def observation(self):
        """The simulator's last `Observation` (pose, scan, goal; the obstacles' true states
        after `reset(options={"privileged": True})`), for an expert acting in the loop."""
        return self._observation

    def _observe(self, observation: Observation) -> np.ndarray:
        """The policy's observation of the loop's (`EpisodeLoop.first`, or a period's last act)."""
        obs = self.seen(observation)
        return policy_input(obs.scan, self.global_planner.local_goal_in_robot(obs.pose, self.lookahead), np.float32)

    def seen(self, obs: Observation) -> Observation:
        """Keep the simulator's observation (a privileged demonstrator reads it) and its pose."""
        self._observation, self._pose = obs, obs.pose
        return obs

    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None):
        self.begin(seed, options)
        return self.started(self._observe(self.loop.first()))

    def begin(self, seed: int | None, options: dict[str, Any] | None) -> None:
        """`reset` up to its observation: the world and the trial drawn, the episode started
        (a batch of worlds observes its new episodes together, then calls `started`)."""
        super().reset(seed=seed)
        options = options or {}
        if self.procedural is not None:
            k = int(options.get("world_index", self.np_random.integers(2**31)))
            drawn = self.procedural.world(k)
            wid, file, difficulty = k, str(drawn.path), drawn.difficulty
            for old in set(self._sims) - self.procedural.paths():  # dropped from the split's cache
                del self._sims[old], self._planners[old]
                forget_world(old)
        elif "world_index" in options:
            wid, file, difficulty = self.entries[int(options["world_index"]) % len(self.entries)]
        else:
            wid, file, difficulty = self.entries[int(self.np_random.integers(len(self.entries)))]
        trial = int(options.get("trial_seed", self.np_random.integers(2**31)))
        if file not in self._sims:
            template, self._planners[file] = shared_world(file)
            self._sims[file] = template.fork()
        sim = self._sims[file]
        self._file = file
        self.global_planner = self._planners[file]
        # Privileged: a demonstrator sees the obstacles' true states (the policy's observation is the same).
        self.episode = Episode(sim, self.protocol, seed=trial, privileged=bool(options.get("privileged", False)))
        self._info = {
            "world": sim.world.name,
            "world_id": wid,
            "difficulty": difficulty,
            "trial_seed": trial,
            "fingerprint": sim.world_fingerprint,
        }
        self.loop = self._observed.loop(self.episode, self.protocol, self._info, observes=not self.batched)

    def started(self, observation: np.ndarray) -> tuple[np.ndarray, dict]:
        """`reset`'s values once the episode's first observation is known."""
        self._cost_to_go = self.global_planner.cost_to_go(float(self._pose[0]), float(self._pose[1]))
        if self.render_mode == "human":
            self._show()
        return observation, {**self._info, "is_success": False}

    def step(self, action):
        outcome = self._apply(action)
        observation = self._observe(self.loop.observation) if outcome is None else self.final_observation()
        return self.conclude(outcome, observation)

    def _apply(self, action) -> Outcome | None:
        """Run one control period of the action; the outcome if the episode ended."""
        if self._closed:
            raise RuntimeError("the environment is closed; make a new one")
        if self.episode is None:
            raise RuntimeError("call reset() before step()")
        v, w = action_to_command(checked_actions(action))
        return self.loop.period(v, w)

    def conclude(self, outcome: Outcome | None, observation: np.ndarray):
        """`step`'s five values once the observation after the period is known."""
        ctg = self.global_planner.cost_to_go(float(self._pose[0]), float(self._pose[1]))
        progress = self._cost_to_go - ctg if math.isfinite(ctg) and math.isfinite(self._cost_to_go) else 0.0
        self._cost_to_go = ctg
        terms = {
            "reward_progress": REWARD_PROGRESS * progress,
            "reward_time": REWARD_TIME,
            "reward_collision": REWARD_COLLISION if outcome is Outcome.COLLISION else 0.0,
            "reward_success": REWARD_SUCCESS if outcome is Outcome.SUCCESS else 0.0,
        }
        terminated = outcome in (Outcome.SUCCESS, Outcome.COLLISION)
        truncated = outcome in (Outcome.TIMEOUT, Outcome.ERROR)
        info = {
            **self._info,
            **terms,
            "outcome": outcome.value if outcome else None,
            "time": self.episode.time,
            "is_success": outcome is Outcome.SUCCESS,
        }
        if outcome is not None:
            self._observed.ended()
        if self.render_mode == "human":
            self._show()
        return observation, float(sum(terms.values())), terminated, truncated, info

    def final_observation(self) -> np.ndarray:
        """After the episode ended: the final pose's observation, without a new scan."""
        ep = self.episode
        self._pose = ep.poses[ep.step].copy()
        g = self.global_planner.local_goal_in_robot(self._pose, self.lookahead)
        scan = np.clip(ep.observation.scan, JACKAL.laser_range_min, JACKAL.laser_range_max)
        return policy_input(scan, g, np.float32)

    # -- rendering ------------------------------------------------------------------------
    def render(self) -> np.ndarray | None:
        """The current frame (rgb_array), or None (human mode draws in `step` and `reset`)."""
        if self.render_mode is None:
            gymnasium.logger.warn("render() without a render_mode: pass render_mode='rgb_array' to make()")
            return None
        if self.episode is None:
            raise gymnasium.error.ResetNeeded("call reset() before render()")
        if self.render_mode == "human":
            self._show()
            return None
        import mujoco

        sim = self.episode.sim
        renderer = self._renderers.get(self._file)
        if renderer is None:
            sim.model.vis.global_.offwidth = max(sim.model.vis.global_.offwidth, self.width)
            sim.model.vis.global_.offheight = max(sim.model.vis.global_.offheight, self.height)
            try:
                renderer = offscreen_renderer(sim.model, self.height, self.width)
            except DynabarnError as e:  # Gymnasium's callers (check_env, RecordVideo) expect a plain error
                raise RuntimeError(str(e)) from None
            self._renderers[self._file] = renderer
            self._camera_view = mujoco.MjvCamera()
            self._scene_option = mujoco.MjvOption()
            self._scene_option.sitegroup[:] = 0  # laser sites would clutter the picture
        place_camera(self._camera_view, self.camera, self._pose)
        renderer.update_scene(sim.data, self._camera_view, self._scene_option)
        return renderer.render()

    def _show(self) -> None:
        """Human mode: MuJoCo's passive viewer on the current world, paced to real time."""
        import time

        import mujoco.viewer

        if self._viewer is not None and (self._viewer_file != self._file or not self._viewer.is_running()):
            self._close_viewer()
        if self._viewer is None:
            sim = self.episode.sim
            before = set(threading.enumerate())
            self._viewer = mujoco.viewer.launch_passive(sim.model, sim.data, show_left_ui=False, show_right_ui=False)
            # The viewer's render thread (launch_passive keeps it to itself): joined on close,
            # or the interpreter's exit tears GLFW down under it (a segmentation fault).
            self._viewer_thread = next((t for t in threading.enumerate() if t not in before), None)
            self._viewer_file = self._file
            place_camera(self._viewer.cam, self.camera, self._pose)
            self._wall_next = time.perf_counter()
        self._viewer.sync()
        self._wall_next += 1.0 / self.metadata["render_fps"]
        time.sleep(max(0.0, self._wall_next - time.perf_counter()))

    def close(self) -> None:
        self._closed = True
        self._observed.leave()
        self._sims, self._planners = {}, {}  # megabytes a world, whoever still holds the closed environment
        self.episode = self.loop = self._observation = None
        for renderer in self._renderers.values():
            renderer.close()
        self._renderers.clear()
        self._close_viewer()
        if self.procedural is not None:
            shutil.rmtree(self.procedural.cache_dir, ignore_errors=True)
        super().close()

    def _close_viewer(self) -> None:
        if self._viewer is None:
            return
        self._viewer.close()
        if self._viewer_thread is not None:
            self._viewer_thread.join(timeout=10.0)
        self._viewer = self._viewer_thread = None
