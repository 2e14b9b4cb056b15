"""Import of the original release's 60 worlds (skips without ../shared/reference)."""

import json

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
    files = sorted(tmp_path.glob("dynabarn60_*.xml"))  # the set's name: the file's, by default
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
        names = ["set", "worlds", "obst", "outside", "static", "blocked", "occup", "cross", "in_corr"]
        return dict(zip(names, [row[1], *map(float, row[2:10])], strict=True))

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
    data = {"plugins": {"a": {"keyframes": [[0, 1]]}}, "worlds": [{"id": 0, "obstacles": ["a"]}]}
    with pytest.raises(ImportFormatError, match="keyframes must be"):
        import_release(data)
    data = {"plugins": {}, "worlds": [{"id": 0, "obstacles": ["a"]}]}
    with pytest.raises(ImportFormatError, match="unknown plugin"):
        import_release(data)


# -- labels from the data, not the order (issue 20) -----------------------------------------

EXPECTED = {**dict.fromkeys(range(20), "easy"), **dict.fromkeys(range(20, 40), "medium")}
EXPECTED |= dict.fromkeys(range(40, 60), "hard")
"""The release's own difficulty of each world id."""


def _labels(worlds) -> dict[int, tuple[str, str, str]]:
    return {w.world_id: (w.difficulty.value, w.count_class.value, w.motion_class.value) for w in worlds}


def test_labels_and_names_come_from_each_world(release_json, release_path):
    worlds = import_release(load_release_json(release_path), name="r60")
    for w, raw in zip(worlds, release_json["worlds"], strict=True):
        n = len(raw["obstacles"])
        assert w.name == f"r60_{raw['id']:03d}" and w.world_id == raw["id"]
        assert w.count_class.value == ("low" if n <= 9 else "high")
        assert w.motion_class.value == ("easy" if raw["difficulty"] == "easy" else "hard")
        assert w.difficulty.value == EXPECTED[w.world_id]  # the data give the release's own labels
        assert w.provenance["paper_set"] == "release60" and w.provenance["recommended_protocol"] == "paper2022"
        assert len(w.provenance["source_sha256"]) == 64 and w.provenance["source_file"] == "dynabarn60.json"


def test_reordered_and_subset_files_keep_every_label(release_json):
    forward = _labels(import_release(release_json))
    reversed_file = release_json | {"worlds": release_json["worlds"][::-1]}
    assert _labels(import_release(reversed_file)) == forward
    rng = np.random.default_rng(0)
    shuffled = release_json | {"worlds": [release_json["worlds"][i] for i in rng.permutation(60)]}
    assert _labels(import_release(shuffled)) == forward
    hard_only = release_json | {"worlds": release_json["worlds"][40:]}
    worlds = import_release(hard_only, name="hard20")
    assert {w.difficulty.value for w in worlds} == {"hard"} and len(worlds) == 20
    assert [w.name for w in worlds] == [f"hard20_{i:03d}" for i in range(40, 60)]


def _with_extra_obstacles(release_json, extra: dict[int, int]) -> dict:
    """The release with `extra[id]` more obstacles in some worlds (new plugins, copies of
    the world's first plugin's motion under new names of the same level)."""
    plugins = dict(release_json["plugins"])
    worlds = []
    for w in release_json["worlds"]:
        w = dict(w)
        for k in range(extra.get(w["id"], 0)):
            first = w["obstacles"][0]
            new = f"{first.split('_')[0]}_{900 + 100 * w['id'] + k}"
            plugins[new] = plugins[first]
            w["obstacles"] = [*w["obstacles"], new]
            w["effective_obstacles"] = [*w["effective_obstacles"], new]
            w.pop("n_obstacles", None)
            w.pop("plugin_difficulty_counts", None)
        worlds.append(w)
    return release_json | {"plugins": plugins, "worlds": worlds}


def test_extra_obstacles_change_the_classes_and_say_so(release_json, tmp_path, capsys):
    counts = {w["id"]: len(w["obstacles"]) for w in release_json["worlds"]}
    # world 5: easy motion, 7 -> 12 obstacles (high + easy: medium); world 25: hard motion,
    # low count -> 10 (high + hard: hard); world 45: 24 obstacles, beyond the paper's 19.
    extra = {5: 12 - counts[5], 25: 10 - counts[25], 45: 24 - counts[45]}
    data = _with_extra_obstacles(release_json, extra)
    labels = _labels(import_release(data))
    assert labels[5] == ("medium", "high", "easy")
    assert labels[25] == ("hard", "high", "hard")
    assert labels[45] == ("hard", "above-high", "hard")
    unchanged = {i: v for i, v in labels.items() if i not in extra}
    assert unchanged == {i: v for i, v in _labels(import_release(release_json)).items() if i not in extra}
    worlds = {w.world_id: w for w in import_release(data)}
    assert all(worlds[i].provenance["paper_set"] is None for i in extra)  # no longer the paper's worlds
    assert worlds[45].provenance["recommended_protocol"] == "barn"
    # The command says so, `worlds show` and `stats` report it.
    src = tmp_path / "barn24.json"
    src.write_text(json.dumps({k: v for k, v in data.items() if k != "_source"}))
    out = tmp_path / "w"
    assert worlds_main(["import", str(src), "--out", str(out)]) == 0
    printed = capsys.readouterr().out
    assert "note: 1 world(s) with more than 19 obstacles (24): count class above-high" in printed
    assert worlds_main(["show", str(out / "barn24_045.xml")]) == 0
    assert "above-high" in capsys.readouterr().out
    assert worlds_main(["stats", str(out)]) == 0
    hard = next(line.split() for line in capsys.readouterr().out.splitlines() if line.startswith("hard"))
    assert hard[1] == str(out) and float(hard[4]) == 1.0  # one world outside the paper's counts
    index = read_index(out)
    assert len(index["sets"]["paper60"]) == 57


