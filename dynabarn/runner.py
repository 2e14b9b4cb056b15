"""One episode described once (`EpisodeSpec`) and run one way (`run_spec`), which builds
what it runs: the simulation with the spec's settings, the planner with its configuration,
the recorder.

Every command that runs an episode goes through here: `dynabarn-run`, `dynabarn-ros`,
`dynabarn-bench` (each job is a spec), `--verify`, the golden set, teleop and the
certificates' oracle stage, none with a simulation of its own (a viewer, which needs the
compiled world, gets it from `on_built`). What was built comes back in an `EpisodeRun`: the
result, where the recording is, the world, the planner's report.
So the simulation's settings (`--dt`, `--control-rate`) are given once, in the spec, and
travel with an episode into a sweep, a resumed sweep and the golden set; and a recording
is made, finished and failed in one place:

- the recording is written as `NAME.part` and renamed when whole (`McapRecorder`, in a
  writer process beside the episode: `BackgroundRecorder`), so a killed run never leaves a
  file that looks finished;
- a recording that cannot be started (a full disk, a missing folder) is one
  `DynabarnError` line; a planner that raises ends the episode as `error` (`run_episode`);
- Ctrl-C (or SIGTERM) lets the recorder close the file whole and says where it is kept;
- a recording cut short (the disk filled up) keeps the result, with a warning on stderr.
"""

from __future__ import annotations

import contextlib
import json
import sys
from collections.abc import Callable, Sequence
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any, Protocol

from dynabarn.errors import DynabarnError
from dynabarn.interfaces import EpisodeObserver, Planner
from dynabarn.metrics import EpisodeResult
from dynabarn.protocol import EvalProtocol
from dynabarn.sim import SimConfig, Simulation
from dynabarn.worlds.spec import WorldSpec

_DEFAULT_SIM = SimConfig()


class RecordingFailed(DynabarnError):
    """The recording could not be started or written (the machine's fault, not the
    episode's: a sweep runs such an episode again)."""

    def __init__(self, message: str, *, target: Path | str | None = None) -> None:
        super().__init__(message)
        self.target = Path(target) if target is not None else None
        """The file the recording was asked for (its `NAME.part` may hold what was written)."""

    @classmethod
    def because(cls, target: Path | str | None, exc: OSError) -> RecordingFailed:
        """The one line for a recording the machine could not start or write (`exc`)."""
        return cls(f"cannot record to {target}: {exc.strerror or exc}", target=target)


@dataclass(frozen=True)
class EpisodeSpec:
    """What makes an episode: the world, the planner and its configuration, the protocol,
    the trial seed and the simulation's settings (only those that differ from the
    defaults, so the keys of earlier results stay valid); `label` is the name results show
    when not the planner's (`dwa@dwa_dynabarn_authors`)."""

    world: str
    planner: str
    protocol: dict  # EvalProtocol.to_dict(): plain data for worker processes
    planner_config: tuple = ()  # sorted (key, value) pairs
    seed: int = 0
    sim: tuple = ()  # sorted (SimConfig field, value) pairs that differ from the defaults
    label: str = ""

    @classmethod
    def make(
        cls,
        world: Path | str,
        planner: str,
        protocol: EvalProtocol,
        *,
        config: dict[str, Any] | None = None,
        seed: int = 0,
        sim: SimConfig = _DEFAULT_SIM,
        label: str = "",
    ) -> EpisodeSpec:
        changed = sim.changed()
        return cls(
            world=str(world),
            planner=planner,
            protocol=json.loads(json.dumps(protocol.to_dict())),  # as it reads back from JSON
            planner_config=tuple(sorted((config or {}).items())),
            seed=int(seed),
            sim=tuple(sorted(changed.items())),
            label=label if label != planner else "",
        )

    @property
    def shown(self) -> str:
        """The planner's name in results: the label, else the registry name."""
        return self.label or self.planner

    @property
    def sim_config(self) -> SimConfig:
        return SimConfig(**dict(self.sim))

    @property
    def key(self) -> str:
        """The episode's identity in results.jsonl (what resuming compares); the simulation's
        settings appear only when they are not the defaults."""
        cfg = json.dumps(dict(self.planner_config), sort_keys=True)
        key = f"{self.planner}|{cfg}|{Path(self.world).name}|{self.protocol['name']}|{self.seed}"
        return f"{key}|sim={json.dumps(dict(self.sim), sort_keys=True)}" if self.sim else key

    def to_dict(self) -> dict:
        d = asdict(self)
        d["planner_config"] = dict(self.planner_config)
        d["sim"] = dict(self.sim)
        return d

    @classmethod
    def from_dict(cls, d: dict) -> EpisodeSpec:
        return cls(
            world=str(d["world"]),
            planner=str(d["planner"]),
            protocol=dict(d["protocol"]),
            planner_config=tuple(sorted(dict(d.get("planner_config", {})).items())),
            seed=int(d.get("seed", 0)),
            sim=tuple(sorted(dict(d.get("sim", {})).items())),
            label=str(d.get("label", "")),
        )


