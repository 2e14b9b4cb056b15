"""The Warp backend's kernels (`learn.warp_worlds`): the obstacles' schedules, the command's
limits, the contacts, the protocol's checks, the scan and the restart of a world, each a
Warp kernel over the batch; and Warp itself, initialised once (`require_warp`). Defined
only where the `gpu` extra is installed."""

from __future__ import annotations

import os
from typing import Any

from dynabarn.errors import NotInstalledHere

try:
    import mujoco_warp as mjw
    import warp as wp
except ImportError:  # the `gpu` extra; the module's kernels are defined only with it
    mjw = wp = None


OUTCOMES = ("running", "success", "collision", "timeout")
"""`WarpWorlds.outcome`'s codes: 0 while a world runs, then how it ended (`Outcome`'s names)."""
RUNNING, SUCCESS, COLLISION, TIMEOUT = range(4)


_warp_ready = False


def require_warp() -> None:
    """Warp, initialised once and quietly: no greeting, no line per kernel module loaded,
    and not the driver's warning on a machine without a GPU (where a command's stderr is
    one line for bad input; `wp.is_cuda_available()` says the same)."""
    if wp is None:
        raise NotInstalledHere("the Warp backend needs MuJoCo Warp: pip install 'dynabarn[gpu]'")
    global _warp_ready
    if _warp_ready:
        return
    wp.config.log_level = wp.LOG_WARNING
    saved = os.dup(2)
    try:
        with open(os.devnull, "wb") as null:
            os.dup2(null.fileno(), 2)  # the driver's probe writes from C, past Python's sys.stderr
            wp.init()
    finally:
        os.dup2(saved, 2)
        os.close(saved)
    _warp_ready = True


