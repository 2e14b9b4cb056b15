"""Named evaluation protocols: where the robot starts, what counts as success, time limits.

A protocol is plain data (`EvalProtocol`); `--protocol` takes a registered name or the
path of a JSON file with the same fields, so users add their own without code.

- `barn` (default): the BARN Challenge's rules applied to DynaBARN worlds. Spawn
  (11, 0, yaw pi); success when the robot centre is within 1.0 m of the goal; 100 s of
  simulated time counted from the first 0.1 m of motion; score = success * OT /
  clip(AT, 2 OT, 8 OT) with OT = 20 m / 2 m/s. (The challenge's own script computes OT
  from a negative path length, so there every success scores 0.125; we use the intended
  20 m.)
- `paper2022`: the paper's demonstration pipeline and the release's `check_goal_node`:
  spawn (12, 0, yaw pi); success when |dx| < 0.3 and |dy| < 0.3; 100 s from the start.

If the robot never covers `timer_start_distance`, the episode times out at `time_limit`
of simulated time from the start (BARN's script would wait forever).
"""

from __future__ import annotations

import enum
import json
import math
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import ClassVar

import numpy as np

from dynabarn.errors import DynabarnError, unknown_choice
from dynabarn.files import plain_name_problem
from dynabarn.registry import Registry, instances_of


class GoalRegion(enum.StrEnum):
    DISC = "disc"
    """Success when the robot centre is within `goal_tolerance` of the goal."""
    SQUARE = "square"
    """Success when |dx| < goal_tolerance and |dy| < goal_tolerance."""


@dataclass(frozen=True, slots=True)
class EvalProtocol:
    """One evaluation protocol.

    Attributes:
        name: identifier, e.g. `barn`.
        version: bumped whenever the rules change, so results name the rules they used.
        spawn: robot start (x [m], y [m], yaw [rad]) in the world frame.
        goal_region: shape of the success region.
        goal_tolerance: radius or half side of the success region [m].
        time_limit: simulated seconds allowed [s].
        timer_start_distance: the clock starts once the robot is this far from its spawn
            [m] (0: at once).
        reference_path_length: path length behind the score's optimal time [m].
        max_speed: speed behind the score's optimal time [m/s].
        score_clip: (low, high) multiples of the optimal time the actual time is clipped to.
    """

    name: str
    version: int = 1
    spawn: tuple[float, float, float] = (11.0, 0.0, math.pi)
    goal_region: GoalRegion = GoalRegion.DISC
    goal_tolerance: float = 1.0
    time_limit: float = 100.0
    timer_start_distance: float = 0.1
    reference_path_length: float = 20.0
    max_speed: float = 2.0
    score_clip: tuple[float, float] = (2.0, 8.0)
    reference_from_world: bool = False
    """Use the world's own reference path length (`provenance['reference_path_length']`,
    e.g. a static BARN world's planned path) instead of `reference_path_length`."""

    LIMITS: ClassVar[dict[str, tuple[float, float]]] = {
        "goal_tolerance": (1e-3, 20.0),
        "time_limit": (0.1, 3600.0),
        "timer_start_distance": (0.0, 20.0),
        "reference_path_length": (1e-3, 1000.0),
        "max_speed": (1e-3, 10.0),
    }
    """Physical ranges of the numbers (a protocol file is untrusted input; one hour of
    simulated time bounds an episode's memory)."""

    def __post_init__(self) -> None:
        problem = plain_name_problem(self.name)
        if problem:  # it names recordings and result lines: never a path or a line break
            raise DynabarnError(f"protocol name {self.name!r} {problem}")
        for key, (low, high) in self.LIMITS.items():
            value = getattr(self, key)
            if isinstance(value, bool) or not isinstance(value, int | float) or not low <= value <= high:
                raise DynabarnError(f"protocol {self.name!r}: {key} {value!r} is not in [{low:g}, {high:g}]")
        spawn, clip = self.spawn, self.score_clip
        if len(spawn) != 3 or not all(math.isfinite(v) for v in spawn) or max(abs(spawn[0]), abs(spawn[1])) > 1000:
            raise DynabarnError(f"protocol {self.name!r}: spawn {spawn!r} must be finite (x, y, yaw) within 1000 m")
        if len(clip) != 2 or not (math.isfinite(clip[0]) and math.isfinite(clip[1]) and 0 < clip[0] < clip[1]):
            raise DynabarnError(f"protocol {self.name!r}: score_clip {clip!r} must be (low, high) with 0 < low < high")
        if type(self.version) is not int or self.version < 1:
            raise DynabarnError(f"protocol {self.name!r}: version must be a positive integer")
        try:
            GoalRegion(self.goal_region)
        except ValueError:
            raise DynabarnError(
                unknown_choice("goal region", str(self.goal_region), [g.value for g in GoalRegion])
            ) from None

    @property
    def optimal_time(self) -> float:
        """OT of the BARN score [s]."""
        return self.reference_path_length / self.max_speed

    @property
    def longest_episode(self) -> float:
        """The most simulated time an episode can last [s]: the clock may start as late as
        one time limit (the robot leaves its spawn just before the limit), then runs one."""
        return 2.0 * self.time_limit

    def timer_started(self, x: float | np.ndarray, y: float | np.ndarray):
        """Whether the robot at (x, y) has left its spawn far enough for the clock to run;
        x and y numbers or arrays (elementwise)."""
        dx, dy = x - self.spawn[0], y - self.spawn[1]
        return dx**2 + dy**2 >= self.timer_start_distance**2

    def reached(self, x: float | np.ndarray, y: float | np.ndarray, goal: tuple[float, float]):
        """Whether the robot centre at (x, y) is inside the success region around `goal`;
        x and y numbers or arrays (elementwise)."""
        dx, dy = x - goal[0], y - goal[1]
        if self.goal_region == GoalRegion.DISC:
            return dx * dx + dy * dy < self.goal_tolerance * self.goal_tolerance
        return (np.abs(dx) < self.goal_tolerance) & (np.abs(dy) < self.goal_tolerance)

    def score(self, success: bool, actual_time: float, reference_length: float | None = None) -> float:
        """BARN score: success * OT / clip(AT, low * OT, high * OT), OT = reference length / max speed."""
        if not success:
            return 0.0
        ot = self.optimal_time if reference_length is None else reference_length / self.max_speed
        lo, hi = self.score_clip
        return ot / min(max(actual_time, lo * ot), hi * ot)

    def optimal_path_length(self, goal: tuple[float, float]) -> float:
        """Shortest distance from spawn to the success region in an empty arena [m] (SPL)."""
        dx, dy = goal[0] - self.spawn[0], goal[1] - self.spawn[1]
        if self.goal_region == GoalRegion.DISC:
            return max(math.hypot(dx, dy) - self.goal_tolerance, 0.0)
        return math.hypot(max(abs(dx) - self.goal_tolerance, 0.0), max(abs(dy) - self.goal_tolerance, 0.0))

    def to_dict(self) -> dict:
        d = asdict(self)
        d["goal_region"] = str(self.goal_region)
        return d

    @classmethod
    def from_dict(cls, d: dict) -> EvalProtocol:
        try:
            fields = dict(d)
            for key in ("spawn", "score_clip"):
                if key in fields:
                    fields[key] = tuple(float(v) for v in fields[key])
            if "goal_region" in fields:
                fields["goal_region"] = GoalRegion(fields["goal_region"])
            for key in ("reference_from_world",):  # a JSON true or false, not "yes"
                if key in fields and not isinstance(fields[key], bool):
                    raise TypeError(f"{key}={fields[key]!r}: expected true or false")
            return cls(**fields)
        except (TypeError, ValueError) as exc:
            raise DynabarnError(f"malformed protocol: {exc}") from None


