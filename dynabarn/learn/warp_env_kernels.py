"""The kernels of `WarpVectorEnv` (`learn.warp_env`): the actions as commands, a period's
rewards and ends, the next trials, a caller's cut, and the observation with its local goal
walked along each world's Dijkstra plan. Defined only where the `gpu` extra is installed."""

from __future__ import annotations

from dynabarn.learn.env import REWARD_COLLISION, REWARD_PROGRESS, REWARD_SUCCESS, REWARD_TIME
from dynabarn.learn.warp_kernels import COLLISION, SUCCESS, TIMEOUT, wp

if wp is not None:

    @wp.struct
    class PlanMap:
        """The static maps of a batch's worlds as the kernels read them: per library world,
        each cell's next cell along the Dijkstra plan (`pred`, < 0 at the goal's cell and
        where the goal cannot be reached), the cost-to-go and the goal; the grid; the local
        goal's distance and the cells a walk to it needs (`GlobalPlanner.plan_suffix`)."""

        pred: wp.array2d(dtype=int)
        cost: wp.array2d(dtype=float)
        goal: wp.array(dtype=wp.vec2)
        origin: wp.vec2
        resolution: float
        nx: int
        ny: int
        lookahead: float
        cells: int

    @wp.func
    def _cell(pose: wp.vec3, plan: PlanMap) -> int:
        i = wp.clamp(int((pose[1] - plan.origin[1]) / plan.resolution), 0, plan.ny - 1)
        j = wp.clamp(int((pose[0] - plan.origin[0]) / plan.resolution), 0, plan.nx - 1)
        return i * plan.nx + j

    @wp.func
    def _local_goal(pose: wp.vec3, k: int, plan: PlanMap) -> wp.vec2:
        """The point `lookahead` metres along world k's plan from the pose (`points_along`
        over `plan_suffix`'s points: the next cells' centres, the goal once the walk meets
        it, the last point repeated where the suffix is cut), in the robot frame."""
        cur = _cell(pose, plan)
        goal = plan.goal[k]
        prev = wp.vec2(pose[0], pose[1])
        out = prev
        p = prev
        along = wp.float32(0.0)  # variables the loop changes (Warp: declared by their type)
        found = wp.int32(0)
        ended = wp.int32(0)
        for n in range(plan.cells):
            if ended == 0:
                nxt = plan.pred[k, cur]
                if nxt < 0:
                    ended = 1
                    p = goal
                elif n < plan.cells - 1:
                    cur = nxt
                    i = nxt // plan.nx
                    j = nxt - i * plan.nx
                    p = plan.origin + wp.vec2(wp.float32(j) + 0.5, wp.float32(i) + 0.5) * plan.resolution
            seg = wp.length(p - prev)
            if found == 0 and along + seg >= plan.lookahead:
                out = prev + (p - prev) * ((plan.lookahead - along) / wp.max(seg, 1.0e-12))
                found = 1
            along = along + seg
            prev = p
        if found == 0:
            out = p
        d = out - wp.vec2(pose[0], pose[1])
        cy = wp.cos(pose[2])
        sy = wp.sin(pose[2])
        return wp.vec2(cy * d[0] + sy * d[1], -sy * d[0] + cy * d[1])

    @wp.func
    def _cost(pose: wp.vec3, k: int, plan: PlanMap) -> float:
        return plan.cost[k, _cell(pose, plan)]

    @wp.kernel
    def actions_to_commands(actions: wp.array2d(dtype=float), limits: wp.vec3, commands: wp.array(dtype=wp.vec2)):
        """`action_to_command`: [-1, 1]^2 -> (v, w)."""
        w = wp.tid()
        a0 = wp.clamp(actions[w, 0], -1.0, 1.0)
        a1 = wp.clamp(actions[w, 1], -1.0, 1.0)
        commands[w] = wp.vec2(limits[0] + 0.5 * (a0 + 1.0) * (limits[1] - limits[0]), limits[2] * a1)

    @wp.kernel
    def conclude_period(
        outcome: wp.array(dtype=int),
        end_pose: wp.array(dtype=wp.vec3),
        qpos: wp.array2d(dtype=float),
        scan: wp.array2d(dtype=float),
        plan: PlanMap,
        world_of: wp.array(dtype=int),
        last_cost: wp.array(dtype=float),
        reward: wp.array(dtype=float),
        terminated: wp.array(dtype=int),
        truncated: wp.array(dtype=int),
        success: wp.array(dtype=int),
        final: wp.array2d(dtype=float),
        episodes: wp.array(dtype=int),
    ):
        """A period's reward and end (`DynaBARNEnv.conclude`); a world that ended gets its
        final observation (this period's scan, the final pose's local goal) and its next trial."""
        w = wp.tid()
        done = outcome[w]
        pose = wp.vec3(qpos[w, 0], qpos[w, 1], qpos[w, 2])
        if done != 0:
            pose = end_pose[w]
        k = world_of[w]
        ctg = _cost(pose, k, plan)
        progress = wp.float32(0.0)
        if wp.isfinite(ctg) and wp.isfinite(last_cost[w]):
            progress = last_cost[w] - ctg
        r = REWARD_PROGRESS * progress + REWARD_TIME
        if done == COLLISION:
            r = r + REWARD_COLLISION
        if done == SUCCESS:
            r = r + REWARD_SUCCESS
        reward[w] = r
        last_cost[w] = ctg
        terminated[w] = int(done == SUCCESS or done == COLLISION)  # noqa: SIM109 (no tuples in a kernel)
        truncated[w] = int(done == TIMEOUT)
        success[w] = int(done == SUCCESS)
        if done != 0:
            nbeam = scan.shape[1]
            for b in range(nbeam):
                final[w, b] = scan[w, b]
            g = _local_goal(pose, k, plan)
            final[w, nbeam] = g[0]
            final[w, nbeam + 1] = g[1]
            episodes[w] += 1

    @wp.kernel
    def next_trials(
        done: wp.array(dtype=int),
        episodes: wp.array(dtype=int),
        offsets: wp.array2d(dtype=float),
        seeds: wp.array2d(dtype=int),
        worlds: wp.array2d(dtype=int),
        mask: wp.array(dtype=int),
        offset: wp.array(dtype=float),
        seed: wp.array(dtype=int),
        world: wp.array(dtype=int),
    ):
        w = wp.tid()
        mask[w] = int(done[w] != 0)
        k = episodes[w] % offsets.shape[1]
        offset[w] = offsets[w, k]
        seed[w] = seeds[w, k]
        world[w] = worlds[w, k]

    @wp.kernel
    def cut_episodes(mask: wp.array(dtype=int), outcome: wp.array(dtype=int), episodes: wp.array(dtype=int)):
        """Episodes their caller ends before the protocol does: counted, to be restarted."""
        w = wp.tid()
        if mask[w] != 0:
            outcome[w] = TIMEOUT
            episodes[w] += 1

    @wp.kernel
    def observe_envs(
        qpos: wp.array2d(dtype=float),
        scan: wp.array2d(dtype=float),
        plan: PlanMap,
        world_of: wp.array(dtype=int),
        restarted: wp.array(dtype=int),
        last_cost: wp.array(dtype=float),
        obs: wp.array2d(dtype=float),
    ):
        w = wp.tid()
        k = world_of[w]
        nbeam = scan.shape[1]
        for b in range(nbeam):
            obs[w, b] = scan[w, b]
        pose = wp.vec3(qpos[w, 0], qpos[w, 1], qpos[w, 2])
        g = _local_goal(pose, k, plan)
        obs[w, nbeam] = g[0]
        obs[w, nbeam + 1] = g[1]
        if restarted[w] != 0:  # a new episode: its progress counts from its spawn
            last_cost[w] = _cost(pose, k, plan)
