"""The documentation site: `mkdocs build --strict` (what `make docs` runs) builds it, a
broken link fails the build, and a real browser (headless Chromium, as for the web viewer)
shows its pages with their figures, option tables and API reference."""

from __future__ import annotations

import functools
import http.server
import io
import os
import shutil
import subprocess
import sys
import threading
import time
from pathlib import Path

import pytest

from tests.browser import Browser, chromium
from tests.conftest import require

REPO = Path(__file__).resolve().parent.parent


def _build(config: Path, site: Path, path: tuple[Path, ...] = ()) -> subprocess.CompletedProcess:
    """`mkdocs build --strict` of `config` into `site` (with `path` before the rest of PYTHONPATH)."""
    require("mkdocs", "docs")
    require("material", "docs")
    require("mkdocstrings_handlers.python", "docs")
    env = {**os.environ, "NO_MKDOCS_2_WARNING": "1"}
    if path:
        env["PYTHONPATH"] = os.pathsep.join([*map(str, path), *filter(None, [env.get("PYTHONPATH")])])
    return subprocess.run(
        [sys.executable, "-m", "mkdocs", "build", "--strict", "--config-file", str(config), "--site-dir", str(site)],
        capture_output=True,
        text=True,
        cwd=config.parent,
        env=env,
        timeout=600,
    )


@pytest.fixture(scope="module")
def site(tmp_path_factory) -> Path:
    site = tmp_path_factory.mktemp("docs") / "site"
    build = _build(REPO / "mkdocs.yml", site)
    assert build.returncode == 0, build.stderr
    return site


def test_every_command_has_a_page_with_its_generated_options(site):
    from dynabarn.cli.dispatch import COMMANDS

    for name in COMMANDS:
        page = (site / "commands" / f"{name}.html").read_text()
        assert f"Generated from <code>dynabarn-{name} --help</code>" in page, name
        # Every option of the parser is in the page's table (but an old spelling kept for one
        # release, hidden from --help as from the docs).
        import argparse

        module = __import__(f"dynabarn.cli.{name}", fromlist=["build_parser"])
        parser = module.build_parser()
        actions = [a for p in [parser, *_subparsers(parser)] for a in p._actions if a.help is not argparse.SUPPRESS]
        for action in actions:
            for flag in action.option_strings:
                if flag not in ("-h", "--help", "--version"):
                    assert f"<code>{flag}</code>" in page, (name, flag)


def _subparsers(parser):
    import argparse

    return [p for a in parser._actions if isinstance(a, argparse._SubParsersAction) for p in a.choices.values()]


def test_the_api_page_documents_every_export(site):
    import dynabarn

    page = (site / "api.html").read_text()
    for name in dynabarn.__all__:
        assert f'id="{dynabarn._WHERE[name]}.{name}"' in page, name


@pytest.mark.slow
def test_what_a_package_installs_is_in_the_documentation_it_builds(tmp_path):
    """The command pages' option tables are generated from the parsers, which offer what the
    registries hold: built with another package installed, the site names its planner, its
    profile set, its behaviour and its import format where the options list them."""
    from tests.helpers import install_extension

    build = _build(REPO / "mkdocs.yml", tmp_path / "site", path=(install_extension(tmp_path / "ext"),))
    assert build.returncode == 0, build.stderr
    run = (tmp_path / "site" / "commands" / "run.html").read_text()
    worlds = (tmp_path / "site" / "commands" / "worlds.html").read_text()
    assert "ext_planner" in run and "ext-json" in worlds and "ext_profiles" in worlds and "ext_freeze" in worlds


def test_a_broken_link_fails_the_build(tmp_path):
    """Strict, so a page that links nowhere stops `make docs` (and CI)."""
    copy = tmp_path / "repo"
    shutil.copytree(REPO / "docs", copy / "docs")
    shutil.copy(REPO / "mkdocs.yml", copy / "mkdocs.yml")
    shutil.copy(REPO / "CHANGELOG.md", copy / "CHANGELOG.md")
    page = copy / "docs" / "speed.md"
    page.write_text(page.read_text() + "\nSee [the missing page](nowhere.md).\n")
    build = _build(copy / "mkdocs.yml", tmp_path / "site")
    assert build.returncode != 0 and "nowhere.md" in build.stderr, build.stderr


