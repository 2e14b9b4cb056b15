"""One episode described once (`EpisodeSpec`) and run one way (`run_spec`).

Every command that runs an episode goes through here: `dynabarn-run`, `dynabarn-ros`,
`dynabarn-bench` (each job is a spec), the golden set and teleop. So the simulation's
settings (`--dt`, `--control-rate`) travel with an episode into a sweep, a resumed sweep
and the golden set, and a recording is made, finished and failed in one place:

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
from dynabarn.interfaces import EpisodeObserver
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
    planner=None,
    factory: Callable | None = None,
    sim: Simulation | None = None,
    record_to: Path | None = None,
    recorder=None,
    live_contexts: tuple = (),
    observers: Sequence[EpisodeObserver] = (),
    on_recorder: Callable | None = None,
):
    """Run the episode `spec` describes; its `EpisodeResult`.

    Args:
        planner: a planner object instead of the registry's (the ROS bridge, teleop).
        factory: the planner's factory when registered at run time (worker processes).
        sim: the compiled world, when the caller has it already (`Simulation.fork` or one
            opened for a viewer); else compiled here with the spec's settings.
        record_to: record the episode to this MCAP file (NAME.part until whole).
        recorder: a recorder the caller made (teleop's, with its input channel) instead.
        live_contexts: foxglove contexts the recorder also streams to.
        observers: further observers (viewers, pacing), after the recorder.
        on_recorder: called with the recorder before the episode starts.
    """
    from dynabarn.planners import get_planner
    from dynabarn.recording import McapRecorder
    from dynabarn.recording.background import BackgroundRecorder
    from dynabarn.sim import run_episode

    if sim is None:
        sim = Simulation(spec.world, config=spec.sim_config)
    elif sim.config != spec.sim_config:
        raise DynabarnError(f"the simulation's settings {sim.config} are not the episode's {spec.sim_config}")
    if planner is None:
        planner = get_planner(spec.planner, factory=factory, **dict(spec.planner_config))
    if recorder is None and (record_to is not None or live_contexts):
        try:
            # A file alone is written by a writer process beside the episode (the same bytes,
            # on the other core); a live view streams from this process.
            recorder = McapRecorder(record_to, live=live_contexts) if live_contexts else BackgroundRecorder(record_to)
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
