"""`BackgroundRecorder`: the MCAP recorder in a writer process beside the episode.

Encoding an episode's messages (protobuf and JSON) and compressing them cost the runner
about as much as the episode itself (docs/speed.md). Here the episode's process only
copies each period's numbers into a buffer, and a writer process (a fresh interpreter,
started once per process and reused) makes the Ticks from them and runs the same
`McapRecorder`: the file is the one the recorder in the episode's process writes, byte
for byte (the golden set and a test compare them), written on the other core.

What crosses: the episode's start (pickled once), then per tick one row of float64
numbers (`tick_rows.TickRows`), sent in batches of up to `BATCH` ticks with the robot's poses of
those ticks' periods (taken from the episode's pose buffer once per batch, and how many
each tick has); a tick's debug dictionary or tracks, of any shape, are pickled beside the
rows when there are any. `on_end` sends the result and waits until the writer has closed and renamed the
file, so the recording is whole when the episode returns, as with `McapRecorder`. A file
that cannot be opened fails in `on_start` (`McapRecorder`'s checks, made here); an error
of the writer's while writing is raised by `on_end`; a writer that dies mid-episode stops
the recording (`stopped` says why) and the episode goes on. The writer exits when its
parent does (its pipe closes).
"""

from __future__ import annotations

import atexit
import contextlib
import fcntl
import importlib
import os
import pickle
import struct
import subprocess
import sys
import threading
from pathlib import Path

import numpy as np

from dynabarn.files import SyncAhead, claim_staging, release
from dynabarn.interfaces.events import EpisodeObserver, EpisodeStart, Period, Tick
from dynabarn.metrics import EpisodeResult
from dynabarn.recording.tick_rows import TickRows
from dynabarn.recording.topic_registry import run_time_topics
from dynabarn.recording.writer import McapRecorder, staging_path

_NO_STEPS = np.zeros(0, dtype=np.int64)
_WRITER_DIED = "the recording's writer process ended; the recording ends there (what it wrote is in NAME.mcap.part)"
BATCH = 64
"""Ticks per message to the writer at most: one pipe write per 6.4 s of simulated time
(each write wakes the writer and costs the episode far more than its bytes: batches of 8
cost a 100 s episode 10 ms more than batches of 32, and 64 saved 3 ms more)."""
FIRST_BATCH = 4
"""Ticks of an episode's first message; each next one twice as many, up to BATCH: a short
episode's rows are written while it runs, not all after it ended."""
PIPE_BYTES = 1 << 20
"""The pipe's buffer (Linux's unprivileged maximum): two and a half batches of a
720-beam scan (6 KB a tick), so that a writer still encoding the last one never holds the
episode up."""
F_SETPIPE_SZ = getattr(fcntl, "F_SETPIPE_SZ", 1031)  # Linux's; elsewhere the call fails and the default stays


# -- the pipe: length-prefixed pickles ------------------------------------------------------
_HEADER = struct.Struct("<Q")


def _send(stream, message) -> None:
    data = pickle.dumps(message, protocol=pickle.HIGHEST_PROTOCOL)
    stream.write(_HEADER.pack(len(data)))
    stream.write(data)


def _read_exactly(stream, n: int) -> bytes:
    data = stream.read(n)
    if len(data) < n:
        raise EOFError
    return data


def _receive(stream):
    (size,) = _HEADER.unpack(_read_exactly(stream, _HEADER.size))
    return pickle.loads(_read_exactly(stream, size))


class _Writer:
    """One writer process (`python -m dynabarn.recording.background`), reused episode after
    episode: a fresh interpreter, so a script without a `__main__` guard is never re-run."""

    def __init__(self) -> None:
        # The writer imports this package from where this process found it (a source tree on
        # sys.path, a test's installed topics), and any module a pickled value names.
        # Safe-path mode (-P, PYTHONSAFEPATH): the current folder is never searched, so a
        # `numpy.py` or `dynabarn/` where the user runs a command is never imported.
        env = dict(os.environ, PYTHONPATH=os.pathsep.join(p for p in sys.path if p), PYTHONSAFEPATH="1")
        command = [sys.executable, "-P", "-m", "dynabarn.recording.background"]
        self.process = subprocess.Popen(command, stdin=subprocess.PIPE, stdout=subprocess.PIPE, env=env)
        with contextlib.suppress(OSError):  # room for many batches: the episode never waits on a busy writer
            fcntl.fcntl(self.process.stdin.fileno(), F_SETPIPE_SZ, PIPE_BYTES)

    def alive(self) -> bool:
        return self.process.poll() is None

    def send(self, message, *raw: memoryview) -> None:
        _send(self.process.stdin, message)
        for block in raw:
            self.process.stdin.write(block)
        self.process.stdin.flush()

    def ask(self, message):
        self.send(message)
        return _receive(self.process.stdout)

    def close(self) -> None:
        """End the writer (its pipe closed: it exits), waiting briefly."""
        with contextlib.suppress(OSError):
            self.process.stdin.close()
        try:
            self.process.wait(timeout=5)
        except subprocess.TimeoutExpired:
            self.process.kill()
            self.process.wait()


