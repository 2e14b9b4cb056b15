"""Motion profiles set by the user: `dynabarn-worlds generate --profile-file` and its options."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from dynabarn.cli import bench_main, worlds_main
from dynabarn.errors import ProfileError
from dynabarn.worlds.profile_file import read_profile_file

REPO = Path(__file__).resolve().parents[1]
EXAMPLE = REPO / "examples" / "profiles" / "sprint.toml"

SPRINT_AS_OPTIONS = """
name = "sprint"
high_count = [12, 24]
[[easy_motion]]
name = "easy"
order = [1, 2]
speed = [0.5, 1.0]
std = [0.01, 0.1]
[[hard_motion]]
name = "hard"
order = [3, 4]
speed = [2.0, 3.0]
std = [0.1, 0.3]
"""
"""Table I with the hard branch and the high count changed, as a file: what the options
`--hard-speed 2,3 --hard-std 0.1,0.3 --high-count 12,24 --profile-name sprint` make."""


def _generate(tmp_path: Path, name: str, *argv: str) -> Path:
    out = tmp_path / name
    assert worlds_main(["generate", "--out", str(out), *argv]) == 0
    return out


def test_the_tutorials_profile_draws_what_it_says(tmp_path):
    """The example of the tutorial: hard obstacles at 2-3 m/s, 12-24 of them on the high
    branch, Table I's easy ones; the set's index records the profile and the file's hash,
    and the same file gives the same bytes again."""
    from dynabarn.mjcf import read_world

    out = _generate(tmp_path, "a", "--profile-file", str(EXAMPLE))
    index = json.loads((out / "index.json").read_text())
    assert index["profile_set"]["name"] == "sprint" and index["profile_set"]["high_count"] == [12, 24]
    assert index["profile_source"]["file"] == "sprint.toml"
    assert len(index["profile_source"]["sha256"]) == 64 and "2-3 m/s" in index["profile_description"]
    for world_id in (0, 100, 150, 250):
        world = read_world(out / f"world_{world_id:03d}.xml")
        counts = (12, 24) if world.count_class.value == "high" else (5, 9)
        assert counts[0] <= len(world.obstacles) <= counts[1], world_id
        for o in world.obstacles:
            # Speeds measured back from the stored waypoints (positions and times to 6
            # digits): within 1 % of the profile's band.
            speeds = o.trajectory.segment_speeds()
            band = (2.0, 3.0) if o.trajectory.profile == "sprint" else (0.5, 1.0)
            assert 0.99 * band[0] <= np.min(speeds) and np.max(speeds) <= 1.01 * band[1], (world_id, o.name)
    assert any(o.trajectory.profile == "sprint" for o in read_world(out / "world_250.xml").obstacles)
    again = _generate(tmp_path, "b", "--profile-file", str(EXAMPLE))
    for name in ("world_000.xml", "world_250.xml", "index.json"):
        assert (out / name).read_bytes() == (again / name).read_bytes()


def test_options_make_the_same_worlds_as_the_same_profile_in_a_file(tmp_path):
    profile = tmp_path / "sprint.toml"
    profile.write_text(SPRINT_AS_OPTIONS)
    from_file = _generate(tmp_path, "file", "--profile-file", str(profile))
    options = ("--hard-speed", "2,3", "--hard-std", "0.1,0.3", "--high-count", "12,24", "--profile-name", "sprint")
    from_options = _generate(tmp_path, "options", *options)
    for world_id in (0, 120, 299):
        name = f"world_{world_id:03d}.xml"
        assert (from_file / name).read_bytes() == (from_options / name).read_bytes()
    index = json.loads((from_options / "index.json").read_text())
    assert index["profile_source"] == {
        "profiles": "table1",
        "options": {"hard_speed": "2,3", "hard_std": "0.1,0.3", "high_count": "12,24", "profile_name": "sprint"},
    }
    # Options change a file's values too: the file's hard obstacles slowed down.
    slower = _generate(tmp_path, "slower", "--profile-file", str(profile), "--hard-speed", "1.0,1.5")
    assert json.loads((slower / "index.json").read_text())["profile_set"]["hard_motion"][0]["speed"] == [1.0, 1.5]


def test_a_custom_profile_never_lands_in_the_shipped_folder_by_default(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    assert worlds_main(["generate", "--easy-speed", "0.6,0.9"]) == 0
    index = json.loads((tmp_path / "table1-custom_worlds" / "index.json").read_text())
    assert index["profile_set"]["name"] == "table1-custom" and not (tmp_path / "generated_worlds").exists()
    # Not the paper's worlds, though drawn from Table I changed by an option: no paper column.
    from dynabarn.worldset import paper_world_ids

    assert paper_world_ids(index) == set() and len(index["sets"]["paper60"]) == 60


def test_a_sweep_records_the_profile_its_worlds_were_drawn_from(tmp_path):
    worlds = _generate(tmp_path, "w", "--profile-file", str(EXAMPLE))
    out = tmp_path / "results"
    argv = ["--planner", "straight", "--no-floor", "--set", str(worlds), "--worlds", "0,250", "--trials", "1"]
    assert bench_main([*argv, "--jobs", "1", "--out", str(out)]) == 0
    recorded = json.loads((out / "worlds.json").read_text())
    assert {w["profile_set"] for w in recorded["worlds"]} == {"sprint"}
    assert recorded["profiles"]["sprint"]["source"]["file"] == "sprint.toml"
    assert recorded["profiles"]["sprint"]["profile_set"]["hard_motion"][0]["speed"] == [2.0, 3.0]
    rows = [json.loads(line) for line in (out / "results.jsonl").read_text().splitlines()]
    assert len(rows) == 2 and {r["profile_set"] for r in rows} == {"sprint"}  # every row names it


BAD_PROFILES = [
    ("profile.toml", "name = 'x'\n[[easy_motion]\n", "not valid TOML"),
    ("profile.json", "{", "not valid JSON"),
    ("profile.json", "[1, 2]", "must be a table"),
    ("profile.toml", "name = 'x'\n", "easy_motion: missing"),
    ("profile.toml", "colour = 'red'\n" + SPRINT_AS_OPTIONS, "the profile: unknown key 'colour'"),
    ("profile.toml", SPRINT_AS_OPTIONS.replace("speed = [2.0, 3.0]", "speed = [3.0, 2.0]"), "has min > max"),
    ("profile.toml", SPRINT_AS_OPTIONS.replace("speed = [2.0, 3.0]", "speed = [0.0, 2.0]"), "must be positive"),
    ("profile.toml", SPRINT_AS_OPTIONS.replace("speed = [2.0, 3.0]", "speed = [2.0, nan]"), "must be finite"),
    ("profile.toml", SPRINT_AS_OPTIONS.replace("speed = [2.0, 3.0]", "speed = [2.0, 'fast']"), "must be a number"),
    ("profile.toml", SPRINT_AS_OPTIONS.replace("speed = [2.0, 3.0]", "speed = [2.0]"), "[min, max] pair"),
    ("profile.toml", SPRINT_AS_OPTIONS.replace("order = [3, 4]", "order = [3, 12]"), "cannot be fitted"),
    ("profile.toml", SPRINT_AS_OPTIONS.replace("order = [3, 4]", "order = [2.5, 4]"), "whole number"),
    ("profile.toml", SPRINT_AS_OPTIONS.replace("[12, 24]", "[0, 24]"), "minimum must be >= 1"),
    ("profile.toml", "shapes = 'blobs'\n" + SPRINT_AS_OPTIONS, "shapes must be cylinder"),
    ("profile.toml", "behavior = 'dance'\n" + SPRINT_AS_OPTIONS, "behavior 'dance': not one of"),
    ("profile.toml", SPRINT_AS_OPTIONS + "[behavior]\nname = 'yield'\nparams = {zoom = 1.0}\n", "no parameter"),
    ("profile.toml", SPRINT_AS_OPTIONS + "[static]\nfill = [0.3, 1.5]\n", "fill must be below 1"),
    ("profile.toml", "x" * (1 << 20 + 1), "not a profile file"),
    ("profile.toml", b"\xff\xfe", "not UTF-8"),
]


@pytest.mark.parametrize("name, content, message", BAD_PROFILES, ids=[m for _, _, m in BAD_PROFILES])
def test_a_bad_profile_file_is_one_line_and_exit_2(tmp_path, capsys, name, content, message):
    path = tmp_path / name
    path.write_bytes(content if isinstance(content, bytes) else content.encode())
    assert worlds_main(["generate", "--profile-file", str(path), "--out", str(tmp_path / "out")]) == 2
    err = [line for line in capsys.readouterr().err.splitlines() if line.strip()]
    assert len(err) == 1 and message in err[0] and str(path) in err[0], err
    assert not (tmp_path / "out").exists(), "nothing is written for a refused profile"


@pytest.mark.parametrize(
    "argv, message",
    [
        (["--hard-speed", "2"], "--hard-speed '2': expected MIN,MAX"),
        (["--low-count", "9,5"], "low_count [9, 5] has min > max"),
        (["--easy-std=-0.1,0.1"], "below 0.0"),
        (["--profile-file", "missing.toml"], "no such profile file"),
    ],
)
def test_bad_profile_options_are_one_line_and_exit_2(tmp_path, capsys, monkeypatch, argv, message):
    monkeypatch.chdir(tmp_path)
    assert worlds_main(["generate", *argv]) == 2
    err = [line for line in capsys.readouterr().err.splitlines() if line.strip()]
    assert len(err) == 1 and message in err[0], err
    assert list(tmp_path.iterdir()) == []


def test_a_profile_file_read_from_python_is_the_profile_set_the_generator_takes():
    from dynabarn.worlds.generate import generate_world

    profile = read_profile_file(EXAMPLE)
    world = generate_world(250, profile.profile_set)
    assert world.profile_set == "sprint" and 12 <= len(world.obstacles) <= 24
    with pytest.raises(ProfileError, match="no such profile file"):
        read_profile_file(EXAMPLE.with_name("absent.toml"))


def test_a_profile_file_sets_the_variants_beyond_the_paper(tmp_path):
    """Shapes by a shipped name, a static field as a table of its fields, a behaviour with
    parameters: each reaches the world as it would from the options."""
    from dynabarn.sim.behaviors import get_behavior
    from dynabarn.worlds.generate import generate_world

    first = next(iter(get_behavior("yield").defaults()))
    path = tmp_path / "variants.toml"
    path.write_text(
        "shapes = 'mixed'\n"
        + SPRINT_AS_OPTIONS
        + "[static]\nname = 'sparse'\nfill = [0.30, 0.32]\nsmooth_iterations = 2\n"
        + f"[behavior]\nname = 'yield'\nparams = {{{first} = 0.5}}\n"
    )
    profile = read_profile_file(path)
    assert profile.shapes.name == "mixed" and profile.static_field.fill == (0.30, 0.32)
    assert profile.behavior == "yield" and profile.behavior_params == {first: 0.5}
    world = generate_world(
        250,
        profile.profile_set,
        shapes=profile.shapes,
        static_field=profile.static_field,
        behavior=profile.behavior,
        behavior_params=get_behavior("yield").defaults() | profile.behavior_params,
    )
    assert {o.shape for o in world.obstacles} > {"cylinder"} and world.layout.cylinders
    assert all(o.behavior == "yield" and o.behavior_params[first] == 0.5 for o in world.obstacles)
    assert world.provenance["static_field"]["name"] == "sparse"
