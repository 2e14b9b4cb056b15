"""Many copies of one world stepped at once on MuJoCo Warp (the `gpu` extra), for training.

The benchmark's own episodes (`dynabarn-run`, `dynabarn-bench`, the golden set) stay on
MuJoCo's C engine, whose results are byte-reproducible; this batch is float32 on another
solver path and agrees with it within stated tolerances (`tests/test_warp_worlds.py`).

What runs on the device for every world at once, each control period, without a trip
through the host:

1. the command limited as the C engine's `Episode.apply` limits it (its grid, the Jackal's
   speed limits, the acceleration over one period) into the actuators' controls;
2. `k` physics steps, each after the obstacles are placed at that step's time from their
   keyframe schedules (linear or Catmull-Rom Hermite, loop or hold, each world's own clock
   offset), the kernel `place_obstacles`, as `worlds.schedule` evaluates them;
3. after each step, the protocol's checks in the C engine's order (`Episode._judge`): a
   contact (any of the world's: in these worlds every contact is the robot's) ends it as a
   collision; else the clock starts once the robot has left its spawn, the goal region
   ends it as a success, the time limit as a timeout; the outcome and its step are kept
   until the world is reset (a world that ended goes on stepping, judged no more);
4. the obstacles placed at the next period's start, then the scan: the model's 720
   rangefinders (the static field included), no return read as the range's end, the
   laser's Gaussian noise (each world's own seed and period: Warp's counter-based random
   numbers, not numpy's stream), clipped to the laser's range and put on its 1 mm grid, as
   `sim.laser` does.

Not yet on the device (a named departure): obstacles that react to the robot (`yield`,
`avoid`) are refused.
"""

from __future__ import annotations

from pathlib import Path

import mujoco
import numpy as np

from dynabarn.determinism import COMMAND_RESOLUTION, LASER_RESOLUTION
from dynabarn.errors import DynabarnError
from dynabarn.learn.warp_kernels import (
    COLLISION,
    OUTCOMES,
    RUNNING,
    SUCCESS,
    TIMEOUT,
    assign_worlds,
    copy_world_rows,
    judge_step,
    limit_commands,
    mjw,
    note_contacts,
    place_obstacles,
    require_warp,
    reset_worlds,
    scan_beams,
    wp,
)
from dynabarn.learn.warp_library import PER_WORLD_FIELDS, WorldLibrary
from dynabarn.protocol import EvalProtocol, GoalRegion, get_protocol
from dynabarn.robot import JACKAL
from dynabarn.sim_config import SimConfig

__all__ = ["COLLISION", "OUTCOMES", "RUNNING", "SUCCESS", "TIMEOUT", "WarpWorlds", "require_warp"]


