"""Checks a plugin author runs on their own planner or tracker before a benchmark does, as
Gymnasium's `check_env` does for an environment: `check_planner` and `check_tracker`.

Each drives the plugin through short episodes of a shipped world with moving obstacles and
checks what it could get wrong in behaviour, not only its type:

- a planner's commands are finite and within the robot's limits (`EpisodeInfo.v_limits`,
  `w_max`: the loop clips what exceeds them, so a planner that relies on that plans
  against a robot it does not drive);
- its configuration (`config()`) is JSON data that reads back the same, and builds the same
  planner again from the registry (less the keys it declares `recorded_only`);
- the same seed gives the same commands, from a fresh planner and from one that has driven
  other episodes since (`reset` leaves nothing behind);
- a tracker's tracks are well formed (shapes agree, values finite, identities unique), the
  same scans give the same tracks, and a tracker made for a new episode remembers nothing;
- the time per call is reported (median and 95th percentile), as `make bench` would.

A check returns a `CheckReport`; with problems it raises `CheckFailed` (one line per
problem) unless `raise_on_problem=False`. Registry tests run both on every shipped planner
and tracker.
"""

from __future__ import annotations

import json
import math
import time
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from dynabarn.errors import DynabarnError
from dynabarn.interfaces import EpisodeInfo, Observation, Planner
from dynabarn.interfaces.planner import check_planner as check_planner_type

CHECK_WORLD = 137
"""The shipped world the checks drive in (hard, eleven moving obstacles)."""
CHECK_SECONDS = 8.0
"""Simulated seconds per checking episode: long enough to meet obstacles, short enough to
check a planner in seconds."""
CHECK_SEEDS = (0, 1)
"""The trial seeds the checks drive: the first is driven again after the second."""


class CheckFailed(DynabarnError):
    """A plugin that does not keep the contract in behaviour: every problem, one line each."""


@dataclass(frozen=True)
class CheckReport:
    """What a check found of one planner or tracker."""

    what: str
    """The plugin checked (its registered name, or its class's)."""
    problems: tuple[str, ...]
    """One line per problem found; empty: it keeps the contract."""
    calls: int
    """`act` or `update` calls timed."""
    ms_per_call: float
    """Median wall time of a call [ms] on this machine."""
    ms_per_call_p95: float
    """95th percentile of the same [ms]."""

    @property
    def passed(self) -> bool:
        return not self.problems

    def summary(self) -> str:
        verdict = "keeps the contract" if self.passed else f"{len(self.problems)} problem(s)"
        timing = f"{self.ms_per_call:.2f} ms a call (p95 {self.ms_per_call_p95:.2f}) over {self.calls} calls"
        return "\n".join([f"{self.what}: {verdict}; {timing}", *(f"  - {p}" for p in self.problems)])


class _Probe(Planner):
    """The planner under check, with every raw command and the time of every `act` kept."""

    name = "probe"

    def __init__(self, inner: Planner) -> None:
        self.inner = inner
        self.privileged = inner.privileged  # type: ignore[misc] - an instance's, read by the loop
        self.commands: list[tuple[float, float]] = []
        self.observations: list[Observation] = []
        self.ms: list[float] = []
        self.info: EpisodeInfo | None = None

    def reset(self, info: EpisodeInfo) -> None:
        self.info = info
        self.inner.reset(info)

    def act(self, obs: Observation) -> tuple[float, float]:
        t0 = time.perf_counter()
        raw = self.inner.act(obs)
        self.ms.append((time.perf_counter() - t0) * 1e3 - self.inner.waited_ms)
        self.commands.append((float(raw[0]), float(raw[1])))
        self.observations.append(obs)
        return raw

    def finish(self, outcome: str) -> None:
        self.inner.finish(outcome)

    def tracks(self):
        return self.inner.tracks()

    def debug(self) -> dict:
        return self.inner.debug()


def _episode(planner: Planner, sim, seed: int, seconds: float) -> tuple[_Probe, object]:
    """Drive `planner` for `seconds` of trial `seed` in the compiled world `sim`: the probe
    and the result."""
    from dynabarn.protocol import get_protocol
    from dynabarn.runner import EpisodeSpec, run_spec

    protocol = replace(get_protocol("barn"), time_limit=seconds)
    probe = _Probe(planner)
    spec = EpisodeSpec.make(sim.world_path, planner.name, protocol, seed=seed, sim=sim.config)
    return probe, run_spec(spec, planner=probe, sim=sim).result


def _world(world: Path | str | int | None):
    """The world to drive in, compiled once for every episode of a check."""
    from dynabarn.sim import Simulation
    from dynabarn.worldset import resolve_world

    return Simulation(resolve_world(CHECK_WORLD if world is None else world))


def _timing(ms: list[float]) -> tuple[int, float, float]:
    if not ms:
        return 0, math.nan, math.nan
    return len(ms), float(np.median(ms)), float(np.percentile(ms, 95))


def _finish(report: CheckReport, raise_on_problem: bool) -> CheckReport:
    if raise_on_problem and report.problems:
        raise CheckFailed(report.summary())
    return report


