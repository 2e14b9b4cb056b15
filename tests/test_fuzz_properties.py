"""The generated part of the fuzz suite: valid files mutated by Hypothesis, at the byte level
and in their structure. Whatever the mutation, a reader either takes the file or refuses
it with one `DynabarnError` (one line on the command line); never another exception, and
never a hang (each example runs under an alarm).

The examples are derandomised: every run tries the same ones, so a failure reproduces;
adding examples or strategies is how the suite grows (`tests/test_fuzz.py` holds the table
of hand-made cases)."""

from __future__ import annotations

import contextlib
import json
import signal
import tempfile
import xml.etree.ElementTree as ET
from pathlib import Path

import pytest

from dynabarn.errors import DynabarnError
from dynabarn.provenance import SHIPPED_WORLDS
from tests.conftest import require

hypothesis = require("hypothesis", "test")
from hypothesis import HealthCheck, given, settings  # noqa: E402
from hypothesis import strategies as st  # noqa: E402

pytestmark = pytest.mark.slow  # a few hundred examples: `make test` runs them

WORLD = SHIPPED_WORLDS / "world_137.xml"
WORLD_BYTES = WORLD.read_bytes()
EXAMPLE_SECONDS = 30
"""Longest one example may take (a world compiles in milliseconds) before it counts as a hang."""

FUZZ = settings(
    max_examples=60, deadline=None, derandomize=True, suppress_health_check=[HealthCheck.too_slow], database=None
)


@contextlib.contextmanager
def no_hang(seconds: int = EXAMPLE_SECONDS):
    def hang(signum, frame):
        raise AssertionError(f"an example took over {seconds} s: a hang")

    previous = signal.signal(signal.SIGALRM, hang)
    signal.alarm(seconds)
    try:
        yield
    finally:
        signal.alarm(0)
        signal.signal(signal.SIGALRM, previous)


def _kind(exc: Exception) -> str:
    """The gist of a refusal, for Hypothesis's statistics (`--hypothesis-show-statistics`)."""
    return str(exc).split(": ", 1)[-1][:40]


def _scratch() -> Path:
    return Path(tempfile.mkdtemp(prefix="dynabarn-fuzz-"))


# -- strategies ------------------------------------------------------------------------------

TEXT_VALUES = st.sampled_from(
    ["", "0", "-1", "1e308", "-1e308", "nan", "inf", "1 2", "1 2 3 4 5 6 7 8 9", "abc", "9" * 400, "0x10", "<", "&amp;"]
) | st.text(max_size=20)
TAGS = st.sampled_from(
    ["geom", "body", "replicate", "include", "hfield", "mesh", "flexcomp", "texture", "numeric", "text", "frame",
     "joint", "site", "light", "material", "model", "attach", "composite", "skin", "plugin", "x"]
)  # fmt: skip
ATTRIBUTES = st.sampled_from(
    ["size", "pos", "quat", "type", "name", "data", "file", "count", "width", "height", "rgba", "mocap", "model",
     "prefix", "body", "timestep", "nrow", "ncol", "builtin", "texture", "content_type", "offwidth"]
)  # fmt: skip


@st.composite
def byte_mutations(draw, data: bytes) -> bytes:
    """A few bytes replaced, inserted or deleted, or the file cut."""
    out = bytearray(data)
    for _ in range(draw(st.integers(1, 4))):
        at = draw(st.integers(0, max(0, len(out) - 1)))
        kind = draw(st.sampled_from(["replace", "insert", "delete", "cut"]))
        byte = draw(st.integers(0, 255))
        if kind == "replace" and out:
            out[at] = byte
        elif kind == "insert":
            out.insert(at, byte)
        elif kind == "delete" and out:
            del out[at]
        elif kind == "cut":
            del out[at:]
    return bytes(out)


@st.composite
def tree_mutations(draw, data: bytes) -> bytes:
    """The parsed world changed as a person editing it might: an attribute set to an odd
    value, an element removed, copied, renamed or added."""
    root = ET.fromstring(data)
    for _ in range(draw(st.integers(1, 3))):
        elements = list(root.iter())
        element = elements[draw(st.integers(0, len(elements) - 1))]
        kind = draw(st.sampled_from(["attribute", "remove", "copy", "rename", "add"]))
        parents = {child: parent for parent in root.iter() for child in parent}
        if kind == "attribute":
            element.set(draw(ATTRIBUTES), draw(TEXT_VALUES))
        elif kind == "remove" and element in parents:
            parents[element].remove(element)
        elif kind == "copy" and element in parents:
            for _ in range(draw(st.integers(1, 50))):
                parents[element].append(ET.fromstring(ET.tostring(element)))
        elif kind == "rename":
            element.tag = draw(TAGS)
        elif kind == "add":
            child = ET.SubElement(element, draw(TAGS))
            child.set(draw(ATTRIBUTES), draw(TEXT_VALUES))
    return ET.tostring(root)


