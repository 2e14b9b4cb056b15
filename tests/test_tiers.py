"""The tiers beyond the paper's hard (issue 43): definitions, byte-for-byte regeneration, `--set NAME`."""

from __future__ import annotations

import json

import numpy as np
import pytest

from dynabarn.cli import bench_main, worlds_main
from dynabarn.worlds.generate import PAPER60
from dynabarn.worlds.tiers import TIERS, get_tier
from dynabarn.worldset import world_set
from dynabarn.worldset.tiers import generate_tier, tier_worlds


def test_the_tiers_are_what_the_issue_defines():
    """A denser tier (20-40 obstacles), a faster and more erratic one (speeds up to the
    Jackal's 2 m/s and a named step beyond, higher orders and variation than Table I), a
    mixed one (static BARN field, mixed shapes) and one that combines them; each on the
    paper's 60 ids with a seed of its own."""
    dense, fast, mixed, combined = (get_tier(n).profile() for n in TIERS)
    assert dense.profile_set.low_count[0] >= 20 and dense.profile_set.high_count == (30, 40)
    hard = {p.name: p for p in fast.profile_set.hard_motion}
    assert hard["jackal"].speed[1] == 2.0 and hard["beyond"].speed == (2.0, 2.5)
    assert min(p.order[1] for p in hard.values()) > 4 and min(p.std[1] for p in hard.values()) > 0.2
    assert mixed.static_field is not None and mixed.shapes is not None and not mixed.shapes.cylinders_only
    assert combined.static_field is not None and combined.shapes is not None
    assert combined.profile_set.hard_motion == fast.profile_set.hard_motion
    assert combined.profile_set.high_count[0] > 19
    assert all(get_tier(n).ids == PAPER60 for n in TIERS)
    assert len({get_tier(n).base_seed for n in TIERS}) == len(TIERS)


@pytest.mark.parametrize("name", list(TIERS))
def test_each_tier_regenerates_byte_for_byte(tmp_path, name):
    first, second = generate_tier(name, tmp_path / "a").parent, generate_tier(name, tmp_path / "b").parent
    files = sorted(p.name for p in first.iterdir() if p.is_file())
    assert len(files) == 61 and files == sorted(p.name for p in second.iterdir() if p.is_file())
    for f in files:
        assert (first / f).read_bytes() == (second / f).read_bytes(), f
    index = json.loads((first / "index.json").read_text())
    assert index["profile_set"]["name"] == name and index["base_seed"] == get_tier(name).base_seed
    assert index["profile_source"]["tier"] == name and len(index["profile_source"]["sha256"]) == 64
    counts = {d: [e["n_obstacles"] for e in index["worlds"] if e["difficulty"] == d] for d in ("easy", "hard")}
    assert len(index["worlds"]) == 60 and len(counts["easy"]) == 20 and len(counts["hard"]) == 20
    assert np.mean(counts["hard"]) >= np.mean(counts["easy"])


def test_a_tier_is_a_set_by_its_name(tmp_path, monkeypatch):
    """`--set tier-fast` generates the tier on first use and runs it; the sweep's worlds.json
    names the tier's profile."""
    monkeypatch.setattr("dynabarn.worldset.tiers.work_root", lambda: tmp_path)
    chosen = world_set("tier-fast", [200, 201])
    assert [w[0] for w in chosen] == [200, 201] and all(w[2] == "hard" for w in chosen)
    assert (tmp_path / "generated_tiers" / "tier-fast" / "index.json").is_file()
    out = tmp_path / "results"
    argv = ["--planner", "straight", "--no-floor", "--set", "tier-fast", "--worlds", "0,200", "--trials", "1"]
    assert bench_main([*argv, "--jobs", "1", "--out", str(out)]) == 0
    recorded = json.loads((out / "worlds.json").read_text())
    assert recorded["profiles"]["tier-fast"]["source"]["tier"] == "tier-fast"