def check_planner(
    planner: Planner | str,
    *,
    config: dict | None = None,
    world: Path | str | int | None = None,
    seconds: float = CHECK_SECONDS,
    raise_on_problem: bool = True,
) -> CheckReport:
    """Check a planner in behaviour: its commands, its configuration, its determinism and its
    `reset`, with the time per call.

    Args:
        planner: a registered planner's name (built with `config`; its configuration is
            also rebuilt through the registry and a fresh one compared), or a `Planner`
            instance (checked as it is: its `reset` between episodes, its configuration as
            JSON).
        config: the configuration to build a named planner with (default: its defaults).
        world: the world to drive in (an id, a name or a file; default: world 137).
        seconds: simulated seconds per checking episode.
        raise_on_problem: raise `CheckFailed` listing every problem (default), else return
            the report with them.
    """
    from dynabarn.planners import get_planner

    if isinstance(planner, str):
        name, config = planner, dict(config or {})
        first = get_planner(name, **config)
    else:
        name, first = None, check_planner_type(planner)
    sim = _world(world)
    problems: list[str] = []
    runs = [_episode(first, sim, seed, seconds) for seed in (*CHECK_SEEDS, CHECK_SEEDS[0])]
    for probe, result in runs:
        problems += _result_problems(result)
        problems += _command_problems(probe)
    if runs[0][0].commands != runs[-1][0].commands:
        problems.append(
            f"seed {CHECK_SEEDS[0]} driven again after seed {CHECK_SEEDS[1]} gives other commands "
            f"(first at tick {_first_difference(runs[0][0].commands, runs[-1][0].commands)}): "
            "reset(info) leaves state of the earlier episodes behind"
        )
    problems += _config_problems(first, name)
    if name is not None:
        fresh, _ = _episode(get_planner(name, **config), sim, CHECK_SEEDS[0], seconds)
        if fresh.commands != runs[0][0].commands:
            problems.append(
                f"two planners built alike give other commands on the same seed (first at tick "
                f"{_first_difference(fresh.commands, runs[0][0].commands)}): it draws from global or unseeded "
                "random state, or the wall clock"
            )
    calls, median, p95 = _timing([ms for probe, _ in runs for ms in probe.ms])
    report = CheckReport(name or type(first).__name__, tuple(dict.fromkeys(problems)), calls, median, p95)
    return _finish(report, raise_on_problem)


def _result_problems(result) -> list[str]:
    from dynabarn.metrics import NON_FINITE_COMMAND, PLANNER_RAISED

    reason = result.reason or ""
    if result.outcome.value == "error" and reason.startswith(PLANNER_RAISED):
        return [f"the episode of seed {result.seed} ended in error: {reason}"]
    if result.outcome.value == "error" and reason.startswith(NON_FINITE_COMMAND):
        return [f"seed {result.seed}: {reason}"]
    return []


def _command_problems(probe: _Probe) -> list[str]:
    """Commands that are not finite or exceed the robot's limits (beyond rounding)."""
    if not probe.commands or probe.info is None:
        return []
    commands = np.asarray(probe.commands, dtype=float)
    problems = []
    if not np.isfinite(commands).all():
        problems.append("a command is not finite (NaN or inf)")
    info = probe.info
    v, w = commands[:, 0], commands[:, 1]
    tol = 1e-9
    low, high = info.v_limits
    if ((v < low - tol) | (v > high + tol)).any():
        problems.append(f"v leaves the robot's limits [{low:g}, {high:g}] m/s (up to {v[np.abs(v).argmax()]:.3g})")
    if (np.abs(w) > info.w_max + tol).any():
        problems.append(f"|w| exceeds the robot's {info.w_max:g} rad/s (up to {np.abs(w).max():.3g})")
    return problems


def _config_problems(planner: Planner, name: str | None) -> list[str]:
    """The configuration as JSON data that reads back the same and, for a registered
    planner, builds a planner with the same configuration."""
    from dynabarn.planners import get_planner

    config = planner.config()
    try:
        text = json.dumps(config, sort_keys=True, allow_nan=False)
    except (TypeError, ValueError) as exc:
        return [f"config() is not JSON data: {exc}"]
    if json.dumps(json.loads(text), sort_keys=True) != text:
        return ["config() does not read back the same from JSON"]
    if name is None:
        return []
    given = {k: v for k, v in json.loads(text).items() if k not in planner.recorded_only}
    try:
        again = get_planner(name, **given)
    except DynabarnError as exc:
        return [f"its recorded config() does not build it again: {exc}"]
    if json.dumps(again.config(), sort_keys=True, allow_nan=False) != text:
        return ["the planner built from its recorded config() records another configuration"]
    return []


def _first_difference(a: list, b: list) -> int:
    return next((i for i, (x, y) in enumerate(zip(a, b, strict=False)) if x != y), min(len(a), len(b)))


