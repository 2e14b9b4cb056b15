"""DynaBARN-v0's observation and action spaces (Gymnasium's), one place for every backend:
the C engine's `DynaBARNEnv` and `DynaBARNVectorEnv`, and the Warp backend's `WarpVectorEnv`."""

from __future__ import annotations

import numpy as np
from gymnasium import spaces

from dynabarn.robot import JACKAL

ACTION_SPACE = spaces.Box(-1.0, 1.0, shape=(2,), dtype=np.float32)
"""(v, w) in [-1, 1]^2, scaled to the Jackal's limits (`action_to_command`)."""


def observation_space(lookahead: float) -> spaces.Box:
    """The 720 ranges within the laser's range, then the local goal within `lookahead` [m]."""
    n = len(JACKAL.laser_angles())
    low = np.concatenate([np.full(n, JACKAL.laser_range_min), [-lookahead, -lookahead]])
    high = np.concatenate([np.full(n, JACKAL.laser_range_max), [lookahead, lookahead]])
    return spaces.Box(low.astype(np.float32), high.astype(np.float32), dtype=np.float32)
