"""The wheel is the product: build it, install it into a fresh virtual environment, and run
the README's quickstart from a folder outside the repository.

The wheel is built from a copy of the working tree (so the build writes nothing into the
checkout) and installed with `--no-deps` into a new venv. Its dependencies (MuJoCo, numpy,
PyTorch, ...) are taken from the test environment by a path line in the new venv (the
folder only: its `.pth` files, among them the editable install of this checkout, are not
run), so `dynabarn` itself can only come from the wheel; the test checks that it does.
Installing the dependencies from PyPI would test PyPI, not the wheel, and take minutes.
"""

from __future__ import annotations

import hashlib
import os
import shutil
import subprocess
import sys
import sysconfig
from pathlib import Path

import pytest

from tests.conftest import require

pytestmark = pytest.mark.slow  # builds and installs the wheel: `make test` runs it, `make test-fast` does not

REPO = Path(__file__).resolve().parent.parent
SKIP_IN_COPY = shutil.ignore_patterns(
    ".venv*", ".git", "build", "dist", "*.egg-info", "runs", ".golden_worlds", "__pycache__", ".pytest_cache",
    ".ruff_cache", "*.rrd", "out", "demos", "imported_worlds", "mixed_worlds", "MUJOCO_LOG.TXT", "site",
)  # fmt: skip


@pytest.fixture(scope="module")
def installed(tmp_path_factory) -> dict:
    """A fresh venv with the wheel installed; returns its paths and a clean environment."""
    setuptools = require("setuptools", "test")  # the wheel is built without build isolation
    if int(setuptools.__version__.split(".")[0]) < 77:  # pyproject's build requirement (SPDX licence)
        pytest.skip(f"needs setuptools>=77, not {setuptools.__version__}: pip install -e '.[test]'")
    tmp = tmp_path_factory.mktemp("wheel")
    src = tmp / "src"
    shutil.copytree(REPO, src, ignore=SKIP_IN_COPY)
    dist = tmp / "dist"
    subprocess.run(
        [sys.executable, "-m", "pip", "wheel", str(src), "--no-deps", "--no-build-isolation", "-q", "-w", str(dist)],
        check=True,
        capture_output=True,
    )
    (wheel,) = dist.glob("dynabarn-*.whl")
    venv = tmp / "venv"
    subprocess.run([sys.executable, "-m", "venv", "--without-pip", str(venv)], check=True)
    python = venv / "bin" / "python"
    subprocess.run(
        [sys.executable, "-m", "pip", "--python", str(python), "install", "--no-deps", "-q", str(wheel)],
        check=True,
        capture_output=True,
    )
    site = Path(
        subprocess.run(
            [str(python), "-c", "import sysconfig; print(sysconfig.get_paths()['purelib'])"],
            check=True,
            capture_output=True,
            text=True,
        ).stdout.strip()
    )
    (site / "_test_dependencies.pth").write_text(sysconfig.get_paths()["purelib"] + "\n")
    work = tmp / "elsewhere"  # the current directory: not the repository, not the venv
    work.mkdir()
    env = {k: v for k, v in os.environ.items() if k not in ("PYTHONPATH", "DYNABARN_WORLDS", "VIRTUAL_ENV")}
    env.update(MUJOCO_GL="egl", XDG_CACHE_HOME=str(tmp / "cache"), HOME=str(tmp / "home"))
    return {"wheel": wheel, "venv": venv, "python": python, "site": site, "work": work, "env": env}


def _run(installed: dict, *argv: str, timeout: float = 300) -> subprocess.CompletedProcess:
    exe = argv[0] if argv[0].startswith("/") else str(installed["venv"] / "bin" / argv[0])
    return subprocess.run(
        [exe, *argv[1:]],
        cwd=installed["work"],
        env=installed["env"],
        capture_output=True,
        text=True,
        timeout=timeout,
    )


def _snapshot(folder: Path) -> dict[str, str]:
    return {
        str(p.relative_to(folder)): hashlib.sha256(p.read_bytes()).hexdigest()
        for p in sorted(folder.rglob("*"))
        if p.is_file() and "__pycache__" not in p.parts
    }


