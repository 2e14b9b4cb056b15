"""The golden set: about 30 episodes whose results and recordings are committed, re-run by
`dynabarn-bench --verify-golden` to show that this machine and install give the same
episodes as the machine that wrote them (docs/reproducibility.md).

Every planner (straight, dwa, teb, predictive, oracle_present, oracle, bc, td3, dagger), the three difficulties, both
protocols, imported release worlds, static BARN worlds, mixed shapes with a static field
and reactive (`avoid`, `yield`) worlds. Worlds that are not committed are built on the
spot, deterministically, into `.golden_worlds/` beside `generated_worlds/` (the user's cache
folder for an installed wheel) naming the robot at `../../assets` (so their files,
hashes and recordings read the same on every checkout); imported worlds need the
reference data (`--reference`, default `../shared/reference`) and are skipped without it.

Compared per episode: every result field except the machine's (wall-clock times, the
machine block) and `versions` (printed when they differ, as the likely explanation), plus
the digest of the recording's messages (`recording.message_digest`): the recording is
byte-identical but for its `dynabarn.machine` metadata record.
"""

from __future__ import annotations

import functools
import json
import os
import tempfile
from collections.abc import Callable, Iterable, Iterator, Sequence
from dataclasses import asdict, dataclass
from pathlib import Path

from dynabarn.errors import DynabarnError
from dynabarn.mjcf import write_world
from dynabarn.processes import map_in_workers
from dynabarn.provenance import REPO_ROOT, SHIPPED_WORLDS, work_root
from dynabarn.recording import MACHINE_FIELDS
from dynabarn.sim_config import SimConfig

GOLDEN_FILE = Path(__file__).resolve().parent / "golden_set.json"
GOLDEN_WORLDS = work_root() / ".golden_worlds"
"""Beside generated_worlds/ in a checkout; in the user's cache for an installed wheel."""
DEFAULT_REFERENCE = REPO_ROOT.parent / "shared" / "reference"
FORMAT = "dynabarn-golden"
IGNORED_FIELDS = frozenset({*MACHINE_FIELDS, "versions"})
"""Result fields not compared (machine speed, machine block; versions are reported apart)."""


@dataclass(frozen=True)
class GoldenCase:
    """One golden episode: a world from a source, a planner, a protocol and a seed."""

    planner: str
    source: str
    """generated (the committed 300) | mixed (shapes + BARN grid) | avoid | yield (reactive)
    | release (imported 2022 release) | barn-static (imported BARN)."""
    world_id: int
    protocol: str = "barn"
    seed: int = 0
    config: str = ""
    """A shipped preset name, or empty for the planner's defaults."""
    sim: SimConfig = SimConfig()
    """The simulation's settings (`--dt`, `--control-rate`): they travel with the episode."""

    @property
    def key(self) -> str:
        cfg = f"[{self.config}]" if self.config else ""
        key = f"{self.planner}{cfg} {self.source}/{self.world_id} {self.protocol} s{self.seed}"
        if self.sim.changed():
            key += f" dt{self.sim.dt:g} {self.sim.control_rate:g}Hz"
        return key


CASES: tuple[GoldenCase, ...] = (
    # The blind floor.
    GoldenCase("straight", "generated", 0),
    GoldenCase("straight", "generated", 137, seed=1),
    GoldenCase("straight", "generated", 250, "paper2022"),
    # DWA: three difficulties, both protocols, the release, BARN, shapes, reactive.
    GoldenCase("dwa", "generated", 5),
    GoldenCase("dwa", "generated", 137, seed=2),
    GoldenCase("dwa", "generated", 205, seed=1),
    GoldenCase("dwa", "generated", 250, "paper2022"),
    GoldenCase("dwa", "release", 3, "paper2022"),
    GoldenCase("dwa", "barn-static", 50, "barn-static", config="dwa_barn_challenge"),
    GoldenCase("dwa", "mixed", 60),
    GoldenCase("dwa", "avoid", 137),
    # base_local_planner's TrajectoryPlanner with the DynaBARN authors' values (stop-and-turn, ramps).
    GoldenCase("trajectory_planner", "generated", 105, seed=1, config="dwa_dynabarn_authors"),
    GoldenCase("trajectory_planner", "generated", 215, config="dwa_dynabarn_authors"),
    # TEB: its optimiser is the most sensitive part, so the most cases.
    GoldenCase("teb", "generated", 10),
    GoldenCase("teb", "generated", 150, seed=1),
    GoldenCase("teb", "generated", 205),
    GoldenCase("teb", "generated", 215, "paper2022", seed=3),
    GoldenCase("teb", "release", 25, "paper2022"),
    GoldenCase("teb", "release", 45, "paper2022", seed=1),
    GoldenCase("teb", "barn-static", 100, "barn-static", config="teb_narrow"),
    GoldenCase("teb", "mixed", 120),
    GoldenCase("teb", "yield", 210),
    GoldenCase("teb", "avoid", 230, seed=2),
    # Prediction from the laser: the tracker feeding the oracle's search, TEB and DWA.
    GoldenCase("predictive", "generated", 205),
    GoldenCase("predictive", "release", 45, "paper2022", seed=1),
    GoldenCase("predictive", "mixed", 120),
    GoldenCase("predictive", "yield", 210),
    GoldenCase("teb", "generated", 150, seed=1, config="teb_dynamic"),
    GoldenCase("dwa", "generated", 137, seed=2, config="dwa_dynamic"),
    # The privileged oracle: the true present state at constant velocity, the exact future.
    GoldenCase("oracle_present", "generated", 215, seed=3),
    GoldenCase("oracle", "generated", 0),
    GoldenCase("oracle", "generated", 137),
    GoldenCase("oracle", "generated", 230, seed=4),
    GoldenCase("oracle", "mixed", 220),
    # Learned policies (PyTorch).
    GoldenCase("bc", "generated", 15),
    GoldenCase("bc", "generated", 140, seed=1),
    GoldenCase("bc", "generated", 240, "paper2022"),
    GoldenCase("bc", "release", 10, "paper2022"),
    GoldenCase("td3", "generated", 2),
    GoldenCase("td3", "generated", 160),
    GoldenCase("dagger", "generated", 205),
    GoldenCase("dagger", "release", 30, seed=2),
    # The simulation's own settings travel with the episode (`--dt`, `--control-rate`).
    GoldenCase("dwa", "generated", 137, seed=2, sim=SimConfig(dt=0.0025, control_rate=20.0)),
)


