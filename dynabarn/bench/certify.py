"""Certify a world set: every world and trial's certificate, recorded in its `index.json`.

For each world and each trial seed 0..trials-1 (the seeds a sweep's trials use, so each
certificate holds for the clock offset that trial runs), `sim.certificate.certify`
searches and `replay_witness` drives the witness in MuJoCo; a trial is
certified if both succeed. Where they do not, the exact oracle's episode of the trial is
run: if it reaches the goal without contact, it is the witness (`by`). Each world's index entry gets, under
`certificates.<protocol>`, the trials' answers, `certified` (every trial certified),
`certified_trials` and the witnesses' `slack` (median arrival minus the unobstructed
arrival, the same search in an empty arena); the index gets the search's resolution.

Certificates are kept by the world file's sha256 and the resolution's version: running it
again only computes what is missing (a stopped run resumes), and a world regenerated to
the same bytes keeps its certificate (`worldset.write_worlds`).
"""

from __future__ import annotations

import json
import math
import statistics
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING

from dynabarn.errors import DynabarnError
from dynabarn.files import write_atomically
from dynabarn.metrics import EpisodeResult
from dynabarn.processes import map_in_workers
from dynabarn.protocol import EvalProtocol
from dynabarn.sim.certificate import CertificateConfig, Witness, certify
from dynabarn.sim_config import trial_clock_offset
from dynabarn.worlds.spec import Layout, WorldSpec
from dynabarn.worldset import (
    INDEX_NAME,
    certificate_problem,
    entry_path,
    index_locked,
    own_certificates,
    read_index,
)

if TYPE_CHECKING:
    from dynabarn.sim import Simulation

ORACLE = "oracle"
"""The planner whose successful episode certifies a trial the search could not: the exact
future and the oracle's search (`planners.oracle`), run to the end of the episode."""
CHECKPOINT_EVERY = 10
"""Worlds between rewrites of index.json during a run (a stopped run loses at most these)."""


@dataclass(frozen=True)
class Job:
    path: str
    sha256: str
    protocol: dict
    seeds: tuple[int, ...]
    budget: int | None = None
    """The search's budget (states expanded per trial; None: none), `sim.certificate.certify`."""
    resolution: dict = field(default_factory=dict)
    """The search's resolution (`CertificateConfig.to_dict`; empty: the default's)."""


def unobstructed_arrival(protocol: EvalProtocol, config: CertificateConfig | None = None) -> float:
    """The search's arrival in an empty arena [s]: what a witness's slack is measured from."""
    empty = WorldSpec(name="empty", world_id=None, difficulty="easy", obstacles=(), layout=Layout())
    cert = certify(empty, protocol, clock_offset=0.0, config=config)
    assert cert.arrival is not None, "an empty arena is always certified"
    return cert.arrival


def replay_witness(
    world: Path | str | Simulation, witness: Witness, protocol: EvalProtocol, *, seed: int
) -> tuple[EpisodeResult, float]:
    """The episode of the witness in `world` with trial `seed`, run as every episode is
    (`runner.run_spec`, the follower given built), and its largest tracking error [m]."""
    from dynabarn.runner import EpisodeSpec, run_spec
    from dynabarn.sim import Simulation
    from dynabarn.sim.witness import WitnessFollower

    sim = world if isinstance(world, Simulation) else Simulation(world)
    follower = WitnessFollower(witness)
    spec = EpisodeSpec.make(sim.world_path, follower.name, protocol, seed=seed, sim=sim.config)
    result = run_spec(spec, planner=follower, sim=sim).result
    return result, follower.largest_error


