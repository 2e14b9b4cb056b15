"""Run the golden set as on a machine whose math library rounds differently.

numpy's float64 sin, cos, exp, log, arctan2, ... dispatch to different code per CPU
(Intel SVML on AVX-512, numpy's own AVX2/AVX512F kernels, the C library otherwise): each
is within an ulp or so of the true value, but not the same ulp. This machine cannot run
the AVX-512 paths, so this script replaces those numpy functions by versions whose results
are moved one ulp up or down (the side chosen by the input's own low bits, so it is
deterministic), then verifies the golden set in this process. Prints the number of
episodes that differ; exit 0 when none do.

    python tests/emulate_ulp.py [--reference DIR]
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

# numpy's float64 functions with CPU-specific implementations (AVX512F / AVX512_SKX SVML,
# AVX2): hypot, sqrt and the arithmetic are the same everywhere (libm's hypot, IEEE ops).
PERTURBED = (
    "sin",
    "cos",
    "tan",
    "arcsin",
    "arccos",
    "arctan",
    "arctan2",
    "sinh",
    "cosh",
    "tanh",
    "exp",
    "exp2",
    "expm1",
    "log",
    "log2",
    "log10",
    "log1p",
    "cbrt",
    "power",
)


def _one_ulp_off(ufunc):
    def wrapped(*args, **kwargs):
        out = ufunc(*args, **kwargs)
        if not isinstance(out, np.ndarray | np.floating) or np.asarray(out).dtype != np.float64:
            return out
        x = np.asarray(args[0], dtype=np.float64)
        side = np.where(x.view(np.int64) & 1 if x.shape else (np.int64(x.view(np.int64)) & 1), np.inf, -np.inf)
        moved = np.nextafter(out, np.broadcast_to(side, np.shape(out)))
        if isinstance(out, np.ndarray) and "out" in kwargs:
            out[...] = moved
            return out
        return moved if isinstance(out, np.ndarray) else np.float64(moved)

    return wrapped


def main() -> int:
    for name in PERTURBED:
        setattr(np, name, _one_ulp_off(getattr(np, name)))
    from dynabarn.bench import golden

    reference = golden.DEFAULT_REFERENCE
    if "--reference" in sys.argv:
        reference = Path(sys.argv[sys.argv.index("--reference") + 1])
    report = golden.verify(reference, jobs=1)
    for m in report.mismatches:
        print(f"MISMATCH {m}")
    print(f"{len({m.case for m in report.mismatches})} of {report.checked} episodes differ")
    return 0 if report.ok else 1


if __name__ == "__main__":
    sys.exit(main())
