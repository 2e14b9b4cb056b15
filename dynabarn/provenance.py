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

REPO_ROOT = Path(__file__).resolve().parent.parent
"""The checkout (or the site-packages folder of an installed wheel) holding the package."""
GENERATED_WORLDS = REPO_ROOT / "generated_worlds"
"""Where `make worlds` writes the 300 generated worlds and their index."""


def portable_path(path: Path) -> str:
    """A path that reads the same on every checkout (relative to the repository)."""
    try:
        return Path(path).resolve().relative_to(REPO_ROOT).as_posix()
    except ValueError:
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
    """The versions that decide a result: ours, MuJoCo, numpy, scipy (TEB's optimiser,
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
    return [
        {k: info.get(k) for k in ("internal_api", "version", "architecture", "num_threads", "prefix")}
        for info in threadpool_info()
        if info.get("user_api") == "blas"
    ]


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