@dataclass(frozen=True)
class Mismatch:
    case: str
    field: str
    golden: object
    now: object

    def __str__(self) -> str:
        return f"{self.case}: {self.field}: golden {self.golden!r}, now {self.now!r}"


# -- worlds ------------------------------------------------------------------------------


IMPORTED = {"release": ("dynabarn-release", "release"), "barn-static": ("barn-static", "barn")}
"""The golden set's imported sources: source -> (its import format, the set's name)."""


def _imported(source: str, reference: Path) -> list:
    from dynabarn.worlds.importers import IMPORTERS, import_worlds

    fmt, name = IMPORTED[source]
    path = reference / IMPORTERS.get_item(fmt).reference_file
    return import_worlds(fmt, path, name=name) if path.is_file() else []


def _generated(source: str, world_id: int):
    from dynabarn.sim.behaviors import get_behavior
    from dynabarn.worlds.generate import generate_world
    from dynabarn.worlds.profiles import get_profile_set, get_shape_mix, get_static_field

    profiles = get_profile_set("table1")
    if source == "mixed":
        return generate_world(
            world_id, profiles, shapes=get_shape_mix("mixed"), static_field=get_static_field("barn-grid")
        )
    return generate_world(world_id, profiles, behavior=source, behavior_params=get_behavior(source).defaults())


def world_file(case: GoldenCase, reference: Path, worlds_dir: Path = GOLDEN_WORLDS) -> Path | None:
    """The case's world file (built into `worlds_dir` when not committed); None when it
    needs reference data that is absent."""
    if case.source == "generated":  # the shipped set, whatever $DYNABARN_WORLDS says
        return SHIPPED_WORLDS / f"world_{case.world_id:03d}.xml"
    path = worlds_dir / case.source / f"world_{case.world_id:03d}.xml"
    if case.source in ("release", "barn-static"):
        worlds = _imported_cached(case.source, str(reference))
        if not worlds:
            return None
        world = worlds[case.world_id]
    elif case.source in ("mixed", "avoid", "yield"):
        world = _generated(case.source, case.world_id)
    else:
        raise DynabarnError(f"golden case {case.key}: unknown world source {case.source!r}")
    try:
        # The robot at worlds_dir/../assets (the repository's layout) in a checkout and in a
        # wheel's cache folder alike: the same bytes, so world_sha256 compares.
        write_world(world, path, asset_root=worlds_dir.parent)
    except OSError as exc:
        raise DynabarnError(f"cannot write the golden set's worlds into {worlds_dir} ({exc.strerror})") from None
    return path


_imported_cached = functools.cache(lambda source, reference: _imported(source, Path(reference)))


# -- running ------------------------------------------------------------------------------


def run_case(case: GoldenCase, world: Path) -> dict:
    """Run one golden episode with a recording; the result row plus `recording_digest`."""
    from dynabarn.planners import read_planner_config
    from dynabarn.protocol import get_protocol
    from dynabarn.recording import message_digest
    from dynabarn.runner import EpisodeSpec, run_spec

    config = read_planner_config(case.config) if case.config else {}
    protocol = get_protocol(case.protocol)
    spec = EpisodeSpec.make(world, case.planner, protocol, config=config, seed=case.seed, sim=case.sim)
    with tempfile.TemporaryDirectory(prefix="dynabarn-golden-") as tmp:
        rec = Path(tmp) / "episode.mcap"
        result = run_spec(spec, record_to=rec).result
        digest = message_digest(rec)
    return {"case": case.key, **result.to_dict(), "recording_digest": digest}


