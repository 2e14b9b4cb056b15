"""A sweep's jobs: one episode each (planner, configuration, world, protocol, seed), and
`run_job`, which runs one and never raises (an exception becomes an `error` row)."""

from __future__ import annotations

import contextlib
import traceback
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

from dynabarn.metrics import Outcome
from dynabarn.planners.from_code import LOADED, CodePlanner, load_again
from dynabarn.planners.registry import PLANNERS, planner_factory, register_planner, registered_at_run_time
from dynabarn.protocol import EvalProtocol
from dynabarn.recording.writer import staging_path
from dynabarn.runner import EpisodeSpec, RecordingFailed, run_spec
from dynabarn.sim_config import SimConfig


@dataclass(frozen=True)
class Job:
    """One episode of a sweep: the episode itself (`spec`), where it sits in the world set,
    and what becomes of its recording."""

    spec: EpisodeSpec
    world_id: int
    difficulty: str
    record: str = "none"  # none | failures | all
    recordings_dir: str = ""
    factory: Callable | None = None
    """The planner's factory, for a planner registered at run time (`register_planner`):
    worker processes that do not fork (spawn, Ray) know only installed planners."""
    code: CodePlanner | None = None
    """A planner named by its code (`--planner FILE.py:CLASS`): loaded again in the worker,
    and its identity written into every row (`planner_code`)."""

    @property
    def shown(self) -> str:
        return self.spec.shown

    @property
    def key(self) -> str:
        """Identity of the episode in results.jsonl (what resuming compares): the spec's."""
        return self.spec.key


def make_jobs(
    planners: list[tuple[str, dict]] | list[tuple[str, dict, str]],
    worlds: list[tuple[int, str, str]],
    protocol: EvalProtocol,
    trials: int,
    *,
    record: str = "none",
    recordings_dir: Path | None = None,
    sim: SimConfig = SimConfig(),
) -> list[Job]:
    return [
        Job(
            spec=EpisodeSpec.make(file, name, protocol, config=cfg, seed=seed, sim=sim, label=(label or [""])[0]),
            world_id=wid,
            difficulty=difficulty,
            record=record,
            recordings_dir=str(recordings_dir or ""),
            factory=planner_factory(name) if registered_at_run_time(name) and name not in LOADED else None,
            code=LOADED.get(name),
        )
        for name, cfg, *label in planners
        for wid, file, difficulty in worlds
        for seed in range(trials)
    ]


def row_head(job: Job) -> dict:
    """The fields every row of `job` starts with, whatever became of the episode."""
    return {
        "key": job.key,
        "planner": job.shown,
        "world_id": job.world_id,
        "difficulty": job.difficulty,
        "seed": job.spec.seed,
        "protocol": job.spec.protocol["name"],
    }


def run_job(job: Job) -> dict:
    """Run one episode; never raises (an exception becomes an `error` row with its traceback)."""
    row = row_head(job)
    try:
        spec = job.spec
        if job.factory is not None and spec.planner not in PLANNERS:
            # Registered at run time in the sweep's process: this worker learns it the same way.
            register_planner(job.factory, name=spec.planner)
        if job.code is not None:
            row["planner_code"] = job.code.identity()
            load_again(job.code)
        record_in = Path(job.recordings_dir) if job.record != "none" else None  # NAME.part until whole
        run = run_spec(spec, record_in=record_in)
        result = run.result
        row.update(result.to_dict())
        # The profile the world was drawn from (the sweep's worlds.json has its numbers).
        row["profile_set"] = run.world.profile_set
        if run.recording_problem:  # disk nearly full: the result stands, run it again
            row.update({"retry": True, "recording_error": run.recording_problem})
        if run.recording_target is not None:
            if job.record == "all" or result.outcome is not Outcome.SUCCESS:
                row["recording"] = str(run.recording_target)
            else:
                run.recording_target.unlink(missing_ok=True)
    except (OSError, MemoryError, RecordingFailed) as exc:  # the machine failed, not the planner: run it again later
        row.update(
            {
                "outcome": Outcome.ERROR.value,
                "reason": f"infrastructure: {type(exc).__name__}: {exc}",
                "retry": True,
            }
        )
        if (
            isinstance(exc, RecordingFailed) and exc.target is not None
        ):  # what the recorder wrote, in the sweep's folder
            with contextlib.suppress(OSError):
                staging_path(exc.target).unlink(missing_ok=True)
    except Exception as exc:  # foreign planner code, a broken world...: record and go on
        row.update(
            {
                "outcome": Outcome.ERROR.value,
                "reason": f"{type(exc).__name__}: {exc}",
                "traceback": traceback.format_exc(),
            }
        )
    row["planner"] = job.shown  # the registry name (or the label), whatever the planner calls itself
    return row
