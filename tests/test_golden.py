"""Reproducibility: the golden set re-runs identically here, under emulated other machines
(numpy's optional SIMD off, other OpenBLAS kernels, 1 vs 2 threads, PyTorch's baseline
kernels, numpy transcendentals one ulp off), and reports every field that differs."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

from dynabarn.bench import golden
from dynabarn.planners import get_planner
from dynabarn.protocol import get_protocol
from dynabarn.recording import MACHINE_METADATA, McapRecorder, read_recording
from dynabarn.sim import run_episode
from tests.conftest import REFERENCE, require

pytestmark = pytest.mark.slow  # minutes of episodes: `make test` runs them, `-m "not slow"` skips them

REPO = Path(__file__).resolve().parent.parent
BENCH = Path(sys.executable).parent / "dynabarn-bench"


def _found_simd() -> list[str]:
    from numpy._core import _multiarray_umath as umath

    return [f for f in umath.__cpu_dispatch__ if umath.__cpu_features__.get(f)]


EMULATED = {
    "this machine": {},
    "numpy without optional SIMD, PyTorch baseline kernels": {
        "NPY_DISABLE_CPU_FEATURES": " ".join(_found_simd()),
        "ATEN_CPU_CAPABILITY": "default",
    },
    "OpenBLAS Prescott kernels, 1 thread": {
        "OPENBLAS_CORETYPE": "Prescott",
        "OPENBLAS_NUM_THREADS": "1",
        "OMP_NUM_THREADS": "1",
    },
    "OpenBLAS Sandybridge kernels, 2 threads": {
        "OPENBLAS_CORETYPE": "Sandybridge",
        "OPENBLAS_NUM_THREADS": "2",
        "OMP_NUM_THREADS": "2",
    },
}


@pytest.mark.parametrize("name", list(EMULATED))
def test_golden_set_is_identical(name):
    require("torch", "learn")  # the golden set runs bc and td3 too
    env = EMULATED[name]
    if "NPY_DISABLE_CPU_FEATURES" in env and not env["NPY_DISABLE_CPU_FEATURES"]:
        pytest.skip("numpy dispatches no optional SIMD target on this CPU")
    run = subprocess.run(
        [str(BENCH), "--verify-golden", "--jobs", "2", "--reference", str(REFERENCE)],
        env={**os.environ, **env},
        capture_output=True,
        text=True,
        timeout=600,
        cwd=REPO,
    )
    assert run.returncode == 0, run.stdout[-4000:] + run.stderr[-2000:]
    assert ", identical" in run.stdout
    machine = json.loads(run.stdout.split("machine: ", 1)[1].splitlines()[0])
    for key, value in env.items():  # the emulation really took effect, and the rows say so
        assert machine["env"][key] == value


def test_golden_set_with_numpy_transcendentals_one_ulp_off():
    require("torch", "learn")  # the golden set runs bc and td3 too
    """As on a CPU whose numpy sin, cos, exp, ... round differently (AVX-512's SVML)."""
    run = subprocess.run(
        [sys.executable, str(REPO / "tests" / "emulate_ulp.py"), "--reference", str(REFERENCE)],
        capture_output=True,
        text=True,
        timeout=600,
        cwd=REPO,
    )
    assert run.returncode == 0, run.stdout[-4000:] + run.stderr[-2000:]
    assert "\n0 of " in "\n" + run.stdout.splitlines()[-1]


def test_golden_set_covers_every_planner_difficulty_protocol_and_world_kind():
    cases = golden.CASES
    assert 25 <= len(cases) <= 45
    assert any(c.sim != golden.SimConfig() for c in cases), "an episode with its own --dt and --control-rate"
    from dynabarn.planners.registry import _BUILTIN

    # ppo ships no policy (dynabarn-train ppo makes one): nothing of it to pin.
    assert {c.planner for c in cases} == set(_BUILTIN) - {"stop", "ppo"}, "every built-in planner that moves"
    assert {"teb_dynamic", "dwa_dynamic"} <= {c.config for c in cases}, "prediction from the laser in TEB and DWA"
    assert {c.protocol for c in cases} >= {"barn", "paper2022", "barn-static"}
    assert {c.source for c in cases} == {"generated", "mixed", "avoid", "yield", "release", "barn-static"}
    generated = {c.world_id // 100 for c in cases if c.source == "generated"}
    assert generated == {0, 1, 2}, "easy, medium and hard worlds"
    committed = golden.read_golden()["episodes"]
    assert set(committed) == {c.key for c in cases}
    assert all(len(e["recording_digest"]) == 64 for e in committed.values())


def test_a_difference_is_reported_with_field_and_both_values(tmp_path):
    data = golden.read_golden()
    case = golden.CASES[1]  # straight, world 137: a collision
    data["episodes"][case.key]["time"] += 1.0
    data["episodes"][case.key]["recording_digest"] = "0" * 64
    path = tmp_path / "golden.json"
    path.write_text(json.dumps(data))
    report = golden.verify(REFERENCE, golden_path=path, cases=[case, golden.CASES[0]])
    assert report.checked == 2 and not report.ok
    fields = {m.field: m for m in report.mismatches}
    assert set(fields) == {"time", "recording_digest"}
    t = fields["time"]
    assert t.golden == pytest.approx(t.now + 1.0)
    assert f"golden {t.golden!r}, now {t.now!r}" in str(t) and case.key in str(t)


def test_bad_golden_file_is_one_line(tmp_path, capsys):
    bad = tmp_path / "g.json"
    bad.write_text("{not json")
    with pytest.raises(golden.DynabarnError, match="not valid JSON"):
        golden.read_golden(bad)
    bad.write_text(json.dumps({"format": "other"}))
    with pytest.raises(golden.DynabarnError, match="not a golden set"):
        golden.read_golden(bad)


def test_results_and_recordings_carry_versions_and_the_machine(tmp_path):
    require("torch", "learn")  # the golden set runs bc and td3 too
    path = tmp_path / "r.mcap"
    result = run_episode(
        REPO / "generated_worlds" / "world_000.xml",
        get_planner("bc"),
        get_protocol("barn"),
        seed=0,
        observers=[McapRecorder(path)],
    )
    assert {"dynabarn", "mujoco", "numpy", "scipy", "torch"} <= set(result.versions)
    m = result.machine
    assert m["numpy_simd"]["baseline"] and isinstance(m["numpy_simd"]["dispatched"], list)
    assert m["blas"] and m["blas"][0]["architecture"] and m["torch_cpu_capability"]
    rec = read_recording(path)
    assert rec.metadata["versions"] == result.versions
    assert "machine" not in rec.result, "the messages stay the same on every machine"
    from mcap.reader import make_reader

    with open(path, "rb") as f:
        records = {r.name: r.metadata for r in make_reader(f).iter_metadata()}
    assert json.loads(records[MACHINE_METADATA]["numpy_simd"]) == m["numpy_simd"]
