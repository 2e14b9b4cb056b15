"""Rewrite the committed results folders' summaries (`summary.csv`, `summary.md`,
`fig5.png`, and the report, which git ignores) from their rows with this version's
statistics, keeping each one's title: what a sweep writes at its end
(`sweep.write_folder_summary`), for folders written before a change to the summary (issue
56's skill interval).

    python benchmarks/resummarise.py
"""

from __future__ import annotations

import sys
from pathlib import Path

from dynabarn.bench.results import RESULTS, read_results
from dynabarn.bench.sweep import write_folder_summary

ROOT = Path(__file__).resolve().parents[1]


def main() -> int:
    done = []
    for folder in sorted(p for p in (ROOT / "results").iterdir() if (p / RESULTS).is_file()):
        rows = read_results(folder / RESULTS)
        if not rows:
            continue
        old = folder / "summary.md"
        title = old.read_text().splitlines()[0].removeprefix("# ") if old.is_file() else ""
        write_folder_summary(folder, rows, title if title.strip() and not title.startswith("|") else "")
        done.append(folder.name)
    print(f"rewrote the summaries of {len(done)} folder(s): {', '.join(done)}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
