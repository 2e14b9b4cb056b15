"""The planner contract: what a planner sees (`Observation`), what it returns, and what
else the episode loop may ask of it, all declared on one base class (`Planner`).

A planner is an instance of `Planner`: it implements `act(obs) -> (v, w)` and overrides
what it needs of the optional capabilities, each with a default that does nothing here
(`reset`, `finish`, `tracks`, `debug`, `config`, `versions`, `report`,
`recording_options`, `attach_recording`, `waited_ms`). It sees only
observations, never MuJoCo's data: the laser scan, its own pose and velocity, the goal,
the time, and (only when it declares `privileged = True`) the true obstacle states and
their schedules. `check_planner` is the one check of the contract: the registry applies it
to every factory registered and to what a factory builds, the loop to what it is given.
"""

from __future__ import annotations

import abc
import copy
import math
import types
import typing
from dataclasses import fields, is_dataclass
from typing import ClassVar

from dynabarn.errors import DynabarnError
from dynabarn.interfaces.observation import EpisodeInfo, Observation

__all__ = [
    "CheckedConfig",
    "Planner",
    "check_planner",
    "check_planner_factory",
    "config_from_kwargs",
    "nested_config",
    "recorded_config",
]


class CheckedConfig:
    """Base of a configuration dataclass that `config_from_kwargs` builds and checks: what it
    declares of itself (ranges, ordered pairs, relations), each with a default that allows
    anything, so that nothing is found by looking."""

    LIMITS: ClassVar[dict[str, tuple[float, float]]] = {}
    """{field: (low, high)}: a number (or each number of a tuple) outside is refused (so
    `vx_samples=100000000` is refused instead of exhausting memory)."""
    ORDERED: ClassVar[tuple[tuple[str, str], ...]] = ()
    """(low, high) field pairs whose values must not cross (`min_vel_x` above `max_vel_x`)."""

    RECORDED_WHEN_SET: ClassVar[dict[str, tuple[str, ...]]] = {}
    """{switch: fields}: fields recorded (`recorded_config`) only when the switch is not at
    its default, so that adding an option leaves every earlier result's configuration (and
    the golden set's bytes) as they were (`scan_guard`, a tracker's `kind`)."""

    def check(self, what: str) -> None:
        """The fields' other relations (the memory a sample grid allocates): raise TypeError
        with one line; `what` names the configuration in it."""


def recorded_config(config) -> dict:
    """A configuration dataclass as results and recordings keep it: `dataclasses.asdict`,
    nested configurations too, less the fields each declares recorded only when set
    (`CheckedConfig.RECORDED_WHEN_SET`)."""
    out = {}
    for f in fields(config):
        value = getattr(config, f.name)
        out[f.name] = recorded_config(value) if is_dataclass(value) else copy.deepcopy(value)
    declared = type(config).RECORDED_WHEN_SET if isinstance(config, CheckedConfig) else {}
    for switch, keys in declared.items():
        default = next(f.default for f in fields(config) if f.name == switch)
        if getattr(config, switch) == default:
            for key in keys:
                out.pop(key, None)
    return out


def config_from_kwargs(cls: type[CheckedConfig], kwargs: dict, what: str):
    """Build the planner configuration dataclass `cls` from keyword values, checked before
    anything runs: unknown keys (naming the known ones), each value against its field's type
    (numbers finite, counts whole), and against the class's `LIMITS` {field: (low, high)}
    (`CheckedConfig.LIMITS`: so `vx_samples=100000000` is refused instead of exhausting memory).
    Raises TypeError with one line (`get_planner` makes it a DynabarnError)."""
    if not (isinstance(cls, type) and issubclass(cls, CheckedConfig)):
        raise TypeError(f"{what}: {cls!r} is not a dataclass subclassing dynabarn.interfaces.CheckedConfig")
    known = {f.name for f in fields(cls)}
    unknown = set(kwargs) - known
    if unknown:
        raise TypeError(f"unknown {what} parameter(s) {sorted(unknown)}; known: {sorted(known)}")
    hints = typing.get_type_hints(cls)
    checked = {
        key: _checked(f"{what} {key}", value, hints.get(key), cls.LIMITS.get(key)) for key, value in kwargs.items()
    }
    config = cls(**checked)
    check_relations(config, what)
    return config


