"""Benchmark harness: planners x worlds x trials, in parallel, resumable, never losing a result.

A sweep is a list of `Job`s (planner, its configuration, world file, protocol, seed). Each
finished episode is appended to `OUT/results.jsonl` as one flushed and fsync'ed line
(full metrics, versions, world hash), so Ctrl-C or a crash loses nothing finished, and
running the same command again skips what is done. An episode whose code raises is
recorded as outcome `error` with its traceback and the sweep goes on.

Backends: `local` (a process pool on this machine) and `ray` (Ray tasks on a cluster or a
local Ray; `pip install dynabarn[ray]`). Both run the same `run_job`, so the same job gives
the same row on either.

The summary per planner and difficulty: success rate with a 95% Wilson interval,
collision and timeout rates, mean time of successes, BARN score, SPL and minimum
clearance; printed, and written as `summary.csv`, `summary.md` and a Fig. 5-style
`fig5.png` with the paper's published values beside ours.
"""

from __future__ import annotations

import csv
import hashlib
import json
import math
import os
import shutil
import sys
import time
import traceback
from collections import defaultdict
from collections.abc import Callable, Iterable, Iterator
from dataclasses import dataclass, field
from pathlib import Path

from dynabarn.errors import DynabarnError
from dynabarn.metrics import Outcome
from dynabarn.protocol import EvalProtocol
from dynabarn.provenance import GENERATED_WORLDS
from dynabarn.worlds.generate import PAPER60
from dynabarn.worldset import read_index

RESULTS = "results.jsonl"
METADATA = "metadata.json"

PAPER_FIG5 = {
    "dwa": {"easy": 0.78, "medium": 0.43, "hard": 0.17},
    "teb": {"easy": 0.40, "medium": 0.16, "hard": 0.00},
    "bc": {"easy": 0.30, "medium": 0.08, "hard": 0.05},
    "td3": {"easy": 0.74, "medium": 0.60, "hard": 0.28},
}
"""The paper's Fig. 5 success rates (read off the bar chart, +-0.02)."""

DIFFICULTIES = ("easy", "medium", "hard")


@dataclass(frozen=True)
class Job:
    """One episode to run."""

    planner: str
    planner_config: tuple  # sorted (key, value) pairs, hashable
    world_file: str
    world_id: int
    difficulty: str
    protocol: dict
    seed: int
    record: str = "none"  # none | failures | all
    recordings_dir: str = ""

    @property
    def key(self) -> str:
        """Identity of the episode in results.jsonl (what resuming compares)."""
        cfg = json.dumps(dict(self.planner_config), sort_keys=True)
        return f"{self.planner}|{cfg}|{Path(self.world_file).name}|{self.protocol['name']}|{self.seed}"


def parse_ids(text: str | None) -> list[int] | None:
    """'0,5,100-119' -> [0, 5, 100, ..., 119]."""
    if not text:
        return None
    ids: list[int] = []
    for part in text.split(","):
        part = part.strip()
        lo, sep, hi = part.partition("-")
        try:
            if sep:
                ids.extend(range(int(lo), int(hi) + 1))
            else:
                ids.append(int(part))
        except ValueError:
            raise DynabarnError(f"bad --worlds item {part!r}: use ids and ranges like 0,5,100-119") from None
    return ids


def world_set(name: str, ids: list[int] | None = None) -> list[tuple[int, str, str]]:
    """(world id, file, difficulty) for `paper60`, `dynabarn300`, or a folder/index.json."""
    if name in ("paper60", "dynabarn300"):
        index_dir = GENERATED_WORLDS
        chosen = list(PAPER60) if name == "paper60" else list(range(300))
    else:
        p = Path(name)
        index_dir = p.parent if p.name == "index.json" else p
        if not (index_dir / "index.json").is_file():
            raise DynabarnError(f"unknown world set {name!r}: use paper60, dynabarn300, or a folder with index.json")
        chosen = None
    index = read_index(index_dir)  # checks the format tag; one clear line when malformed
    entries = {e["id"]: e for e in index["worlds"]}
    chosen = chosen if chosen is not None else sorted(entries)
    if ids is not None:
        missing = sorted(set(ids) - set(entries))
        if missing:
            raise DynabarnError(f"world id(s) {missing[:5]} not in set {name!r}")
        chosen = [i for i in chosen if i in set(ids)] if name == "paper60" else ids
    return [(i, str(index_dir / entries[i]["file"]), entries[i]["difficulty"]) for i in chosen]


