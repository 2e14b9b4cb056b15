"""Import of the original release's 60 worlds (skips without ../shared/reference)."""

import numpy as np
import pytest

from dynabarn.cli import worlds_main
from dynabarn.errors import ImportFormatError
from dynabarn.mjcf import load_model, read_world
from dynabarn.worlds.importers.release import import_release, load_release_json
from dynabarn.worlds.schedule import SchedulePlayer
from dynabarn.worldset import read_index


def test_import_plays_keyframes_like_gazebo(release_json):
    worlds = import_release(release_json)
    assert len(worlds) == 60
    assert [w.difficulty.value for w in worlds] == ["easy"] * 20 + ["medium"] * 20 + ["hard"] * 20
    for w, raw in zip(worlds, release_json["worlds"], strict=True):
        assert w.interpolation == "spline" and w.end_behavior == "loop"
        player = SchedulePlayer(w)
        for i, name in enumerate(raw["effective_obstacles"]):
            kf = np.asarray(release_json["plugins"][name]["keyframes"])
            for t, x, y in kf[:-1]:
                np.testing.assert_allclose(player.state(t)[0][i], [x, y], atol=1e-9)
            # The loop wraps at `duration`: back at the first keyframe.
            duration = release_json["plugins"][name]["duration"]
            np.testing.assert_allclose(player.state(duration)[0][i], kf[0, 1:], atol=1e-9)
            np.testing.assert_allclose(player.state(duration + 1e-9)[0][i], kf[0, 1:], atol=1e-6)


def test_effective_obstacles_differ_in_five_worlds(release_json):
    worlds = import_release(release_json)
    dup = [w.world_id for w in worlds if w.provenance["plugins"] != w.provenance["effective_plugins"]]
    assert dup == [23, 48, 56, 58, 59]


def test_cli_import_writes_loadable_worlds(release_path, tmp_path):
    assert worlds_main(["import", str(release_path), "--format", "dynabarn-release", "--out", str(tmp_path)]) == 0
    files = sorted(tmp_path.glob("release_*.xml"))
    assert len(files) == 60
    m = load_model(files[23])
    assert m.nmocap == 6
    assert read_world(files[23]).provenance["effective_plugins"][0] == "mediumlibobs_88"
    index = read_index(tmp_path)  # a world set like any other
    assert index["source_format"] == "dynabarn-release" and len(index["sets"]["hard"]) == 20


def test_original_hard_worlds_measure_harder_than_generated_ones(release_path, tmp_path, capsys):
    """`dynabarn-worlds stats`: the release's hard worlds keep the corridor blocked longer
    than our generated hard worlds with as many obstacles (README, comparison with the paper)."""
    assert worlds_main(["import", str(release_path), "--out", str(tmp_path)]) == 0
    capsys.readouterr()

    def hard_row(argv):
        assert worlds_main(["stats", *argv]) == 0
        row = next(line.split() for line in capsys.readouterr().out.splitlines() if line.startswith("hard"))
        names = ["worlds", "obst", "static", "blocked", "occup", "cross", "in_corr"]
        return dict(zip(names, map(float, row[1:8]), strict=True))

    original = hard_row([str(tmp_path)])
    generated = hard_row(["--worlds", "200-219"])
    assert original["worlds"] == generated["worlds"] == 20
    assert abs(original["obst"] - generated["obst"]) < 1.5
    assert original["blocked"] > generated["blocked"] + 0.1
    assert original["in_corr"] > generated["in_corr"] * 1.2


@pytest.mark.parametrize(
    "content, message",
    [
        ("not json", "not valid JSON"),
        ('{"worlds": []}', "needs 'plugins' and 'worlds'"),
    ],
)
def test_malformed_import_files(tmp_path, content, message):
    p = tmp_path / "bad.json"
    p.write_text(content)
    with pytest.raises(ImportFormatError, match=message):
        load_release_json(p)


def test_malformed_plugin(tmp_path):
    data = {"plugins": {"a": {"keyframes": [[0, 1]]}}, "worlds": [{"obstacles": ["a"]}]}
    with pytest.raises(ImportFormatError, match="keyframes must be"):
        import_release(data)
    data = {"plugins": {}, "worlds": [{"obstacles": ["a"]}]}
    with pytest.raises(ImportFormatError, match="unknown plugin"):
        import_release(data)
