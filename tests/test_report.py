"""A sweep's report.html in a real browser, and `dynabarn-bench --verify` on real results."""

from __future__ import annotations

import json
import shutil
import time
from pathlib import Path

import pytest

from dynabarn.bench.report import OUTCOME_COLOURS, REPORT, write_report
from dynabarn.bench.row_rules import parse_key
from dynabarn.bench.verify import sample_rows
from dynabarn.cli.bench import bench_main
from dynabarn.errors import DynabarnError
from tests.browser import Browser, chromium
from tests.helpers import assert_urls_stay_inside, page_outside_scripts, report_data

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
    """One file: every episode in its data, every recording's still inside it."""
    html = (sweep / REPORT).read_text()
    rows = _rows(sweep)
    recorded = [r for r in rows if r.get("recording")]
    assert recorded, "hard worlds at two trials: the floor fails somewhere"
    data = report_data(html)
    assert len(data["episodes"]["outcome"]) == len(rows)
    stills = [r["still"] for r in data["recordings"]]
    assert len(stills) == len(recorded) and all(s.startswith("data:image/png;base64,") for s in stills)
    outside = page_outside_scripts(html)
    assert "https://" not in outside and "http://" not in outside  # nothing to fetch
    assert "Content-Security-Policy" in html
    assert_urls_stay_inside(html)


@pytest.mark.slow
@pytest.mark.skipif(chromium() is None, reason="needs Debian's chromium: sudo make system-deps")
def test_the_report_opens_offline_sorts_filters_and_opens_episodes_in_chromium(sweep):
    """Worlds as rows, planners side by side: one cell per episode in each planner's column
    group, coloured by outcome; one sort moves every planner's row together; a cell opens
    its episode; the charts draw from the page alone."""
    rows = _rows(sweep)
    with Browser() as browser:
        browser.call("Network.enable")
        browser.open((sweep / REPORT).resolve().as_uri())
        _wait_for_charts(browser)
        urls = browser.requests()
        assert urls and all(u.startswith(("file://", "data:", "blob:")) for u in urls), urls
        cells = browser.evaluate(
            "Array.from(document.querySelectorAll('td.cell')).map(c => "
            "[c.dataset.outcome, getComputedStyle(c).backgroundColor])"
        )
        assert len(cells) == len(rows)
        for outcome, colour in cells:
            hex_ = OUTCOME_COLOURS[outcome].lstrip("#")
            assert colour == "rgb({}, {}, {})".format(*(int(hex_[i : i + 2], 16) for i in (0, 2, 4)))
        groups = browser.evaluate("Array.from(document.querySelectorAll('th.group')).map(t => t.dataset.planner)")
        assert groups == ["straight", "dwa"]
        # One sort for all: by the floor's successes, every row (all planners' cells) moves together.
        before = browser.evaluate(ROW_CELLS)
        browser.evaluate(_select("sort", "planner:0"))
        after = browser.evaluate(ROW_CELLS)
        assert sorted(before) == sorted(after)  # the same rows, each whole
        floor_successes = browser.evaluate(
            "Array.from(document.querySelectorAll('#grid tbody tr')).map(r => +r.dataset.s0)"
        )
        assert floor_successes == sorted(floor_successes)
        # Filters: a difficulty hides other worlds' rows, a planner's box hides its columns.
        browser.evaluate(_select("difficulty", "easy"))
        assert browser.evaluate("document.querySelectorAll('#grid tbody tr').length") == 0
        browser.evaluate(_select("difficulty", ""))
        browser.evaluate(
            "(() => { const b = document.querySelector('#planners input[value=\"0\"]'); b.checked = false;"
            " b.dispatchEvent(new Event('change', {bubbles: true})); })()"
        )
        assert browser.evaluate("document.querySelectorAll('td.cell').length") == sum(
            r["planner"] == "dwa" for r in rows
        )
        # A recorded cell opens its episode: its still, metrics and a replay command relative to the report.
        browser.evaluate(_select("sort", "id"))
        browser.evaluate(
            "(() => { const b = document.querySelector('#planners input[value=\"0\"]'); b.checked = true;"
            " b.dispatchEvent(new Event('change', {bubbles: true})); })()"
        )
        recorded = next(r for r in rows if r.get("recording"))
        browser.evaluate(
            "Array.from(document.querySelectorAll('td.cell')).find(c => c.title.startsWith("
            f"{json.dumps(recorded['planner'] + ' · seed ' + str(recorded['seed']))}) && "
            f"c.closest('tr').dataset.world === {json.dumps(recorded['world'])}).click()"
        )
        panel = browser.evaluate(
            "JSON.stringify({hidden: document.getElementById('episode').hidden,"
            " still: document.getElementById('episode-still').naturalWidth,"
            " command: document.getElementById('episode-command').textContent,"
            " mcap: document.getElementById('episode-mcap').href,"
            " metrics: document.querySelectorAll('#episode-metrics tr').length})"
        )
        panel = json.loads(panel)
        assert not panel["hidden"] and panel["still"] > 0 and panel["metrics"] >= 8
        relative = (sweep / recorded["recording"]).resolve().relative_to(sweep.resolve()).as_posix()
        assert panel["command"] == f"dynabarn-replay --web {relative}"  # from the report's folder
        assert Path(panel["mcap"].removeprefix("file://")) == (sweep / relative).resolve()
        # The charts: plotly drew each from the page alone.
        assert browser.evaluate("document.querySelectorAll('#chart-fig5 .main-svg').length") > 0
        assert browser.evaluate("document.querySelectorAll('#chart-distribution .main-svg').length") > 0


