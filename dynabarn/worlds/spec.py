"""The `WorldSpec`: one world's obstacles, layout and provenance, and its JSON form.

A world is data: every field is checked when it is built, so a world file that reaches
the compiler or the simulator is well formed. Generation (Alg. 2) is `worlds.generate`.
"""

from __future__ import annotations

import enum
import json
import math
from collections.abc import Mapping
from dataclasses import dataclass, field

import numpy as np

from dynabarn.errors import WorldError
from dynabarn.files import plain_name_problem
from dynabarn.worlds.profiles import (
    ARENA_HALF_SIZE,
    CountClass,
    Difficulty,
    MotionClass,
)
from dynabarn.worlds.ranges import MAX_OBSTACLES, check_layout, check_obstacle_numbers
from dynabarn.worlds.trajectory import Trajectory

WORLD_FORMAT_VERSION = 1

OBSTACLE_RADIUS = 0.5
"""Cylinder obstacle radius [m] (paper Fig. 3)."""
OBSTACLE_HEIGHT = 1.0
"""Cylinder obstacle height [m] (the release's cylinder length)."""


class Interpolation(enum.StrEnum):
    LINEAR = "linear"
    """Straight lines at constant speed between waypoints (the paper)."""
    SPLINE = "spline"
    """Gazebo's PoseAnimation: a Catmull-Rom (tension 0) Hermite spline per keyframe."""


class EndBehavior(enum.StrEnum):
    LOOP = "loop"
    """Restart at the first waypoint after the last (Gazebo's loop=true)."""
    HOLD = "hold"
    """Stay at the last waypoint."""


@dataclass(frozen=True, slots=True)
class Wall:
    """An axis-aligned box wall. centre (x, y) [m], size (sx, sy, sz) full lengths [m]."""

    name: str
    centre: tuple[float, float]
    size: tuple[float, float, float]


@dataclass(frozen=True, slots=True)
class Layout:
    """The static part of a world: arena, walls and goal (as in the original release)."""

    walls: tuple[Wall, ...] = (
        Wall("wall_back", (-10.0, 0.0), (0.5, 20.0, 1.0)),
        Wall("wall_left", (0.0, 10.0), (20.0, 0.5, 1.0)),
        Wall("wall_right", (0.0, -10.0), (20.0, 0.5, 1.0)),
    )
    goal: tuple[float, float] = (-9.0, 0.0)
    arena_half_size: float = ARENA_HALF_SIZE
    cylinders: tuple[tuple[float, float, float], ...] = ()
    """Static cylinders (x, y, radius) [m], e.g. the obstacles of a static BARN world."""

    def __post_init__(self) -> None:
        check_layout(self)

    def to_dict(self) -> dict:
        d = {
            "walls": [{"name": w.name, "centre": list(w.centre), "size": list(w.size)} for w in self.walls],
            "goal": list(self.goal),
            "arena_half_size": self.arena_half_size,
        }
        if self.cylinders:  # only when present, so dynamic worlds' files stay as they were
            d["cylinders"] = [list(c) for c in self.cylinders]
        return d

    @classmethod
    def from_dict(cls, d: dict) -> Layout:
        return cls(
            walls=tuple(
                Wall(str(w["name"]), tuple(map(float, w["centre"])), tuple(map(float, w["size"])))  # type: ignore[arg-type]
                for w in d["walls"]
            ),
            goal=(float(d["goal"][0]), float(d["goal"][1])),
            arena_half_size=float(d["arena_half_size"]),
            cylinders=tuple((float(x), float(y), float(r)) for x, y, r in d.get("cylinders", [])),
        )


SCRIPTED = "scripted"
"""The paper's behaviour: the obstacle follows its schedule whatever the robot does."""
SHAPE_NAMES = ("cylinder", "box", "capsule")


OBSTACLE_FIELDS = frozenset(
    {"name", "profile", "order", "avg_speed", "avg_std", "radius", "height", "source", "behavior", "keyframes"}
    | {"shape", "half_length", "half_width", "yaw"}
)
"""Keys of an obstacle in a world file; any other key is a parameter of its behaviour."""