_IDLE: list[_Writer] = []
_LOCK = threading.Lock()


@atexit.register
def _close_idle() -> None:
    """At exit the idle writers end with this process (a busy one ends when its pipe closes)."""
    with _LOCK:
        writers, _IDLE[:] = list(_IDLE), []
    for w in writers:
        w.close()


def _take_writer() -> _Writer:
    with _LOCK:
        while _IDLE:
            w = _IDLE.pop()
            if w.alive():
                return w
    return _Writer()


def _give_back(w: _Writer) -> None:
    with _LOCK:
        _IDLE.append(w)


class BackgroundRecorder(EpisodeObserver):
    """`McapRecorder`'s file, written by a writer process (see the module docstring).

    Args: as `McapRecorder` (`path`, `chunk_size`, `extra_channels`, `extra_metadata`),
    without live contexts (a live view streams from the episode's process)."""

    def __init__(self, path: Path | str, **recorder_options) -> None:
        if "live" in recorder_options:
            raise TypeError("BackgroundRecorder has no live contexts; use McapRecorder")
        self.path = Path(path)
        self.staging = staging_path(self.path)
        self._options = recorder_options
        self._check = McapRecorder(self.path, **recorder_options)  # its checks before a file is opened
        self.stopped: str | None = None
        self._writer: _Writer | None = None
        self._inline: McapRecorder | None = None
        """The recorder in this process, where no writer process could be started."""
        self._claim: int | None = None
        """The staging file's claim (`files.claim_staging`), held here while the episode runs."""
        self.kept: Path | None = None
        """Where the finished recording is (as `McapRecorder.kept`)."""

    def on_start(self, start: EpisodeStart) -> None:
        self._check.check_can_open()
        # Claimed here, not in the writer: a second run to the same file is refused before
        # its episode starts, and a writer that dies takes no lock with it.
        release(self._claim)
        self._claim = claim_staging(self.staging, self.path)
        self._layout = TickRows.for_episode(start)
        self._rows = np.zeros((BATCH, self._layout.width))
        self._limit = FIRST_BATCH
        self._count = 0
        self._extras: dict[int, tuple] = {}
        self._spans: dict[int, tuple[int, int, bool]] = {}
        """Row -> its period's `Period.pose_span` (the poses are taken at the flush)."""
        self._episode = None
        self._facts_sent = False
        try:
            self._writer = _take_writer()
            # This process's sys.path now: the topics installed by packages added since the
            # writer started are recorded too (the table is read per sys.path).
            options = dict(self._options, claim=False)  # this process holds the claim
            # The topics registered in this process, by reference, where this process would
            # write them: after the installed ones, before any the planner adds.
            options["extra_channels"] = (*run_time_topics(), *options.get("extra_channels", ()))
            self._writer.send(("start", str(self.path), options, start, list(sys.path)))
        except OSError:  # no writer process here (an interpreter that cannot start one): this one records
            self._writer, self._inline = None, self._check
            self._inline.hold(self._claim)
            self._claim = None
            self._inline.on_start(start)

    def on_tick(self, tick: Tick) -> None:
        if self._writer is None:
            if self._inline is not None:
                self._inline.on_tick(tick)
            return
        if self._count == self._limit:
            self._flush()
        self._layout.pack(self._rows[self._count], tick)
        if tick.debug or tick.tracks is not None:
            self._extras[self._count] = (tick.debug, tick.tracks)
        self._count += 1

    def on_tick_period(self, period: Period) -> None:
        """The period's own numbers, not its Tick: the writer makes the Tick (the same bits),
        so the episode's process never does."""
        if self._writer is None:
            if self._inline is not None:
                self._inline.on_tick(period.tick)
            return
        if not self._facts_sent:
            self._send(("facts", period.episode.tick_facts))
            self._facts_sent = True
        if self._count == self._limit:
            self._flush()
        self._layout.pack_numbers(self._rows[self._count], period.numbers())
        if period.debug or period.tracks is not None:
            self._extras[self._count] = (period.debug, period.tracks)
        self._count += 1

    def on_poses_period(self, period: Period) -> None:
        """The period's poses, taken from the episode's pose buffer with the batch's others
        when it is sent (the same rows `period.poses` would copy now)."""
        if self._writer is None or not self._count or (self._count - 1) in self._spans:
            times, poses = period.poses  # no tick row of its own to go with (not the loop's order)
            if len(times):
                self.on_poses(times, poses)
            return
        span = self._spans[self._count - 1] = period.pose_span()
        self._episode = period.episode
        if span[2]:  # the episode ended: the writer takes the last rows while the result is computed
            self._flush()

    def on_poses(self, times: np.ndarray, poses: np.ndarray) -> None:
        if self._writer is None:
            if self._inline is not None:
                self._inline.on_poses(times, poses)
            return
        self._flush()
        self._send(("poses", times, poses))

    def on_end(self, result: EpisodeResult) -> None:
        try:
            self._end(result)
        finally:
            release(self._claim)
            self._claim = None

    def _end(self, result: EpisodeResult) -> None:
        if self._writer is None:
            if self._inline is not None:
                self._inline.on_end(result)
                self.stopped, self.kept = self._inline.stopped, self._inline.kept
            return
        self._flush()
        writer, self._writer = self._writer, None
        try:
            reply = writer.ask(("end", result))
        except (OSError, EOFError):
            self.stopped = self.stopped or _WRITER_DIED
            return
        _give_back(writer)
        kind, *rest = reply
        if kind == "error":
            code, text = rest
            raise OSError(code, text)
        self.stopped, kept = rest
        self.kept = Path(kept) if kept is not None else None

    def _flush(self) -> None:
        if not self._count:
            return
        # The rows follow their header as they are in memory (no copy into the pickle), then
        # the batch's pose times and poses (as `Episode.poses_between` makes them).
        rows = memoryview(self._rows[: self._count]).cast("B")
        counts = [0] * self._count
        raw = [rows]
        if self._spans:
            idx, counts = self._pose_steps()
            episode = self._episode
            raw += [memoryview(idx * episode.dt).cast("B"), memoryview(episode.poses[idx]).cast("B")]
        self._send(("ticks", self._count, self._extras, counts), *raw)
        self._count, self._extras, self._spans = 0, {}, {}
        self._limit = min(2 * self._limit, BATCH)

    def _pose_steps(self) -> tuple[np.ndarray, list[int]]:
        """The batch's pose steps and how many are each row's: what `Episode.pose_steps` gives
        each row's period, taken at once where the periods follow each other (the loop's
        case: one period ends where the next begins, and only the last can have ended it)."""
        episode, spans, count = self._episode, self._spans, self._count
        if len(spans) == count and all(spans[i][0] == spans[i - 1][1] and not spans[i - 1][2] for i in range(1, count)):
            idx = episode.pose_steps(spans[0][0], spans[count - 1][1], spans[count - 1][2])
            ends = np.searchsorted(idx, [spans[i][1] for i in range(count)], side="right")
            return idx, np.diff(ends, prepend=0).tolist()
        steps = [episode.pose_steps(*spans[i]) if i in spans else _NO_STEPS for i in range(count)]
        return np.concatenate(steps), [len(s) for s in steps]

    def _send(self, message, *raw: memoryview) -> None:
        try:
            self._writer.send(message, *raw)
        except OSError:  # the writer died: the episode goes on without its recording
            self.stopped = _WRITER_DIED
            self._writer = None


