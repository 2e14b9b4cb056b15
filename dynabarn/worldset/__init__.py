"""World sets on disk: the 300 generated worlds with their `index.json`, and imports.

`generate_worlds` writes `world_000.xml` ... `world_299.xml` and `index.json` (id,
difficulty, count, profile, seed, file hash, and the named subsets such as `paper60`).
Everything written is a pure function of (profile set, base seed), so `make worlds`
reproduces the committed files byte for byte.
"""

from __future__ import annotations

import json
import re
from collections.abc import Callable, Iterable, Mapping
from pathlib import Path

from dynabarn.errors import WorldError
from dynabarn.files import write_atomically
from dynabarn.mjcf import write_world
from dynabarn.provenance import WORLDS_ENV, worlds_dir
from dynabarn.worlds.difficulty import difficulty_scores
from dynabarn.worlds.generate import DEFAULT_BASE_SEED, N_WORLDS, PAPER60, branch_of, generate_world
from dynabarn.worlds.profile_file import GenerationProfile
from dynabarn.worlds.profiles import Difficulty, ProfileSet, ShapeMix, StaticField, difficulty_of, get_profile_set
from dynabarn.worlds.spec import SCRIPTED, EndBehavior, Interpolation, WorldSpec
from dynabarn.worlds.tiers import TIERS
from dynabarn.worldset.integrity import (
    INDEX_NAME,
    certificate_problem,
    check_listed_bytes,
    check_not_foreign,
    index_locked,
)


def _entry(world: WorldSpec, file: str, sha256: str) -> dict:
    return {
        "id": world.world_id,
        "name": world.name,
        "file": file,
        "difficulty": world.difficulty.value,
        "count_class": world.count_class.value if world.count_class else None,
        "motion_class": world.motion_class.value if world.motion_class else None,
        "n_obstacles": len(world.obstacles),
        **({"n_static": len(world.layout.cylinders)} if world.layout.cylinders else {}),
        **(
            {"shapes": sorted({o.shape for o in world.obstacles})}
            if any(o.shape != "cylinder" for o in world.obstacles)
            else {}
        ),
        "profiles": sorted({o.trajectory.profile for o in world.obstacles}),
        "profile_set": world.profile_set,
        "seed": world.seed,
        "interpolation": world.interpolation.value,
        "end_behavior": world.end_behavior.value,
        "sha256": sha256,
        "measured": difficulty_scores(world),
        **({"draw": world.provenance["draw"]} if world.provenance.get("draw") else {}),
    }


def own_certificates(entry: dict) -> dict[str, dict]:
    """An index entry's certificates by protocol, those computed for the bytes its file has
    (a record names the sha256 it was computed for; any other is ignored) and that agree with
    their own trials (`certificate_problem`; `certify --verify` names the others)."""
    records = entry.get("certificates")
    if not isinstance(records, dict):
        return {}
    return {
        protocol: record
        for protocol, record in records.items()
        if isinstance(record, dict)
        and record.get("sha256") == entry.get("sha256")
        and certificate_problem(record) is None
    }


def write_index(out_dir: Path, entries: list[dict], *, meta: dict, sets: dict[str, list[int]]) -> Path:
    """Write the index; certificates already in the folder's index are kept for the worlds
    whose files are still the same bytes (`bench.certify`: computing them takes minutes)."""
    meta = {**meta, **_kept_certificates(Path(out_dir), entries)}
    # The format tag goes last: `meta` must not override it.
    index = {**meta, "format": "dynabarn-index", "format_version": 1, "sets": sets, "worlds": entries}
    path = Path(out_dir) / INDEX_NAME
    write_atomically(path, json.dumps(index, indent=1, sort_keys=True) + "\n")
    return path


def _kept_certificates(out_dir: Path, entries: list[dict]) -> dict:
    """Copy into `entries` the certificates the folder's current index holds for the same
    files (by sha256); the index's `certification` facts when any were kept."""
    try:
        old = read_index(out_dir)
    except WorldError:
        return {}
    by_file = {e.get("file"): e for e in old["worlds"]}
    kept = False
    for entry in entries:
        before = by_file.get(entry["file"], {})
        certificates = own_certificates({**before, "sha256": entry["sha256"]})
        if certificates:
            entry["certificates"] = certificates
            kept = True
    return {"certification": old["certification"]} if kept and "certification" in old else {}