# -- worlds ----------------------------------------------------------------------------------


def _load_world(data: bytes) -> None:
    """What `dynabarn-run` does with a world before the episode: read, compile, set up."""
    from dynabarn.mjcf import load_model, read_world
    from dynabarn.sim import Simulation

    path = _scratch() / "world.xml"
    path.write_bytes(data)
    with no_hang(), contextlib.chdir(path.parent):  # MuJoCo's warnings go to ./MUJOCO_LOG.TXT
        try:
            read_world(path)
            load_model(path)
            Simulation(path)
            hypothesis.event("accepted")
        except DynabarnError as exc:
            assert "\n" not in str(exc).strip(), str(exc)
            hypothesis.event(f"refused: {_kind(exc)}")


@FUZZ
@given(st.data())
def test_a_world_with_bytes_changed_loads_or_is_one_clear_error(data):
    _load_world(data.draw(byte_mutations(WORLD_BYTES)))


@FUZZ
@given(st.data())
def test_a_world_edited_in_its_structure_loads_or_is_one_clear_error(data):
    _load_world(data.draw(tree_mutations(WORLD_BYTES)))


# -- recordings ------------------------------------------------------------------------------


@pytest.fixture(scope="module")
def recording_bytes() -> bytes:
    from dynabarn.planners import get_planner
    from dynabarn.protocol import get_protocol
    from dynabarn.recording import McapRecorder
    from dynabarn.sim import run_episode

    path = _scratch() / "dwa.mcap"
    run_episode(WORLD, get_planner("dwa"), get_protocol("barn"), seed=0, observers=[McapRecorder(path)])
    return path.read_bytes()


@FUZZ
@given(st.data())
def test_a_damaged_recording_reads_up_to_the_damage_or_is_one_clear_error(recording_bytes, data):
    """What replay, render and the dataset export read of a recording, after damage."""
    from dynabarn.demos.dataset import episode_rows
    from dynabarn.recording import pose_track, read_recording, recorded_world

    path = _scratch() / "damaged.mcap"
    path.write_bytes(data.draw(byte_mutations(recording_bytes)))
    with no_hang():
        try:
            rec = read_recording(path)
            recorded_world(rec)
            pose_track(rec)
            episode_rows(rec, lookahead=2.0)
            hypothesis.event("read, cut" if rec.truncated else "read whole")
        except DynabarnError as exc:
            assert "\n" not in str(exc).strip(), str(exc)
            hypothesis.event(f"refused: {_kind(exc)}")


# -- results ---------------------------------------------------------------------------------

JSON_VALUES = st.recursive(
    st.none() | st.booleans() | st.integers() | st.floats(allow_nan=False) | st.text(max_size=10),
    lambda children: st.lists(children, max_size=3) | st.dictionaries(st.text(max_size=5), children, max_size=3),
    max_leaves=6,
)


@pytest.fixture(scope="module")
def result_rows() -> list[dict]:
    from dynabarn.bench import read_results

    rows = read_results(Path(__file__).resolve().parent.parent / "results" / "paper60_barn" / "results.jsonl")
    assert rows
    return [r for r in rows if r["planner"] in ("straight", "dwa")][:40]


@FUZZ
@given(st.data())
def test_a_results_file_edited_or_torn_is_summarised_or_skipped(result_rows, data):
    """Rows with fields of another type, foreign lines and torn lines: the readers keep the
    rows they can use, the summary never fails, and resuming drops the rest."""
    from dynabarn.bench import read_results, summarise
    from dynabarn.bench.results import prepare_resume

    rows = [dict(r) for r in result_rows]
    for _ in range(data.draw(st.integers(1, 4))):
        row = rows[data.draw(st.integers(0, len(rows) - 1))]
        row[data.draw(st.sampled_from([*row, "extra"]))] = data.draw(JSON_VALUES)
    lines = [json.dumps(r) for r in rows]
    if data.draw(st.booleans()):
        lines.insert(data.draw(st.integers(0, len(lines))), data.draw(st.text(max_size=30)))
    text = "\n".join(lines)
    if data.draw(st.booleans()):
        text = text[: data.draw(st.integers(0, len(text)))]  # torn by a crash
    path = _scratch() / "results.jsonl"
    path.write_text(text)
    with no_hang():
        kept = read_results(path)
        summarise(kept)
        assert len(prepare_resume(path)) <= len(kept)
