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
   offset), the kernel `_place_obstacles`, as `worlds.schedule` evaluates them;
3. whether a step touched (any contact of a world: in these worlds every contact is the
   robot's), kept until the world is reset;
4. the obstacles placed at the next period's start, then the scan: the model's 720
   rangefinders (the static field included), no return read as the range's end, clipped
   to the laser's range and put on its 1 mm grid, as `sim.laser` does.

Not yet on the device (named departures): obstacles that react to the robot (`yield`,
`avoid`) are refused, and the laser's noise is not added.
"""

from __future__ import annotations

from pathlib import Path

import mujoco
import numpy as np

from dynabarn.determinism import COMMAND_RESOLUTION, LASER_RESOLUTION
from dynabarn.errors import DynabarnError, NotInstalledHere
from dynabarn.mjcf import load_model, read_world
from dynabarn.robot import JACKAL
from dynabarn.sim_config import SimConfig
from dynabarn.worlds.schedule import keyframes_of
from dynabarn.worlds.spec import EndBehavior, Interpolation

try:
    import mujoco_warp as mjw
    import warp as wp
except ImportError:  # the `gpu` extra; the module's kernels are defined only with it
    mjw = wp = None


def _require_warp() -> None:
    if wp is None:
        raise NotInstalledHere("the Warp backend needs MuJoCo Warp: pip install 'dynabarn[gpu]'")


if wp is not None:

    @wp.kernel
    def _place_obstacles(
        steps: wp.array(dtype=int),
        dt: float,
        lead: int,
        clock_offset: wp.array(dtype=float),
        durations: wp.array(dtype=float),
        seg_lo: wp.array(dtype=int),
        seg_hi: wp.array(dtype=int),
        key_t: wp.array(dtype=float),
        key_p: wp.array(dtype=wp.vec2),
        key_m: wp.array(dtype=wp.vec2),
        loop: int,
        spline: int,
        mocap_pos: wp.array2d(dtype=wp.vec3),
    ):
        """Obstacle i of world w at the time of that world's step `steps[w] + lead`."""
        w, i = wp.tid()
        tl = wp.float32(steps[w] + lead) * dt + clock_offset[w]
        span = durations[i]
        if loop != 0:  # noqa: SIM108 (a Warp kernel: plain branches)
            tl = tl - span * wp.floor(tl / span)
        else:
            tl = wp.min(tl, span)
        seg = seg_lo[i]  # the last keyframe at or before tl, within the obstacle's segments
        for s in range(seg_lo[i] + 1, seg_hi[i] + 1):
            if key_t[s] <= tl:
                seg = s
        t0 = key_t[seg]
        u = wp.clamp((tl - t0) / (key_t[seg + 1] - t0), 0.0, 1.0)
        p0 = key_p[seg]
        p1 = key_p[seg + 1]
        p = p0 + (p1 - p0) * u
        if spline != 0:
            u2 = u * u
            u3 = u2 * u
            p = (
                (2.0 * u3 - 3.0 * u2 + 1.0) * p0
                + (u3 - 2.0 * u2 + u) * key_m[seg]
                + (-2.0 * u3 + 3.0 * u2) * p1
                + (u3 - u2) * key_m[seg + 1]
            )
        mocap_pos[w, i] = wp.vec3(p[0], p[1], mocap_pos[w, i][2])

    @wp.kernel
    def _limit_commands(
        commands: wp.array(dtype=wp.vec2),
        previous: wp.array(dtype=wp.vec2),
        limits: wp.vec3,
        change: wp.vec2,
        grid: float,
        ctrl: wp.array2d(dtype=float),
    ):
        """`Episode.apply`'s limits: the command's grid, the speed limits, then at most
        `change` (v, w) from the last period's command; into the actuators (v, slip, w)."""
        w = wp.tid()
        v = wp.clamp(wp.rint(commands[w][0] / grid) * grid, limits[0], limits[1])
        yaw_rate = wp.clamp(wp.rint(commands[w][1] / grid) * grid, -limits[2], limits[2])
        v = wp.clamp(v, previous[w][0] - change[0], previous[w][0] + change[0])
        yaw_rate = wp.clamp(yaw_rate, previous[w][1] - change[1], previous[w][1] + change[1])
        previous[w] = wp.vec2(v, yaw_rate)
        ctrl[w, 0] = v
        ctrl[w, 1] = 0.0
        ctrl[w, 2] = yaw_rate

    @wp.kernel
    def _advance(steps: wp.array(dtype=int)):
        steps[wp.tid()] += 1

    @wp.kernel
    def _note_contacts(nacon: wp.array(dtype=int), worldid: wp.array(dtype=int), touched: wp.array(dtype=int)):
        c = wp.tid()
        if c < nacon[0]:
            touched[worldid[c]] = 1

    @wp.kernel
    def _scan(
        sensordata: wp.array2d(dtype=float),
        first: int,
        range_min: float,
        range_max: float,
        grid: float,
        scan: wp.array2d(dtype=float),
    ):
        """A rangefinder's distance (-1: no return) as `sim.laser` reads a beam."""
        w, b = wp.tid()
        r = sensordata[w, first + b]
        if r < 0.0:
            r = range_max
        scan[w, b] = wp.rint(wp.clamp(r, range_min, range_max) / grid) * grid

    @wp.kernel
    def _reset_worlds(
        mask: wp.array(dtype=int),
        spawn: wp.array(dtype=wp.vec3),
        qpos: wp.array2d(dtype=float),
        steps: wp.array(dtype=int),
        previous: wp.array(dtype=wp.vec2),
        touched: wp.array(dtype=int),
    ):
        w = wp.tid()
        if mask[w] != 0:
            qpos[w, 0] = spawn[w][0]
            qpos[w, 1] = spawn[w][1]
            qpos[w, 2] = spawn[w][2]
            steps[w] = 0
            previous[w] = wp.vec2(0.0, 0.0)
            touched[w] = 0


class WarpWorlds:
    """`nworld` copies of one world on a Warp device (`"cpu"`, `"cuda"`, `"cuda:1"`): the
    robot, the scheduled obstacles, the scan and the contacts of each, stepped together.

    State lives on the device; `scan`, `pose` and `touched` are Warp arrays there (hand
    them to PyTorch with `wp.to_torch`, no copy). Every world starts where `reset` puts it
    and ends when its caller says (a reset mask), without stopping the others."""

    def __init__(self, world_path: Path | str, nworld: int, *, device: str = "cpu", config: SimConfig = SimConfig()):
        _require_warp()
        if nworld < 1:
            raise DynabarnError(f"nworld {nworld}: at least 1")
        self.world = read_world(world_path)
        reactive = sorted({o.behavior for o in self.world.obstacles if o.behavior != "scripted"})
        if reactive:
            raise DynabarnError(
                f"{world_path}: obstacles that react to the robot ({', '.join(reactive)}) are not on the Warp backend"
            )
        self.config, self.nworld, self.device = config, nworld, device
        self.k = config.steps_per_tick
        model = load_model(world_path, beam_sensors=True)  # the Jackal with its 720 rangefinders
        model.opt.timestep = config.dt
        model.sensor_interval[:, 0] = 0.0  # every beam read whenever the sensors are computed
        self.model_c = model
        rangefinders = np.flatnonzero(model.sensor_type == mujoco.mjtSensor.mjSENS_RANGEFINDER)
        self.n_beams = len(rangefinders)
        self._first_beam = int(model.sensor_adr[rangefinders[0]])
        keys = keyframes_of(self.world)
        with wp.ScopedDevice(device):
            self.m = mjw.put_model(model)
            self.d = mjw.make_data(model, nworld=nworld)
            self.steps = wp.zeros(nworld, dtype=int)
            self.clock_offset = wp.zeros(nworld, dtype=float)
            self.previous = wp.zeros(nworld, dtype=wp.vec2)
            self.touched = wp.zeros(nworld, dtype=int)
            self.scan = wp.zeros((nworld, self.n_beams), dtype=float)
            self.n_obstacles = keys.n
            if keys.n:
                self._keys = (
                    wp.array(keys.durations, dtype=float),
                    wp.array(keys.seg_lo, dtype=int),
                    wp.array(keys.seg_hi, dtype=int),
                    wp.array(keys.flat_t, dtype=float),
                    wp.array(keys.flat_p, dtype=wp.vec2),
                    wp.array(keys.flat_m, dtype=wp.vec2),
                )
        self._loop = int(EndBehavior(self.world.end_behavior) is EndBehavior.LOOP)
        self._spline = int(Interpolation(self.world.interpolation) is Interpolation.SPLINE)
        period = self.k * config.dt
        self._limits = wp.vec3(JACKAL.v_min, JACKAL.v_max, JACKAL.w_max)
        self._change = wp.vec2(config.max_linear_accel * period, config.max_angular_accel * period)

    def reset(self, mask: np.ndarray, spawn: np.ndarray, clock_offset: np.ndarray) -> None:
        """Worlds where `mask` (nworld,) is set start again: the robot at `spawn` (nworld, 3)
        at rest, time 0, the obstacles' clocks at `clock_offset` (nworld,) [s]; the others
        go on untouched. Then the scan of every world is current."""
        with wp.ScopedDevice(self.device):
            mask_d = wp.array(np.asarray(mask, dtype=np.int32))
            mjw.reset_data(self.m, self.d, reset=mask_d)
            offsets = np.where(mask, clock_offset, self.clock_offset.numpy())
            wp.copy(self.clock_offset, wp.array(offsets, dtype=float))
            spawn_d = wp.array(np.asarray(spawn, dtype=np.float32), dtype=wp.vec3)
            wp.launch(
                _reset_worlds,
                self.nworld,
                inputs=[mask_d, spawn_d, self.d.qpos, self.steps, self.previous, self.touched],
            )
            self._observe()

    def step(self, commands) -> None:
        """One control period of every world: `commands` (nworld, 2) [v m/s, w rad/s], a
        Warp array of vec2 on the device (or anything `wp.array` takes)."""
        with wp.ScopedDevice(self.device):
            if not isinstance(commands, wp.array):
                commands = wp.array(np.asarray(commands, dtype=np.float32), dtype=wp.vec2)
            wp.launch(
                _limit_commands,
                self.nworld,
                inputs=[commands, self.previous, self._limits, self._change, COMMAND_RESOLUTION, self.d.ctrl],
            )
            for _ in range(self.k):
                self._place(0)
                mjw.step(self.m, self.d)
                wp.launch(
                    _note_contacts,
                    self.d.naconmax,
                    inputs=[self.d.nacon, self.d.contact.worldid, self.touched],
                )
                wp.launch(_advance, self.nworld, inputs=[self.steps])
            self._observe()

    def _place(self, lead: int) -> None:
        if self.n_obstacles:
            wp.launch(
                _place_obstacles,
                (self.nworld, self.n_obstacles),
                inputs=[self.steps, self.config.dt, lead, self.clock_offset, *self._keys, self._loop, self._spline],
                outputs=[self.d.mocap_pos],
            )

    def _observe(self) -> None:
        """The obstacles where the next period starts, the kinematics, then the scan."""
        self._place(0)
        mjw.kinematics(self.m, self.d)
        mjw.sensor_pos(self.m, self.d)
        p = JACKAL
        wp.launch(
            _scan,
            (self.nworld, self.n_beams),
            inputs=[self.d.sensordata, self._first_beam, p.laser_range_min, p.laser_range_max, LASER_RESOLUTION],
            outputs=[self.scan],
        )

    @property
    def pose(self):
        """(nworld, 3) x, y, yaw of each robot (the model's qpos: a view on the device)."""
        return self.d.qpos