if wp is not None:

    @wp.kernel
    def place_obstacles(
        steps: wp.array(dtype=int),
        dt: float,
        clock_offset: wp.array(dtype=float),
        world_of: wp.array(dtype=int),
        durations: wp.array(dtype=float),
        seg_lo: wp.array(dtype=int),
        seg_hi: wp.array(dtype=int),
        key_t: wp.array(dtype=float),
        key_p: wp.array(dtype=wp.vec2),
        key_m: wp.array(dtype=wp.vec2),
        loop: wp.array(dtype=int),
        spline: wp.array(dtype=int),
        mocap_pos: wp.array2d(dtype=wp.vec3),
    ):
        """Obstacle j of batch world w at the time of its step `steps[w]`: the library's
        world `world_of[w]`, whose obstacle j is key row `world_of[w] * n + j`."""
        w, j = wp.tid()
        k = world_of[w]
        i = k * mocap_pos.shape[1] + j
        tl = wp.float32(steps[w]) * dt + clock_offset[w]
        span = durations[i]
        if loop[k] != 0:  # noqa: SIM108 (a Warp kernel: plain branches)
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
        if spline[k] != 0:
            u2 = u * u
            u3 = u2 * u
            p = (
                (2.0 * u3 - 3.0 * u2 + 1.0) * p0
                + (u3 - 2.0 * u2 + u) * key_m[seg]
                + (-2.0 * u3 + 3.0 * u2) * p1
                + (u3 - u2) * key_m[seg + 1]
            )
        mocap_pos[w, j] = wp.vec3(p[0], p[1], mocap_pos[w, j][2])

    @wp.kernel
    def limit_commands(
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
    def note_contacts(
        nacon: wp.array(dtype=int),
        worldid: wp.array(dtype=int),
        contact_now: wp.array(dtype=int),
        touched: wp.array(dtype=int),
    ):
        c = wp.tid()
        if c < nacon[0]:
            contact_now[worldid[c]] = 1
            touched[worldid[c]] = 1

    @wp.kernel
    def judge_step(
        qpos: wp.array2d(dtype=float),
        steps: wp.array(dtype=int),
        contact_now: wp.array(dtype=int),
        spawn: wp.array(dtype=wp.vec3),
        world_of: wp.array(dtype=int),
        goals: wp.array(dtype=wp.vec2),
        rules: wp.vec4,
        square: int,
        dt: float,
        outcome: wp.array(dtype=int),
        t_start: wp.array(dtype=float),
        end_step: wp.array(dtype=int),
        end_pose: wp.array(dtype=wp.vec3),
    ):
        """The step just taken, counted (`steps`), then judged as `Episode._judge` judges
        it. rules: the goal's tolerance, the time limit, the distance that starts the clock,
        unused."""
        w = wp.tid()
        steps[w] += 1
        contact_now_w = contact_now[w]
        contact_now[w] = 0
        if outcome[w] != RUNNING:
            return
        end_pose[w] = wp.vec3(qpos[w, 0], qpos[w, 1], qpos[w, 2])  # kept once it ends
        if contact_now_w != 0:
            outcome[w] = COLLISION
            end_step[w] = steps[w]
            return
        x = qpos[w, 0]
        y = qpos[w, 1]
        t = wp.float32(steps[w]) * dt
        moved = wp.vec2(x - spawn[w][0], y - spawn[w][1])
        if t_start[w] < 0.0 and wp.dot(moved, moved) >= rules[2] * rules[2]:
            t_start[w] = t
        goal = goals[world_of[w]]
        off = wp.vec2(x - goal[0], y - goal[1])
        inside = wp.dot(off, off) < rules[0] * rules[0]
        if square != 0:
            inside = wp.abs(off[0]) < rules[0] and wp.abs(off[1]) < rules[0]
        if inside:
            outcome[w] = SUCCESS
            end_step[w] = steps[w]
        elif t - wp.max(t_start[w], 0.0) >= rules[1]:
            outcome[w] = TIMEOUT
            end_step[w] = steps[w]

    @wp.kernel
    def scan_beams(
        sensordata: wp.array2d(dtype=float),
        first: int,
        laser: wp.vec3,
        grid: float,
        seed: wp.array(dtype=int),
        steps: wp.array(dtype=int),
        scan: wp.array2d(dtype=float),
    ):
        """A rangefinder's distance (-1: no return) as `sim.laser` reads a beam. laser: the
        range's ends and the noise's standard deviation (0: none)."""
        w, b = wp.tid()
        nbeam = scan.shape[1]
        r = sensordata[w, first + b]
        if r < 0.0:
            r = laser[1]
        if laser[2] > 0.0:  # each world's seed, each period and beam its own number
            state = wp.rand_init(seed[w], steps[w] * nbeam + b)
            r = r + laser[2] * wp.randn(state)
        scan[w, b] = wp.rint(wp.clamp(r, laser[0], laser[1]) / grid) * grid

    @wp.kernel
    def assign_worlds(mask: wp.array(dtype=int), new_world: wp.array(dtype=int), world_of: wp.array(dtype=int)):
        """Which of the library's worlds each restarting batch world plays next."""
        w = wp.tid()
        if mask[w] != 0:
            world_of[w] = new_world[w]

    @wp.kernel
    def copy_world_rows(
        mask: wp.array(dtype=int),
        world_of: wp.array(dtype=int),
        library: wp.array2d(dtype=Any),
        rows: wp.array2d(dtype=Any),
    ):
        """A per-world model field's row of each restarting batch world, from its library
        world's (`learn.warp_library`): one kernel for every such field, whatever its type."""
        w, j = wp.tid()
        if mask[w] != 0:
            rows[w, j] = library[world_of[w], j]

    @wp.kernel
    def reset_worlds(
        mask: wp.array(dtype=int),
        new_spawn: wp.array(dtype=wp.vec3),
        new_seed: wp.array(dtype=int),
        new_offset: wp.array(dtype=float),
        qpos: wp.array2d(dtype=float),
        spawn: wp.array(dtype=wp.vec3),
        seed: wp.array(dtype=int),
        clock_offset: wp.array(dtype=float),
        steps: wp.array(dtype=int),
        previous: wp.array(dtype=wp.vec2),
        touched: wp.array(dtype=int),
        outcome: wp.array(dtype=int),
        t_start: wp.array(dtype=float),
        end_step: wp.array(dtype=int),
    ):
        w = wp.tid()
        if mask[w] != 0:
            for j in range(3):
                qpos[w, j] = new_spawn[w][j]
            spawn[w] = new_spawn[w]
            seed[w] = new_seed[w]
            clock_offset[w] = new_offset[w]
            steps[w] = 0
            previous[w] = wp.vec2(0.0, 0.0)
            touched[w] = 0
            outcome[w] = RUNNING
            t_start[w] = -1.0
            end_step[w] = 0