def test_wheel_carries_worlds_robot_and_policies(installed):
    import zipfile

    names = set(zipfile.ZipFile(installed["wheel"]).namelist())
    worlds = {n for n in names if n.startswith("dynabarn/data/generated_worlds/world_")}
    assert len(worlds) == 300
    for needed in (
        "dynabarn/data/generated_worlds/index.json",
        "dynabarn/data/assets/jackal/jackal.xml",
        "dynabarn/data/assets/jackal/LICENSE",
        "dynabarn/policies/bc.pt",
        "dynabarn/policies/td3.pt",
        "dynabarn/planners/presets/dwa_barn_challenge.json",
        "dynabarn/ros/launch/move_base_dwa.launch",
        "dynabarn/ros/launch/dyna_barn/trajectory_planner.yaml",
        "dynabarn/ros/launch/barn_main/overrides.yaml",
        "dynabarn/bench/report_assets/report.html.j2",  # every sweep's report.html
        "dynabarn/bench/report_assets/report.css",
        "dynabarn/bench/report_assets/report.js",
        "dynabarn/worlds/tier_profiles/mixed.certified.json",
        "dynabarn/worlds/tier_profiles/combined.certified.json",
        "dynabarn/__main__.py",
    ):
        assert needed in names, needed
    # Byte for byte the checkout's files.
    with zipfile.ZipFile(installed["wheel"]) as z:
        assert (
            z.read("dynabarn/data/generated_worlds/world_137.xml")
            == (REPO / "generated_worlds/world_137.xml").read_bytes()
        )
    meta = (
        zipfile.ZipFile(installed["wheel"]).read(next(n for n in names if n.endswith(".dist-info/METADATA"))).decode()
    )
    assert "License-Expression: MIT" in meta and "Project-URL:" in meta and "Classifier:" in meta


def test_quickstart_from_outside_the_repository(installed):
    before = _snapshot(installed["site"] / "dynabarn")
    # The package imported is the wheel's, not the checkout's.
    where = _run(
        installed,
        "python",
        "-c",
        "import dynabarn, dynabarn.provenance as p; print(dynabarn.__file__); print(p.DATA_ROOT)",
    )
    assert where.returncode == 0, where.stderr
    file, data_root = where.stdout.split()
    assert Path(file).is_relative_to(installed["site"]) and Path(data_root) == installed["site"] / "dynabarn" / "data"

    run = _run(installed, "dynabarn-run", "--world", "137", "--planner", "dwa")
    assert run.returncode == 0, run.stderr
    # The same episode as in the checkout (README, make demo).
    assert "world_137 | dwa | barn | seed 0: SUCCESS in 14.27 s" in run.stdout
    assert list((installed["work"] / "runs").glob("world_137_dwa_barn_s0.mcap"))

    show = _run(installed, "dynabarn-worlds", "show", "world_137")
    assert show.returncode == 0 and show.stdout.startswith("world_137"), show.stderr

    # MuJoCo opens an installed world on its own (the robot reference resolves in the wheel).
    viewer_load = _run(
        installed,
        "python",
        "-c",
        "import mujoco, dynabarn.provenance as p; "
        "m = mujoco.MjModel.from_xml_path(str(p.SHIPPED_WORLDS / 'world_137.xml')); print(m.nsensor, m.nmocap)",
    )
    assert viewer_load.returncode == 0, viewer_load.stderr
    assert viewer_load.stdout.split() == ["720", "5"]

    # Generated worlds go to the current directory with their robot, and open in MuJoCo.
    gen = _run(installed, "dynabarn-worlds", "generate")
    assert gen.returncode == 0, gen.stderr
    out = installed["work"] / "generated_worlds"
    assert len(list(out.glob("world_*.xml"))) == 300 and (out / "assets" / "jackal" / "jackal.xml").is_file()
    assert "DYNABARN_WORLDS=" in gen.stdout
    opened = _run(
        installed, "python", "-c", f"import mujoco; print(mujoco.MjModel.from_xml_path('{out}/world_200.xml').nmocap)"
    )
    assert opened.returncode == 0 and int(opened.stdout) > 0, opened.stderr
    # ... and DYNABARN_WORLDS points the ids at them.
    installed["env"]["DYNABARN_WORLDS"] = str(out)
    try:
        mine = _run(installed, "dynabarn-worlds", "show", "137")
    finally:
        del installed["env"]["DYNABARN_WORLDS"]
    assert mine.returncode == 0 and str(out / "world_137.xml") in mine.stdout, mine.stderr

    # Nothing was written into the installed package.
    assert _snapshot(installed["site"] / "dynabarn") == before


def test_learned_planners_and_the_environment_from_the_wheel(installed):
    """The learn extra's part of the quickstart: the shipped policies and DynaBARN-v0."""
    require("torch", "learn")
    require("gymnasium", "learn")
    bc = _run(installed, "python", "-m", "dynabarn", "run", "--world", "137", "--planner", "bc", "--no-log")
    assert bc.returncode == 0 and "world_137 | bc | barn" in bc.stdout, bc.stderr

    gym = _run(
        installed,
        "python",
        "-c",
        "import gymnasium as gym, dynabarn; env = gym.make('dynabarn/DynaBARN-v0'); "
        "obs, info = env.reset(seed=0); print(obs.shape, env.spec.max_episode_steps, info['world'])",
    )
    assert gym.returncode == 0, gym.stderr
    shape, limit, world = gym.stdout.split()
    assert (shape, limit) == ("(722,)", "2000") and world.startswith("world_")
