"""Planner registry: built-in planners plus any installed under the entry-point group
`dynabarn.planners` (name = "module:factory"), so a researcher adds a planner from their
own package without touching this one:

    [project.entry-points."dynabarn.planners"]
    my_planner = "my_pkg.planner:MyPlanner"
"""

from __future__ import annotations

from collections.abc import Callable

from dynabarn.errors import DynabarnError, unknown_choice
from dynabarn.interfaces import Planner
from dynabarn.interfaces.planner import check_planner, check_planner_factory
from dynabarn.planners.dwa import DWAPlanner
from dynabarn.planners.learned import BCPlanner, DaggerPlanner, PPOPlanner, TD3Planner
from dynabarn.planners.oracle import OraclePlanner, PresentStateOraclePlanner
from dynabarn.planners.predictive import PredictivePlanner
from dynabarn.planners.presets import planner_presets, read_planner_config
from dynabarn.planners.simple import StopPlanner, StraightPlanner
from dynabarn.planners.teb import TEBPlanner
from dynabarn.planners.trajectory_planner import TrajectoryPlanner
from dynabarn.registry import Registry

ENTRY_POINT_GROUP = "dynabarn.planners"


_BUILTIN: dict[str, Callable[..., Planner]] = {
    "dwa": DWAPlanner,
    "teb": TEBPlanner,
    "trajectory_planner": TrajectoryPlanner,
    "oracle": OraclePlanner,
    "oracle_present": PresentStateOraclePlanner,
    "predictive": PredictivePlanner,
    "bc": BCPlanner,  # the learned ones import torch only when built
    "td3": TD3Planner,
    "dagger": DaggerPlanner,
    "ppo": PPOPlanner,  # trained on the Warp backend; none shipped (policy=FILE)
    "straight": StraightPlanner,
    "stop": StopPlanner,
}
PLANNERS: Registry[Callable[..., Planner]] = Registry(
    "planner", _BUILTIN, group=ENTRY_POINT_GROUP, check=check_planner_factory
)
"""Every planner factory by name: built in, registered at run time, installed."""


def register_planner(factory, legacy=None, *, name: str | None = None):
    """Register a planner at run time: a `Planner` subclass under its `name`
    (`register_planner(MyPlanner)`), or any factory with `name=` (the older shape,
    `register_planner(name, factory)`, warns: `Registry.register`). Checked: `check_planner_factory`."""
    return PLANNERS.register(factory, legacy, name=name)


def available_planners() -> list[str]:
    return PLANNERS.names()


def planner_factory(name: str) -> Callable[..., Planner]:
    """The factory registered under `name`: registered at run time, built in, or installed."""
    return PLANNERS.get_item(name)


def declared(name: str, attribute: str, default):
    """What planner `name` declares of itself before it is built: the class's attribute
    (`Planner.privileged`, `external_options`), or, for a factory that is not a class, the
    attribute of the same name it carries (`ros.bridge.ros_planner.external_options`)."""
    return getattr(planner_factory(name), attribute, default)


def privileged(name: str) -> bool:
    """Whether planner `name` reads the true obstacle states (`Planner.privileged`)."""
    return bool(declared(name, "privileged", False))


def external_options(name: str) -> dict[str, str]:
    """The options of planner `name` whose values name something outside the results (a
    program, a file, an address), each with what it names (`Planner.external_options`)."""
    options = declared(name, "external_options", None)
    return {str(k): str(v) for k, v in options.items()} if isinstance(options, dict) else {}


def registered_at_run_time(name: str) -> bool:
    """`name` lives only in this process (`register_planner`): worker processes that do not
    fork must be handed its factory (pickled by reference)."""
    return PLANNERS.registered_at_run_time(name)


def get_planner(name: str, /, factory: Callable[..., Planner] | None = None, **config) -> Planner:
    """Instantiate the planner `name` (or `factory`, when given) with keyword configuration
    (`name` positional only: a configuration key called `name` is the planner's to refuse)."""
    if factory is not None and not callable(factory):  # `--planner-config factory=x`
        raise DynabarnError(f"planner {name!r}: bad configuration: unknown parameter 'factory'")
    factory = factory or planner_factory(name)
    try:
        planner = factory(**config)
    except TypeError as exc:
        raise DynabarnError(f"planner {name!r}: bad configuration: {exc}") from None
    return check_planner(planner, f"what planner {name!r}'s factory built")


def planner_spec(spec: str) -> tuple[str, dict, str]:
    """`NAME` or `NAME@PRESET` (a named preset, `planners.presets.PRESETS`, e.g. `dwa@dwa_dynabarn_authors`) ->
    (registry name, the preset's parameters, the label results carry). A planner named by its
    code is loaded first: `from_code.planner_spec`, what the commands call."""
    name, sep, preset = spec.strip().partition("@")
    name = name.strip()
    if not sep:
        return name, {}, name
    preset = preset.strip()
    if preset not in planner_presets():
        raise DynabarnError(unknown_choice("planner preset", preset, planner_presets()))
    return name, read_planner_config(preset), f"{name}@{preset}"
