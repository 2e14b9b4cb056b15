"""Motion profiles (paper Table I), obstacle-count classes and the difficulty tree (Fig. 2).

A `MotionProfile` is the (order, speed, std) ranges of paper Sec. III-C. A `ProfileSet`
bundles what the generator needs to build a benchmark: the profiles of the "easy motion"
and "hard motion" branches of Fig. 2, the low/high obstacle-count ranges, and the
waypoint scheme. Two sets ship:

- `table1`: the paper's Table I verbatim, waypoints at every integer x (Sec. III-A).
- `release2022`: what the released worlds actually contain, measured from the 600
  trajectories of the original release (docs/concepts/worlds.md, "Paper versus release"): three
  speed bands quantised to 0.1 m/s, the hard branch a mix of medium and hard obstacles,
  and waypoints at ten evenly spaced x values plus the polynomial's sample points.

Profiles are plain data: a user builds their own with `MotionProfile(...)` and
`ProfileSet(...)`, and every parameter is validated on construction.
"""

from __future__ import annotations

import enum
from dataclasses import dataclass, field

from dynabarn.errors import ProfileError, unknown_choice
from dynabarn.registry import Registry, instances_of
from dynabarn.worlds import profile_limits as limits
from dynabarn.worlds.classes import (  # noqa: F401 (Fig. 2's classes, named here too)
    HIGH_COUNT,
    LOW_COUNT,
    CountClass,
    Difficulty,
    MotionClass,
    count_class_of,
    difficulty_of,
)
from dynabarn.worlds.profile_limits import check_range as _check_range

ARENA_HALF_SIZE = 10.0
"""Half the side of the square arena [m]: obstacles live in [-10, 10]^2."""


class WaypointScheme(enum.StrEnum):
    """Where Alg. 1 puts waypoints along the fitted polynomial."""

    INTEGER = "integer"
    """Every integer x in [-10, 10] plus the edge crossings (paper Sec. III-A)."""
    RELEASE = "release"
    """x = linspace(-10, 10, 10), the sample points and the edge crossings (the release)."""


@dataclass(frozen=True, slots=True)
class MotionProfile:
    """The six parameters of paper Sec. III-C for one class of obstacle motion.

    Attributes:
        name: label stored with every obstacle drawn from this profile.
        order: [order_min, order_max] of the fitted polynomial (integers >= 1).
        speed: [speed_min, speed_max] of segment speeds [m/s], speed_min > 0.
        std: [std_min, std_max] of the per-obstacle speed standard deviation [m/s].
        speed_step: quantum of segment speeds [m/s]; 0 keeps them continuous. The release
            stores speeds on a 0.1 m/s grid inside [speed_min, speed_max).
        speed_limit: how a drawn speed outside [speed_min, speed_max] is limited: `clip`
            (the paper's "limited below and above") or `redraw` (draw again from the same
            normal, a truncated normal; fits the release's speed histogram better).
    """

    name: str
    order: tuple[int, int]
    speed: tuple[float, float]
    std: tuple[float, float]
    speed_step: float = 0.0
    speed_limit: str = "clip"

    def __post_init__(self) -> None:
        n = self.name
        if self.speed_limit not in ("clip", "redraw"):
            raise ProfileError(unknown_choice("speed_limit", self.speed_limit, ["clip", "redraw"]))
        if not n:
            raise ProfileError("a motion profile needs a name")
        if any(int(o) != o for o in self.order):
            raise ProfileError(f"profile {n!r}: order must be whole numbers, got {self.order}")
        _check_range(n, "order", self.order[0], self.order[1], minimum=1)
        if self.order[1] > 10:
            raise ProfileError(f"profile {n!r}: order {self.order[1]} > 10 cannot be fitted to grid points")
        _check_range(n, "speed", self.speed[0], self.speed[1], minimum=0.0)
        if self.speed[0] <= 0:
            raise ProfileError(f"profile {n!r}: speed minimum must be positive, got {self.speed[0]}")
        if self.speed[1] > limits.MAX_OBSTACLE_SPEED:
            raise ProfileError(f"profile {n!r}: speed {self.speed[1]} is above {limits.MAX_OBSTACLE_SPEED:g} m/s")
        _check_range(n, "std", self.std[0], self.std[1], minimum=0.0)
        if self.std[1] > limits.MAX_SPEED_STD:
            raise ProfileError(f"profile {n!r}: std maximum {self.std[1]} is above {limits.MAX_SPEED_STD:g} m/s")
        if not (self.speed_step == 0 or limits.MIN_SPEED_STEP <= self.speed_step <= limits.MAX_OBSTACLE_SPEED):
            raise ProfileError(
                f"profile {n!r}: speed_step must be 0 (continuous speeds) or in [{limits.MIN_SPEED_STEP:g}, "
                f"{limits.MAX_OBSTACLE_SPEED:g}] m/s, got {self.speed_step}"
            )
        if self.speed_step > 0 and self.quantised_speeds().size == 0:
            raise ProfileError(f"profile {n!r}: no multiple of speed_step {self.speed_step} lies in {self.speed}")

    def quantised_speeds(self):  # -> np.ndarray, imported lazily to keep this module light
        """The admissible speeds [m/s] on the `speed_step` grid, in [speed_min, speed_max)."""
        import numpy as np

        step = self.speed_step
        k = np.arange(np.ceil(self.speed[0] / step - 1e-9), np.ceil(self.speed[1] / step - 1e-9))
        return np.round(k * step, 6)

    def to_dict(self) -> dict:
        return {
            "name": self.name,
            "order": list(self.order),
            "speed": list(self.speed),
            "std": list(self.std),
            "speed_step": self.speed_step,
            "speed_limit": self.speed_limit,
        }

    @classmethod
    def from_dict(cls, d: dict) -> MotionProfile:
        try:
            return cls(
                name=str(d["name"]),
                order=(int(d["order"][0]), int(d["order"][1])),
                speed=(float(d["speed"][0]), float(d["speed"][1])),
                std=(float(d["std"][0]), float(d["std"][1])),
                speed_step=float(d.get("speed_step", 0.0)),
                speed_limit=str(d.get("speed_limit", "clip")),
            )
        except (KeyError, TypeError, IndexError, ValueError) as exc:
            raise ProfileError(f"malformed motion profile {d!r}: {exc}") from None


