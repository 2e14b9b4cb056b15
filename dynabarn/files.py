"""Writing finished files so that nothing finished is ever lost: a crash, a kill or a full
disk at any moment leaves the old file or the new one, never a cut one."""

from __future__ import annotations

import contextlib
import os
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