def certify_world(job: Job) -> tuple[str, list[dict]]:
    """Every trial of one world: the search, then the witness's replay in MuJoCo."""
    from dynabarn.mjcf import read_world
    from dynabarn.sim import Simulation

    protocol = EvalProtocol.from_dict(job.protocol)
    world = read_world(job.path)
    sim = None
    trials = []
    config = CertificateConfig.from_dict(job.resolution)
    for seed in job.seeds:
        cert = certify(world, protocol, clock_offset=trial_clock_offset(seed), budget=job.budget, config=config)
        row = {"seed": seed, **cert.to_dict()}
        if cert.witness is not None:
            sim = sim or Simulation(job.path)
            result, error = replay_witness(sim, cert.witness, protocol, seed=seed)
            row["replay"] = {
                "outcome": result.outcome.value,
                "min_clearance": round(float(result.min_clearance), 4),
                "tracking_error": round(error, 4),
            }
            if result.outcome.value != "success":
                row["certified"] = False
                row["reason"] = f"the witness's replay ended in {result.outcome.value}"
        if not row["certified"]:
            _oracle_stage(row, job.path, protocol, seed)
        trials.append(row)
    return job.path, trials


def _oracle_stage(row: dict, world: str, protocol: EvalProtocol, seed: int) -> None:
    """Where the search found no witness, the exact oracle's episode of the same trial (run
    as every episode is, `runner.run_spec`): if it reaches the goal without contact, that
    episode is the witness (MuJoCo drove it), and the trial is certified by it; the
    search's reason stays beside it."""
    from dynabarn.runner import EpisodeSpec, run_spec

    result = run_spec(EpisodeSpec.make(world, ORACLE, protocol, seed=seed)).result
    row["oracle"] = {
        "outcome": result.outcome.value,
        "time": round(float(result.time), 4),
        "min_clearance": round(float(result.min_clearance), 4) if math.isfinite(result.min_clearance) else None,
    }
    if result.outcome.value == "success":
        row["certified"] = True
        row["by"] = "the exact oracle's episode"


def world_record(trials: list[dict], unobstructed: float) -> dict:
    """A world's record: its trials, whether all are certified, and the witnesses' slack."""
    arrivals = [t["arrival"] for t in trials if t["certified"] and "by" not in t]  # the search's witnesses
    record = {
        "trials": trials,
        "certified": all(t["certified"] for t in trials),
        "certified_trials": sum(t["certified"] for t in trials),
    }
    if arrivals:
        record["slack"] = round(statistics.median(arrivals) - unobstructed, 4)
    return record


def certify_set(
    index_dir: Path,
    protocol: EvalProtocol,
    *,
    trials: int = 10,
    ids: list[int] | None = None,
    jobs: int = 1,
    budget: int | None = None,
    config: CertificateConfig | None = None,
    progress: Callable = lambda it: it,
) -> dict:
    """Certify the worlds `ids` (default: all) of the set in `index_dir`; returns the
    updated index (also written to its index.json). `budget`: the search's, per trial
    (`sim.certificate.certify`), recorded in the index for `verify_set`; `config`: the
    search's resolution (default: version 2's disc, breadth-first), recorded beside it. The
    set's index lock is held throughout (`worldset.index_locked`): a second writer at once
    is refused."""
    with index_locked(index_dir):
        return _certify_set(index_dir, protocol, trials, ids, jobs, budget, config or CertificateConfig(), progress)


def _certify_set(index_dir, protocol, trials, ids, jobs, budget, config: CertificateConfig, progress) -> dict:
    index = read_index(index_dir)
    resolution = config.to_dict()
    seeds = tuple(range(trials))
    unobstructed = unobstructed_arrival(protocol, config)
    wanted = set(ids) if ids is not None else None
    todo: list[Job] = []
    for entry in index["worlds"]:
        if wanted is not None and entry["id"] not in wanted:
            continue
        if not _current(entry, protocol.name, resolution, seeds):
            path = entry_path(Path(index_dir), entry)
            todo.append(Job(str(path), entry["sha256"], protocol.to_dict(), seeds, budget, resolution))
    by_path = {Path(entry_path(Path(index_dir), e)).name: e for e in index["worlds"]}
    for done, (path, rows) in enumerate(progress(map_in_workers(certify_world, todo, jobs)), start=1):
        entry = by_path[Path(path).name]
        record = world_record(rows, unobstructed)
        entry.setdefault("certificates", {})[protocol.name] = {
            "sha256": entry["sha256"],
            "resolution_version": config.version,
            **record,
        }
        if done % CHECKPOINT_EVERY == 0:
            _write(index_dir, index, protocol, resolution, unobstructed, budget)
    _write(index_dir, index, protocol, resolution, unobstructed, budget)
    return index


