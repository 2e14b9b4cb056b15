"""One episode described once (`EpisodeSpec`) and run one way (`run_spec`), which builds
what it runs: the simulation with the spec's settings, the planner with its configuration,
the recorder.

Every command that runs an episode goes through here: `dynabarn-run`, `dynabarn-ros`,
`dynabarn-bench` (each job is a spec), `--verify`, the golden set and teleop, none with a
simulation of its own (what needs the compiled world, a viewer, gets it from `on_built`).
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

import json
import sys
from collections.abc import Callable, Sequence
from dataclasses import asdict, dataclass, fields
from pathlib import Path
from typing import Any

from dynabarn.errors import DynabarnError
from dynabarn.interfaces import EpisodeObserver, Planner
from dynabarn.protocol import EvalProtocol
from dynabarn.sim import SimConfig, Simulation

_DEFAULT_SIM = SimConfig()


class RecordingFailed(DynabarnError):
    """The recording could not be started or written (the machine's fault, not the
    episode's: a sweep runs such an episode again)."""


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
        changed = {f.name: getattr(sim, f.name) for f in fields(SimConfig)}
        changed = {k: v for k, v in changed.items() if v != getattr(_DEFAULT_SIM, k)}
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


def run_spec(
    spec: EpisodeSpec,
    *,
    record_to: Path | None = None,
    record_in: Path | None = None,
    live_contexts: tuple = (),
    observers: Sequence[EpisodeObserver] = (),
    on_built: Callable[[Simulation, Planner], Sequence[EpisodeObserver] | None] | None = None,
    on_recorder: Callable | None = None,
    record_options: dict | None = None,
):
    """Build what `spec` describes (the simulation with its settings, the planner with its
    configuration, the recorder) and run the episode; its `EpisodeResult`. Each setting is
    given once, in the spec: nothing passed here changes what happens in the episode.

    Args:
        record_to: record the episode to this MCAP file (NAME.part until whole).
        record_in: or to this folder, under the default name (`default_run_path`: world,
            the planner as results show it, protocol, seed).
        live_contexts: foxglove contexts the recorder also streams to.
        observers: further observers (pacing, live views), after the recorder.
        on_built: called with the compiled simulation and the planner before the episode
            starts; returns observers that need them (a viewer of the MuJoCo model), which run
            after the others.
        on_recorder: called with the recorder before the episode starts.
        record_options: the recorder's options (`McapRecorder`: channels and metadata of its
            own, e.g. teleop's input channel); with them it records in this process, where
            the planner can write to it.
    """
    from dynabarn.planners import get_planner
    from dynabarn.recording import McapRecorder, default_run_path
    from dynabarn.recording.background import BackgroundRecorder
    from dynabarn.sim import run_episode

    # Before the world is compiled: a bad configuration is one line at once.
    planner = get_planner(spec.planner, **dict(spec.planner_config))
    sim = Simulation(spec.world, config=spec.sim_config)
    observers = [*observers, *((on_built(sim, planner) or ()) if on_built is not None else ())]
    if record_to is None and record_in is not None:
        record_to = default_run_path(record_in, sim.world.name, spec.shown, spec.protocol["name"], spec.seed)
    recorder = None
    if record_to is not None or live_contexts:
        try:
            # A file alone is written by a writer process beside the episode (the same bytes,
            # on the other core); a live view, or a planner writing to it, from this process.
            here = live_contexts or record_options is not None
            options = record_options or {}
            recorder = McapRecorder(record_to, live=live_contexts, **options) if here else BackgroundRecorder(record_to)
        except OSError as exc:  # a full disk, a missing or read-only folder
            raise RecordingFailed(f"cannot record to {record_to}: {exc.strerror or exc}") from None
    if recorder is not None and on_recorder is not None:
        on_recorder(recorder)
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
            kept = getattr(recorder, "kept", None)
            raise type(exc)(f"recording kept: {kept}" if kept else f"recording started in {record_to}.part") from None
        raise
    except OSError as exc:  # the recording could not be started or written
        raise RecordingFailed(f"cannot record to {record_to}: {exc.strerror or exc}") from None
    if recorder is not None and recorder.stopped:  # the disk filled up: the result stands, the file is cut
        print(f"warning: {record_to}: {recorder.stopped}", file=sys.stderr)
    return result