def check_relations(config, what: str) -> None:
    """A configuration's fields against each other, where its class declares them:
    `ORDERED` pairs (low, high) whose values must not cross (`min_vel_x` above `max_vel_x`,
    a rollout step longer than the rollout), and a `check(what)` method for the rest (the
    memory a sample grid allocates). Raises TypeError with one line."""
    for low, high in type(config).ORDERED:
        a, b = getattr(config, low), getattr(config, high)
        if a > b:
            raise TypeError(f"{what} {low}={a!r} is above {high}={b!r}; it must not be")
    config.check(what)


def nested_config(kwargs: dict, key: str, build: typing.Callable[[dict], object], what: str) -> dict:
    """A planner's keyword configuration with its `KEY.PARAM` entries (or a `KEY` dict, e.g.
    from a JSON preset) gathered and built by `build(dict)` into the one value under KEY
    (e.g. `costmap.resolution=0.05` -> `costmap=CostmapConfig(resolution=0.05)`)."""
    kwargs = dict(kwargs)
    sub = kwargs.pop(key, {})
    if not isinstance(sub, dict):  # `costmap=null` must not run with the defaults unsaid
        raise TypeError(f"{what} {key}={sub!r}: expected an object of {key} parameters")
    sub = dict(sub)
    for k in [k for k in kwargs if k.startswith(f"{key}.")]:
        sub[k.split(".", 1)[1]] = kwargs.pop(k)
    return {**kwargs, key: build(sub)}


def _checked(name: str, value, kind, limits: tuple[float, float] | None):
    """`value` as the field's type (float, int, bool, str, or a tuple of floats; any of them
    or None, where the field is optional), in range."""
    optional = [k for k in typing.get_args(kind) if k is not type(None)] if type(kind) is types.UnionType else []
    if len(optional) == 1 and type(None) in typing.get_args(kind):
        return None if value is None else _checked(name, value, optional[0], limits)
    if kind is bool:
        if not isinstance(value, bool):
            raise TypeError(f"{name}={value!r}: expected true or false")
        return value
    if kind is str:
        if not isinstance(value, str):
            raise TypeError(f"{name}={value!r}: expected a string")
        return value
    if kind in (float, int):
        number = _number(name, value, whole=kind is int)
        if limits is not None and not limits[0] <= number <= limits[1]:
            raise TypeError(f"{name}={value!r}: out of range [{limits[0]:g}, {limits[1]:g}]")
        return number
    if kind is tuple:
        if not isinstance(value, list | tuple) or not value:
            raise TypeError(f"{name}={value!r}: expected a non-empty list of numbers")
        numbers = tuple(_number(name, v, whole=False) for v in value)
        if limits is not None and not all(limits[0] <= v <= limits[1] for v in numbers):
            raise TypeError(f"{name}={value!r}: values out of range [{limits[0]:g}, {limits[1]:g}]")
        return numbers
    return value  # nested configurations check themselves


def _number(name: str, value, *, whole: bool) -> float | int:
    if isinstance(value, bool) or not isinstance(value, int | float):
        raise TypeError(f"{name}={value!r}: expected {'a whole number' if whole else 'a number'}")
    if not math.isfinite(value):
        raise TypeError(f"{name}={value!r}: expected a finite number")
    if whole:
        if float(value) != int(value):
            raise TypeError(f"{name}={value!r}: expected a whole number")
        return int(value)
    return value  # as given: an int stays an int in the recorded configuration