@dataclass(frozen=True, slots=True)
class Obstacle:
    """One moving obstacle: its name, schedule, shape and behaviour.

    Shapes (the paper's obstacles are all cylinders; the others are beyond it). In the
    plane every shape is a rounded rectangle: a core rectangle of half sizes
    (`half_length` along `yaw`, `half_width` across) grown by `radius`:
    - `cylinder`: radius r, half_length = half_width = 0, standing, `height` tall;
    - `box`: half_length x half_width, radius 0, standing, `height` tall;
    - `capsule`: radius r around a horizontal axis segment of half length `half_length`
      along `yaw`, lying on the floor (axis at height r).
    The yaw is fixed: obstacles translate along their schedules without turning.
    """

    name: str
    trajectory: Trajectory
    radius: float = OBSTACLE_RADIUS
    height: float = OBSTACLE_HEIGHT
    source: str = ""
    """Provenance, e.g. the release plugin it was imported from."""
    behavior: str = SCRIPTED
    """How it answers the robot: `scripted` (the paper's: follows its schedule whatever the
    robot does) or a reactive behaviour such as `yield` or `avoid` (`dynabarn.sim.behaviors`,
    where behaviours are registered and their parameters checked)."""
    behavior_params: Mapping[str, float] = field(default_factory=dict)
    """The behaviour's parameters, e.g. {"yield_distance": 1.5}; stored beside `behavior`."""
    shape: str = "cylinder"
    half_length: float = 0.0
    half_width: float = 0.0
    yaw: float = 0.0

    def __post_init__(self) -> None:
        check_obstacle_numbers(self)
        if not (isinstance(self.behavior, str) and self.behavior.isidentifier()):
            raise WorldError(f"obstacle {self.name!r}: behavior must be a name, got {self.behavior!r}")
        for key, value in self.behavior_params.items():
            if key in OBSTACLE_FIELDS or not key.isidentifier():
                raise WorldError(f"obstacle {self.name!r}: {key!r} cannot be a behaviour parameter")
            if not (isinstance(value, int | float) and math.isfinite(value)):
                raise WorldError(f"obstacle {self.name!r}: {key} must be a finite number, got {value!r}")
        if self.behavior == SCRIPTED and self.behavior_params:
            raise WorldError(f"obstacle {self.name!r}: a scripted obstacle takes no {sorted(self.behavior_params)}")
        if self.shape not in SHAPE_NAMES:
            raise WorldError(
                f"obstacle {self.name!r}: unknown shape {self.shape!r}; available: " + ", ".join(SHAPE_NAMES)
            )
        ok = {
            "cylinder": self.radius > 0 and self.half_length == 0 and self.half_width == 0,
            "box": self.radius == 0 and self.half_length > 0 and self.half_width > 0,
            "capsule": self.radius > 0 and self.half_length > 0 and self.half_width == 0,
        }[self.shape]
        if not ok or self.height <= 0:
            raise WorldError(
                f"obstacle {self.name!r}: a {self.shape} needs "
                + {
                    "cylinder": "radius > 0 and no half_length/half_width",
                    "box": "radius 0 and half_length, half_width > 0",
                    "capsule": "radius > 0, half_length > 0 and half_width 0",
                }[self.shape]
                + " (and height > 0)"
            )

    @property
    def reactive(self) -> bool:
        """It answers the robot (any behaviour but the paper's `scripted`)."""
        return self.behavior != SCRIPTED

    @property
    def half_extents(self) -> tuple[float, float]:
        """Half sizes of the core rectangle, (along yaw, across) [m]."""
        return (self.half_length, self.half_width)

    @property
    def bounding_radius(self) -> float:
        """Radius of the smallest circle around the footprint [m] (the radius, for cylinders)."""
        return math.hypot(self.half_length, self.half_width) + self.radius

    @property
    def top(self) -> float:
        """Height of the obstacle's top [m]."""
        return 2 * self.radius if self.shape == "capsule" else self.height

    def extra_fields(self) -> dict:
        """What a non-default behaviour or shape adds to the world file (nothing for the
        paper's scripted cylinders, so their files stay as they were)."""
        d: dict = {}
        if self.reactive:
            d.update(behavior=self.behavior, **self.behavior_params)
        if self.shape != "cylinder":
            d.update(shape=self.shape, half_length=self.half_length, half_width=self.half_width, yaw=self.yaw)
        return d


