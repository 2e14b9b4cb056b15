"""The bounds of what a motion profile, a count range, a shape mix or a static field may ask
for: each is a number a generator would otherwise run for hours on (a million obstacles, a
speed grid of 1e300 steps), named in the refusal (`ProfileError`)."""

from __future__ import annotations

from dynabarn.errors import ProfileError

MAX_OBSTACLE_COUNT = 200
"""Obstacles a count range may ask for (the paper's worlds have up to 19, the densest tier
24): a generator given a million would run for hours."""
MAX_OBSTACLE_SPEED = 20.0
"""[m/s] ten times the Jackal's top speed; a faster obstacle crosses the arena in a step."""
MAX_SPEED_STD = 10.0
"""[m/s] of an obstacle's speed variation."""
MIN_SPEED_STEP = 0.001
"""[m/s] the finest speed grid (a step of 1e-300 would make a grid of 1e300 speeds)."""
MAX_SHAPE_SIZE = 5.0
"""[m] an obstacle's half size or radius (the arena is 20 m across)."""
MIN_FIELD_CELL = 0.05
"""[m] a static field's finest grid: 400 x 400 cells over the whole arena."""
MAX_SMOOTH_ITERATIONS = 100
"""Rounds of a static field's cellular automaton."""


def check_range(name: str, what: str, lo: float, hi: float, *, minimum: float) -> None:
    """A [lo, hi] range of profile `name`: numbers, lo at least `minimum`, lo <= hi."""
    if not (lo == lo and hi == hi):  # NaN check without importing math
        raise ProfileError(f"profile {name!r}: {what} range contains NaN")
    if lo < minimum:
        raise ProfileError(f"profile {name!r}: {what} minimum {lo} is below {minimum}")
    if lo > hi:
        raise ProfileError(f"profile {name!r}: {what} range [{lo}, {hi}] has min > max")