def make_jobs(
    planners: list[tuple[str, dict]],
    worlds: list[tuple[int, str, str]],
    protocol: EvalProtocol,
    trials: int,
    *,
    record: str = "none",
    recordings_dir: Path | None = None,
) -> list[Job]:
    return [
        Job(
            planner=name,
            planner_config=tuple(sorted(cfg.items())),
            world_file=file,
            world_id=wid,
            difficulty=difficulty,
            protocol=protocol.to_dict(),
            seed=seed,
            record=record,
            recordings_dir=str(recordings_dir or ""),
        )
        for name, cfg in planners
        for wid, file, difficulty in worlds
        for seed in range(trials)
    ]


def run_job(job: Job) -> dict:
    """Run one episode; never raises (an exception becomes an `error` row with its traceback)."""
    from dynabarn.planners import get_planner
    from dynabarn.recording import McapRecorder
    from dynabarn.sim import Simulation, run_episode

    row: dict = {
        "key": job.key,
        "planner": job.planner,
        "world_id": job.world_id,
        "difficulty": job.difficulty,
        "seed": job.seed,
        "protocol": job.protocol["name"],
    }
    rec_path = None
    try:
        sim = Simulation(job.world_file)
        planner = get_planner(job.planner, **dict(job.planner_config))
        observers = []
        if job.record != "none":
            rec_dir = Path(job.recordings_dir)
            rec_path = rec_dir / f"{sim.world.name}_{job.planner}_{job.protocol['name']}_s{job.seed}.mcap"
            observers.append(McapRecorder(rec_path.with_suffix(".mcap.part")))
        result = run_episode(
            sim,
            planner,
            EvalProtocol.from_dict(job.protocol),
            seed=job.seed,
            observers=observers,
            planner_name=job.planner,
        )
        row.update(result.to_dict())
        if rec_path is not None:
            part = rec_path.with_suffix(".mcap.part")
            if job.record == "all" or result.outcome is not Outcome.SUCCESS:
                part.replace(rec_path)
                row["recording"] = str(rec_path)
            else:
                part.unlink(missing_ok=True)
    except Exception as exc:  # foreign planner code, a broken world...: record and go on
        row.update(
            {
                "outcome": Outcome.ERROR.value,
                "reason": f"{type(exc).__name__}: {exc}",
                "traceback": traceback.format_exc(),
            }
        )
    row["planner"] = job.planner  # the registry name, whatever the planner calls itself
    return row


# -- backends -------------------------------------------------------------------------


def _local_backend(jobs: list[Job], n_workers: int) -> Iterator[dict]:
    if n_workers <= 1:
        for job in jobs:
            yield run_job(job)
        return
    import multiprocessing as mp

    ctx = mp.get_context("fork" if sys.platform.startswith("linux") else "spawn")
    with ctx.Pool(n_workers) as pool:
        try:
            yield from pool.imap_unordered(run_job, jobs, chunksize=1)
        except KeyboardInterrupt:
            pool.terminate()
            raise


def _ray_backend(jobs: list[Job], n_workers: int, address: str | None) -> Iterator[dict]:
    try:
        import ray
    except ImportError:
        raise DynabarnError("the ray backend needs Ray: pip install 'dynabarn[ray]'") from None
    started_here = not ray.is_initialized()
    if started_here:
        kwargs = {"address": address} if address else {"num_cpus": n_workers, "include_dashboard": False}
        ray.init(ignore_reinit_error=True, log_to_driver=False, **kwargs)
    remote = ray.remote(num_cpus=1)(run_job)
    pending = [remote.remote(job) for job in jobs]
    try:
        while pending:
            done, pending = ray.wait(pending, num_returns=1)
            yield ray.get(done[0])
    finally:
        for ref in pending:
            ray.cancel(ref, force=True)
        if started_here:
            ray.shutdown()


# -- results file -----------------------------------------------------------------------


def read_results(path: Path) -> list[dict]:
    """Rows of a results.jsonl; a last line cut by a crash is ignored."""
    rows = []
    if not path.is_file():
        return rows
    with path.open() as f:
        for line in f:
            line = line.strip()
            if not line:
                continue
            try:
                rows.append(json.loads(line))
            except json.JSONDecodeError:
                continue  # a line half-written when the process died
    return rows


def append_row(f, row: dict) -> None:
    f.write(json.dumps(row, sort_keys=True) + "\n")
    f.flush()
    os.fsync(f.fileno())


@dataclass
class SweepReport:
    ran: int = 0
    skipped: int = 0
    errors: int = 0
    wall_time: float = 0.0
    rows: list[dict] = field(default_factory=list)


