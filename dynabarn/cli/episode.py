"""One recorded episode, run and reported the same way by `dynabarn-run` and `dynabarn-ros`."""

from __future__ import annotations

import json
import sys
from pathlib import Path

from dynabarn.cli.common import EXIT_EPISODE_ERROR
from dynabarn.errors import DynabarnError


def run_recorded(
    sim,
    planner,
    protocol,
    *,
    seed: int,
    log_path: Path | None,
    planner_name: str,
    live_contexts: tuple = (),
    observers: tuple = (),
    on_recorder=None,
):
    """`run_episode` with an MCAP recorder when `log_path` is given (or live foxglove
    contexts to stream to), then further `observers` (viewers, pacing): Ctrl-C says where
    the recording is kept, a recording that cannot start is one line, a cut one a warning."""
    from dynabarn.recording import McapRecorder
    from dynabarn.sim import run_episode

    recorder = McapRecorder(log_path, live=live_contexts) if log_path is not None or live_contexts else None
    if recorder is not None and on_recorder is not None:
        on_recorder(recorder)
    try:
        result = run_episode(
            sim,
            planner,
            protocol,
            seed=seed,
            observers=[*([recorder] if recorder else []), *observers],
            planner_name=planner_name,
        )
    except KeyboardInterrupt as exc:  # Ctrl-C or SIGTERM: the recorder closed it whole
        if log_path:
            raise type(exc)(f"recording kept: {log_path}") from None
        raise
    except OSError as exc:  # the recording could not be started: a full disk, a folder...
        raise DynabarnError(f"cannot record to {log_path}: {exc.strerror or exc}") from None
    if recorder is not None and recorder.stopped:
        print(f"warning: {log_path}: {recorder.stopped}", file=sys.stderr)
    return result


def print_result(result, *, as_json: bool, recording: Path | None, extra: dict | None = None) -> None:
    """The one-line summary (and the recording's path), or the full result as strict JSON."""
    if as_json:
        d = {**result.to_dict(), "recording": str(recording) if recording else None, **(extra or {})}
        print(json.dumps(d, indent=1, sort_keys=True, allow_nan=False))
        return
    print(result.summary())
    if recording:
        print(f"recording: {recording}")


def exit_status(result, *, as_json: bool) -> int:
    """0 for any judged outcome; 1 (with the reason on stderr) when the episode ended in error."""
    from dynabarn.metrics import Outcome

    if result.outcome is not Outcome.ERROR:
        return 0
    if not as_json:
        print(f"error: {result.reason}", file=sys.stderr)
    return EXIT_EPISODE_ERROR
