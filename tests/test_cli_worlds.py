"""`dynabarn-worlds` through its real entry point: exit codes and first lines."""

import subprocess
import sys

import pytest

from dynabarn.cli import worlds_main


def test_show_prints_summary_and_plot(tmp_path, capsys):
    png = tmp_path / "w.png"
    assert worlds_main(["show", "137", "--plot", str(png)]) == 0
    out = capsys.readouterr().out
    assert out.startswith("world_137") and "difficulty medium" in out
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n" and png.stat().st_size > 20_000


def test_show_lists_shapes_and_static_cylinders_of_a_mixed_world(tmp_path, capsys):
    import numpy as np
    from PIL import Image

    from dynabarn.mjcf import write_world
    from dynabarn.worlds.generate import generate_world
    from dynabarn.worlds.profiles import SHAPE_MIXES, STATIC_FIELDS, get_profile_set

    world = generate_world(
        250, get_profile_set("table1"), shapes=SHAPE_MIXES["mixed"], static_field=STATIC_FIELDS["barn-grid"]
    )
    path = tmp_path / "world_250.xml"
    write_world(world, path)
    png = tmp_path / "w.png"
    assert worlds_main(["show", str(path), "--plot", str(png)]) == 0
    out = capsys.readouterr().out
    assert f"static cylinders: {len(world.layout.cylinders)}" in out
    assert "box " in out and "capsule r " in out
    # The static field is drawn: thousands of its dark grey pixels (the plain world 250 has ~440).
    pixels = np.asarray(Image.open(png).convert("RGB")).astype(int)
    dark = (np.abs(pixels - 77).max(axis=2) < 12).sum()
    assert dark > 2000


def test_generate_subset_is_byte_identical(tmp_path):
    from dynabarn.provenance import SHIPPED_WORLDS
    from dynabarn.worlds.profiles import get_profile_set
    from dynabarn.worldset import generate_worlds

    generate_worlds(get_profile_set("table1"), tmp_path, world_ids=[0, 137, 299])

    def without_robot_path(text: str) -> list[str]:
        # The robot is referenced relative to the world's folder; everything else is equal.
        return [line for line in text.splitlines() if '<model name="jackal"' not in line]

    for name in ("world_000.xml", "world_137.xml", "world_299.xml"):
        ours, committed = (tmp_path / name).read_text(), (SHIPPED_WORLDS / name).read_text()
        assert without_robot_path(ours) == without_robot_path(committed)
        assert len(ours.splitlines()) == len(committed.splitlines())


@pytest.mark.parametrize(
    "argv, first_line",
    [
        (["show", "300"], "error: unknown world id 300"),
        (["show", "no/such/world.xml"], "error: world not found"),
        (["import", "no_such_file.json"], "error: import file not found"),
    ],
)
def test_bad_input_gives_one_line(argv, first_line, capsys):
    assert worlds_main(argv) == 2
    err = capsys.readouterr().err
    assert err.startswith(first_line) and err.count("\n") == 1


def test_not_a_world_file(tmp_path, capsys):
    p = tmp_path / "x.xml"
    p.write_text("<mujoco/>")
    assert worlds_main(["show", str(p)]) == 2
    assert "not a DynaBARN world" in capsys.readouterr().err


def test_malformed_import_file(tmp_path, capsys):
    p = tmp_path / "x.json"
    p.write_text("{ nope")
    assert worlds_main(["import", str(p), "--out", str(tmp_path / "o")]) == 2
    assert "not valid JSON" in capsys.readouterr().err


def test_console_script_has_no_traceback(tmp_path):
    exe = [sys.executable, "-m", "dynabarn.cli", "worlds", "show", "999"]
    r = subprocess.run(exe, capture_output=True, text=True)
    assert r.returncode == 2 and "Traceback" not in r.stderr and r.stderr.startswith("error:")


def test_help_explains_defaults(capsys):
    with pytest.raises(SystemExit):
        worlds_main(["generate", "--help"])
    out = " ".join(capsys.readouterr().out.split())
    assert "--profiles" in out and "(default: table1)" in out and "(default: 2022)" in out
