"""A sweep's report.html in a real browser, and `dynabarn-bench --verify` on real results."""

from __future__ import annotations

import json
import shutil
import time
from pathlib import Path

import pytest

from dynabarn.bench.report import OUTCOME_COLOURS, REPORT, STILLS, write_report
from dynabarn.bench.row_rules import parse_key
from dynabarn.bench.verify import sample_rows
from dynabarn.cli.bench import bench_main
from dynabarn.errors import DynabarnError
from tests.browser import Browser, chromium

REPO = Path(__file__).resolve().parents[1]


@pytest.fixture(scope="module")
def sweep(tmp_path_factory) -> Path:
    """DWA and the floor on three hard worlds, two trials, failures recorded."""
    out = tmp_path_factory.mktemp("report") / "sweep"
    argv = ["--planner", "dwa", "--set", "paper60", "--worlds", "200,201,202", "--trials", "2"]
    assert bench_main([*argv, "--jobs", "1", "--record", "failures", "--out", str(out)]) == 0
    return out


def _rows(out: Path) -> list[dict]:
    return [json.loads(line) for line in (out / "results.jsonl").read_text().splitlines()]


def test_every_sweep_writes_its_report_with_a_still_per_recording(sweep):
    html = (sweep / REPORT).read_text()
    rows = _rows(sweep)
    recorded = [r for r in rows if r.get("recording")]
    assert recorded, "hard worlds at two trials: the floor fails somewhere"
    assert len(list((sweep / STILLS).glob("*.png"))) == len(recorded)
    assert html.count('class="cell ') == len(rows)
    assert "https://" not in html and "http://" not in html  # nothing to fetch
    assert "Content-Security-Policy" in html


@pytest.mark.slow
@pytest.mark.skipif(chromium() is None, reason="needs Debian's chromium: sudo make system-deps")
def test_the_report_opens_offline_and_sorts_in_chromium(sweep):
    rows = _rows(sweep)
    with Browser() as browser:
        browser.call("Network.enable")
        browser.open((sweep / REPORT).resolve().as_uri())
        deadline = time.monotonic() + 30
        while browser.evaluate("document.readyState") != "complete" and time.monotonic() < deadline:
            time.sleep(0.2)
        urls = browser.requests()
        assert urls and all(u.startswith(("file://", "data:")) for u in urls), urls
        cells = browser.evaluate(
            "Array.from(document.querySelectorAll('td.cell')).map(c => "
            "[c.dataset.outcome, getComputedStyle(c).backgroundColor])"
        )
        assert len(cells) == len(rows)
        for outcome, colour in cells:
            hex_ = OUTCOME_COLOURS[outcome].lstrip("#")
            assert colour == "rgb({}, {}, {})".format(*(int(hex_[i : i + 2], 16) for i in (0, 2, 4)))
        grid = "document.querySelector('details[data-planner=\"straight\"] tbody')"
        before = browser.evaluate(f"Array.from({grid}.rows).map(r => r.dataset.world)")
        successes = browser.evaluate(f"Array.from({grid}.rows).map(r => +r.dataset.successes)")
        browser.evaluate(
            "(() => { const s = document.getElementById('sort'); s.value = 'successes';"
            " s.dispatchEvent(new Event('change')); })()"
        )
        after = browser.evaluate(f"Array.from({grid}.rows).map(r => +r.dataset.successes)")
        assert after == sorted(successes)
        if successes != sorted(successes):
            assert browser.evaluate(f"Array.from({grid}.rows).map(r => r.dataset.world)") != before
        # Each recorded failure: its still loaded, its link names a file that is there.
        shown = browser.evaluate(
            "Array.from(document.querySelectorAll('figure.recording')).map(f => "
            "[f.querySelector('img').naturalWidth, f.querySelector('a.replay').href])"
        )
        assert len(shown) == sum(1 for r in rows if r.get("recording"))
        for width, href in shown:
            assert width > 0
            assert Path(href.removeprefix("file://")).is_file() and href.endswith(".mcap")


