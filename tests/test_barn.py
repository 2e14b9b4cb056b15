"""Static BARN worlds: import against the reference, the barn-static protocol, planners in them."""

import mujoco
import numpy as np
import pytest

from dynabarn.cli import worlds_main
from dynabarn.errors import ImportFormatError
from dynabarn.metrics import Outcome
from dynabarn.mjcf import load_model, read_world, write_world
from dynabarn.planners import get_planner
from dynabarn.protocol import get_protocol
from dynabarn.sim import run_episode
from dynabarn.worlds.importers.barn import cell_xy, import_barn_static, reference_length_check

NARROW_DWA = {"collision_radius": 0.26, "costmap.inscribed_radius": 0.22}


def test_imported_worlds_match_the_reference_cells(barn_json):
    worlds = import_barn_static(barn_json)
    assert len(worlds) == 300
    for w, ref in zip(worlds[::37], barn_json["worlds"][::37], strict=True):
        cyl = np.array(w.layout.cylinders)
        expected = np.array([[-0.075 - 0.15 * i, 0.075 + 0.15 * j] for i, j in ref["cells"]])
        np.testing.assert_allclose(cyl[:, :2], expected, atol=1e-9)
        assert np.all(cyl[:, 2] == 0.075) and len(cyl) == ref["n_cylinders"]
        assert w.layout.goal == tuple(ref["goal_link_xy"]) and w.obstacles == ()
        assert w.provenance["reference_path_length"] == pytest.approx(reference_length_check(w))


def test_world_files_hold_the_cylinders_and_load(barn_json, tmp_path):
    (world,) = import_barn_static({"worlds": [barn_json["worlds"][0]]})
    path = tmp_path / "barn_000.xml"
    write_world(world, path)
    assert read_world(path) == world
    m = load_model(path, beam_sensors=False)
    static = [i for i in range(m.ngeom) if m.geom(i).name.startswith("static_")]
    assert len(static) == barn_json["worlds"][0]["n_cylinders"]
    d = mujoco.MjData(m)
    d.qpos[:3] = get_protocol("barn-static").spawn
    mujoco.mj_forward(m, d)
    assert d.ncon == 0, "the spawn is free"


def test_cell_formula():
    np.testing.assert_allclose(cell_xy([[0, 0], [29, 63]]), [[-0.075, 0.075], [-4.425, 9.525]])


@pytest.mark.parametrize("wid", [50, 150])
def test_dwa_crosses_a_static_barn_world(barn_json, tmp_path, wid):
    (world,) = import_barn_static({"worlds": [barn_json["worlds"][wid]]})
    path = tmp_path / "w.xml"
    write_world(world, path)
    r = run_episode(path, get_planner("dwa", **NARROW_DWA), get_protocol("barn-static"), seed=0)
    assert r.outcome is Outcome.SUCCESS, r.summary()
    # Scored against the world's own reference path, clearance counts the static cylinders.
    ot = world.provenance["reference_path_length"] / 2.0
    assert r.score == pytest.approx(ot / min(max(r.time, 2 * ot), 8 * ot))
    assert 0.0 < r.min_clearance < 1.0


def test_cli_import_barn_static(barn_json, tmp_path, capsys):
    from tests.conftest import REFERENCE

    assert (
        worlds_main(
            ["import", str(REFERENCE / "barn300_static.json"), "--format", "barn-static", "--out", str(tmp_path)]
        )
        == 0
    )
    assert len(list(tmp_path.glob("barn300_static_*.xml"))) == 300  # named after the file by default
    bad = tmp_path / "bad.json"
    bad.write_text('{"worlds": [{"no": 1}]}')
    assert worlds_main(["import", str(bad), "--format", "barn-static", "--out", str(tmp_path / "o")]) == 2
    assert "not a barn-static file" in capsys.readouterr().err
    with pytest.raises(ImportFormatError):
        import_barn_static({"worlds": [{"cells": "x"}]})


@pytest.mark.slow
def test_barn_challenge_dwa_configuration_threads_the_static_worlds(barn_json, tmp_path):
    """With the BARN Challenge's own DWA configuration (preset `dwa_barn_challenge`), DWA
    crosses most static worlds; BARN's published example reports 0.88."""
    from dynabarn.cli.common import planner_config as _planner_config

    config = _planner_config("dwa_barn_challenge")
    worlds = import_barn_static({"worlds": barn_json["worlds"][::25]})  # 12 worlds, every difficulty
    outcomes = []
    for world in worlds:
        path = tmp_path / f"{world.name}.xml"
        write_world(world, path)
        outcomes.append(run_episode(path, get_planner("dwa", **config), get_protocol("barn-static"), seed=0).outcome)
    assert outcomes.count(Outcome.SUCCESS) >= 9, outcomes