def verify_set(
    index_dir: Path,
    protocol: EvalProtocol,
    *,
    ids: list[int] | None = None,
    jobs: int = 1,
    progress: Callable = lambda it: it,
) -> tuple[list[str], int]:
    """Compute the certificates of the worlds `ids` (default: all) that the index holds
    again, for the trials it holds, and compare: (one line per difference, trials checked,
    worlds left out because they have no certificate). Refuses (one line) when none of the
    worlds has one: a pass on nothing is not a pass. Writes nothing."""
    index = read_index(index_dir)
    certification = index.get("certification", {}).get(protocol.name, {})
    budget = certification.get("search_budget")
    # Under the resolution the certificates were made at (its version's fields).
    resolution = recorded_resolution(index_dir, certification).to_dict()
    wanted = set(ids) if ids is not None else None
    stored: dict[str, dict] = {}
    todo = []
    differences = []
    uncertified = 0
    for entry in index["worlds"]:
        if wanted is not None and entry["id"] not in wanted:
            continue
        records = entry.get("certificates")
        raw = records.get(protocol.name) if isinstance(records, dict) else None
        problem = certificate_problem(raw) if raw is not None else None
        if problem is not None:  # a record that contradicts itself is a difference, not a pass
            differences.append(f"{entry.get('file')}: its {protocol.name} certificate: {problem}")
            continue
        record = own_certificates(entry).get(protocol.name)
        if record is None:
            uncertified += 1
            continue
        path = entry_path(Path(index_dir), entry)
        stored[path.name] = record
        seeds = tuple(t["seed"] for t in record["trials"])
        todo.append(Job(str(path), entry["sha256"], protocol.to_dict(), seeds, budget, resolution))
    if not todo and not differences:
        raise DynabarnError(
            f"{index_dir}: none of the {uncertified} world(s) asked for has a {protocol.name} certificate to verify; "
            "certify them first (dynabarn-worlds certify without --verify)"
        )
    checked = 0
    for path, rows in progress(map_in_workers(certify_world, todo, jobs)):
        for old, new in zip(stored[Path(path).name]["trials"], rows, strict=True):
            checked += 1
            for key in ("certified", "arrival", "reason", "by"):
                if old.get(key) != new.get(key):
                    differences.append(
                        f"{Path(path).name} seed {old['seed']}: {key} {old.get(key)!r} -> {new.get(key)!r}"
                    )
    return differences, checked, uncertified


def recorded_resolution(index_dir: Path, certification: dict) -> CertificateConfig:
    """The search's resolution an index's certification records (version 2's default where
    it records none); one `DynabarnError` line where the record is not one."""
    raw = certification.get("resolution", {})
    try:
        if not isinstance(raw, dict):
            raise TypeError(f"not an object: {type(raw).__name__}")
        return CertificateConfig.from_dict(raw)
    except (TypeError, ValueError) as exc:
        raise DynabarnError(f"{index_dir}: its certification's resolution is not one the search has ({exc})") from None


def _current(entry: dict, protocol: str, resolution: dict, seeds: tuple[int, ...]) -> bool:
    record = own_certificates(entry).get(protocol)
    return (
        record is not None
        and record.get("resolution_version") == resolution["version"]
        and [t.get("seed") for t in record.get("trials", [])][: len(seeds)] == list(seeds)
        # Records from before the oracle's stage: their uncertified trials have not had it.
        and all(t.get("certified") or "oracle" in t for t in record["trials"])
    )


def _write(
    index_dir: Path, index: dict, protocol: EvalProtocol, resolution: dict, unobstructed: float, budget: int | None
) -> None:
    index.setdefault("certification", {})[protocol.name] = {
        "resolution": resolution,
        **({"search_budget": budget} if budget is not None else {}),
        "unobstructed_arrival": unobstructed,
        "protocol": protocol.to_dict(),
    }
    try:
        write_atomically(Path(index_dir) / INDEX_NAME, json.dumps(index, indent=1, sort_keys=True) + "\n")
    except OSError as exc:  # a read-only install, a full disk: say so, keep the index as it was
        why = exc.strerror or exc
        raise DynabarnError(f"cannot write the certificates into {Path(index_dir) / INDEX_NAME}: {why}") from None