def test_tier_generation_refuses_profile_options(tmp_path, capsys):
    assert worlds_main(["generate", "--tier", "tier-dense", "--hard-speed", "1,2", "--out", str(tmp_path / "x")]) == 2
    assert "--tier takes its profile from its own file" in capsys.readouterr().err
    assert worlds_main(["generate", "--tier", "all", "--out", str(tmp_path / "x")]) == 2
    assert not (tmp_path / "x").exists()


def test_workers_starting_together_never_see_half_a_tier(tmp_path, monkeypatch):
    """Four processes ask for the same tier at once: each gets the whole tier, one folder,
    no staging copy left behind."""
    import multiprocessing as mp

    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path))
    monkeypatch.setattr("dynabarn.worldset.tiers.work_root", lambda: tmp_path)
    with mp.get_context("fork").Pool(4) as pool:
        counts = pool.map(_count_tier_worlds, ["tier-dense"] * 4)
    assert counts == [60] * 4
    assert [p.name for p in (tmp_path / "generated_tiers").iterdir()] == ["tier-dense"]


def _count_tier_worlds(name: str) -> int:
    return len(world_set(name))


def test_a_redraw_is_the_next_seed_of_the_worlds_own_sequence():
    from dynabarn.worlds.generate import generate_world
    from dynabarn.worlds.profiles import get_profile_set

    table1 = get_profile_set("table1")
    first, again = generate_world(250, table1), generate_world(250, table1, draw=0)
    redrawn = generate_world(250, table1, draw=1)
    assert first == again and "draw" not in first.provenance
    assert redrawn != first and redrawn.provenance["draw"] == 1
    assert redrawn == generate_world(250, table1, draw=1)  # byte for byte, every time
    assert redrawn != generate_world(250, table1, draw=2) and redrawn != generate_world(251, table1, draw=1)


CERTIFIED_TIERS = ("tier-dense", "tier-fast", "tier-mixed", "tier-combined")
"""The tiers whose every world is certified for every trial (committed records)."""


@pytest.mark.parametrize("name", CERTIFIED_TIERS)
def test_every_world_of_a_certified_tier_is_certified_with_its_digest(name, tmp_path, monkeypatch):
    """Each world certified for trials 0-9, and the tier generated anywhere (here a cache
    folder outside the checkout) has exactly the bytes the certificates were computed for:
    the committed sha256 are the tier's golden digests."""
    tier = get_tier(name)
    record = tier.certified()
    assert record is not None and record["trials"] == 10
    assert sorted(map(int, record["certificates"])) == sorted(tier.ids)
    for certificates in record["certificates"].values():
        barn = certificates["barn"]
        assert barn["certified"] and [t["seed"] for t in barn["trials"]] == list(range(10))
    assert all(k >= 1 for k in record["draws"].values())
    monkeypatch.setattr("dynabarn.worldset.tiers.work_root", lambda: tmp_path)
    index = json.loads((tier_worlds(name) / "index.json").read_text())
    for entry in index["worlds"]:
        assert entry["sha256"] == record["certificates"][str(entry["id"])]["barn"]["sha256"]
        assert entry["certificates"]["barn"]["certified"]
        assert entry.get("draw", 0) == record["draws"].get(str(entry["id"]), 0)


def test_a_tier_folder_from_an_older_definition_is_made_again(tmp_path, monkeypatch):
    monkeypatch.setattr("dynabarn.worldset.tiers.work_root", lambda: tmp_path)
    folder = tier_worlds("tier-fast")
    index = json.loads((folder / "index.json").read_text())
    index["profile_source"]["certified"] = "an older record"
    (folder / "index.json").write_text(json.dumps(index))
    (folder / "world_000.xml").write_text("stale")
    assert tier_worlds("tier-fast") == folder
    assert (folder / "world_000.xml").read_text() != "stale"
    assert [p.name for p in (tmp_path / "generated_tiers").iterdir()] == ["tier-fast"]