@pytest.mark.slow
@pytest.mark.skipif(chromium() is None, reason="needs Debian's chromium: sudo make system-deps")
def test_the_results_page_renders_with_its_figure_in_chromium(site, tmp_path):
    iio = require("imageio.v3", "test")
    handler = functools.partial(http.server.SimpleHTTPRequestHandler, directory=str(site))
    handler.log_message = lambda *args: None  # quiet
    server = http.server.ThreadingHTTPServer(("127.0.0.1", 0), handler)
    threading.Thread(target=server.serve_forever, daemon=True).start()
    try:
        url = f"http://127.0.0.1:{server.server_address[1]}/results.html"
        with Browser() as browser:
            browser.open(url)
            state: dict = {}
            deadline = time.monotonic() + 60
            while time.monotonic() < deadline:
                time.sleep(0.5)
                state = browser.evaluate(
                    "(() => { const img = document.querySelector('img[src$=\"fig5_paper60_barn.png\"]');"
                    " return {title: document.title, loaded: document.readyState,"
                    " figure: img ? img.naturalWidth : -1, rows: document.querySelectorAll('table tr').length,"
                    " copy: document.querySelectorAll('.md-code__button').length,"
                    " nav: document.querySelectorAll('.md-nav__link').length}; })()"
                )
                if state.get("loaded") == "complete" and state.get("figure", -1) > 0 and state.get("copy", 0) > 0:
                    break
            browser.call("Runtime.evaluate", expression="document.querySelector('img[src$=\"fig5_paper60_barn.png\"]')"
                         ".scrollIntoView()")  # fmt: skip
            time.sleep(0.5)
            shot = browser.screenshot()
        (tmp_path / "results.png").write_bytes(shot)
    finally:
        server.shutdown()
        server.server_close()
    assert state["title"].startswith("Results"), state
    assert state["figure"] > 500, f"the Fig. 5 image did not load: {state}"
    assert state["rows"] > 30 and state["nav"] > 20, state  # the tables and the site's navigation
    assert state["copy"] > 0, "Material's JavaScript ran (code blocks got copy buttons)"
    # The figure is on screen: its bars are coloured, not the page's white and grey text.
    pixels = iio.imread(io.BytesIO(shot))[..., :3].astype(int)
    coloured = (pixels.max(axis=-1) - pixels.min(axis=-1)) > 80
    assert coloured.sum() > 5000, f"no figure in the screenshot; see {tmp_path}/results.png"


def test_every_metric_is_defined_once_and_everything_reads_it():
    """A metric is one entry of `metrics.METRICS`: the result's number fields, their JSON
    schema, a summary's columns and the protocols page's table all follow it."""
    import dataclasses

    from dynabarn.bench.summary import summarise
    from dynabarn.metrics import METRICS, RESULT_NUMBERS, EpisodeResult, metrics_table
    from dynabarn.recording.schemas import MACHINE_FIELDS, result_schema

    names = [m.name for m in METRICS]
    floats = [f.name for f in dataclasses.fields(EpisodeResult) if f.type == "float"]
    assert floats == names == list(RESULT_NUMBERS)
    schema = result_schema()["properties"]
    assert all(schema[name]["type"] == ["number", "null"] for name in names if name not in MACHINE_FIELDS)
    assert {"time", "score", "spl", "min_clearance"} <= set(schema)
    row = {"planner": "dwa", "difficulty": "easy", "outcome": "success", "seed": 0, "world": "w"}
    row |= {name: 1.0 for name in names}
    (summary, _) = summarise([row, row | {"outcome": "collision", "seed": 1}])[:2]
    shown = {m.name if m.summary == "mean" else f"{m.name}_success" for m in METRICS if m.summary}
    assert shown <= set(summary) and {"time_success", "score", "spl", "min_clearance"} == shown
    page = (REPO / "docs" / "concepts" / "protocols.md").read_text()
    assert metrics_table() in page, "docs/concepts/protocols.md's metric table: regenerate it from metrics_table()"


def test_the_site_loads_nothing_from_the_network(site):
    """Every script and stylesheet of every page is the site's own (the offline search's
    worker shim included): it opens from disk on a machine without a network."""
    import re

    for page in site.rglob("*.html"):
        if page.parent.name == "reports":
            continue  # the sweep reports: checked as reports (tests/test_report.py)
        for url in re.findall(r'<(?:script|link)\b[^>]*(?:src|href)="([^"]+)"', page.read_text()):
            assert not url.startswith(("http:", "https:", "//")), (page.name, url)


