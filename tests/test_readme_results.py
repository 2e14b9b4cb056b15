"""The result tables of the README and the documentation are what the committed results say
(`make readme`)."""

import json
import subprocess
import sys
from pathlib import Path

import pytest

from dynabarn.bench import read_results

ROOT = Path(__file__).resolve().parents[1]
SCRIPT = ROOT / "benchmarks" / "readme_results.py"
RESULTS = ROOT / "results"


def test_readme_tables_match_the_committed_results():
    proc = subprocess.run([sys.executable, str(SCRIPT), "--check"], capture_output=True, text=True, cwd=ROOT)
    assert proc.returncode == 0, proc.stderr + proc.stdout


def test_every_planner_shares_the_floors_episodes():
    """Same seeds for every planner: each folder's floor ran every (world, seed) the others ran."""
    folders = [p for p in RESULTS.iterdir() if (p / "results.jsonl").is_file()]
    assert {p.name for p in folders} >= {"paper60_barn", "original60_barn", "unseen_barn"}
    for folder in folders:
        rows = [r for r in read_results(folder / "results.jsonl") if not r.get("retry")]
        assert rows and not [r for r in rows if r["outcome"] == "error"], folder
        floor = {(r["world"], r["seed"]) for r in rows if r["planner"] == "straight"}
        for r in rows:
            assert (r["world"], r["seed"]) in floor, (folder.name, r["planner"], r["world"], r["seed"])
        meta = json.loads((folder / "metadata.json").read_text())
        assert meta["protocol"]["name"] == "barn"


def test_the_check_fails_when_a_table_is_edited(tmp_path):
    """The check can fail: a page whose table was edited by hand is caught."""
    sys.path.insert(0, str(SCRIPT.parent))
    try:
        import readme_results
    finally:
        sys.path.remove(str(SCRIPT.parent))
    folders, summaries = readme_results.load_all()
    pages = readme_results.PAGES
    assert {b for blocks in pages.values() for b in blocks} == set(readme_results.BLOCKS)
    results_page = ROOT / "docs" / "results.md"
    text = results_page.read_text()
    blocks = pages[results_page]
    assert readme_results.render(text, folders, summaries, blocks) == text
    edited = text.replace("<!-- results:skill -->\n", "<!-- results:skill -->\n| made up |\n", 1)
    assert readme_results.render(edited, folders, summaries, blocks) == text
    with pytest.raises(SystemExit, match="no block"):
        readme_results.render(text.replace("<!-- results:floor -->", ""), folders, summaries, blocks)
    readme = (ROOT / "README.md").read_text()
    assert readme_results.render(readme, folders, summaries, pages[ROOT / "README.md"]) == readme
