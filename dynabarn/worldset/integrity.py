"""A world set's integrity: one writer of its `index.json` at a time, no file replaced that
the set did not write, world files that are the bytes the index lists, certificates that
agree with their own trials. An index is someone else's file too: each check is one
`WorldError` line."""

from __future__ import annotations

import contextlib
from collections.abc import Callable, Iterable, Iterator
from pathlib import Path

from dynabarn.errors import WorldError
from dynabarn.files import folder_lock

INDEX_NAME = "index.json"
"""A set's index, in its folder: every world's file, sha256, difficulty and certificates."""
INDEX_LOCK = ".index.lock"
"""Held (flock) by whatever writes a set's index.json: generate, import, certify."""


@contextlib.contextmanager
def index_locked(folder: Path | str) -> Iterator[None]:
    """One writer per set: hold the set's index lock while reading, changing and writing its
    index.json (and world files), so two runs at once never lose one's work: the second is
    refused with one line. Re-entrant in a process."""
    busy = (
        "{folder}: another dynabarn-worlds (pid {pid}) is writing this set's index.json now; "
        "wait for it to finish (two writers at once would lose one's work)"
    )
    with folder_lock(folder, INDEX_LOCK, busy=busy):
        yield


def check_not_foreign(out_dir: Path, files: Iterable[str], read_index: Callable[[Path], dict]) -> None:
    """Refuse to replace what this package did not write: a file among `files` that is in
    `out_dir` but not listed by the folder's own index.json as `read_index` reads it (or any
    such file when the folder's index.json is not ours). One `WorldError` line naming it
    (`--force` writes anyway)."""
    out_dir = Path(out_dir)
    if not out_dir.is_dir():
        return
    try:
        listed = {e["file"] for e in read_index(out_dir)["worlds"]} | {INDEX_NAME}
    except WorldError:
        listed = set()  # no index of ours: nothing there was written by us
    clash = [f for f in (*files, INDEX_NAME) if f not in listed and (out_dir / f).exists()]
    if clash:
        more = f" and {len(clash) - 1} more" if len(clash) > 1 else ""
        raise WorldError(
            f"{out_dir / clash[0]}{more}: not written by dynabarn (the folder's index.json does not list it) and would "
            "be replaced; choose another --out, or give --force to replace it"
        )


def certificate_problem(record: object) -> str | None:
    """Why a world's certificate record is not one `certify` writes, or None: its trials a
    list of {seed: whole number, certified: true or false}, its world-level `certified` and
    `certified_trials` what those trials say (an index is someone else's file too)."""
    if not isinstance(record, dict):
        return "not an object"
    trials = record.get("trials")
    if not isinstance(trials, list) or not trials:
        return "no trials"
    for t in trials:
        if not isinstance(t, dict) or not isinstance(t.get("certified"), bool):
            return "a trial without a certified flag"
        if not isinstance(t.get("seed"), int) or isinstance(t.get("seed"), bool):
            return "a trial without a whole-number seed"
    if record.get("certified") is not all(t["certified"] for t in trials):
        return f"certified {record.get('certified')!r} contradicts its trials"
    count = record.get("certified_trials")
    if isinstance(count, bool) or count != sum(t["certified"] for t in trials):
        return f"certified_trials {count!r} contradicts its trials"
    return None


def check_listed_bytes(path: Path, entry: dict) -> None:
    """A world file holds the bytes its index entry lists (`sha256`): a file swapped for
    another's, or edited since, is one `WorldError` line, never a sweep of other worlds
    under this set's name."""
    from dynabarn.world_file import MAX_WORLD_BYTES, world_sha256

    try:
        digest = world_sha256(path)
    except OSError as exc:
        raise WorldError(f"{path}: cannot read the world file ({exc.strerror or exc})") from None
    if digest is None:
        raise WorldError(f"{path}: larger than {MAX_WORLD_BYTES >> 20} MiB or not a regular file; not a world file")
    if digest != entry.get("sha256"):
        raise WorldError(
            f"{path}: not the bytes its index.json lists (sha256 differs): the file was replaced or edited since the "
            "set was written; generate or import the set again (a tier's folder: remove it, it is made anew)"
        )