@dataclass(frozen=True, slots=True)
class WorldSpec:
    """A whole DynaBARN world: everything needed to compile it and play it back.

    Attributes:
        name: file stem, e.g. `world_137`.
        world_id: index in its world set (None for a one-off world).
        difficulty: easy | medium | hard.
        count_class, motion_class: the world's branch of Fig. 2 (None when imported).
        profile_set: name of the profile set it was drawn from (or `dynabarn-release`).
        seed: the base seed; the world's generator is SeedSequence([seed, world_id]).
        obstacles: the moving obstacles, in spawn order.
        interpolation: how positions are played back between waypoints.
        end_behavior: what happens after an obstacle's last waypoint.
        layout: walls and goal.
        provenance: free-form facts about where the world came from.
    """

    name: str
    world_id: int | None
    difficulty: Difficulty
    obstacles: tuple[Obstacle, ...]
    count_class: CountClass | None = None
    motion_class: MotionClass | None = None
    profile_set: str = ""
    seed: int | None = None
    interpolation: Interpolation = Interpolation.LINEAR
    end_behavior: EndBehavior = EndBehavior.LOOP
    layout: Layout = field(default_factory=Layout)
    provenance: dict = field(default_factory=dict)

    def __post_init__(self) -> None:
        # Accept plain strings for the enum fields (JSON, users) and validate them.
        try:
            for attr, kind in (
                ("difficulty", Difficulty),
                ("interpolation", Interpolation),
                ("end_behavior", EndBehavior),
                ("count_class", CountClass),
                ("motion_class", MotionClass),
            ):
                value = getattr(self, attr)
                if value is not None and not isinstance(value, kind):
                    object.__setattr__(self, attr, kind(value))
        except ValueError as exc:
            raise WorldError(f"world {self.name!r}: {exc}") from None
        problem = plain_name_problem(self.name)
        if problem:  # it names the world's recordings and rows: never a path, a line break or nothing
            raise WorldError(f"world name {self.name!r} {problem}")
        if self.world_id is not None:  # a JSON 1.5 or true is no index
            if isinstance(self.world_id, bool) or not isinstance(self.world_id, int | np.integer) or self.world_id < 0:
                raise WorldError(f"world {self.name!r}: world_id {self.world_id!r} must be a whole number >= 0 or null")
            object.__setattr__(self, "world_id", int(self.world_id))
        if len(self.obstacles) > MAX_OBSTACLES:
            raise WorldError(f"world {self.name!r}: {len(self.obstacles)} obstacles (at most {MAX_OBSTACLES})")
        names = [o.name for o in self.obstacles]
        if len(set(names)) != len(names):
            raise WorldError(f"world {self.name!r}: obstacle names must be unique")

    def __repr__(self) -> str:
        return (
            f"WorldSpec(name={self.name!r}, difficulty={self.difficulty.value}, "
            f"n_obstacles={len(self.obstacles)}, interpolation={self.interpolation.value}, "
            f"end={self.end_behavior.value})"
        )

    # -- JSON round trip -------------------------------------------------------------
    def metadata(self) -> dict:
        """Everything but the schedules (which travel as numeric arrays in the MJCF)."""
        return {
            "format": "dynabarn-world",
            "format_version": WORLD_FORMAT_VERSION,
            "name": self.name,
            "world_id": self.world_id,
            "difficulty": self.difficulty.value,
            "count_class": self.count_class.value if self.count_class else None,
            "motion_class": self.motion_class.value if self.motion_class else None,
            "profile_set": self.profile_set,
            "seed": self.seed,
            "interpolation": self.interpolation.value,
            "end_behavior": self.end_behavior.value,
            "layout": self.layout.to_dict(),
            "provenance": self.provenance,
            "obstacles": [
                {
                    "name": o.name,
                    "profile": o.trajectory.profile,
                    "order": o.trajectory.order,
                    "avg_speed": o.trajectory.avg_speed,
                    "avg_std": o.trajectory.avg_std,
                    "radius": o.radius,
                    "height": o.height,
                    "source": o.source,
                    **o.extra_fields(),
                }
                for o in self.obstacles
            ],
        }

    def to_dict(self) -> dict:
        d = self.metadata()
        for od, o in zip(d["obstacles"], self.obstacles, strict=True):
            od["keyframes"] = np.column_stack([o.trajectory.times, o.trajectory.xy]).tolist()
        return d

    def to_json(self) -> str:
        return json.dumps(self.to_dict(), sort_keys=True)

    @classmethod
    def from_dict(cls, d: dict, keyframes: list[np.ndarray] | None = None) -> WorldSpec:
        """Build from `to_dict()` output, or from `metadata()` plus (N, 3) [t, x, y] arrays."""
        if not isinstance(d, dict) or d.get("format") != "dynabarn-world":
            raise WorldError("not a DynaBARN world (missing format tag 'dynabarn-world')")
        if d.get("format_version", 0) > WORLD_FORMAT_VERSION:
            raise WorldError(
                f"world format version {d['format_version']} is newer than this dynabarn "
                f"understands ({WORLD_FORMAT_VERSION}); upgrade dynabarn"
            )
        try:
            obstacles = []
            for i, od in enumerate(d["obstacles"]):
                kf = np.asarray(keyframes[i] if keyframes is not None else od["keyframes"], dtype=np.float64)
                if kf.ndim != 2 or kf.shape[1] != 3 or len(kf) < 2:
                    raise WorldError(f"obstacle {od.get('name', i)}: keyframes must be (N>=2, 3) [t, x, y]")
                traj = Trajectory(
                    times=np.ascontiguousarray(kf[:, 0]),
                    xy=np.ascontiguousarray(kf[:, 1:3]),
                    profile=str(od["profile"]),
                    order=int(od["order"]),
                    avg_speed=float(od["avg_speed"]),
                    avg_std=float(od["avg_std"]),
                )
                obstacles.append(
                    Obstacle(
                        name=str(od["name"]),
                        trajectory=traj,
                        radius=float(od["radius"]),
                        height=float(od["height"]),
                        source=str(od.get("source", "")),
                        behavior=str(od.get("behavior", SCRIPTED)),
                        behavior_params={k: float(v) for k, v in od.items() if k not in OBSTACLE_FIELDS},
                        shape=str(od.get("shape", "cylinder")),
                        half_length=float(od.get("half_length", 0.0)),
                        half_width=float(od.get("half_width", 0.0)),
                        yaw=float(od.get("yaw", 0.0)),
                    )
                )
            return cls(
                name=d["name"],
                world_id=d["world_id"],
                difficulty=Difficulty(d["difficulty"]),
                obstacles=tuple(obstacles),
                count_class=CountClass(d["count_class"]) if d.get("count_class") else None,
                motion_class=MotionClass(d["motion_class"]) if d.get("motion_class") else None,
                profile_set=str(d["profile_set"]),
                seed=None if d.get("seed") is None else int(d["seed"]),
                interpolation=Interpolation(d["interpolation"]),
                end_behavior=EndBehavior(d["end_behavior"]),
                layout=Layout.from_dict(d["layout"]),
                provenance=dict(d.get("provenance", {})),
            )
        except WorldError:
            raise
        except (KeyError, TypeError, ValueError, IndexError) as exc:
            raise WorldError(f"malformed world description: {type(exc).__name__}: {exc}") from None

    @classmethod
    def from_json(cls, text: str) -> WorldSpec:
        try:
            return cls.from_dict(json.loads(text))
        except json.JSONDecodeError as exc:
            raise WorldError(f"world JSON is not valid JSON: {exc}") from None

    def __eq__(self, other: object) -> bool:
        if not isinstance(other, WorldSpec):
            return NotImplemented
        return self.to_json() == other.to_json()

    __hash__ = None  # type: ignore[assignment]