def test_two_imported_sets_never_collide(release_path, tmp_path, capsys):
    a, b = tmp_path / "a", tmp_path / "b"
    assert worlds_main(["import", str(release_path), "--out", str(a), "--name", "first"]) == 0
    assert worlds_main(["import", str(release_path), "--out", str(b), "--name", "second"]) == 0
    names_a = {e["name"] for e in read_index(a)["worlds"]}
    names_b = {e["name"] for e in read_index(b)["worlds"]}
    assert len(names_a) == len(names_b) == 60 and not names_a & names_b
    assert worlds_main(["import", str(release_path), "--out", str(b), "--name", "no spaces"]) == 2
    assert "set name 'no spaces'" in capsys.readouterr().err


def _problem_file(tmp_path, release_json, edit) -> tuple[int, str]:
    data = json.loads(json.dumps({k: v for k, v in release_json.items() if k != "_source"}))
    edit(data)
    p = tmp_path / "bad.json"
    p.write_text(json.dumps(data))
    return p


def test_every_problem_is_one_line(release_json, tmp_path, capsys):
    def edit(data):
        w = data["worlds"]
        w[0]["difficulty"] = "hard+medium"  # over easylibobs_* plugins
        w[3]["id"] = 2  # the same id twice
        w[7]["obstacles"][1] = "easylibobs_9999"  # no such plugin
        w[8]["obstacles"][1] = w[8]["obstacles"][0]  # listed twice
        w[21]["difficulty"] = "easy"  # over hard and medium plugins
        kf = data["plugins"]["hardlibobs_3"]["keyframes"]
        kf[2][0] = kf[1][0]  # keyframe times not increasing
        data["plugins"]["mediumlibobs_7"]["difficulty"] = "easy"  # its name says medium

    path = _problem_file(tmp_path, release_json, edit)
    assert worlds_main(["import", str(path), "--out", str(tmp_path / "out")]) == 2
    err = capsys.readouterr().err
    lines = [line.strip() for line in err.splitlines()]
    expected = [
        "world #0 (id 0): difficulty 'hard+medium' but its plugins",
        "world #3 (id 2): the same id as world #2",
        "world #7 (id 7): unknown plugin(s) 'easylibobs_9999'",
        "world #8 (id 8): plugin(s)",
        "world #21 (id 21): difficulty 'easy' but its plugins",
        "plugin 'hardlibobs_3': keyframe times are not increasing",
        "plugin 'mediumlibobs_7': its name says medium but its difficulty field says easy",
    ]
    for start in expected:
        assert sum(line.startswith(start) for line in lines) == 1, (start, err)
    assert "Traceback" not in err and not (tmp_path / "out").exists()


def test_the_paper_column_only_for_the_papers_worlds(tmp_path):
    """Generated paper60 worlds and the recognised release worlds are the paper's; a variant
    of the generated worlds is not, and a summary of its runs leaves the paper column blank."""
    from dynabarn.bench import summarise
    from dynabarn.provenance import worlds_dir
    from dynabarn.worlds.generate import PAPER60
    from dynabarn.worldset import paper_world_ids

    assert paper_world_ids(read_index(worlds_dir())) == set(PAPER60)
    variant = tmp_path / "mixed"
    assert worlds_main(["generate", "--shapes", "mixed", "--out", str(variant)]) == 0
    assert "paper60" in read_index(variant)["sets"] and paper_world_ids(read_index(variant)) == set()
    rows = [
        {"planner": "dwa", "difficulty": "easy", "protocol": "barn", "world": f"world_00{i}", "outcome": "success"}
        for i in range(3)
    ]
    assert summarise(rows, {"world_000", "world_001", "world_002"})[0]["paper"] == 0.78
    assert summarise(rows, {"world_000", "world_001"})[0]["paper"] is None  # one world is not the paper's
    assert summarise(rows)[0]["paper"] is None
