"""Snapping to fixed resolutions: how the same episode stays the same on every machine.

A closed loop of physics and planner is chaotic: a difference in the last bit of one
number (numpy's SIMD transcendentals, OpenBLAS's CPU-specific kernels and thread count,
and PyTorch's CPU kernels all round differently on different machines or
installs; docs/reproducibility.md has the measured list) grows until an episode ends
differently. So every value that crosses from one part of the loop to the next, or from
one control tick to the next, is snapped to a fixed grid far coarser than those last bits
and far finer than anything physical:

- the laser range, to the UST-10's own resolution (1 mm, as its driver reports);
- the command the robot receives, to 1 um/s and 1 urad/s;
- a planner's continuous state carried to the next tick (TEB's band), to 0.1 mm / 0.1 mrad;
- a reactive obstacle's sideways speed, to 1 um/s;
- the scores by which DWA and the oracle choose among candidates, to 1e-6: candidates
  that tie in exact arithmetic (common: costs on grids, mirror-image arcs) then tie
  exactly, and the first wins, instead of whichever the last bits favour;
- recorded values that no decision reads but a recording's hash does (clearance, debug
  geometry).

A last-bit difference then changes nothing unless it straddles a grid boundary, which
for differences of 1e-14 and grids of 1e-6..1e-3 happens about once in 1e8 values.

Where a computation amplifies last bits by itself (TEB's Levenberg-Marquardt: an ulp in a
residual moves the band by centimetres within one tick, through the finite-difference
Jacobian and the trust-region's accept/reject), snapping its output is not enough: its
inputs must be the same bits everywhere. `sincos` and `exp` below are computed with
IEEE-754 operations only (+, -, *, /, rint, ldexp, each correctly rounded), so they give the
same bits on every CPU, unlike numpy's, which dispatch to CPU-specific SIMD code.
"""

from __future__ import annotations

import math

import numpy as np

LASER_RESOLUTION = 1e-3
"""[m] The Hokuyo UST-10 reports whole millimetres."""
COMMAND_RESOLUTION = 1e-6
"""[m/s, rad/s] What reaches the actuators. (1e-3 was tried: DWA's smallest turning rates
then round to zero and it can stand still for good in a narrow passage.)"""
STATE_RESOLUTION = 1e-4
"""[m, rad, s] A planner's continuous state kept from one tick to the next."""
OBSTACLE_SPEED_RESOLUTION = 1e-6
"""[m/s] A reactive obstacle's sideways speed."""
SCORE_RESOLUTION = 1e-6
"""Candidate scores compared by a planner's argmin (DWA, oracle)."""
RECORD_RESOLUTION = 1e-6
"""[m] Recorded metrics computed with numpy's transcendentals (per-tick clearance)."""


def snap(x: float, resolution: float) -> float:
    """x on the grid k * resolution (nearest; exact halves to even). Deterministic: one
    multiplication, one rounding, one correctly rounded division. Infinities pass."""
    if not math.isfinite(x):
        return x
    scale = 1.0 / resolution
    return round(x * scale) / scale


def snap_array(x: np.ndarray, resolution: float, out: np.ndarray | None = None) -> np.ndarray:
    """`snap` elementwise (in place when out is x)."""
    scale = 1.0 / resolution
    out = np.multiply(x, scale, out=out)
    np.rint(out, out=out)
    np.divide(out, scale, out=out)
    return out


# fdlibm's kernels (k_sin.c, k_cos.c) on [-pi/4, pi/4], and pi/2 in three parts (Cody-Waite).
_S = (
    -1.66666666666666324348e-01,
    8.33333333332248946124e-03,
    -1.98412698298579493134e-04,
    2.75573137070700676789e-06,
    -2.50507602534068634195e-08,
    1.58969099521155010221e-10,
)
_C = (
    4.16666666666666019037e-02,
    -1.38888888888741095749e-03,
    2.48015872894767294178e-05,
    -2.75573143513906633035e-07,
    2.08757232129817482790e-09,
    -1.13596475577881948265e-11,
)
_PIO2 = (1.57079632673412561417e00, 6.07710050630396597660e-11, 2.02226624871116645580e-21)
_INV_PIO2 = 6.36619772367581382433e-01
_LN2 = (6.93147180369123816490e-01, 1.90821492927058770002e-10)
_INV_LN2 = 1.44269504088896338700e00
_EXP_TAYLOR = tuple(1.0 / math.factorial(n) for n in range(13, 1, -1))  # 1/13!, ..., 1/2!


def hypot(dx: np.ndarray, dy: np.ndarray) -> np.ndarray:
    """sqrt(dx^2 + dy^2) elementwise, in IEEE-754 operations (each correctly rounded): the
    same bits on every CPU and C library. `np.hypot` calls the C library's hypot, which
    the C standard does not require to be correctly rounded (its last bits are the
    library's own), and takes ten times as long (1.9 ms against 0.19 ms for 106,000
    distances, about what the oracle's search measures per tick); it guards against
    overflow and underflow that distances in metres never reach."""
    return np.sqrt(dx * dx + dy * dy)


def sincos(x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(sin x, cos x) within 2 ulp for |x| < 1e5, bit-identical on every CPU."""
    x = np.asarray(x, dtype=np.float64)
    k = np.rint(x * _INV_PIO2)
    r = ((x - k * _PIO2[0]) - k * _PIO2[1]) - k * _PIO2[2]
    z = r * r
    ps = _S[5]
    for c in _S[4::-1]:
        ps = ps * z + c
    pc = _C[5]
    for c in _C[4::-1]:
        pc = pc * z + c
    sin_r = r + r * z * ps
    cos_r = (1.0 - 0.5 * z) + z * z * pc
    quadrant = k.astype(np.int64) & 3
    # Quadrant q: sin x is the q-th of (sin r, cos r, -sin r, -cos r), cos x the (q + 1)-th.
    turns = (sin_r, cos_r, -sin_r, -cos_r)
    return np.choose(quadrant, turns), np.choose((quadrant + 1) & 3, turns)


def exp(x: np.ndarray) -> np.ndarray:
    """e**x within 2 ulp for |x| < 700, bit-identical on every CPU."""
    x = np.asarray(x, dtype=np.float64)
    k = np.rint(x * _INV_LN2)
    r = (x - k * _LN2[0]) - k * _LN2[1]  # |r| <= ln(2) / 2
    p = _EXP_TAYLOR[0]
    for c in _EXP_TAYLOR[1:]:
        p = p * r + c
    return np.ldexp(1.0 + r + r * r * p, k.astype(np.int64))