class Planner(abc.ABC):
    """Base class of local planners. Subclasses set `name` and implement `act`."""

    name: ClassVar[str] = "planner"
    privileged: ClassVar[bool] = False
    """True if the planner needs the true obstacle states (`Observation.obstacles`)."""
    recorded_only: ClassVar[tuple[str, ...]] = ()
    """Keys of `config()` that describe what the planner loaded or derived (a policy file's
    sha256, its kind, its inputs) rather than parameters it takes: a planner is built again
    from its recorded configuration without them (`dynabarn.check_planner` does so)."""
    external_options: ClassVar[dict[str, str]] = {}
    """Configuration options whose value names something outside the results, each with
    what it names ("a program it runs", "a file it reads"): a results file written elsewhere
    never supplies them (`dynabarn-bench --verify` runs a row that has one only when the
    person verifying gives it on their own command line). A factory that is not a class
    declares them as an attribute of the same name."""

    def reset(self, info: EpisodeInfo) -> None:  # noqa: B027 - optional hook
        """Called once before the first `act` of an episode."""

    def finish(self, outcome: str) -> None:  # noqa: B027 - optional hook
        """Called once when the episode has ended (its outcome's name), also after an error
        or Ctrl-C: release what `reset` started (processes, connections)."""

    @abc.abstractmethod
    def act(self, obs: Observation) -> tuple[float, float]:
        """Return the command (v [m/s], w [rad/s]) for this tick."""

    def tracks(self):
        """The planner's tracked obstacles (`dynabarn.perception.Tracks`) after its last
        `act`, for planners that track them: the runner scores them against the truth
        (recall, position and velocity errors, identity switches) and records them. None
        for planners without a tracker."""
        return None

    def debug(self) -> dict:
        """Optional planner internals to record (e.g. {'local_plan': (n, 2) array})."""
        return {}

    def config(self) -> dict:
        """The planner's parameters, recorded with every episode."""
        return {}

    def versions(self) -> dict[str, str]:
        """Versions of the libraries beyond the runner's that decide this planner's
        commands (e.g. PyTorch), recorded with every episode."""
        return {}

    def command_set(self):
        """The (n, 2) commands (v, w) this planner chooses among each tick, for a planner
        that chooses from a finite set (the oracle's sample grid): a student taught by it
        classifies among them (`dynabarn-train dagger --head classify`). None: it does not."""
        return None

    def report(self) -> dict:
        """What the planner says of the episode once it has finished (plain JSON data, e.g.
        the ROS bridge's overhead per period and the periods it held the last command):
        handed back beside the result (`runner.EpisodeRun.planner_report`), not part of it."""
        return {}

    def recording_options(self) -> dict:
        """Channels and metadata of its own this planner writes to the episode's recording
        (`McapRecorder`'s `extra_channels`, `extra_metadata`; empty: none). A planner that
        declares some gets the recorder through `attach_recording` before the episode, and
        the recorder then runs in the episode's process."""
        return {}

    def attach_recording(self, recorder) -> None:  # noqa: B027 - optional hook
        """The episode's recorder, before the first `act`, for a planner whose
        `recording_options` declares channels of its own (teleop's operator input)."""

    waited_ms: float = 0.0
    """Milliseconds of the last `act` spent waiting on purpose (a ROS stack's start-up,
    pacing to the wall clock): the loop records planning time, not waiting time."""


def check_planner(planner: object, what: str = "planner") -> Planner:
    """`planner` if it keeps the contract (an instance of `Planner`); one `DynabarnError` line
    otherwise."""
    if not isinstance(planner, Planner):
        raise DynabarnError(f"{what} is a {type(planner).__name__}, not a dynabarn.interfaces.Planner (subclass it)")
    return planner


def check_planner_factory(factory: object) -> None:
    """What may be registered as a planner: a `Planner` subclass, or any other callable
    (a function, a partial) whose product `check_planner` checks when it is built."""
    if isinstance(factory, type):
        if not issubclass(factory, Planner):
            raise TypeError(f"{factory.__name__} is not a subclass of dynabarn.interfaces.Planner")
    elif not callable(factory):
        raise TypeError(f"{factory!r} is neither a Planner subclass nor a callable that builds one")