def run_sweep(
    jobs: list[Job],
    out_dir: Path,
    *,
    backend: str = "local",
    n_workers: int = 1,
    address: str | None = None,
    progress: Callable[[Iterable, int], Iterable] | None = None,
) -> SweepReport:
    """Run the jobs not already in OUT/results.jsonl, appending each result as it arrives."""
    out_dir.mkdir(parents=True, exist_ok=True)
    results_path = out_dir / RESULTS
    # Drop a torn last line (a crash mid-write) so appends start on a fresh line.
    done_rows = read_results(results_path)
    if results_path.is_file():
        with results_path.open("w") as f:
            for row in done_rows:
                f.write(json.dumps(row, sort_keys=True) + "\n")
    done = {r["key"] for r in done_rows}
    todo = [j for j in jobs if j.key not in done]
    report = SweepReport(skipped=len(jobs) - len(todo))
    if any(j.record != "none" for j in todo):
        Path(todo[0].recordings_dir).mkdir(parents=True, exist_ok=True)
    t0 = time.perf_counter()
    stream = _ray_backend(todo, n_workers, address) if backend == "ray" else _local_backend(todo, n_workers)
    if progress is not None:
        stream = progress(stream, len(todo))
    with results_path.open("a") as f:
        for row in stream:
            append_row(f, row)
            report.ran += 1
            report.errors += row.get("outcome") == Outcome.ERROR.value
    report.wall_time = time.perf_counter() - t0
    wanted = {j.key for j in jobs}
    report.rows = [r for r in read_results(results_path) if r["key"] in wanted]
    return report


# -- summary -------------------------------------------------------------------------------


def wilson_interval(successes: int, n: int, z: float = 1.959964) -> tuple[float, float]:
    """95% Wilson score interval of a binomial proportion."""
    if n == 0:
        return 0.0, 1.0
    p = successes / n
    denom = 1 + z * z / n
    centre = (p + z * z / (2 * n)) / denom
    half = z * math.sqrt(p * (1 - p) / n + z * z / (4 * n * n)) / denom
    # The interval always contains p; rounding could otherwise put p = 1 just above it.
    return max(0.0, min(p, centre - half)), min(1.0, max(p, centre + half))


def _mean(values: list[float]) -> float:
    vals = [v for v in values if v is not None and math.isfinite(v)]
    return sum(vals) / len(vals) if vals else float("nan")


PAPER_PROTOCOLS = ("barn", "paper2022")


def summarise(rows: list[dict]) -> list[dict]:
    """One summary row per (planner, difficulty), plus 'all' per planner."""
    groups: dict[tuple[str, str], list[dict]] = defaultdict(list)
    for r in rows:
        groups[(r["planner"], r["difficulty"])].append(r)
        groups[(r["planner"], "all")].append(r)
    out = []
    order = {d: i for i, d in enumerate((*DIFFICULTIES, "all"))}
    for (planner, difficulty), rs in sorted(groups.items(), key=lambda kv: (kv[0][0], order.get(kv[0][1], 9))):
        n = len(rs)
        k = sum(r["outcome"] == "success" for r in rs)
        lo, hi = wilson_interval(k, n)
        succ = [r for r in rs if r["outcome"] == "success"]
        out.append(
            {
                "planner": planner,
                "difficulty": difficulty,
                "episodes": n,
                "success": k / n,
                "success_lo": lo,
                "success_hi": hi,
                "collision": sum(r["outcome"] == "collision" for r in rs) / n,
                "timeout": sum(r["outcome"] == "timeout" for r in rs) / n,
                "error": sum(r["outcome"] == "error" for r in rs) / n,
                "time_success": _mean([r.get("time") for r in succ]),
                "score": _mean([r.get("score", 0.0) for r in rs]),
                "spl": _mean([r.get("spl", 0.0) for r in rs]),
                "min_clearance": _mean([r.get("min_clearance") for r in rs]),
                # The paper's Fig. 5 only compares with runs in DynaBARN worlds under its protocols.
                "paper": PAPER_FIG5.get(planner, {}).get(difficulty)
                if all(r.get("protocol") in PAPER_PROTOCOLS for r in rs)
                else None,
            }
        )
    return out


def format_table(summary: list[dict]) -> str:
    head = (
        f"{'planner':<10}{'difficulty':<11}{'n':>5}{'success [95% CI]':>22}{'coll':>7}{'timeout':>8}"
        f"{'t_succ':>8}{'score':>7}{'SPL':>6}{'clear':>7}{'paper':>7}"
    )
    lines = [head, "-" * len(head)]
    for s in summary:
        ci = f"{s['success']:.2f} [{s['success_lo']:.2f}, {s['success_hi']:.2f}]"
        paper = f"{s['paper']:.2f}" if s["paper"] is not None else "-"
        lines.append(
            f"{s['planner']:<10}{s['difficulty']:<11}{s['episodes']:>5}{ci:>22}{s['collision']:>7.2f}"
            f"{s['timeout']:>8.2f}{s['time_success']:>8.1f}{s['score']:>7.3f}{s['spl']:>6.2f}"
            f"{s['min_clearance']:>7.2f}{paper:>7}"
        )
    return "\n".join(lines)


