"""`python -m dynabarn bench ...` from a benchmark script: the command printed, then run in
the checkout (each sweep resumes where its folder stops)."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def run_dynabarn(*args: str) -> int:
    """Run `python -m dynabarn ARGS` in the checkout; its exit status."""
    print(" ".join(args), flush=True)
    return subprocess.run([sys.executable, "-m", "dynabarn", *args], cwd=ROOT).returncode


RELEASE = ROOT.parent / "shared" / "reference" / "dynabarn60.json"
"""The original release's 60 worlds, recovered (never copied into the repository)."""
IMPORTED = ROOT / "imported_worlds"


def import_release() -> bool:
    """The release's 60 worlds imported into imported_worlds/ (set `imported_worlds`) when
    ../shared/reference holds them; whether they are there (said where they are not)."""
    if (IMPORTED / "index.json").is_file():
        return True
    if not RELEASE.is_file():
        print(f"{RELEASE} is not here: the release's 60 are left out", flush=True)
        return False
    importing = ["worlds", "import", str(RELEASE), "--format", "dynabarn-release", "--name", "release"]
    return run_dynabarn(*importing, "--out", IMPORTED.name) == 0