PROTOCOLS: Registry[EvalProtocol] = Registry(
    "protocol",
    {
        # The BARN Challenge on the static BARN worlds: start (-1, 1) facing +y below the
        # obstacle grid, goal region 1 m, 100 s from the first 0.1 m of motion, score with the
        # world's own reference path (BARN's path file) as the optimal length.
        "barn-static": EvalProtocol(
            "barn-static",
            spawn=(-1.0, 1.0, math.pi / 2),
            goal_region=GoalRegion.DISC,
            goal_tolerance=1.0,
            time_limit=100.0,
            timer_start_distance=0.1,
            reference_from_world=True,
        ),
        "barn": EvalProtocol("barn"),
        "paper2022": EvalProtocol(
            "paper2022",
            spawn=(12.0, 0.0, math.pi),
            goal_region=GoalRegion.SQUARE,
            goal_tolerance=0.3,
            time_limit=100.0,
            timer_start_distance=0.0,
        ),
    },
    group="dynabarn.protocols",
    check=instances_of(EvalProtocol),
)
"""Every protocol by name: built in, registered at run time, installed."""


def register_protocol(protocol: EvalProtocol) -> None:
    """Make `protocol` available by name in this process (other processes: install it under
    the entry-point group `dynabarn.protocols`)."""
    PROTOCOLS.register(protocol)


def get_protocol(name_or_path: str) -> EvalProtocol:
    """A protocol by name (built in, registered, installed), or one read from a JSON file."""
    if name_or_path in PROTOCOLS or name_or_path in PROTOCOLS.installed():
        return PROTOCOLS.get_item(name_or_path)
    path = Path(name_or_path)
    if path.suffix == ".json":
        if not path.is_file():
            raise DynabarnError(f"protocol file not found: {path}")
        try:
            return EvalProtocol.from_dict(json.loads(path.read_text()))
        except (json.JSONDecodeError, RecursionError, UnicodeDecodeError) as exc:
            raise DynabarnError(f"{path}: protocol is not valid JSON ({type(exc).__name__})") from None
    raise DynabarnError(unknown_choice("protocol", name_or_path, PROTOCOLS.names()) + " (or a .json file)")