def check_tracker(
    tracker: str | type,
    *,
    config: dict | None = None,
    world: Path | str | int | None = None,
    seconds: float = CHECK_SECONDS,
    raise_on_problem: bool = True,
) -> CheckReport:
    """Check a tracker in behaviour on the scans of short episodes (the robot driven by
    `dwa`): its tracks well formed, the same scans giving the same tracks, a tracker made for
    a new episode remembering nothing of the last, with the time per `update`.

    Args:
        tracker: a tracker kind (`tracker.kind`: registered or installed), or a tracker
            class (`for_episode(cfg, info)`, `update(time, scan, pose) -> Tracks`).
        config: fields of the tracker's own `Config` besides `kind` (default: its defaults).
        world: the world to drive in (an id, a name or a file; default: world 137).
        seconds: simulated seconds per checking episode.
        raise_on_problem: raise `CheckFailed` listing every problem (default), else return
            the report with them.
    """
    from dynabarn.interfaces.planner import config_from_kwargs
    from dynabarn.interfaces.tracker import DEFAULT_TRACKER
    from dynabarn.perception.trackers import TRACKERS
    from dynabarn.planners import get_planner

    if isinstance(tracker, str):
        kind, cls = tracker, TRACKERS.get_item(tracker)
    else:
        kind, cls = getattr(tracker, "name", tracker.__name__), tracker
        try:
            TRACKERS.check(cls)  # the registry's contract, as registering it would apply
        except TypeError as exc:
            raise CheckFailed(f"{kind}: {exc}") from None
    try:  # the tracker's own configuration (`Tracker.Config`), its kind the name it is checked as
        cfg = config_from_kwargs(cls.Config, {**(config or {}), "kind": DEFAULT_TRACKER}, "tracker")
    except TypeError as exc:
        raise DynabarnError(str(exc)) from None
    cfg = replace(cfg, kind=kind)
    sim = _world(world)
    scans = [_episode(get_planner("dwa"), sim, seed, seconds)[0] for seed in CHECK_SEEDS]
    problems: list[str] = []
    ms: list[float] = []
    first = _track(cls, cfg, scans[0], ms, problems)
    _track(cls, cfg, scans[1], ms, problems)
    again = _track(cls, cfg, scans[0], ms, problems)
    if not _same_tracks(first, again):
        problems.append(
            "the same scans give other tracks after a tracker of another episode ran: "
            "state is kept outside the tracker made by for_episode (a class attribute, a module global)"
        )
    if not any(len(t) for t in first):
        problems.append(f"no track in {len(first)} scans of world {sim.world.name} with moving obstacles in view")
    calls, median, p95 = _timing(ms)
    report = CheckReport(str(kind), tuple(dict.fromkeys(problems)), calls, median, p95)
    return _finish(report, raise_on_problem)


def _track(cls, cfg, probe: _Probe, ms: list[float], problems: list[str]) -> list:
    """One episode's scans through a tracker made for it: its tracks at every scan."""
    tracker = cls.for_episode(cfg, probe.info)
    out = []
    for obs in probe.observations:
        t0 = time.perf_counter()
        tracks = tracker.update(obs.time, obs.scan, obs.pose)
        ms.append((time.perf_counter() - t0) * 1e3)
        problems += _tracks_problems(tracks, obs.time)
        out.append(tracks)
    return out


_PER_TRACK = {  # field -> shape after n
    "positions": (2,),
    "velocities": (2,),
    "sizes": (),
    "position_var": (2,),
    "velocity_var": (2,),
    "position_velocity_cov": (2,),
    "age": (),
    "last_seen": (),
}


def _tracks_problems(tracks, now: float) -> list[str]:
    from dynabarn.perception import Tracks

    if not isinstance(tracks, Tracks):
        return [f"update() returned a {type(tracks).__name__}, not dynabarn.perception.Tracks"]
    n = len(tracks.ids)
    problems = []
    if len(np.unique(tracks.ids)) != n:
        problems.append(f"t = {now:.1f} s: two tracks share an identity")
    if tracks.time != now:
        problems.append(f"t = {now:.1f} s: the tracks hold for t = {tracks.time}, not the scan's time")
    for name, tail in _PER_TRACK.items():
        value = np.asarray(getattr(tracks, name))
        if value.shape != (n, *tail):
            problems.append(f"{name} has shape {value.shape}, not {(n, *tail)} for {n} tracks")
        elif not np.isfinite(value).all():
            problems.append(f"t = {now:.1f} s: {name} is not finite")
    if (np.asarray(tracks.position_var) < 0).any() or (np.asarray(tracks.velocity_var) < 0).any():
        problems.append(f"t = {now:.1f} s: a negative variance")
    if (np.asarray(tracks.last_seen) > now + 1e-9).any():
        problems.append(f"t = {now:.1f} s: a track last seen in the future")
    if tracks.headings is not None:
        for name, tail in (("headings", ()), ("half_sizes", (2,)), ("half_size_std", (2,))):
            value = getattr(tracks, name)
            if value is None or np.asarray(value).shape != (n, *tail) or not np.isfinite(value).all():
                problems.append(f"{name} is missing, misshapen or not finite beside headings")
    return problems


def _same_tracks(a: list, b: list) -> bool:
    if len(a) != len(b):
        return False
    fields = ("ids", "positions", "velocities", "sizes")
    return all(all(np.array_equal(getattr(x, f), getattr(y, f)) for f in fields) for x, y in zip(a, b, strict=True))