def write_worlds(
    worlds: Iterable[WorldSpec],
    out_dir: Path,
    *,
    meta: dict,
    sets: dict[str, list[int]],
    asset_root: Path | None = None,
    progress: Callable[[Iterable], Iterable] = lambda it: it,
    force: bool = False,
) -> Path:
    """Write each world as `<name>.xml` in `out_dir` and the index; returns the index path.
    `asset_root`: where the robot the worlds name is (default: `mjcf.asset_root_for`).
    A file there that the folder's index does not list is never replaced unless `force`
    (`check_not_foreign`); the set's index lock is held throughout (`index_locked`)."""
    out_dir = Path(out_dir)
    worlds = list(progress(worlds))  # drawn first (the time goes here): their names are checked before any write
    if not force:
        check_not_foreign(out_dir, [f"{world.name}.xml" for world in worlds], read_index)
    out_dir.mkdir(parents=True, exist_ok=True)
    with index_locked(out_dir):
        entries = []
        for world in worlds:
            file = f"{world.name}.xml"
            sha = write_world(world, out_dir / file, asset_root=asset_root)
            entries.append(_entry(world, file, sha))
        return write_index(out_dir, entries, meta=meta, sets=sets)


def generate_worlds(
    profile_set: ProfileSet,
    out_dir: Path,
    *,
    base_seed: int = DEFAULT_BASE_SEED,
    world_ids: Iterable[int] = range(N_WORLDS),
    interpolation: str = "linear",
    end_behavior: str = "loop",
    shapes: ShapeMix | None = None,
    static_field: StaticField | None = None,
    behavior: str = SCRIPTED,
    behavior_params: Mapping[str, float] | None = None,
    profile_source: Mapping | None = None,
    draws: Mapping[int, int] | None = None,
    asset_root: Path | None = None,
    progress: Callable[[Iterable], Iterable] = lambda it: it,
    force: bool = False,
) -> Path:
    """Generate and write the benchmark's worlds; returns the index path.

    `profile_source` (a user's profile: the file's name and sha256, or the options that
    made it) is recorded in `index.json` beside the profile set.

    `shapes`, `static_field` and `behavior` make the variants beyond the paper (obstacle
    shapes, mixed static and moving worlds, reactive obstacles); the motions stay those of
    the plain worlds. `draws` {id: k} redraws world id for the k-th time (a tier's worlds
    that were not certified solvable: `worlds.generate.world_rng`)."""
    ids = list(world_ids)
    draws = {int(i): int(k) for i, k in (draws or {}).items() if k}
    worlds = (
        generate_world(
            i,
            profile_set,
            base_seed=base_seed,
            interpolation=Interpolation(interpolation),
            end_behavior=EndBehavior(end_behavior),
            shapes=shapes,
            static_field=static_field,
            behavior=behavior,
            behavior_params=behavior_params,
            draw=draws.get(i, 0),
        )
        for i in ids
    )
    sets = {
        "all": ids,
        "paper60": [i for i in PAPER60 if i in ids],
        **{d.value: [i for i in ids if difficulty_of(*branch_of(i)) is d] for d in Difficulty},
    }
    meta = {"generator": "dynabarn", "profile_set": profile_set.to_dict(), "base_seed": base_seed}
    if profile_source is not None:
        meta["profile_source"] = dict(profile_source)
        if profile_set.description:
            meta["profile_description"] = profile_set.description
    if shapes is not None and not shapes.cylinders_only:
        meta["shapes"] = shapes.to_dict()
    if static_field is not None:
        meta["static_field"] = static_field.to_dict()
    if behavior != SCRIPTED:
        meta["behavior"] = behavior
    if draws:
        meta["draws"] = {str(i): k for i, k in sorted(draws.items())}
    return write_worlds(worlds, out_dir, meta=meta, sets=sets, asset_root=asset_root, progress=progress, force=force)