@dataclass(frozen=True, slots=True)
class ProfileSet:
    """Everything Alg. 1 and 2 need to build a benchmark of three difficulties.

    Attributes:
        name: identifier (`table1`, `release2022`, or a user's).
        easy_motion: profiles of Fig. 2's "easy" branch; each obstacle draws one uniformly.
        hard_motion: profiles of Fig. 2's "hard" branch.
        low_count: [min, max] obstacles of the "low" branch.
        high_count: [min, max] obstacles of the "high" branch.
        waypoints: where waypoints are placed along the polynomial.
    """

    name: str
    easy_motion: tuple[MotionProfile, ...]
    hard_motion: tuple[MotionProfile, ...]
    low_count: tuple[int, int] = LOW_COUNT
    high_count: tuple[int, int] = HIGH_COUNT
    waypoints: WaypointScheme = WaypointScheme.INTEGER
    description: str = field(default="", compare=False)

    def __post_init__(self) -> None:
        if not self.easy_motion or not self.hard_motion:
            raise ProfileError(f"profile set {self.name!r}: each motion branch needs at least one profile")
        for what, (lo, hi) in (("low_count", self.low_count), ("high_count", self.high_count)):
            if int(lo) != lo or int(hi) != hi:
                raise ProfileError(f"profile set {self.name!r}: {what} must be whole numbers")
            if lo < 1:
                raise ProfileError(f"profile set {self.name!r}: {what} minimum must be >= 1, got {lo}")
            if lo > hi:
                raise ProfileError(f"profile set {self.name!r}: {what} [{lo}, {hi}] has min > max")
            if hi > limits.MAX_OBSTACLE_COUNT:
                raise ProfileError(
                    f"profile set {self.name!r}: {what} {hi} is above {limits.MAX_OBSTACLE_COUNT} obstacles a world"
                )
        try:
            WaypointScheme(self.waypoints)
        except ValueError:
            raise ProfileError(
                unknown_choice("waypoint scheme", str(self.waypoints), [s.value for s in WaypointScheme])
            ) from None

    def motion_profiles(self, motion: MotionClass) -> tuple[MotionProfile, ...]:
        return self.easy_motion if motion is MotionClass.EASY else self.hard_motion

    def count_range(self, count: CountClass) -> tuple[int, int]:
        return self.low_count if count is CountClass.LOW else self.high_count

    def profile(self, name: str) -> MotionProfile:
        for p in (*self.easy_motion, *self.hard_motion):
            if p.name == name:
                return p
        names = sorted({p.name for p in (*self.easy_motion, *self.hard_motion)})
        raise ProfileError(unknown_choice("motion profile", name, names))

    def to_dict(self) -> dict:
        return {
            "name": self.name,
            "easy_motion": [p.to_dict() for p in self.easy_motion],
            "hard_motion": [p.to_dict() for p in self.hard_motion],
            "low_count": list(self.low_count),
            "high_count": list(self.high_count),
            "waypoints": str(self.waypoints),
        }

    @classmethod
    def from_dict(cls, d: dict) -> ProfileSet:
        try:
            return cls(
                name=str(d["name"]),
                easy_motion=tuple(MotionProfile.from_dict(p) for p in d["easy_motion"]),
                hard_motion=tuple(MotionProfile.from_dict(p) for p in d["hard_motion"]),
                low_count=(int(d["low_count"][0]), int(d["low_count"][1])),
                high_count=(int(d["high_count"][0]), int(d["high_count"][1])),
                waypoints=WaypointScheme(d.get("waypoints", "integer")),
            )
        except ProfileError:
            raise
        except (KeyError, TypeError, IndexError, ValueError) as exc:
            raise ProfileError(f"malformed profile set: {exc}") from None


