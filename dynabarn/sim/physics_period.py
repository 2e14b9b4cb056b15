"""One control period of physics in one call into MuJoCo's C (`mujoco.rollout`).

A period is `k` physics steps (20 at 5 ms and 10 Hz) with the obstacles moved before each
step. Stepping them from Python cost a call, an array write and a pose copy per step; here
the obstacles' positions go in as the rollout's per-step controls (`mjSTATE_MOCAP_POS`
beside `mjSTATE_CTRL`), the robot's poses come back as its per-step states, and the
solver's warm start is handed in from the data and left there by the last step, so the
steps are MuJoCo's own `mj_step`s on the same data, bit for bit (a test compares them with
the step-by-step loop over whole episodes, and the golden set checks the runner).

A contact ends an episode at the step it happens, but a rollout runs all `k` steps: the
robot's contact sensor (the runner's Jackal has one: every contact in these worlds is the
robot's) says whether any step touched, and only then is the period run again from its
start step by step, stopping at the contact, so `data` holds what the loop left there.
"""

from __future__ import annotations

import mujoco
import numpy as np
from mujoco import rollout

from dynabarn.errors import DynabarnError
from dynabarn.mjcf import ROBOT_PREFIX

_FULL = int(mujoco.mjtState.mjSTATE_FULLPHYSICS.value)
_CONTROLS = int(mujoco.mjtState.mjSTATE_CTRL.value | mujoco.mjtState.mjSTATE_MOCAP_POS.value)


class PhysicsPeriod:
    """`k` physics steps of one model and data with per-step obstacle positions; buffers
    reused from period to period."""

    def __init__(self, model: mujoco.MjModel, data: mujoco.MjData, k: int) -> None:
        self.model, self.data, self.k = model, data, k
        self._runner = rollout.Rollout(nthread=0)  # on the calling thread: no pool to start or stop
        self._state0 = np.empty((1, mujoco.mj_stateSize(model, _FULL)))
        self._warm0 = np.empty((1, model.nv))
        self._controls = np.empty((1, k, mujoco.mj_stateSize(model, _CONTROLS)))
        self._mocap = self._controls[0, :, model.nu :].reshape(k, model.nmocap, 3)  # a view
        self._states = np.empty((1, k, self._state0.shape[1]))
        self._sensors = np.empty((1, k, model.nsensordata))
        # The runner's Jackal counts every contact in its sensor (`mjSENS_CONTACT`, "found").
        try:
            contact = model.sensor(f"{ROBOT_PREFIX}contact").id
        except KeyError:
            raise DynabarnError("the model's robot has no contact sensor (not the runner's Jackal)") from None
        self._touches = self._sensors[0, :, int(model.sensor_adr[contact])]  # views, read after each period
        self._poses = self._states[0, :, 1:4]
        self._state_row, self._ctrl = self._state0[0], self._controls[0, :, : model.nu]
        self._models, self._datas = [model], [data]

    def run(self, obstacle_xy: np.ndarray, poses_out: np.ndarray) -> tuple[int, bool]:
        """Step with the first n mocap bodies at obstacle_xy[j] (k, n, 2) before step j; the
        robot's pose (x, y, yaw) after each step into poses_out's rows. Returns (steps run,
        contact): all k without a contact, else up to and including the first that touched."""
        data, k = self.data, self.k
        mujoco.mj_getState(self.model, data, self._state_row, _FULL)
        self._warm0[0] = data.qacc_warmstart
        self._ctrl[:] = data.ctrl
        self._mocap[:] = data.mocap_pos  # heights and any other mocap bodies stay where they are
        self._mocap[:, : obstacle_xy.shape[1], :2] = obstacle_xy[:k]
        self._runner.rollout(
            self._models,
            self._datas,
            self._state0,
            self._controls,
            control_spec=_CONTROLS,
            skip_checks=True,
            nstep=k,
            initial_warmstart=self._warm0,
            state=self._states,
            sensordata=self._sensors,
        )
        if not self._touches.any():
            poses_out[:k] = self._poses  # the state's time, then qpos: the robot's x, y, yaw first
            return k, False
        return self._step_to_contact(obstacle_xy, poses_out), True

    def _step_to_contact(self, obstacle_xy: np.ndarray, poses_out: np.ndarray) -> int:
        """The period again from its start, step by step, up to the first contact (rare: it
        ends the episode), leaving data exactly as that step left it."""
        model, data = self.model, self.data
        mujoco.mj_setState(model, data, self._state_row, _FULL)
        data.qacc_warmstart[:] = self._warm0[0]
        mocap_xy = data.mocap_pos[: obstacle_xy.shape[1], :2]
        for j in range(self.k):
            mocap_xy[...] = obstacle_xy[j]
            mujoco.mj_step(model, data)
            poses_out[j] = data.qpos[:3]
            if data.ncon:
                return j + 1
        raise RuntimeError("the contact sensor saw a contact the step-by-step replay did not")