def generate_profile_worlds(
    profile: GenerationProfile,
    out_dir: Path,
    *,
    behavior_params: Mapping[str, float] | None = None,
    **options,
) -> Path:
    """`generate_worlds` with everything a `GenerationProfile` says: its profile set, shapes,
    static field and behaviour, with `behavior_params` (default: the profile's own) and the
    rest of `generate_worlds`' options."""
    return generate_worlds(
        profile.profile_set,
        out_dir,
        shapes=profile.shapes,
        static_field=profile.static_field,
        behavior=profile.behavior,
        behavior_params=profile.behavior_params if behavior_params is None else behavior_params,
        **options,
    )


MAX_INDEX_WORLDS = 100_000
"""Worlds an index may list (the shipped set has 300; every one is checked when read)."""
MAX_INDEX_BYTES = 256 * 1024 * 1024


def read_index(path_or_dir: Path | str | None = None) -> dict:
    """A folder's (or a file's) world index; default: the current world set (`worlds_dir`)."""
    p = Path(path_or_dir) if path_or_dir is not None else worlds_dir()
    if p.is_dir():
        p = p / INDEX_NAME
    if not p.is_file():
        raise WorldError(f"no world index at {p}")
    if p.stat().st_size > MAX_INDEX_BYTES:
        raise WorldError(f"{p}: {p.stat().st_size / 1e6:.0f} MB is larger than a world index can be")
    try:
        index = json.loads(p.read_text())
    except (ValueError, RecursionError) as exc:
        raise WorldError(f"{p}: index is not valid JSON ({type(exc).__name__})") from None
    if not isinstance(index, dict) or index.get("format") != "dynabarn-index":
        raise WorldError(f"{p}: not a dynabarn world index")
    worlds = index.get("worlds")
    if not isinstance(worlds, list):
        raise WorldError(f"{p}: index has no list of worlds")
    if len(worlds) > MAX_INDEX_WORLDS:
        raise WorldError(f"{p}: {len(worlds):,} worlds; an index holds at most {MAX_INDEX_WORLDS:,}")
    seen: set[int] = set()
    for e in worlds:
        if not (isinstance(e, dict) and type(e.get("id")) is int and isinstance(e.get("difficulty"), str | None)):
            raise WorldError(f"{p}: every world entry needs an integer id, a file and a difficulty")
        if e["id"] in seen:
            raise WorldError(f"{p}: world id {e['id']} appears twice")
        seen.add(e["id"])
        entry_path(p.parent, e)  # a file name inside the folder, nothing else
    return index


def entry_path(index_dir: Path, entry: dict) -> Path:
    """An index entry's world file: a plain file name inside the index's folder (an entry
    cannot point elsewhere, e.g. "../../etc/passwd")."""
    file = entry.get("file")
    if (
        not isinstance(file, str)
        or not file
        or file in (".", "..")
        or "\x00" in file
        or Path(file).name != file
        or "\\" in file
    ):
        raise WorldError(f"{index_dir / INDEX_NAME}: world file {file!r} must be a file name inside the folder")
    path = Path(index_dir) / file
    if path.is_symlink():  # a link is a way out of the folder too
        raise WorldError(f"{index_dir / INDEX_NAME}: world file {file!r} is a symbolic link; worlds are plain files")
    return path


_WORLD_NAME = re.compile(r"(?:world_)?(\d{1,6})(?:\.xml)?")


def resolve_world(id_or_path: str | int | Path, set_name: str | None = None) -> Path:
    """A world by id or name ("137", "world_137", "world_137.xml") in the set `set_name`
    (`--set`: paper60, dynabarn300, a tier, a folder with index.json; default: the current
    set, $DYNABARN_WORLDS or the shipped 300), or the path of a world file, to an existing
    world file. A path that exists wins where no set is named."""
    s = str(id_or_path).strip()
    match = _WORLD_NAME.fullmatch(s)
    if set_name is not None:
        if match is None:
            raise WorldError(f"--world {s!r}: with --set, a world id or name (210, world_210), not a path")
        return Path(world_set(set_name, [int(match[1])])[0][1])
    path = Path(s)
    if path.is_file():
        return path
    if match:
        folder = worlds_dir()
        path = folder / f"world_{int(match[1]):03d}.xml"
        if not path.is_file():
            raise WorldError(
                f"unknown world id {s}: no {path.name} in {folder} (ids of the paper's set are 0-299; "
                f"${WORLDS_ENV} names another set)"
            )
        return path
    raise WorldError(f"world not found: {s} (give a world id 0-299, a name like world_137, or a world .xml path)")


