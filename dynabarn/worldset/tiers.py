"""Tiers as world sets on disk: generated into `generated_tiers/NAME/` (on first use too),
each world in the draw its committed certificates chose, with those certificates."""

from __future__ import annotations

import contextlib
import hashlib
import json
import os
import secrets
import shutil
from collections.abc import Callable, Mapping
from pathlib import Path

from dynabarn.errors import WorldError
from dynabarn.files import write_atomically
from dynabarn.provenance import work_root
from dynabarn.worlds.tiers import Tier, get_tier
from dynabarn.worldset import INDEX_NAME, generate_profile_worlds, index_locked, read_index

TIERS_FOLDER = "generated_tiers"
"""Where the tiers' worlds are generated, under the work root (the checkout, or the cache)."""


def generate_tier(
    name: str | Tier,
    out_dir: Path | None = None,
    *,
    draws: Mapping[int, int] | None = None,
    progress: Callable = lambda it: it,
) -> Path:
    """Write tier NAME's worlds (`worlds.tiers`) to `out_dir` (default: its folder under the
    work root), each world in the draw its committed certificates chose (`draws` instead:
    those, without certificates); returns the index path. The same bytes on every run and
    machine."""
    tier = get_tier(name)  # resolved once: what follows is handed the tier
    profile = tier.profile()
    record = tier.certified()
    out = Path(out_dir) if out_dir is not None else tier_dir(tier)
    # In the tiers' own folder (and its staging siblings) the robot is the work root's, as
    # in the checkout: the same bytes in a checkout and in an installed package's cache, so
    # the committed certificates' digests hold in both.
    home = tier_dir(tier).parent
    inside = out.resolve().parent == home.resolve()
    with index_locked(out):  # the worlds and their certificates as one write
        index = generate_profile_worlds(
            profile,
            out,
            base_seed=tier.base_seed,
            world_ids=tier.ids,
            profile_source=tier_source(tier),
            draws=tier.draws() if draws is None else draws,
            asset_root=home.parent if inside else None,
            progress=progress,
        )
        if record and draws is None:
            attach_certificates(out, record)
    return index


def attach_certificates(index_dir: Path, record: dict) -> None:
    """Put a tier's committed certificates (`worlds.tiers.Tier.certified`) into its index,
    each on the world whose file has the bytes it was computed for."""
    with index_locked(index_dir):
        _attach_certificates(index_dir, record)


def _attach_certificates(index_dir: Path, record: dict) -> None:
    index = read_index(index_dir)
    by_id = record.get("certificates", {})
    for entry in index["worlds"]:
        for protocol, certificate in by_id.get(str(entry["id"]), {}).items():
            if certificate.get("sha256") == entry["sha256"]:
                entry.setdefault("certificates", {})[protocol] = certificate
    index["certification"] = record.get("certification", {})
    write_atomically(Path(index_dir) / INDEX_NAME, json.dumps(index, indent=1, sort_keys=True) + "\n")


def tier_source(name: str | Tier) -> dict:
    """What a tier's folder was made from, as its index records it: the tier, its profile
    file (name, sha256) and the sha256 of its committed certificates (None before): a folder
    made from anything else is stale (`tier_worlds`)."""
    tier = get_tier(name)
    try:
        certified = hashlib.sha256(tier.certified_file.read_bytes()).hexdigest()
    except FileNotFoundError:
        certified = None
    return {"tier": tier.name, **tier.profile().source, "certified": certified}


def tier_dir(name: str | Tier) -> Path:
    return work_root() / TIERS_FOLDER / get_tier(name).name


def tier_worlds(name: str | Tier) -> Path:
    """Tier NAME's folder, its worlds generated there first when absent or made from an
    older definition or older certificates (a few seconds):
    into a folder of this process's own, renamed into place whole, so that workers starting
    together never read a half-written tier (the first rename wins; the others' copies,
    the same bytes, are removed)."""
    tier = get_tier(name)
    folder = tier_dir(tier)
    if _current(folder, tier):
        return folder
    token = f"{os.getpid()}.{secrets.token_hex(4)}"
    staging, stale = folder.with_name(f".{folder.name}.{token}"), folder.with_name(f".{folder.name}.stale.{token}")
    try:
        generate_tier(tier, staging)
        if folder.exists() and not _current(folder, tier):  # made from an older definition
            with contextlib.suppress(OSError):  # another process moved it first
                folder.rename(stale)
        try:
            staging.rename(folder)
        except OSError:
            if not _current(folder, tier):
                raise
    finally:
        shutil.rmtree(staging, ignore_errors=True)
        shutil.rmtree(stale, ignore_errors=True)
    return folder


def _current(folder: Path, tier: Tier) -> bool:
    """Whether `folder` holds `tier` as its definition and certificates make it now."""
    try:
        return read_index(folder).get("profile_source") == tier_source(tier)
    except WorldError:
        return False