SHAPES = ("cylinder", "box", "capsule")


@dataclass(frozen=True, slots=True)
class ShapeMix:
    """Which obstacle shapes a world draws and how big (beyond the paper: all cylinders).

    Every obstacle draws its shape with probabilities `weights` (cylinder, box, capsule),
    then its size uniformly from the ranges and a fixed yaw uniformly in [0, pi). Boxes
    stand on the floor (height 1 m); capsules lie on it, their axis horizontal along the
    yaw at the height of their radius, so the laser (0.30 m up) sees them.

    Attributes:
        name: label stored in the worlds' provenance.
        weights: relative probabilities of cylinder, box and capsule.
        box_half_size: range of each of a box's half length and half width [m].
        capsule_radius: range of a capsule's radius [m].
        capsule_half_length: range of half the length of a capsule's axis segment [m].
    """

    name: str
    weights: tuple[float, float, float] = (1.0, 0.0, 0.0)
    box_half_size: tuple[float, float] = (0.2, 0.6)
    capsule_radius: tuple[float, float] = (0.25, 0.45)
    capsule_half_length: tuple[float, float] = (0.3, 0.8)

    def __post_init__(self) -> None:
        if len(self.weights) != 3 or min(self.weights) < 0 or sum(self.weights) <= 0:
            raise ProfileError(f"shape mix {self.name!r}: weights must be 3 non-negative numbers, not all zero")
        _check_range(self.name, "box_half_size", *self.box_half_size, minimum=0.05)
        _check_range(self.name, "capsule_radius", *self.capsule_radius, minimum=0.16)
        _check_range(self.name, "capsule_half_length", *self.capsule_half_length, minimum=0.05)
        for what in ("box_half_size", "capsule_radius", "capsule_half_length"):
            if getattr(self, what)[1] > limits.MAX_SHAPE_SIZE:
                raise ProfileError(f"shape mix {self.name!r}: {what} maximum is above {limits.MAX_SHAPE_SIZE:g} m")

    @property
    def cylinders_only(self) -> bool:
        return self.weights[1] == 0 and self.weights[2] == 0

    def to_dict(self) -> dict:
        return {
            "name": self.name,
            "weights": list(self.weights),
            "box_half_size": list(self.box_half_size),
            "capsule_radius": list(self.capsule_radius),
            "capsule_half_length": list(self.capsule_half_length),
        }


SHAPE_MIXES: Registry[ShapeMix] = Registry(
    "shape mix",
    {
        "cylinder": ShapeMix("cylinder"),
        "mixed": ShapeMix("mixed", weights=(1.0, 1.0, 1.0)),
    },
    group="dynabarn.shape_mixes",
    error=ProfileError,
)