class WarpWorlds:
    """`nworld` copies of one world on a Warp device (`"cpu"`, `"cuda"`, `"cuda:1"`): the
    robot, the scheduled obstacles, the scan, the contacts and the protocol's judgement of
    each, stepped together.

    State lives on the device; `scan`, `pose`, `outcome` and the rest are Warp arrays there
    (hand them to PyTorch with `wp.to_torch`, no copy). Every world starts where `reset`
    puts it and ends as the protocol says (`outcome`, `end_step`); its caller restarts the
    worlds it chooses with a mask, without stopping the others."""

    def __init__(
        self,
        world_path: Path | str | list[Path | str],
        nworld: int,
        *,
        device: str = "cpu",
        protocol: EvalProtocol | str = "barn",
        laser_noise: bool = True,
        config: SimConfig = SimConfig(),
    ):
        require_warp()
        if nworld < 1:
            raise DynabarnError(f"nworld {nworld}: at least 1")
        paths = list(world_path) if isinstance(world_path, list | tuple) else [world_path]
        self.library = WorldLibrary(paths)
        """The worlds the batch plays (`learn.warp_library`); batch world w plays `world_of[w]`."""
        self.world = self.library.worlds[0]
        self.protocol = get_protocol(protocol) if isinstance(protocol, str) else protocol
        self.config, self.nworld, self.device = config, nworld, device
        self.k = config.steps_per_tick
        model = self.library.model  # the Jackal's 720 rangefinders, the padded worlds' structure
        model.opt.timestep = config.dt
        model.sensor_interval[:, 0] = 0.0  # every beam read whenever the sensors are computed
        rangefinders = np.flatnonzero(model.sensor_type == mujoco.mjtSensor.mjSENS_RANGEFINDER)
        self.n_beams = len(rangefinders)
        self._first_beam = int(model.sensor_adr[rangefinders[0]])
        self.n_obstacles = self.library.n_obstacles
        lib = self.library
        with wp.ScopedDevice(device):
            batched = {name: nworld for name in PER_WORLD_FIELDS} if len(lib) > 1 else None
            self.m = mjw.put_model(model, batch_sizes=batched)
            self.d = mjw.make_data(model, nworld=nworld)
            self.world_of = wp.array(np.arange(nworld, dtype=np.int32) % len(lib), dtype=int)
            """Which of the library's worlds each batch world plays (set by each restart)."""
            self._rows, self._placed = [], []
            if batched is not None:
                self._rows = [_field_rows(self.m, name, lib.fields[name]) for name in batched]
                self._placed = [_field_rows(self.d, name, lib.placed[name]) for name in lib.placed]
            everyone = wp.ones(nworld, dtype=int)
            self._copy_rows(everyone, self._rows)
            self._copy_rows(everyone, self._placed)
            self.steps = wp.zeros(nworld, dtype=int)
            """Physics steps since each world's reset."""
            self.clock_offset = wp.zeros(nworld, dtype=float)
            self.seed = wp.zeros(nworld, dtype=int)
            self.spawn = wp.zeros(nworld, dtype=wp.vec3)
            self.previous = wp.zeros(nworld, dtype=wp.vec2)
            self.touched = wp.zeros(nworld, dtype=int)
            self.contact_now = wp.zeros(nworld, dtype=int)
            self.outcome = wp.zeros(nworld, dtype=int)
            """`OUTCOMES`' code of each world: 0 while it runs."""
            self.t_start = wp.full(nworld, -1.0, dtype=float)
            self.end_step = wp.zeros(nworld, dtype=int)
            """The physics step each world's episode ended at (0 while it runs)."""
            self.end_pose = wp.zeros(nworld, dtype=wp.vec3)
            """The robot's pose at that step (where the episode's final observation is made)."""
            self.scan = wp.zeros((nworld, self.n_beams), dtype=float)
            if lib.keys is not None:
                keys = lib.keys
                self._keys = [
                    wp.array(keys["durations"], dtype=float),
                    wp.array(keys["seg_lo"], dtype=int),
                    wp.array(keys["seg_hi"], dtype=int),
                    wp.array(keys["flat_t"], dtype=float),
                    wp.array(keys["flat_p"], dtype=wp.vec2),
                    wp.array(keys["flat_m"], dtype=wp.vec2),
                ]
            self._ends = [wp.array(lib.loop, dtype=int), wp.array(lib.spline, dtype=int)]
            self._goals = wp.array(lib.goal, dtype=wp.vec2)
        period, p, rules = self.k * config.dt, JACKAL, self.protocol
        self._limits = wp.vec3(p.v_min, p.v_max, p.w_max)
        self._change = wp.vec2(config.max_linear_accel * period, config.max_angular_accel * period)
        self._laser = wp.vec3(p.laser_range_min, p.laser_range_max, p.laser_noise_std if laser_noise else 0.0)
        self._rules = wp.vec4(rules.goal_tolerance, rules.time_limit, rules.timer_start_distance, 0.0)
        self._square = int(rules.goal_region == GoalRegion.SQUARE)

    def reset(self, mask, spawn, clock_offset, seed, world=None) -> None:
        """Worlds where `mask` (nworld,) is set start again: the robot at `spawn` (nworld, 3)
        at rest, time 0, the obstacles' clocks at `clock_offset` (nworld,) [s], the laser's
        noise from `seed` (nworld,), playing the library's world `world` (nworld,) (default:
        the one each played); the rows of the others are not read, and those worlds go on
        untouched. Then every world's scan is current."""
        with wp.ScopedDevice(self.device):
            self.restart(
                wp.array(np.asarray(mask, dtype=np.int32)),
                wp.array(np.asarray(spawn, dtype=np.float32), dtype=wp.vec3),
                wp.array(np.asarray(clock_offset, dtype=np.float32), dtype=float),
                wp.array(np.asarray(seed, dtype=np.int32), dtype=int),
                self.world_of if world is None else wp.array(self._checked_worlds(world), dtype=int),
            )
            self._observe()

    def _checked_worlds(self, world) -> np.ndarray:
        world = np.asarray(world, dtype=np.int64)
        if world.shape != (self.nworld,) or world.min() < 0 or world.max() >= len(self.library):
            raise DynabarnError(f"world: {self.nworld} indices into the batch's {len(self.library)} worlds")
        return world.astype(np.int32)

    def restart(self, mask, spawn, clock_offset, seed, world) -> None:
        """`reset`'s restart from arrays on the device (no trip through the host), without
        the scan: a vector environment resets the worlds that ended, then observes all."""
        wp.launch(assign_worlds, self.nworld, inputs=[mask, world, self.world_of])
        self._copy_rows(mask, self._rows)  # before reset_data, which starts each mocap body at its world's place
        mjw.reset_data(self.m, self.d, reset=mask)
        self._copy_rows(mask, self._placed)
        state = [self.spawn, self.seed, self.clock_offset, self.steps, self.previous, self.touched]
        state += [self.outcome, self.t_start, self.end_step]
        wp.launch(reset_worlds, self.nworld, inputs=[mask, spawn, seed, clock_offset, self.d.qpos, *state])

    def _copy_rows(self, mask, fields: list) -> None:
        """Per-world fields (`_rows`: the model's, `_placed`: the static geoms' placement in
        the data) of the worlds in `mask`, from their library worlds."""
        for library, rows in fields:
            wp.launch(copy_world_rows, rows.shape, inputs=[mask, self.world_of, library, rows])

    def step(self, commands, *, observe: bool = True) -> None:
        """One control period of every world: `commands` (nworld, 2) [v m/s, w rad/s], a
        Warp array of vec2 on the device (or anything `wp.array` takes); `observe=False`
        leaves the period's first scan in `scan` (a caller that observes later)."""
        with wp.ScopedDevice(self.device):
            if not isinstance(commands, wp.array):
                commands = wp.array(np.asarray(commands, dtype=np.float32), dtype=wp.vec2)
            wp.launch(
                limit_commands,
                self.nworld,
                inputs=[commands, self.previous, self._limits, self._change, COMMAND_RESOLUTION, self.d.ctrl],
            )
            judged = [self.d.qpos, self.steps, self.contact_now, self.spawn, self.world_of, self._goals, self._rules]
            judged += [self._square]
            judged += [self.config.dt, self.outcome, self.t_start, self.end_step, self.end_pose]
            for _ in range(self.k):
                self._place()
                mjw.step(self.m, self.d)
                wp.launch(
                    note_contacts,
                    self.d.naconmax,
                    inputs=[self.d.nacon, self.d.contact.worldid, self.contact_now, self.touched],
                )
                wp.launch(judge_step, self.nworld, inputs=judged)
            if observe:
                self._observe()

    def _place(self) -> None:
        """Each world's obstacles at the time of its current step."""
        if self.n_obstacles:
            wp.launch(
                place_obstacles,
                (self.nworld, self.n_obstacles),
                inputs=[self.steps, self.config.dt, self.clock_offset, self.world_of, *self._keys, *self._ends],
                outputs=[self.d.mocap_pos],
            )

    def observe(self) -> None:
        """Every world's scan, where its obstacles are at its current step (after `restart`)."""
        with wp.ScopedDevice(self.device):
            self._observe()

    def _observe(self) -> None:
        """The obstacles where the next period starts, the kinematics, then the scan."""
        self._place()
        mjw.kinematics(self.m, self.d)
        mjw.sensor_pos(self.m, self.d)
        wp.launch(
            scan_beams,
            (self.nworld, self.n_beams),
            inputs=[self.d.sensordata, self._first_beam, self._laser, LASER_RESOLUTION, self.seed, self.steps],
            outputs=[self.scan],
        )

    @property
    def pose(self):
        """(nworld, 3) x, y, yaw of each robot (the model's qpos: a view on the device)."""
        return self.d.qpos


def _field_rows(arrays, name: str, library: np.ndarray) -> tuple:
    """(the library's rows of a per-world field on the device, the batch's rows in MuJoCo
    Warp's model or data `arrays`), both as 2-D arrays of the field's element type (a view:
    the model's or data's own memory) for `copy_world_rows`."""
    rows = getattr(arrays, name)
    element = rows.dtype
    width = int(np.prod(rows.shape[1:]))
    shape = (len(library), width, *getattr(element, "_shape_", ()))
    lib = wp.array(library.reshape(shape).astype(np.float32), dtype=element)
    return lib, rows.reshape((rows.shape[0], width))