def _run_one(item: tuple[GoldenCase, str]) -> dict:
    case, world = item
    try:
        return run_case(case, Path(world))
    except Exception as exc:  # a broken case is a mismatch to report, not a crash
        return {"case": case.key, "outcome": "error", "reason": f"{type(exc).__name__}: {exc}"}


def run_cases(
    cases: Iterable[GoldenCase], reference: Path, *, jobs: int = 1, worlds_dir: Path = GOLDEN_WORLDS
) -> Iterator[tuple[GoldenCase, dict | None]]:
    """(case, row) for every case, as they finish; row None when its world needs absent
    reference data. Worlds are built first, in this process."""
    cases = list(cases)
    items, skipped = [], []
    for case in cases:
        world = world_file(case, reference, worlds_dir)
        (skipped.append(case) if world is None else items.append((case, str(world))))
    for case in skipped:
        yield case, None
    by_key = {c.key: c for c in cases}
    for row in map_in_workers(_run_one, items, jobs):
        yield by_key[row["case"]], row


# -- comparing ------------------------------------------------------------------------------


def compare(case: str, golden: dict, now: dict) -> list[Mismatch]:
    """Every field that differs (machine fields and versions left out)."""
    keys = sorted((set(golden) | set(now)) - IGNORED_FIELDS)
    return [Mismatch(case, k, golden.get(k), now.get(k)) for k in keys if golden.get(k) != now.get(k)]


def read_golden(path: Path = GOLDEN_FILE) -> dict:
    try:
        data = json.loads(Path(path).read_text())
    except FileNotFoundError:
        raise DynabarnError(f"no golden set at {path}: write one with --update-golden") from None
    except json.JSONDecodeError as exc:
        raise DynabarnError(f"{path}: not valid JSON ({exc})") from None
    if not isinstance(data, dict) or data.get("format") != FORMAT or not isinstance(data.get("episodes"), dict):
        raise DynabarnError(f"{path}: not a golden set (format {FORMAT!r} with episodes)")
    return data


def write_golden(rows: dict[str, dict], path: Path = GOLDEN_FILE) -> Path:
    """Write the golden set atomically (temporary file, fsync, rename)."""
    from dynabarn.provenance import machine, versions

    data = {
        "format": FORMAT,
        "cases": [asdict(c) for c in CASES],
        "versions": versions(),
        "written_on": machine(),
        "episodes": {k: {f: v for f, v in rows[k].items() if f not in MACHINE_FIELDS} for k in sorted(rows)},
    }
    path = Path(path)
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=path.name, suffix=".tmp")
    try:
        with os.fdopen(fd, "w") as f:
            json.dump(data, f, indent=1, sort_keys=True)
            f.write("\n")
            f.flush()
            os.fsync(f.fileno())
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise
    return path


@dataclass
class Verification:
    checked: int
    skipped: list[str]
    mismatches: list[Mismatch]
    version_notes: list[str]

    @property
    def ok(self) -> bool:
        return not self.mismatches


def verify(
    reference: Path = DEFAULT_REFERENCE,
    *,
    jobs: int = 1,
    golden_path: Path = GOLDEN_FILE,
    cases: Sequence[GoldenCase] = CASES,
    progress: Callable[[Iterable, int], Iterable] = lambda it, total: it,
) -> Verification:
    """Re-run the golden set (or some of its cases) and compare with the committed results."""
    from dynabarn.provenance import versions

    golden = read_golden(golden_path)
    episodes = golden["episodes"]
    mismatches, skipped = [], []
    checked = 0
    for case, row in progress(run_cases(cases, reference, jobs=jobs), len(cases)):
        if row is None:
            skipped.append(case.key)
            continue
        checked += 1
        if case.key not in episodes:
            mismatches.append(Mismatch(case.key, "(episode)", None, "not in the golden set: --update-golden"))
            continue
        mismatches.extend(compare(case.key, episodes[case.key], row))
    notes = [
        f"{name} {golden['versions'].get(name)} in the golden set, {v} here"
        for name, v in versions().items()
        if name != "dynabarn" and golden.get("versions", {}).get(name) != v
    ]
    return Verification(checked, skipped, mismatches, notes)


def update(
    reference: Path = DEFAULT_REFERENCE,
    *,
    jobs: int = 1,
    golden_path: Path = GOLDEN_FILE,
    progress: Callable[[Iterable, int], Iterable] = lambda it, total: it,
) -> Path:
    """Run every case and write the golden set; refuses when reference data is missing
    (a golden set must cover every case)."""
    rows, skipped = {}, []
    for case, row in progress(run_cases(CASES, reference, jobs=jobs), len(CASES)):
        if row is None:
            skipped.append(case.key)
        else:
            rows[case.key] = row
    if skipped:
        raise DynabarnError(f"reference data missing under {reference} for {len(skipped)} cases; not writing")
    errors = [k for k, r in rows.items() if r.get("outcome") == "error"]
    if errors:
        raise DynabarnError(f"{len(errors)} golden cases raised ({errors[0]}: {rows[errors[0]].get('reason')})")
    return write_golden(rows, golden_path)
