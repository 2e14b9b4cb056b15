"""Writing finished files so that nothing finished is ever lost: a crash, a kill or a full
disk at any moment leaves the old file or the new one, never a cut one."""

from __future__ import annotations

import contextlib
import os
import threading
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import BinaryIO


def fsync_folder(folder: Path) -> None:
    """Make a rename in `folder` durable (POSIX; a no-op where folders cannot be opened)."""
    try:
        fd = os.open(folder, os.O_RDONLY)
    except OSError:
        return
    try:
        os.fsync(fd)
    except OSError:
        pass
    finally:
        os.close(fd)


@contextlib.contextmanager
def staged_path(path: Path | str) -> Iterator[Path]:
    """For writers that take a file name (ffmpeg, rerun): a temporary name beside `path`
    (same suffix, so the format is recognised), made durable and renamed over `path` when
    the block finishes, removed on any error, so `path` holds the old file or a whole new one."""
    path = Path(path)
    part = path.with_name(f".{path.stem}.{os.getpid()}.part{path.suffix}")
    try:
        yield part
        with open(part, "rb") as f:
            os.fsync(f.fileno())
        os.replace(part, path)
    except BaseException:
        part.unlink(missing_ok=True)
        raise
    fsync_folder(path.parent)


@contextlib.contextmanager
def atomic_file(path: Path | str) -> Iterator[BinaryIO]:
    """Write `path` through a temporary file beside it (`staged_path`): flushed, fsync'ed and
    renamed over `path` only when the block finishes; on any error the temporary file is
    removed and `path` is untouched."""
    with staged_path(path) as part, open(part, "wb") as f:
        yield f


def write_atomically(path: Path | str, data: bytes | str) -> None:
    """`path` now holds `data` (text is written as UTF-8), or, after a failure, what it held."""
    with atomic_file(path) as f:
        f.write(data.encode() if isinstance(data, str) else data)


def save_atomically(path: Path | str, save: Callable[[BinaryIO], object]) -> None:
    """For writers that take a file object (matplotlib's savefig, torch.save, numpy.savez)."""
    with atomic_file(path) as f:
        save(f)


_datasync = getattr(os, "fdatasync", os.fsync)  # macOS has no fdatasync


class SyncAhead:
    """Writes a growing file's pages to disk from a thread while it is written (`poke` after
    each piece), so the fsync that finishes it has little left to write: that one is waited
    for (3.5 ms for a 100 s episode's recording written at once, under 1 ms after this).
    Syncing early changes nothing of what the file holds or when it is whole, so a file that
    cannot be opened again (gone, renamed) is simply not synced ahead: the final fsync is
    what reports a problem.

    Args:
        path: the file (already created).
    """

    def __init__(self, path: Path | str) -> None:
        self._wanted = threading.Event()
        self._lock = threading.Lock()
        self._thread: threading.Thread | None = None
        try:
            self._fd: int | None = os.open(path, os.O_RDONLY)
        except OSError:
            self._fd = None
            return
        self._thread = threading.Thread(target=self._run, name="sync-ahead", daemon=True)
        self._thread.start()

    def poke(self) -> None:
        """More was written: sync it when the thread is free (pokes meanwhile coalesce)."""
        self._wanted.set()

    def _run(self) -> None:
        while True:
            self._wanted.wait()
            with self._lock:
                if self._fd is None:
                    return
                self._wanted.clear()
                with contextlib.suppress(OSError):  # a failed early sync: the final fsync reports it
                    _datasync(self._fd)

    def close(self) -> None:
        """Stop (after a sync under way) and let go of the file."""
        with self._lock:
            if self._fd is not None:
                os.close(self._fd)
                self._fd = None
        self._wanted.set()
        if self._thread is not None:
            self._thread.join()