def write_summary(summary: list[dict], out_dir: Path, *, title: str = "") -> dict[str, Path]:
    paths = {"csv": out_dir / "summary.csv", "md": out_dir / "summary.md", "png": out_dir / "fig5.png"}
    with paths["csv"].open("w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=list(summary[0].keys()))
        w.writeheader()
        w.writerows(summary)
    md = [
        "| planner | difficulty | episodes | success [95% CI] | collision | timeout | mean time of successes [s] "
        "| score | SPL | min clearance [m] | paper |",
        "|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    for s in summary:
        paper = f"{s['paper']:.2f}" if s["paper"] is not None else "-"
        md.append(
            f"| {s['planner']} | {s['difficulty']} | {s['episodes']} | {s['success']:.2f} "
            f"[{s['success_lo']:.2f}, {s['success_hi']:.2f}] | {s['collision']:.2f} | {s['timeout']:.2f} | "
            f"{s['time_success']:.1f} | {s['score']:.3f} | {s['spl']:.2f} | {s['min_clearance']:.2f} | {paper} |"
        )
    paths["md"].write_text((f"# {title}\n\n" if title else "") + "\n".join(md) + "\n")
    plot_fig5(summary, paths["png"], title=title)
    return paths


def plot_fig5(summary: list[dict], path: Path, *, title: str = "") -> Path:
    """Bars of success per difficulty with 95% intervals, the paper's values as hatched bars."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    import numpy as np

    planners = sorted({s["planner"] for s in summary})
    fig, ax = plt.subplots(figsize=(2.2 + 2.4 * len(planners), 4.0), dpi=120)
    width = 0.8 / (2 * len(planners))
    colors = plt.get_cmap("tab10")
    x = np.arange(len(DIFFICULTIES))
    for k, planner in enumerate(planners):
        rows = {s["difficulty"]: s for s in summary if s["planner"] == planner}
        ours = [rows[d]["success"] if d in rows else np.nan for d in DIFFICULTIES]
        err = np.array(
            [
                [rows[d]["success"] - rows[d]["success_lo"], rows[d]["success_hi"] - rows[d]["success"]]
                if d in rows
                else [0, 0]
                for d in DIFFICULTIES
            ]
        ).T
        pos = x - 0.4 + width * (2 * k + 0.5)
        ax.bar(pos, ours, width, yerr=err, capsize=3, color=colors(k), label=f"{planner} (ours)")
        paper = [rows[d]["paper"] if d in rows and rows[d]["paper"] is not None else np.nan for d in DIFFICULTIES]
        if not all(np.isnan(paper)):
            ax.bar(
                pos + width, paper, width, color="white", edgecolor=colors(k), hatch="//", label=f"{planner} (paper)"
            )
    ax.set_xticks(x, DIFFICULTIES)
    ax.set_ylim(0, 1.05)
    ax.set_ylabel("success rate")
    ax.grid(axis="y", alpha=0.3)
    ax.legend(fontsize=8, ncol=2)
    ax.set_title(title or "success rate per difficulty (95% Wilson intervals)", fontsize=10)
    fig.tight_layout()
    fig.savefig(path)
    plt.close(fig)
    return path


def metadata(args_dict: dict, jobs: list[Job]) -> dict:
    from dynabarn.provenance import versions

    world_hashes = sorted({hashlib.sha256(Path(j.world_file).read_bytes()).hexdigest()[:16] for j in jobs})
    return {
        "format": "dynabarn-bench",
        "versions": versions(),
        "python": sys.version.split()[0],
        "arguments": args_dict,
        "protocol": jobs[0].protocol if jobs else None,
        "planners": sorted({j.planner for j in jobs}),
        "episodes": len(jobs),
        "worlds_digest": hashlib.sha256("".join(world_hashes).encode()).hexdigest()[:16],
    }


def check_or_write_metadata(out_dir: Path, meta: dict, *, force: bool) -> None:
    """Refuse to mix sweeps in one folder: same planners/protocol/worlds, or --force."""
    path = out_dir / METADATA
    out_dir.mkdir(parents=True, exist_ok=True)
    meta = json.loads(json.dumps(meta))  # compare as stored (tuples become lists)
    if path.is_file() and not force:
        old = json.loads(path.read_text())
        for key in ("protocol", "worlds_digest"):
            if old.get(key) != meta.get(key):
                raise DynabarnError(f"{out_dir} holds a different sweep ({key} differs); use another --out or --force")
    elif path.is_file() and force:
        for name in (RESULTS, "summary.csv", "summary.md", "fig5.png"):
            (out_dir / name).unlink(missing_ok=True)
        shutil.rmtree(out_dir / "recordings", ignore_errors=True)
    path.write_text(json.dumps(meta, indent=1, sort_keys=True) + "\n")


def jsonable_args(args) -> dict:
    d = dict(vars(args))
    return {k: (str(v) if isinstance(v, Path) else v) for k, v in d.items()}
