"""Writing finished files so that nothing finished is ever lost: a crash, a kill or a full
disk at any moment leaves the old file or the new one, never a cut one."""

from __future__ import annotations

import contextlib
import errno
import os
import re
import secrets
import stat
import threading
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import BinaryIO

PLAIN_NAME = re.compile(r"[A-Za-z0-9][A-Za-z0-9._+-]{0,127}")
"""A name that may become part of a file name as it is: letters, digits and `._+-`, not
starting with a dot or dash (no hidden file, no option), at most 128 characters; never a
separator, a `..`, a control character or a NUL."""


def plain_name_problem(text: object) -> str | None:
    """Why `text` is not a plain name (`PLAIN_NAME`), or None when it is one. The one test
    for every name that data or an option gives and that may reach a path (a world's or a
    protocol's `name`, an operator, an imported set's name)."""
    if not isinstance(text, str) or not text:
        return "must be a non-empty string"
    if not PLAIN_NAME.fullmatch(text):
        return (
            "must be a plain name: letters, digits and ._+- (no separators, spaces or control characters),"
            " starting with a letter or digit, at most 128 characters"
        )
    return None


def file_name_part(text: object, fallback: str = "unnamed") -> str:
    """`text` made safe as part of a file name: a plain name is kept as it is; anything else
    (a world name written by an older or a foreign tool) has every run of other characters
    replaced by `_`, leading dots and dashes dropped and its length bounded."""
    text = str(text)
    if PLAIN_NAME.fullmatch(text):
        return text
    safe = re.sub(r"[^A-Za-z0-9._+-]+", "_", text).lstrip("._-")[:128]
    return safe or fallback


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


def check_target(path: Path | str) -> None:
    """A file about to be replaced must be a regular file or absent: a rename over a device
    node (`--log /dev/null` as root), a folder or a FIFO would destroy it or fail late. A
    symbolic link is followed for this check only (a link to a device is refused too); the
    rename then replaces the link, never what it points to."""
    try:
        st = os.stat(path)
    except FileNotFoundError:
        return
    except OSError as exc:  # a dangling or looping link, a path under a file: the write says so
        if exc.errno in (errno.ELOOP, errno.ENOTDIR):
            raise
        return
    if stat.S_ISDIR(st.st_mode):
        raise IsADirectoryError(errno.EISDIR, "a folder is there, not a file", str(path))
    if not stat.S_ISREG(st.st_mode):
        raise OSError(errno.EPERM, "not a regular file (a device, FIFO or socket is never replaced)", str(path))


_NO_FOLLOW = getattr(os, "O_NOFOLLOW", 0) | getattr(os, "O_CLOEXEC", 0)


def create_exclusively(path: Path | str) -> int:
    """A new empty file at `path`, opened for writing: created here and now (`O_EXCL`), never
    through a symbolic link planted at that name (`O_NOFOLLOW`), with the permissions the
    umask gives. FileExistsError when anything is at `path`."""
    return os.open(path, os.O_WRONLY | os.O_CREAT | os.O_EXCL | _NO_FOLLOW, 0o666)


def open_plain(path: Path | str, flags: int, mode: int = 0o666) -> int:
    """`os.open` for a lock or a claim: never through a symbolic link at `path`, and only a
    regular file (not a device, FIFO or socket); OSError (EPERM) saying what is there
    otherwise."""
    try:
        fd = os.open(path, flags | _NO_FOLLOW, mode)
    except OSError as exc:
        if exc.errno == errno.ELOOP:
            raise OSError(errno.EPERM, "a symbolic link is there; not opened through it", str(path)) from None
        raise
    if not stat.S_ISREG(os.fstat(fd).st_mode):
        os.close(fd)
        raise OSError(errno.EPERM, "not a regular file", str(path))
    return fd


def unique_sibling(path: Path, tag: str = "part") -> Path:
    """An unpredictable hidden name beside `path` with its suffix (writers such as ffmpeg
    recognise the format by it): `.NAME.<pid>.<random>.part.SUFFIX`."""
    return path.with_name(f".{path.stem}.{os.getpid()}.{secrets.token_hex(4)}.{tag}{path.suffix}")


def is_same_file(path: Path | str, fd: int) -> bool:
    """`path` is still the file `fd` was created as (nobody swapped a link in meanwhile)."""
    try:
        st = os.lstat(path)
    except OSError:
        return False
    mine = os.fstat(fd)
    return stat.S_ISREG(st.st_mode) and (st.st_dev, st.st_ino) == (mine.st_dev, mine.st_ino)


@contextlib.contextmanager
def staged_path(path: Path | str) -> Iterator[Path]:
    """For writers that take a file name (ffmpeg, rerun): a temporary name beside `path`
    (same suffix, so the format is recognised), made durable and renamed over `path` when
    the block finishes, removed on any error, so `path` holds the old file or a whole new one.

    The temporary file is created here exclusively under an unpredictable name (so nothing
    planted beside `path` is written through), and is renamed only if it is still the file
    created; `path` itself must be a regular file or absent (`check_target`)."""
    path = Path(path)
    check_target(path)
    for _ in range(16):
        part = unique_sibling(path)
        try:
            fd = create_exclusively(part)
            break
        except FileExistsError:
            continue
    else:  # pragma: no cover - 16 collisions of 32 random bits
        raise FileExistsError(errno.EEXIST, "no free temporary name", str(path))
    try:
        yield part
        if not is_same_file(part, fd):
            raise OSError(errno.EPERM, "the temporary file was replaced while it was written", str(part))
        with open(part, "rb") as f:
            os.fsync(f.fileno())
        check_target(path)
        os.replace(part, path)
    except BaseException:
        with contextlib.suppress(OSError):
            if is_same_file(part, fd):
                part.unlink()
        raise
    finally:
        os.close(fd)
    fsync_folder(path.parent)


