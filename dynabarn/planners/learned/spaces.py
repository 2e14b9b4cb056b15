"""The observation and action of the paper's learned baselines (Fig. 4), in numpy.

Observation: the 720 laser ranges [m], then the local goal (g_x, g_y) [m] in the robot
frame, `lookahead` metres along the global plan. Action: two numbers in [-1, 1], mapped
linearly onto v in [v_min, v_max] and w in [-w_max, w_max] of the Jackal. The planners,
the Gymnasium environment and the demonstration datasets all use these two mappings.
"""

from __future__ import annotations

import numpy as np

from dynabarn.robot import JACKAL

V_MIN, V_MAX, W_MAX = JACKAL.v_min, JACKAL.v_max, JACKAL.w_max
HEADS = ("regress", "classify")
"""How a student turns its inputs into an action (`student.StudentActor`): the action
itself, or the most likely of a teacher's candidate commands."""
ENCODERS = ("mlp", "set")
"""How a student reads its features (`student.StudentActor`): `mlp`, one flat vector
through dense layers (the first students); `set`, the scans by convolution and the tracks
as a set (`set_encoder`)."""


def policy_input(scan: np.ndarray, local_goal: np.ndarray, dtype=np.float64) -> np.ndarray:
    """The policy's observation (722,): ranges then the local goal in the robot frame."""
    return np.concatenate([scan, local_goal]).astype(dtype)


def checked_actions(action, count: int | None = None) -> np.ndarray:
    """An environment's action(s) as float64, checked like any input: shape (2,) (or
    (count, 2) for `count` worlds) and finite. ValueError with one line otherwise (a NaN
    action would drive a NaN command into the physics)."""
    expected = (2,) if count is None else (count, 2)
    try:
        a = np.asarray(action, dtype=np.float64)
    except (TypeError, ValueError):
        raise ValueError(f"action {action!r:.80}: expected numbers of shape {expected}") from None
    if count is not None and a.size == 2 * count:
        a = a.reshape(expected)
    if a.shape != expected:
        raise ValueError(f"action of shape {a.shape}: expected {expected}")
    if not np.isfinite(a).all():
        raise ValueError("action holds NaN or infinity; actions are finite numbers in [-1, 1]")
    return a


def action_to_command(action: np.ndarray) -> tuple[float, float]:
    """Normalised action in [-1, 1]^2 -> (v [m/s], w [rad/s])."""
    a = np.clip(np.asarray(action, dtype=np.float64), -1.0, 1.0)
    return V_MIN + 0.5 * (a[0] + 1.0) * (V_MAX - V_MIN), W_MAX * a[1]


def command_to_action(v: np.ndarray, w: np.ndarray) -> np.ndarray:
    """(v, w) -> normalised actions (..., 2), the inverse of `action_to_command`."""
    a0 = 2.0 * (np.asarray(v) - V_MIN) / (V_MAX - V_MIN) - 1.0
    a1 = np.asarray(w) / W_MAX
    return np.clip(np.stack([a0, a1], axis=-1), -1.0, 1.0).astype(np.float32)