MAX_DRAWS = 50
"""Redraws of one tier world before giving up: a profile whose worlds are so rarely
solvable is a profile to change, not to draw from."""


def certify_tier(
    name: str,
    protocol: EvalProtocol,
    *,
    trials: int = 10,
    jobs: int = 1,
    budget: int | None = None,
    progress: Callable = lambda it: it,
    say: Callable[[str], None] = print,
) -> dict:
    """Certify tier `name` from its first draws, redrawing every world that is not certified
    for every trial from the next seed of its own sequence until all are; write the draws
    and certificates beside its profile (`Tier.certified_file`) and regenerate its folder
    with them. Nothing here looks at a planner. Returns the record written."""
    from dynabarn.worlds.tiers import get_tier
    from dynabarn.worldset.tiers import generate_tier, tier_dir

    tier = get_tier(name)  # resolved once, then handed on
    folder = tier_dir(tier).with_name(f".{tier.name}.certifying")  # kept: a stopped run resumes from it
    draws: dict[int, int] = {}
    pending = list(tier.ids)
    while True:
        generate_tier(tier, folder, draws=draws)  # unchanged files keep their certificates
        index = certify_set(folder, protocol, trials=trials, ids=pending, jobs=jobs, budget=budget, progress=progress)
        entries = {e["id"]: e for e in index["worlds"]}
        failed = [i for i in pending if not entries[i]["certificates"][protocol.name]["certified"]]
        if not failed:
            break
        say(f"{name}: {len(failed)} world(s) not certified, drawn again: {failed}")
        for i in failed:
            draws[i] = draws.get(i, 0) + 1
            if draws[i] > MAX_DRAWS:
                raise DynabarnError(f"{name}: world {i} was not certified in {MAX_DRAWS} draws; change the profile")
        pending = failed
    return _write_tier_record(tier, protocol, trials, draws, index)


def recertify_tier(
    name: str,
    protocol: EvalProtocol,
    *,
    config: CertificateConfig,
    trials: int = 10,
    jobs: int = 1,
    budget: int | None = None,
    progress: Callable = lambda it: it,
) -> dict:
    """Certify tier `name`'s committed draws again at the resolution `config` (a newer
    version of the search), every world and trial, and write those certificates beside its
    profile in place of the old: the worlds stay exactly the ones every committed result
    ran (no redraw; a trial neither the search nor the oracle's episode certifies stays
    uncertified, counted). Returns the record written."""
    from dynabarn.worlds.tiers import get_tier
    from dynabarn.worldset.tiers import generate_tier, tier_dir

    tier = get_tier(name)  # resolved once, then handed on
    draws = tier.draws()
    folder = tier_dir(tier).with_name(f".{tier.name}.recertifying")  # kept: a stopped run resumes from it
    generate_tier(tier, folder, draws=draws)  # unchanged files keep the certificates made so far
    index = certify_set(
        folder, protocol, trials=trials, ids=list(tier.ids), jobs=jobs, budget=budget, config=config, progress=progress
    )
    return _write_tier_record(tier, protocol, trials, draws, index)


def _write_tier_record(tier, protocol: EvalProtocol, trials: int, draws: dict[int, int], index: dict) -> dict:
    """Write `tier`'s draws and certificates beside its profile (`Tier.certified_file`) and
    regenerate its folder with them."""
    from dynabarn.worldset.tiers import generate_tier, tier_dir

    wanted = set(tier.ids)
    record = {
        "tier": tier.name,
        "protocol": protocol.name,
        "trials": trials,
        "draws": {str(i): k for i, k in sorted(draws.items())},
        "certificates": {str(e["id"]): e["certificates"] for e in index["worlds"] if e["id"] in wanted},
        "certification": index["certification"],
    }
    try:
        write_atomically(tier.certified_file, json.dumps(record, indent=1, sort_keys=True) + "\n")
    except OSError as exc:
        raise DynabarnError(
            f"cannot write {tier.certified_file}: {exc.strerror or exc} (certify tiers in a checkout)"
        ) from None
    generate_tier(tier, tier_dir(tier))
    return record