@dataclass(frozen=True, slots=True)
class StaticField:
    """A BARN-style field of static cylinders for mixed worlds (beyond the paper).

    As BARN (Perille et al. 2020) builds its worlds: cells of a grid are filled at random
    with probability `fill`, then `smooth_iterations` rounds of a cellular automaton (a
    cell becomes filled with >= 5 filled neighbours of 8, empty with <= 3) grow clumps and
    passages; every filled cell holds a cylinder of radius `radius`, except cells whose
    8 neighbours are all filled (BARN leaves those out: nothing can reach them). A field is kept only
    when the Jackal can cross it from its spawn side to its goal side; otherwise it is
    drawn again from the same generator. Crossable means a disc of the Jackal's
    circumscribed radius (room to turn) fits through, 3 cm from every cylinder.

    Attributes:
        name: label stored in the worlds' provenance.
        x_range, y_range: the rectangle the field covers [m].
        cell: grid spacing [m] (BARN's 0.15).
        radius: cylinder radius [m] (BARN's 0.075).
        fill: range of the initial fill probability, drawn per world.
        smooth_iterations: cellular-automaton rounds.
    """

    name: str
    x_range: tuple[float, float] = (-2.25, 2.25)
    """30 cells deep, as BARN's worlds, across the middle of the arena."""
    y_range: tuple[float, float] = (-9.75, 9.75)
    """Wall to wall: the robot cannot go around the field."""
    cell: float = 0.15
    radius: float = 0.075
    fill: tuple[float, float] = (0.36, 0.43)
    """Gives 7-22% of the cells filled after smoothing (BARN's grids: 12% on average)."""
    smooth_iterations: int = 3

    def __post_init__(self) -> None:
        _check_range(self.name, "x_range", *self.x_range, minimum=-ARENA_HALF_SIZE)
        _check_range(self.name, "y_range", *self.y_range, minimum=-ARENA_HALF_SIZE)
        if max(self.x_range[1], self.y_range[1]) > ARENA_HALF_SIZE:
            raise ProfileError(f"static field {self.name!r}: must lie inside the arena [-10, 10]^2")
        if not limits.MIN_FIELD_CELL <= self.cell <= ARENA_HALF_SIZE:
            why = f"cell must be in [{limits.MIN_FIELD_CELL:g}, {ARENA_HALF_SIZE:g}] m"
            raise ProfileError(f"static field {self.name!r}: {why}")
        if not 0 < 2 * self.radius <= self.cell:
            raise ProfileError(f"static field {self.name!r}: need 0 < 2 radius <= cell")
        _check_range(self.name, "fill", *self.fill, minimum=0.0)
        if self.fill[1] >= 1:
            raise ProfileError(f"static field {self.name!r}: fill must be below 1")
        if not 0 <= self.smooth_iterations <= limits.MAX_SMOOTH_ITERATIONS:
            raise ProfileError(
                f"static field {self.name!r}: smooth_iterations must be in [0, {limits.MAX_SMOOTH_ITERATIONS}]"
            )

    def to_dict(self) -> dict:
        return {
            "name": self.name,
            "x_range": list(self.x_range),
            "y_range": list(self.y_range),
            "cell": self.cell,
            "radius": self.radius,
            "fill": list(self.fill),
            "smooth_iterations": self.smooth_iterations,
        }


STATIC_FIELDS: Registry[StaticField] = Registry(
    "static field", {"barn-grid": StaticField("barn-grid")}, group="dynabarn.static_fields", error=ProfileError
)


# Paper Table I, verbatim.
TABLE1_EASY = MotionProfile("easy", order=(1, 2), speed=(0.5, 1.0), std=(0.01, 0.1))
TABLE1_HARD = MotionProfile("hard", order=(3, 4), speed=(1.0, 2.0), std=(0.1, 0.2))

# Measured from the release's 600 trajectories (../shared/reference/dynabarn60.json):
# segment speeds lie on a 0.1 m/s grid in [0.5, 1.0), [1.0, 1.5) and [1.5, 2.0); the
# orders [1, 2], [2, 3], [3, 4] give the closest waypoints-per-trajectory distribution
# under our distinct-x sampling (docs/concepts/worlds.md: "Paper versus release"); per-trajectory speed
# std has medians 0.035, 0.087 and 0.107 m/s.
RELEASE_EASY = MotionProfile(
    "easy", order=(1, 2), speed=(0.5, 1.0), std=(0.01, 0.1), speed_step=0.1, speed_limit="redraw"
)
RELEASE_MEDIUM = MotionProfile(
    "medium", order=(2, 3), speed=(1.0, 1.5), std=(0.05, 0.15), speed_step=0.1, speed_limit="redraw"
)
RELEASE_HARD = MotionProfile(
    "hard", order=(3, 4), speed=(1.5, 2.0), std=(0.1, 0.2), speed_step=0.1, speed_limit="redraw"
)

PROFILE_SETS: Registry[ProfileSet] = Registry(
    "profile set",
    {
        "table1": ProfileSet(
            "table1",
            easy_motion=(TABLE1_EASY,),
            hard_motion=(TABLE1_HARD,),
            waypoints=WaypointScheme.INTEGER,
            description="paper Table I; waypoints at every integer x (Sec. III-A)",
        ),
        "release2022": ProfileSet(
            "release2022",
            easy_motion=(RELEASE_EASY,),
            hard_motion=(RELEASE_MEDIUM, RELEASE_HARD),
            waypoints=WaypointScheme.RELEASE,
            description="measured from the 2022 release: 3 speed bands on a 0.1 m/s grid",
        ),
    },
    group="dynabarn.profile_sets",
    error=ProfileError,
    check=instances_of(ProfileSet),
)
"""Profile sets by name: built in, registered at run time (`PROFILE_SETS.register`), installed."""


def get_profile_set(name: str) -> ProfileSet:
    return PROFILE_SETS.get_item(name)


def get_shape_mix(name: str) -> ShapeMix:
    return SHAPE_MIXES.get_item(name)


def get_static_field(name: str) -> StaticField:
    return STATIC_FIELDS.get_item(name)