class LiveView(Protocol):
    """Outputs that watch an episode as it runs (`dynabarn-run --viewer/--live`), opened by
    the runner once the planner's configuration has been checked and closed when the
    episode ends, whatever happens (a context manager)."""

    contexts: tuple
    """Foxglove contexts the recorder also streams to."""
    observers: tuple
    """Observers after the recorder (pacing, rerun)."""

    def __enter__(self) -> LiveView: ...

    def __exit__(self, *exc) -> None: ...

    def watch(self, sim: Simulation, planner: Planner) -> Sequence[EpisodeObserver]:
        """Observers that need the compiled world (MuJoCo's viewer), after the others."""

    def attach(self, recorder) -> None:
        """The recorder, whose latched messages late subscribers get again."""


@dataclass(frozen=True)
class EpisodeRun:
    """What `run_spec` ran and built: the result, where its recording is, the world it
    compiled and what the planner said of the episode (`Planner.report`)."""

    spec: EpisodeSpec
    result: EpisodeResult
    world: WorldSpec
    """The world as compiled (its name, its profile set, its obstacles)."""
    recording: Path | None = None
    """Where the finished recording is; None when none was asked for or its writer ended early."""
    recording_target: Path | None = None
    """The file the recording was asked for (`record_to`, or its default name in `record_in`)."""
    recording_problem: str | None = None
    """Why the recording is cut short or missing (a full disk, an installed topic's bug, its
    writer ended early); None when it is whole or none was asked for."""
    planner_report: dict = field(default_factory=dict)


def run_spec(
    spec: EpisodeSpec,
    *,
    record_to: Path | None = None,
    record_in: Path | None = None,
    live: LiveView | None = None,
    observers: Sequence[EpisodeObserver] = (),
    on_built: Callable[[Simulation, Planner], Sequence[EpisodeObserver] | None] | None = None,
    planner: Planner | None = None,
    sim: Simulation | None = None,
) -> EpisodeRun:
    """Build what `spec` describes (the planner with its configuration, the simulation with
    its settings, the recorder), run the episode and hand back what became of it
    (`EpisodeRun`). Each setting is given once, in the spec: nothing passed here changes
    what happens in the episode. The runner owns the lifecycle of what it builds: the
    planner's `finish` is called whatever happens, the recording is finished or said to be
    cut short, the live view closed.

    Args:
        record_to: record the episode to this MCAP file (NAME.part until whole).
        record_in: or to this folder, under the default name (`default_run_path`: world,
            the planner as results show it, protocol, seed).
        live: outputs that watch the episode as it runs (`LiveView`), opened here after the
            configuration is checked: a bad one is one line before a server starts.
        observers: further observers, after the recorder and the live view's.
        on_built: for viewers: called with the compiled simulation and the planner before
            the episode starts; returns observers that need them, which run after the others.
        planner: a planner built in code rather than named in the registry (a certificate's
            witness follower, a benchmark's probe); `spec.planner` then only names it in the
            result, and `spec.planner_config` must be empty (the planner carries its own).
        sim: the spec's world already compiled with the spec's settings, for a caller that
            runs one world many times and times the episodes, not the compiles.
    """
    from dynabarn.planners import get_planner
    from dynabarn.sim.loop import finish_planner

    if planner is not None and spec.planner_config:
        raise DynabarnError(f"{spec.planner}: a planner given built takes no configuration from the spec")
    if sim is not None and (Path(sim.world_path) != Path(spec.world) or sim.config != spec.sim_config):
        raise DynabarnError(f"the simulation given is not the spec's ({sim.world_path}, {spec.world})")
    # The configuration is checked here, once, before anything starts: one line.
    planner = planner if planner is not None else get_planner(spec.planner, **dict(spec.planner_config))
    try:
        with live if live is not None else contextlib.nullcontext():
            return _run_built(spec, planner, sim, record_to, record_in, live, observers, on_built)
    except Exception:
        finish_planner(planner, "error")  # what broke outside the loop (an observer, the recorder)
        raise