def claim_staging(path: Path | str, target: Path | str | None = None) -> int:
    """Claim the staging file `path` (a recording's `NAME.mcap.part`) for one writer: a new
    empty regular file, created exclusively and locked (flock) until the returned descriptor
    is closed (`release`). A writer that finds the name taken by a file nobody holds (a killed
    run's leftover) removes it and creates its own; one held by a running writer is refused
    (FileExistsError: one writer per target at a time); a symbolic link or anything but a
    regular file there is refused, never written through.

    Args:
        path: the staging name.
        target: the final name, for the messages (default: `path`)."""
    import fcntl

    shown = str(target if target is not None else path)
    busy = FileExistsError(
        errno.EBUSY, "another run is recording to this file now; wait for it or record elsewhere", shown
    )
    for _ in range(16):
        try:
            fd = create_exclusively(path)
        except FileExistsError:
            try:
                fd = open_plain(path, os.O_RDONLY)  # a link or a device there: refused
            except FileNotFoundError:  # its writer just renamed it: try again
                continue
            try:
                try:
                    fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
                except BlockingIOError:
                    raise busy from None
                if is_same_file(path, fd):  # a killed writer's start: nobody holds it
                    os.unlink(path)
            finally:
                os.close(fd)
            continue
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:  # another writer opened our new file first: it is theirs
            os.close(fd)
            raise busy from None
        return fd
    raise FileExistsError(errno.EBUSY, "the recording's staging name keeps changing under us", shown)


def release(fd: int | None) -> None:
    """Let go of a claim (`claim_staging`): its lock ends with the descriptor."""
    if fd is not None:
        with contextlib.suppress(OSError):
            os.close(fd)


def kept_beside(path: Path, tag: str = "interrupted") -> Path:
    """Where a file that must not replace `path` is kept instead: `NAME.<tag>.SUFFIX`."""
    return path.with_name(f"{path.stem}.{tag}{path.suffix}")


def publish(part: Path | str, path: Path | str, *, replace: bool = True) -> Path:
    """Rename the whole, fsync'ed file `part` to `path` and make that durable; returns where
    it went. `replace=False` (an interrupted episode's recording) never replaces a file at
    `path`: it is kept beside it instead (`kept_beside`), so an interrupted re-run never
    costs a finished file."""
    part, path = Path(part), Path(path)
    check_target(path)
    if not replace:
        try:
            os.link(part, path)  # fails rather than replace what is there
        except FileExistsError:
            path = kept_beside(path)
            check_target(path)
            os.replace(part, path)
        except OSError:  # a file system without hard links: the same test, not atomic
            if os.path.lexists(path):
                path = kept_beside(path)
                check_target(path)
            os.replace(part, path)
        else:
            os.unlink(part)
    else:
        os.replace(part, path)
    fsync_folder(path.parent)
    return path


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


_held: dict[tuple[Path, str], tuple[int, int]] = {}
"""Folder locks this process holds: (folder, lock name) -> (file descriptor, depth)."""


@contextlib.contextmanager
def folder_lock(folder: Path | str, name: str, *, busy: str) -> Iterator[None]:
    """Hold `folder/name` (flock) while this process writes in `folder`: one writer at a time
    (a sweep's results, a world set's index.json). A second writer, in another process, is
    refused at once with `busy` (`{folder}` and `{pid}`, the holder's, filled in) as a
    `DynabarnError`. Re-entrant in a process; the lock file is never opened through a link
    and is removed when the last holder is done."""
    import fcntl

    from dynabarn.errors import DynabarnError

    folder = Path(folder).resolve()
    key = (folder, name)
    # A read-only folder, a missing parent: one line, as any write there would give.
    if key in _held:
        fd, depth = _held[key]
        _held[key] = (fd, depth + 1)
        try:
            yield
        finally:
            fd, depth = _held[key]
            _held[key] = (fd, depth - 1)
        return
    try:
        folder.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise DynabarnError(f"cannot write in {folder}: {exc.strerror or exc}") from None
    path = folder / name
    while True:
        try:  # never through a link planted at the name, never a device or FIFO there
            fd = open_plain(path, os.O_RDWR | os.O_CREAT, 0o644)
        except OSError as exc:
            if exc.errno == errno.EPERM:
                why = f"{path}: {exc.strerror}; the lock is a plain file (remove what is there)"
                raise DynabarnError(why) from None
            raise DynabarnError(f"cannot write in {folder}: {exc.strerror or exc}") from None
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            holder = os.pread(fd, 32, 0).decode(errors="replace").strip() or "?"
            os.close(fd)
            raise DynabarnError(busy.format(folder=folder, pid=holder)) from None
        # The holder before us removes the file when it is done: a lock on a file that is no
        # longer at the path guards nothing, so take the one that is there now.
        try:
            if os.stat(path).st_ino == os.fstat(fd).st_ino:
                break
        except FileNotFoundError:
            pass
        os.close(fd)
    try:
        # Who holds it, for the message a second writer gets; a courtesy that a full disk
        # (a new file has no block to write into) must not turn into a lock never released.
        with contextlib.suppress(OSError):
            os.ftruncate(fd, 0)
            os.pwrite(fd, f"{os.getpid()}\n".encode(), 0)
        _held[key] = (fd, 1)
        yield
    finally:
        _held.pop(key, None)
        with contextlib.suppress(FileNotFoundError):
            path.unlink()  # still holding it: nothing stays behind in the folder
        fcntl.flock(fd, fcntl.LOCK_UN)
        os.close(fd)