def _serve(stdin, stdout) -> None:
    """The writer process: recorder hooks from the pipe until it closes."""
    recorder: McapRecorder | None = None
    layout: TickRows | None = None
    facts = None
    failed: OSError | None = None
    ahead: SyncAhead | None = None
    while True:
        try:
            kind, *args = _receive(stdin)
            # A batch's rows and poses follow its header, raw: read them whatever happens to them.
            raw = _read_exactly(stdin, (args[0] * layout.width + 4 * sum(args[2])) * 8) if kind == "ticks" else b""
        except EOFError:  # the episode's process is gone: what came is closed into NAME.part, not renamed
            if ahead is not None:
                ahead.close()
            if recorder is not None:
                recorder.abandon()
            return
        try:
            if kind == "start":
                path, options, start, search_path = args
                if sys.path != search_path:
                    sys.path[:] = search_path
                    importlib.invalidate_caches()
                if ahead is not None:  # an episode that never ended (its process raised)
                    ahead.close()
                    ahead = None
                recorder, failed = McapRecorder(path, **options), None
                layout = TickRows.for_episode(start)
                recorder.on_start(start)
            elif kind == "facts":
                facts = args[0]
            elif failed is not None:
                pass
            elif kind == "ticks":
                count, extras, counts = args
                numbers = np.frombuffer(raw, dtype=np.float64)
                rows = numbers[: count * layout.width].reshape(count, layout.width)
                n_poses = sum(counts)
                times = numbers[count * layout.width :][:n_poses]
                poses = numbers[count * layout.width + n_poses :].reshape(n_poses, 3)
                at = 0
                for i in range(count):
                    recorder.on_tick(layout.unpack(rows[i], extras.get(i), facts))
                    if counts[i]:
                        recorder.on_poses(times[at : at + counts[i]], poses[at : at + counts[i]])
                        at += counts[i]
                if ahead is None:  # from the first batch on (an episode of one tick never needs it)
                    ahead = SyncAhead(recorder.staging)
                ahead.poke()
            elif kind == "poses":
                recorder.on_poses(*args)
        except OSError as exc:
            failed = exc
        if kind == "end":
            if ahead is not None:
                ahead.close()
                ahead = None
            if failed is None:
                try:
                    recorder.on_end(args[0])
                except OSError as exc:
                    failed = exc
            reply = (
                ("done", recorder.stopped, None if recorder.kept is None else str(recorder.kept))
                if failed is None
                else ("error", failed.errno, failed.strerror or str(failed))
            )
            _send(stdout, reply)
            stdout.flush()
            recorder = None


if __name__ == "__main__":
    # Replies on a copy of stdout; anything printed (a library's warning) goes to stderr.
    replies = os.fdopen(os.dup(1), "wb")
    os.dup2(2, 1)
    _serve(sys.stdin.buffer, replies)