ROW_CELLS = (
    "Array.from(document.querySelectorAll('#grid tbody tr')).map(r => "
    "r.dataset.world + ':' + Array.from(r.querySelectorAll('td.cell')).map(c => c.dataset.outcome).join(','))"
)


def _select(name: str, value: str) -> str:
    return (
        f"(() => {{ const s = document.getElementById({json.dumps(name)}); s.value = {json.dumps(value)};"
        " s.dispatchEvent(new Event('change')); })()"
    )


def _wait_for_charts(browser, limit: float = 60.0) -> dict:
    """Wait until the page drew its charts; the page's own timings (ms from navigation)."""
    deadline = time.monotonic() + limit
    while browser.evaluate("document.body && document.body.dataset.charts") != "drawn":
        assert time.monotonic() < deadline, "the charts were not drawn"
        time.sleep(0.1)
    return json.loads(browser.evaluate("JSON.stringify(document.body.dataset)"))


@pytest.mark.slow
@pytest.mark.skipif(chromium() is None, reason="needs Debian's chromium: sudo make system-deps")
def test_the_committed_paper60_report_at_scale(tmp_path, capsys):
    """13 planners x 60 worlds x 10 trials: one cell per episode, within its size budget;
    how long Chromium takes to show the grid and the charts is measured and reported (not
    asserted: a shared machine's timing is no test)."""
    committed = REPO / "results" / "paper60_barn"
    if not (committed / "results.jsonl").is_file():
        pytest.skip("committed results absent")
    for name in ("results.jsonl", "metadata.json", "worlds.json"):
        shutil.copy(committed / name, tmp_path / name)
    page = write_report(tmp_path)
    rows = _rows(tmp_path)
    assert len({r["planner"] for r in rows}) == 13
    assert page.stat().st_size < REPORT_BUDGET
    with Browser() as browser:
        browser.open(page.resolve().as_uri())
        timings = _wait_for_charts(browser)
        assert browser.evaluate("document.querySelectorAll('td.cell').length") == len(rows)
        assert browser.evaluate("document.querySelectorAll('th.group').length") == 13
    with capsys.disabled():
        print(
            f"\npaper60 report: {page.stat().st_size / 1e6:.1f} MB, grid shown at {timings['gridMs']} ms, "
            f"charts drawn at {timings['chartsMs']} ms after navigation (this machine, now)"
        )


REPORT_BUDGET = 12_000_000
"""The report's size budget at paper60 (13 planners x 60 worlds x 10 trials, no recordings):
about 5 MB of plotly.js and 1 MB of episodes (docs/concepts/report.md)."""


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
    data = report_data(write_report(copy).read_text())
    assert len(data["episodes"]["outcome"]) == len(rows)
    assert {w["name"] for w in data["worlds"]} == {r.get("world") or "world_200" for r in rows}


def test_stills_draw_every_shape_as_it_is():
    """A box is its rectangle turned by its yaw, a capsule its stadium, a cylinder its
    circle: not the circle around each (the report drew those before)."""
    from types import SimpleNamespace

    import numpy as np

    from dynabarn.bench.stills import outline

    box = outline(0.0, 0.0, SimpleNamespace(half_length=1.0, half_width=0.5, radius=0.0, yaw=0.0))
    assert np.allclose(box.min(axis=0), [-1.0, -0.5]) and np.allclose(box.max(axis=0), [1.0, 0.5])
    cylinder = outline(1.0, 2.0, SimpleNamespace(half_length=0.0, half_width=0.0, radius=0.3, yaw=1.0))
    assert np.allclose(np.hypot(cylinder[:, 0] - 1.0, cylinder[:, 1] - 2.0), 0.3)
    capsule = outline(0.0, 0.0, SimpleNamespace(half_length=0.5, half_width=0.0, radius=0.2, yaw=np.pi / 2))
    assert np.allclose(capsule.min(axis=0), [-0.2, -0.7]) and np.allclose(capsule.max(axis=0), [0.2, 0.7])
