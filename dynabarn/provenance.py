"""Where things are and what produced a result: the repository's paths, package versions
(decide results, the same under the lock) and the machine (CPU features and math kernels
that numpy, OpenBLAS and PyTorch chose).

`versions()` goes into every result, bench row and recording. `machine()` goes into
results, bench rows and `metadata.json`, and into a recording's MCAP metadata record
`dynabarn.machine` (never into its messages, which stay byte-identical across machines).
Two results that differ can be explained from these two blocks alone.
"""

from __future__ import annotations

import functools
import os
import platform
import sys
from importlib.metadata import PackageNotFoundError, version
from pathlib import Path

PACKAGE_DIR = Path(__file__).resolve().parent
REPO_ROOT = PACKAGE_DIR.parent
"""The checkout (or the site-packages folder of an installed wheel) holding the package."""
IS_CHECKOUT = (REPO_ROOT / "pyproject.toml").is_file() and (REPO_ROOT / "generated_worlds").is_dir()
"""Running from a source checkout (an editable install included), not an installed wheel."""
_WHEEL_DATA = PACKAGE_DIR / "data"
DATA_ROOT = REPO_ROOT if IS_CHECKOUT or not (_WHEEL_DATA / "generated_worlds").is_dir() else _WHEEL_DATA
"""The folder holding `generated_worlds/` beside `assets/jackal/`: the checkout's root, or
`dynabarn/data` in an installed wheel (the same two folders, copied there by setup.py)."""
SHIPPED_WORLDS = DATA_ROOT / "generated_worlds"
"""The 300 generated worlds and their index, as committed (and shipped in the wheel)."""
ASSETS_DIR = DATA_ROOT / "assets"
WORLDS_ENV = "DYNABARN_WORLDS"
"""Environment variable naming another folder of worlds with an index.json (default: the shipped set)."""


def worlds_dir() -> Path:
    """The world set that ids (`--world 137`) and the paper sets refer to: `$DYNABARN_WORLDS`,
    else the shipped worlds. Read on every call, so a test or a notebook can switch sets."""
    other = os.environ.get(WORLDS_ENV, "").strip()
    return Path(other).expanduser() if other else SHIPPED_WORLDS


def work_root() -> Path:
    """Where the package builds worlds it needs on the spot (the golden set's): the checkout,
    or the user's cache folder for an installed wheel (which may be read-only)."""
    if IS_CHECKOUT:
        return REPO_ROOT
    cache = os.environ.get("XDG_CACHE_HOME", "").strip() or str(Path.home() / ".cache")
    return Path(cache) / "dynabarn"


def portable_path(path: Path) -> str:
    """A path that reads the same on every checkout and install: relative to the data root
    (`generated_worlds/world_137.xml`) or to the work root, else as given."""
    resolved = Path(path).resolve()
    for root in (DATA_ROOT, work_root()):
        try:
            return resolved.relative_to(root.resolve()).as_posix()
        except ValueError:
            continue
    return str(path)


ENVIRONMENT_KNOBS = (
    "NPY_DISABLE_CPU_FEATURES",
    "NPY_ENABLE_CPU_FEATURES",
    "OPENBLAS_CORETYPE",
    "OPENBLAS_NUM_THREADS",
    "OMP_NUM_THREADS",
    "MKL_NUM_THREADS",
    "ATEN_CPU_CAPABILITY",
)
"""Environment variables that change which kernels numpy, OpenBLAS and PyTorch run."""


def _version(dist: str) -> str | None:
    try:
        return version(dist)
    except PackageNotFoundError:
        return None


@functools.cache
def versions() -> dict[str, str]:
    """The versions that decide a result: ours, MuJoCo, numpy, scipy (Dijkstra,
    the costmap's distance transform). PyTorch is added by the planners that use it
    (`Planner.versions`)."""
    import mujoco
    import numpy as np

    out = {"dynabarn": _version("dynabarn") or "0+unknown", "mujoco": mujoco.__version__, "numpy": np.__version__}
    scipy = _version("scipy")
    if scipy:
        out["scipy"] = scipy
    return out


def _cpu_model() -> str:
    try:
        with open("/proc/cpuinfo", encoding="utf-8") as f:
            for line in f:
                if line.startswith("model name"):
                    return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or platform.machine()


def _numpy_simd() -> dict:
    try:
        from numpy._core import _multiarray_umath as umath
    except ImportError:  # numpy < 2
        from numpy.core import _multiarray_umath as umath  # type: ignore[no-redef]
    features = umath.__cpu_features__
    return {
        "baseline": list(umath.__cpu_baseline__),
        "dispatched": [f for f in umath.__cpu_dispatch__ if features.get(f)],
    }


def _blas() -> list[dict]:
    try:
        from threadpoolctl import threadpool_info
    except ImportError:
        return []
    keys = ("internal_api", "version", "architecture", "num_threads", "prefix")
    found = [{k: info.get(k) for k in keys} for info in threadpool_info() if info.get("user_api") == "blas"]
    # threadpoolctl lists libraries in the order the loader happened to map them (numpy's and
    # scipy's OpenBLAS swap places from run to run): sorted, the same episode's rows are equal.
    return sorted(found, key=lambda d: tuple(str(d[k]) for k in keys))


@functools.cache
def _machine_once() -> dict:
    import scipy.linalg  # noqa: F401  (loads scipy's OpenBLAS, so threadpoolctl sees it)

    return {
        "cpu": _cpu_model(),
        "arch": platform.machine(),
        "python": sys.version.split()[0],
        "numpy_simd": _numpy_simd(),
        "blas": _blas(),
        "env": {k: os.environ[k] for k in ENVIRONMENT_KNOBS if k in os.environ},
    }


def machine() -> dict:
    """The machine's part of a result: CPU, numpy's dispatched SIMD targets, the BLAS
    kernels and threads in use, PyTorch's CPU capability (once loaded) and the environment
    variables that choose kernels."""
    out = dict(_machine_once())
    torch = sys.modules.get("torch")
    if torch is not None:
        out["torch_cpu_capability"] = torch.backends.cpu.get_cpu_capability()
        out["torch_threads"] = torch.get_num_threads()
    return out


def has_display() -> bool:
    """Whether windows can open here (an X display, Xvfb included, or Wayland)."""
    return bool(os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY"))