MAX_WORLD_ID = 999_999


def parse_ids(text: str | None) -> list[int] | None:
    """'0,5,100-119' -> [0, 5, 100, ..., 119], each id once, in the order first given; None
    (every world) only when no --worlds was given: an empty one selects nothing, so it is
    refused rather than read as "all"."""
    if text is None:
        return None
    if not text.strip():
        raise WorldError("--worlds is empty: give ids and ranges like 0,5,100-119, or leave it out for every world")
    ids: dict[int, None] = {}
    for part in text.split(","):
        part = part.strip()
        lo, sep, hi = part.partition("-")
        try:
            first, last = (int(lo), int(hi)) if sep else (int(part), int(part))
        except ValueError:
            raise WorldError(f"bad --worlds item {part!r}: use ids and ranges like 0,5,100-119") from None
        if not 0 <= first <= last <= MAX_WORLD_ID:
            raise WorldError(f"bad --worlds item {part!r}: ids are 0-{MAX_WORLD_ID}, ranges go upwards")
        ids.update(dict.fromkeys(range(first, last + 1)))
    return list(ids)


PAPER_SET = "paper60"
"""The index set of the worlds whose provenance is the paper's."""


def paper_world_ids(index: dict) -> set[int]:
    """Ids of an index's worlds whose provenance is the paper's, the only ones compared with
    the paper's Fig. 5: the `paper60` subset of worlds generated with the paper's Table I
    profiles (all of them, not a user's profile of the same name) and nothing beyond the
    paper (shapes, static fields, behaviours), or imported
    worlds the importer recognised as the release's (it lists them as `paper60`)."""
    ids = set(index.get("sets", {}).get(PAPER_SET, []))
    generator = index.get("generator")
    if generator == "dynabarn import":
        return ids
    profile_set = index.get("profile_set")
    plain = not any(k in index for k in ("shapes", "static_field", "behavior", "profile_source"))
    if generator == "dynabarn" and plain and profile_set == get_profile_set("table1").to_dict():
        return ids
    return set()


def set_folder(name: str) -> tuple[Path, list[int] | None]:
    """The folder of world set `name` (`paper60`, `dynabarn300`, a tier, generated on first
    use, or a folder/index.json) and the ids the name selects there (None: all)."""
    if name in ("paper60", "dynabarn300"):
        return worlds_dir(), list(PAPER60) if name == "paper60" else list(range(300))
    if name in TIERS:
        from dynabarn.worldset.tiers import tier_worlds

        return tier_worlds(name), None
    p = Path(name)
    index_dir = p.parent if p.name == INDEX_NAME else p
    if not (index_dir / INDEX_NAME).is_file():
        from dynabarn.errors import unknown_choice

        named = ["paper60", "dynabarn300", *TIERS]
        raise WorldError(f"{unknown_choice('world set', name, named)}, or a folder with {INDEX_NAME}")
    return index_dir, None


def world_set(name: str, ids: list[int] | None = None) -> list[tuple[int, str, str]]:
    """(world id, file, difficulty) for `paper60`, `dynabarn300`, a tier (`worlds.tiers`,
    generated on first use) or a folder/index.json."""
    index_dir, chosen = set_folder(name)
    index = read_index(index_dir)  # checks the format tag; one clear line when malformed
    entries = {e["id"]: e for e in index["worlds"]}
    chosen = chosen if chosen is not None else sorted(entries)
    if ids is not None:
        missing = sorted(set(ids) - set(entries))
        if missing:
            raise WorldError(f"world id(s) {missing[:5]} not in set {name!r}")
        chosen = [i for i in chosen if i in set(ids)] if name == "paper60" else ids
        if not chosen:
            raise WorldError(f"none of the world ids {ids[:5]} is in set {name!r} (dynabarn300 has all 300)")
    found = [(i, entry_path(index_dir, entries[i]), entries[i]) for i in chosen]
    for _, path, entry in found:
        check_listed_bytes(path, entry)
    return [(i, str(path), entry["difficulty"]) for i, path, entry in found]
