from __future__ import annotations

import os

# MuJoCo picks its OpenGL platform when first imported: offscreen EGL unless a display is set
# (dynabarn/__init__.py does the same, but a test module may import mujoco before dynabarn).
if "MUJOCO_GL" not in os.environ and not os.environ.get("DISPLAY"):
    os.environ["MUJOCO_GL"] = "egl"

import json
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parent.parent
REFERENCE = REPO.parent / "shared" / "reference"


@pytest.fixture(scope="session")
def release_json() -> dict:
    path = REFERENCE / "dynabarn60.json"
    if not path.is_file():
        pytest.skip("reference data ../shared/reference/dynabarn60.json not present")
    return json.loads(path.read_text())


@pytest.fixture(scope="session")
def release_path(release_json) -> Path:
    return REFERENCE / "dynabarn60.json"


@pytest.fixture(scope="session")
def barn_json() -> dict:
    path = REFERENCE / "barn300_static.json"
    if not path.is_file():
        pytest.skip("reference data ../shared/reference/barn300_static.json not present")
    return json.loads(path.read_text())


@pytest.fixture
def display():
    """An Xvfb display of its own (1280x800), for tests of real windows; skips without Xvfb."""
    import shutil
    import subprocess
    import time

    if not (shutil.which("Xvfb") and shutil.which("xdotool")):
        pytest.skip("Xvfb and xdotool are installed by `make system-deps`")
    number = next(n for n in range(90, 200) if not Path(f"/tmp/.X11-unix/X{n}").exists())
    xvfb = subprocess.Popen(["Xvfb", f":{number}", "-screen", "0", "1280x800x24"], stderr=subprocess.DEVNULL)
    for _ in range(50):
        if Path(f"/tmp/.X11-unix/X{number}").exists():
            break
        time.sleep(0.1)
    yield f":{number}"
    xvfb.terminate()
    xvfb.wait(timeout=10)
