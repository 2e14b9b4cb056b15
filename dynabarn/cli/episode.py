"""One episode's report, the same for `dynabarn-run` and `dynabarn-ros` (both run it with
`dynabarn.runner.run_spec`)."""

from __future__ import annotations

import json
import sys
from pathlib import Path

from dynabarn.cli.common import EXIT_EPISODE_ERROR


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