def _run_built(spec, planner, sim, record_to, record_in, live, observers, on_built) -> EpisodeRun:
    """`run_spec` once the planner is built and the live view open."""
    from dynabarn.recording import default_run_path
    from dynabarn.sim import run_episode

    if sim is None:
        sim = Simulation(spec.world, config=spec.sim_config)
    if live is not None:
        observers = [*live.observers, *observers, *live.watch(sim, planner)]
    observers = [*observers, *((on_built(sim, planner) or ()) if on_built is not None else ())]
    if record_to is None and record_in is not None:
        record_to = default_run_path(record_in, sim.world.name, spec.shown, spec.protocol["name"], spec.seed)
    recorder = _recorder(record_to, planner, live)
    try:
        result = run_episode(
            sim,
            planner,
            EvalProtocol.from_dict(spec.protocol),
            seed=spec.seed,
            observers=[*([recorder] if recorder is not None else []), *observers],
            planner_name=spec.shown,
        )
    except KeyboardInterrupt as exc:  # Ctrl-C or SIGTERM: the recorder closed it whole
        if record_to is not None:
            kept = recorder.kept if recorder is not None else None
            raise type(exc)(f"recording kept: {kept}" if kept else f"recording started in {record_to}.part") from None
        raise
    except OSError as exc:  # the recording could not be started or written
        raise RecordingFailed.because(record_to, exc) from None
    problem = recorder.stopped if recorder is not None else None
    if problem:  # the disk filled up: the result stands, the file is cut
        print(f"warning: {record_to}: {problem}", file=sys.stderr)
    return EpisodeRun(
        spec=spec,
        result=result,
        world=sim.world,
        recording=recorder.kept if recorder is not None else None,
        recording_target=Path(record_to) if record_to is not None else None,
        recording_problem=problem,
        planner_report=planner.report(),
    )


def _recorder(record_to: Path | None, planner: Planner, live: LiveView | None):
    """The episode's recorder, or None: a file alone is written by a writer process beside
    the episode (the same bytes, on the other core); a live view, or a planner that writes
    channels of its own (`Planner.recording_options`), are served from this process."""
    from dynabarn.recording import McapRecorder
    from dynabarn.recording.background import BackgroundRecorder

    contexts = live.contexts if live is not None else ()
    if record_to is None and not contexts:
        return None
    options = planner.recording_options()
    try:
        if contexts or options:
            recorder = McapRecorder(record_to, live=contexts, **options)
        else:
            recorder = BackgroundRecorder(record_to)
    except OSError as exc:  # a full disk, a missing or read-only folder
        raise RecordingFailed.because(record_to, exc) from None
    if options:
        planner.attach_recording(recorder)
    if live is not None:
        live.attach(recorder)
    return recorder