def test_report_of_an_existing_folder_and_of_no_folder(sweep, tmp_path, capsys):
    (sweep / REPORT).unlink()
    assert bench_main(["--report", str(sweep)]) == 0
    assert (sweep / REPORT).is_file()
    assert bench_main(["--report", str(tmp_path)]) == 2
    assert "not a results folder" in capsys.readouterr().err
    with pytest.raises(DynabarnError):
        write_report(tmp_path)


def test_verify_reproduces_committed_results(tmp_path, capsys):
    committed = REPO / "results" / "paper60_barn"
    if not (committed / "results.jsonl").is_file():
        pytest.skip("committed results absent")
    folder = tmp_path / "paper60_barn"  # the verdict is written beside the rows: not into the checkout
    folder.mkdir()
    for name in ("results.jsonl", "metadata.json", "worlds.json"):
        shutil.copy(committed / name, folder / name)
    assert bench_main(["--verify", str(folder), "--sample", "3"]) == 0
    out = capsys.readouterr().out
    assert "3 rows re-run: 3 identical" in out


def test_verify_names_a_row_whose_planner_configuration_was_edited(sweep, tmp_path, capsys):
    copy = tmp_path / "edited"
    shutil.copytree(sweep, copy)
    rows = _rows(copy)
    edited = next(r for r in rows if r["planner"] == "dwa")
    edited["planner_config"] = dict(edited["planner_config"], max_vel_x=1.0)
    (copy / "results.jsonl").write_text("".join(json.dumps(r) + "\n" for r in rows))
    assert bench_main(["--verify", str(copy), "--sample", "all"]) == 1
    out = capsys.readouterr().out
    assert f"DIFFERS    {edited['key']}" in out
    assert f"{edited['key']}: planner_config" in out
    assert out.count("identical  ") == len(rows) - 1
    verdict = json.loads((copy / "verification.json").read_text())
    assert not verdict["ok"] and verdict["identical"] == len(rows) - 1
    assert "Verification" in (copy / REPORT).read_text()  # the report shows it


def test_verify_refuses_what_is_not_a_results_file(sweep, tmp_path, capsys):
    bad = tmp_path / "results.jsonl"
    bad.write_text('{"outcome": "success", "key": "nonsense"}\n')
    assert bench_main(["--verify", str(bad)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "not a results file" in err[0]
    bad.write_text(json.dumps(_rows(sweep)[0] | {"key": "nonsense|{}"}) + "\n")  # a row, but a forged key
    assert bench_main(["--verify", str(bad)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "nonsense" in err[0]
    assert bench_main(["--verify", str(tmp_path / "nothing")]) == 2
    for bad in ("x", "0", "-3"):  # refused by the parser: one line, exit 2
        with pytest.raises(SystemExit) as stop:
            bench_main(["--verify", str(bad), "--sample", bad])
        assert stop.value.code == 2
        assert "--sample" in capsys.readouterr().err


def test_the_sample_is_fixed_and_keys_parse():
    rows = [{"i": i} for i in range(100)]
    assert sample_rows(rows, 5) == sample_rows(rows, 5)
    assert len(sample_rows(rows, 5)) == 5 and sample_rows(rows, None) == rows
    parts = parse_key('dwa|{"include_dynamic_obstacles": true}|world_000.xml|barn|3|sim={"dt": 0.004}')
    assert parts["config"] == {"include_dynamic_obstacles": True} and parts["seed"] == 3
    assert parts["sim"] == {"dt": 0.004} and parts["world"] == "world_000.xml"
    with pytest.raises(DynabarnError):
        parse_key("dwa|{}|world_000.xml")


def test_a_row_without_its_world_still_has_its_cell(sweep, tmp_path):
    """A worker that died mid-episode leaves a row without `world`: the report names the
    world from the row's key."""
    copy = tmp_path / "cut"
    shutil.copytree(sweep, copy)
    rows = _rows(copy)
    del rows[0]["world"]
    (copy / "results.jsonl").write_text("".join(json.dumps(r) + "\n" for r in rows))
    html = write_report(copy).read_text()
    assert html.count('class="cell ') == len(rows)
