"""Repair the committed results folders' metadata.json (issue 56): before invocations were
kept, each `dynabarn-bench` into a folder rewrote metadata.json with only its own planners.

For each folder under results/ whose metadata.json has no `invocations`:
- every earlier version of metadata.json in git's history becomes an invocation, marked
  `recovered` with its commit (its date is the commit's, not the sweep's);
- planners in the rows that no recovered invocation names become one more invocation,
  marked as counted from the rows (no record of its command line survives), with their
  episodes and the versions the rows carry;
- `planners` names every planner in the rows.

    python benchmarks/repair_metadata.py          # rewrites only folders not yet repaired
"""

from __future__ import annotations

import json
import subprocess
import sys
from collections import Counter
from pathlib import Path

from dynabarn.bench.results import METADATA, RESULTS, read_results
from dynabarn.files import write_atomically

ROOT = Path(__file__).resolve().parents[1]


def history(path: Path) -> list[tuple[str, str, dict]]:
    """(commit, ISO date, content) of every committed version of `path`, oldest first."""
    relative = path.relative_to(ROOT).as_posix()
    log = subprocess.run(
        ["git", "log", "--reverse", "--format=%H %cI", "--", relative], cwd=ROOT, capture_output=True, text=True
    ).stdout.split("\n")
    out = []
    for line in filter(None, log):
        commit, date = line.split(" ", 1)
        shown = subprocess.run(["git", "show", f"{commit}:{relative}"], cwd=ROOT, capture_output=True, text=True)
        if shown.returncode == 0:
            try:
                out.append((commit, date, json.loads(shown.stdout)))
            except ValueError:
                continue
    return out


def repaired(folder: Path) -> dict | None:
    """The folder's metadata with its invocations recovered; None when nothing to repair."""
    meta = json.loads((folder / METADATA).read_text())
    if "invocations" in meta:
        return None
    rows = [r for r in read_results(folder / RESULTS) if not r.get("retry")]
    invocations, seen = [], set()
    for commit, date, version in history(folder / METADATA):
        text = json.dumps(version, sort_keys=True)
        if text in seen:
            continue
        seen.add(text)
        invocations.append(
            {
                "when": None,
                "arguments": version.get("arguments"),
                "versions": version.get("versions"),
                "python": version.get("python"),
                "planners": version.get("planners"),
                "episodes": version.get("episodes"),
                "recovered": f"from metadata.json as committed in {commit[:12]} ({date}); the sweep ran before that",
            }
        )
    named = {p for i in invocations for p in (i["planners"] or [])}
    counts = Counter(r["planner"] for r in rows)
    rest = sorted(set(counts) - named)
    if rest:
        versions = {json.dumps(r.get("versions"), sort_keys=True) for r in rows if r["planner"] in rest}
        invocations.append(
            {
                "when": None,
                "arguments": None,
                "versions": json.loads(versions.pop()) if len(versions) == 1 else None,
                "planners": rest,
                "episodes": sum(counts[p] for p in rest),
                "recovered": "no record of this invocation survives: its planners and episodes are counted from the "
                "rows (and its versions, where the rows agree on them)",
            }
        )
    meta["invocations"] = invocations
    meta["planners"] = sorted(counts)
    return meta


def main() -> int:
    changed = []
    for folder in sorted(
        p for p in (ROOT / "results").iterdir() if (p / METADATA).is_file() and (p / RESULTS).is_file()
    ):
        meta = repaired(folder)
        if meta is not None:
            write_atomically(folder / METADATA, json.dumps(meta, indent=1, sort_keys=True) + "\n")
            changed.append(folder.name)
    print(f"repaired {len(changed)} folder(s): {', '.join(changed) or 'none'}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
