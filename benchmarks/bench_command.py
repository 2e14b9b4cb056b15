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