@pytest.mark.slow
@pytest.mark.skipif(chromium() is None, reason="needs Debian's chromium: sudo make system-deps")
def test_the_leaderboard_is_wide_sortable_and_search_works_from_disk(site):
    """At 1920 px the leaderboard's tables use the width (no horizontal scroll, names whole),
    a heading sorts its table, and the site's search answers from file://."""
    with Browser() as browser:
        browser.call("Emulation.setDeviceMetricsOverride", width=1920, height=1080, deviceScaleFactor=1, mobile=False)
        browser.open((site / "leaderboard.html").resolve().as_uri())
        deadline = time.monotonic() + 60
        while browser.evaluate("document.readyState") != "complete" and time.monotonic() < deadline:
            time.sleep(0.2)
        time.sleep(1.0)
        state = browser.evaluate(
            "(() => { const t = document.querySelector('table.leaderboard');"
            " const w = t.closest('.leaderboard-scroll');"
            " return {tables: document.querySelectorAll('table.leaderboard').length, sections: "
            "document.querySelectorAll('article h3').length, overflow: w.scrollWidth - w.clientWidth,"
            " width: t.getBoundingClientRect().width,"
            " broken: Array.from(t.querySelectorAll('td.planner code'))"
            ".filter(c => c.getClientRects().length > 1).length}; })()"
        )
        assert state["tables"] >= 7 and state["sections"] == state["tables"], state
        assert state["overflow"] <= 0 and state["width"] > 1200 and state["broken"] == 0, state
        column = (
            "Array.from(document.querySelector('table.leaderboard').tBodies[0].rows).map(r => +r.cells[8].dataset.sort)"
        )
        browser.evaluate("document.querySelector('table.leaderboard').querySelectorAll('th')[8].click()")
        hard = browser.evaluate(column)
        assert hard == sorted(hard, reverse=True)
        browser.evaluate("document.querySelector('table.leaderboard').querySelectorAll('th')[8].click()")
        assert browser.evaluate(column) == sorted(hard)
        # Search, from disk.
        browser.open((site / "index.html").resolve().as_uri())
        time.sleep(2.0)
        browser.evaluate("document.querySelector('input.md-search__input').focus()")
        browser.call("Input.insertText", text="certificate")
        deadline = time.monotonic() + 30
        while browser.evaluate("document.querySelectorAll('.md-search-result__item').length") == 0:
            assert time.monotonic() < deadline, "the search answered nothing from file://"
            time.sleep(0.3)


def _extending_table() -> list[list[str]]:
    """The rows of the architecture page's "where additions go" table, cells stripped."""
    text = (Path(__file__).resolve().parent.parent / "docs" / "architecture.md").read_text()
    section = text[text.index("## Extending") :]
    lines = section[section.index("| kind |") :].splitlines()
    rows = []
    for line in lines[2:]:
        if not line.startswith("|"):
            break
        rows.append([cell.strip() for cell in line.strip().strip("|").split(" | ")])
    return rows


def test_the_architecture_table_is_one_row_per_kind_and_matches_the_code():
    """One row per kind of addition, four cells each; every registry the package defines is
    named in it, and every `module.NAME` its registry column names exists."""
    import ast
    import importlib
    import re

    rows = _extending_table()
    assert all(len(row) == 4 for row in rows), [row[0] for row in rows if len(row) != 4]
    kinds = [row[0] for row in rows]
    assert len(kinds) == len(set(kinds)) and len(kinds) >= 15, kinds
    named = " ".join(row[1] for row in rows)
    package = Path(__file__).resolve().parent.parent / "dynabarn"
    defined = set()
    for path in package.rglob("*.py"):
        for node in ast.walk(ast.parse(path.read_text())):
            value = getattr(node, "value", None)
            if isinstance(node, ast.Assign | ast.AnnAssign) and isinstance(value, ast.Call):
                called = value.func
                name = called.id if isinstance(called, ast.Name) else getattr(called, "attr", "")
                if name.endswith("Registry"):
                    targets = node.targets if isinstance(node, ast.Assign) else [node.target]
                    defined |= {t.id for t in targets if isinstance(t, ast.Name)}
    assert defined >= {"PLANNERS", "TRACKERS", "BEHAVIORS", "PROTOCOLS", "TIERS", "STACKS"}, defined
    missing = sorted(name for name in defined if f".{name}`" not in named)
    assert not missing, f"registries the architecture table does not name: {missing}"
    for row in rows:  # the registry column's first name is the place in the code (then its entry-point group)
        module, _, attr = re.search(r"`([^`]+)`", row[1]).group(1).partition("(")[0].rpartition(".")
        target = importlib.import_module(f"dynabarn.{module}")
        assert hasattr(target, attr), f"{row[0]}: the table names dynabarn.{module}.{attr}, which does not exist"


def test_no_source_or_page_cites_a_file_the_repository_does_not_have():
    """DESIGN.md (and the like) are the project's working notes outside the repository: a
    reader of the code or the pages must find every file cited."""
    root = Path(__file__).resolve().parent.parent
    for path in [*root.joinpath("dynabarn").rglob("*.py"), *root.joinpath("docs").rglob("*.md"), root / "README.md"]:
        assert "DESIGN" not in path.read_text(), path
    for path in root.joinpath("tests").glob("*.py"):
        if path.name != "test_docs.py":
            assert "DESIGN" not in path.read_text(), path
    assert "DESIGN" not in (root / "assets" / "jackal" / "README.md").read_text()
