"""The fourth pass on untrusted input: a results file is data, a report runs nothing it was
given, the current folder supplies no code, one writer per world set, bounds on every count,
and extensions that fail alone.

`FOURTH_PASS` is a table like the third pass's (command, arguments, the text of the one error
line, exit 2). Below it, the cases a table cannot say, the security ones end to end: a marker
file that must not appear, a link whose target stays empty, a command pasted into bash, a
link clicked in Chromium; then property tests over keys, rows, report fields and profiles.
"""

from __future__ import annotations

import json
import os
import re
import shutil
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest

from dynabarn.bench.report import REPORT, STILLS, write_report
from dynabarn.bench.row_rules import parse_key
from dynabarn.cli.bench import bench_main
from dynabarn.errors import DynabarnError
from dynabarn.provenance import SHIPPED_WORLDS
from tests.browser import Browser, chromium
from tests.conftest import require
from tests.helpers import assert_urls_stay_inside, report_data
from tests.test_fuzz import one_clear_line

REPO = Path(__file__).resolve().parent.parent
WORLD = SHIPPED_WORLDS / "world_000.xml"
HARD = ["--planner", "stop", "--set", "paper60", "--worlds", "200", "--trials", "1", "--jobs", "1"]


def _world(replace: str, by: str) -> bytes:
    text = WORLD.read_text()
    assert replace in text, replace
    return text.replace(replace, by, 1).encode()


PROFILE = """\
low_count = [5, 9]
high_count = [10, 19]
[[easy_motion]]
order = [1, 2]
speed = [0.5, 1.0]
std = [0.01, 0.1]
[[hard_motion]]
order = [3, 4]
speed = [1.0, 2.0]
std = [0.1, 0.2]
"""


@pytest.fixture(scope="module")
def fourth_files(tmp_path_factory) -> Path:
    d = tmp_path_factory.mktemp("fourth")
    (d / "ok.toml").write_text(PROFILE)
    (d / "count.toml").write_text(PROFILE.replace("high_count = [10, 19]", "high_count = [1000000, 1000000]"))
    (d / "date.toml").write_text(PROFILE.replace("speed = [1.0, 2.0]", "speed = [1979-05-27, 2.0]"))
    (d / "step.toml").write_text(PROFILE.replace("std = [0.1, 0.2]", "std = [0.1, 0.2]\nspeed_step = 1e-300"))
    (d / "digits.toml").write_text(PROFILE.replace("[5, 9]", "[5, " + "9" * 5000 + "]"))
    (d / "digits.json").write_text('{"low_count": [5, ' + "9" * 5000 + "]}")
    (d / "speed.toml").write_text(PROFILE.replace("speed = [1.0, 2.0]", "speed = [1.0, 2000.0]"))
    textures = "".join(
        f'<texture name="t{i}" type="2d" builtin="checker" width="4096" height="4096"/>' for i in range(3)
    )
    (d / "textures.xml").write_bytes(_world("<asset>", "<asset>" + textures))
    numerics = "".join(f'<numeric name="n{i}" size="300000"/>' for i in range(40))
    (d / "numerics.xml").write_bytes(_world("<custom>", "<custom>" + numerics))
    (d / "a_folder").mkdir()
    foreign = d / "foreign"
    foreign.mkdir()
    (foreign / "world_000.xml").write_text("a user's own file\n")
    return d


FOURTH_PASS: list[tuple[str, list[str], str]] = [
    # Options that were silently accepted or ignored.
    ("bench", ["--sample", "3", "--out", "out"], "--sample: only with --verify"),
    ("bench", ["--report", "out", "--sample", "3"], "only with --verify"),
    ("bench", ["--report", "out", "--policy", "x.pt"], "only with --verify"),
    ("bench", ["--planner", "straight,,stop", "--out", "out"], "an empty name between commas"),
    ("worlds", ["generate", "--out", "out", "--profiles", "table1", "--profile-file", "{bad}/ok.toml"], "give one"),
    ("worlds", ["generate", "--tier", "tier-dense", "--profiles", "table1"], "drop --profiles"),
    # Counts and sizes with their limit named.
    ("worlds", ["generate", "--out", "out", "--high-count", "100000,100000"], "above 200 obstacles"),
    ("worlds", ["generate", "--out", "out", "--profile-file", "{bad}/count.toml"], "above 200 obstacles"),
    ("worlds", ["generate", "--out", "out", "--profile-file", "{bad}/step.toml"], "speed_step must be 0"),
    ("worlds", ["generate", "--out", "out", "--profile-file", "{bad}/speed.toml"], "above 20 m/s"),
    ("worlds", ["generate", "--out", "out", "--profile-file", "{bad}/date.toml"], "must be a number, not date"),
    ("worlds", ["generate", "--out", "out", "--profile-file", "{bad}/digits.toml"], "a number too long"),
    ("worlds", ["generate", "--out", "out", "--profile-file", "{bad}/digits.json"], "a number too long"),
    ("run", ["--world", "{bad}/textures.xml", "--no-log"], "textures of more than"),
    ("run", ["--world", "{bad}/numerics.xml", "--no-log"], "numbers in all"),
    # Files the command did not write are never replaced.
    ("worlds", ["generate", "--out", "{bad}/foreign"], "not written by dynabarn"),
    # The ROS bridge's options.
    ("ros", ["--world", "0", "--remap", "/nothing:=/scan"], "the bridge has no topic /nothing"),
    ("ros", ["--world", "0", "--launch", ""], "an empty command"),
    ("ros", ["--world", "0", "--launch", "true", "--stack-log", "{bad}/a_folder"], "a folder"),
]


@pytest.mark.parametrize("command, argv, message", FOURTH_PASS, ids=[f"{c} {' '.join(a)}" for c, a, _ in FOURTH_PASS])
def test_fourth_pass_bad_input_gives_one_clear_line(command, argv, message, fourth_files, monkeypatch, tmp_path):
    monkeypatch.chdir(tmp_path)
    line = one_clear_line(command, [a.replace("{bad}", str(fourth_files)) for a in argv])
    assert message in line, line
    assert not (tmp_path / "out").exists() or not any((tmp_path / "out").iterdir()), "nothing may be written"
    assert (fourth_files / "foreign" / "world_000.xml").read_text() == "a user's own file\n"


def test_the_documentation_counts_the_fourth_pass():
    page = (REPO / "docs" / "faults.md").read_text()
    match = re.search(r"(\d+) cases of the fourth pass", page)
    assert match and int(match[1]) == len(FOURTH_PASS), "update docs/faults.md's count of the fourth pass's cases"


# -- a results file is data ---------------------------------------------------------------------


@pytest.fixture(scope="module")
def sweep(tmp_path_factory) -> Path:
    """`stop` and the floor on one hard world, one trial, both recorded."""
    out = tmp_path_factory.mktemp("fourth_sweep") / "sweep"
    assert bench_main([*HARD, "--record", "all", "--out", str(out)]) == 0
    return out


def _rows(folder: Path) -> list[dict]:
    return [json.loads(line) for line in (folder / "results.jsonl").read_text().splitlines()]


def _forged(sweep: Path, tmp_path: Path, edit, name: str = "forged") -> Path:
    """A copy of the sweep whose first row `edit(row)` changed (or replaced, if it returns one)."""
    copy = tmp_path / name
    shutil.copytree(sweep, copy)
    rows = _rows(copy)
    rows[0] = edit(rows[0]) or rows[0]
    (copy / "results.jsonl").write_text("".join(json.dumps(r) + "\n" for r in rows))
    return copy


def _key(planner: str, config: dict, world: str = "world_200.xml", protocol: str = "barn", rest: str = "0") -> str:
    return f"{planner}|{json.dumps(config, sort_keys=True)}|{world}|{protocol}|{rest}"


def _external_options() -> list[tuple[str, str]]:
    from dynabarn.planners import available_planners
    from dynabarn.planners.registry import external_options

    return [(p, o) for p in available_planners() for o in external_options(p)]


def test_every_option_that_names_a_program_a_file_or_an_address_is_declared():
    options = set(_external_options())
    assert {("ros", "launch"), ("ros", "nav_workspace"), ("ros", "stack_log"), ("ros", "master")} <= options
    assert {("bc", "policy"), ("td3", "policy"), ("dagger", "policy")} <= options


@pytest.mark.parametrize("planner, option", _external_options(), ids=lambda x: str(x))
def test_verify_never_takes_a_program_a_file_or_an_address_from_a_row(
    planner, option, sweep, tmp_path, monkeypatch, capsys
):
    """Per option: the row's value is a shell command writing a marker; --verify runs
    nothing of it: the row is 'not checked', naming the option and how to give it, and the
    exit status (3) says rows went unchecked, not that they differ."""
    monkeypatch.chdir(tmp_path)
    marker = tmp_path / "MARKER"
    value = ["sh", "-c", f"id > {marker}"] if option == "launch" else f"$(touch {marker})"
    copy = _forged(sweep, tmp_path, lambda r: r.update(key=_key(planner, {option: value})))
    assert bench_main(["--verify", str(copy), "--sample", "all"]) == 3
    out = capsys.readouterr().out
    line = next(line for line in out.splitlines() if line.startswith("not checked"))
    assert f"{option}=" in line and "name it yourself" in line, line
    assert not marker.exists()
    verdict = json.loads((copy / "verification.json").read_text())
    assert verdict["ok"] and verdict["not_checked"] == 1 and not verdict["complete"]


def test_verify_runs_a_launch_line_as_a_string_only_when_given(sweep, tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    marker = tmp_path / "MARKER"
    copy = _forged(sweep, tmp_path, lambda r: r.update(key=_key("ros", {"launch": f"sh -c 'id > {marker}'"})))
    assert bench_main(["--verify", str(copy), "--sample", "all"]) == 3
    assert "(--ros-launch COMMAND)" in capsys.readouterr().out
    assert not marker.exists()
    # Given for rows that name none: refused too, never silently unused.
    assert "no row of" in one_clear_line("bench", ["--verify", str(sweep), "--ros-launch", "true"])
    assert "no row of" in one_clear_line("bench", ["--verify", str(sweep), "--policy", str(tmp_path / "x.pt")])


FORGED_KEYS = [
    ("nested", "dwa|" + "[" * 5000 + "]" * 5000 + "|world_200.xml|barn|0", "not one dynabarn-bench writes"),
    ("sim", _key("stop", {}) + '|sim={"gravity": 1}', "unknown simulation setting 'gravity'"),
    ("sim value", _key("stop", {}) + '|sim={"dt": "0.005"}', "expected a number"),
    ("sim range", _key("stop", {}) + '|sim={"dt": 1}', "dt must be in"),
    ("protocol path", _key("stop", {}, protocol="../../p.json"), "protocol '../../p.json'"),
    ("protocol unknown", _key("stop", {}, protocol="mine"), "neither one of this package's"),
    ("world path", _key("stop", {}, world="../world_200.xml"), "world file '../world_200.xml'"),
    ("seed", _key("stop", {}, rest="-1"), "seed '-1'"),
    ("long", "stop|{" + '"a": 1,' * 20_000 + '"b": 2}|world_200.xml|barn|0', "at most 65,536 characters"),
]


@pytest.mark.parametrize("what, key, message", FORGED_KEYS, ids=[w for w, *_ in FORGED_KEYS])
def test_verify_refuses_a_forged_key_in_one_line(what, key, message, sweep, tmp_path):
    copy = _forged(sweep, tmp_path, lambda r: r.update(key=key))
    line = one_clear_line("bench", ["--verify", str(copy)])
    assert message in line, line


def test_a_planner_not_installed_here_is_not_checked(sweep, tmp_path, capsys):
    copy = _forged(sweep, tmp_path, lambda r: r.update(key=_key("nothing_here", {})))
    assert bench_main(["--verify", str(copy), "--sample", "all"]) == 3
    out = capsys.readouterr().out
    assert "not checked" in out and "'nothing_here' is not installed here" in out
    assert "1 not checked here" in out


def test_verify_reads_world_files_only_where_worlds_are(sweep, tmp_path, capsys):
    """A row's world_file naming a file outside the folder and this package's sets is never
    opened, and one inside that is a sparse 4 GB file is refused by its size, not read."""
    outside = tmp_path / "elsewhere"
    outside.mkdir()
    shutil.copy(SHIPPED_WORLDS / "world_200.xml", outside / "world_200.xml")
    copy = _forged(sweep, tmp_path, lambda r: r.update(world_file=str(outside / "world_200.xml")), "outside")
    bench_main(["--verify", str(copy), "--sample", "all"])
    verdict = json.loads((copy / "verification.json").read_text())
    # Re-run from this package's set, not from there: only the field that names it differs.
    assert verdict["checked"] == 2 and {d["field"] for d in verdict["differences"]} == {"world_file"}

    def sparse(row):
        row.update(world_file="worlds/world_900.xml", key=row["key"].replace("world_200.xml", "world_900.xml"))

    copy = _forged(sweep, tmp_path, sparse, "sparse")
    (copy / "worlds").mkdir()
    with open(copy / "worlds" / "world_900.xml", "wb") as f:
        f.truncate(4 * 1024**3)  # sparse: nothing is written, and nothing must be read whole
    assert bench_main(["--verify", str(copy), "--sample", "all"]) == 1
    out = capsys.readouterr().out
    assert "larger than 64 MiB" in out and "MemoryError" not in out


def test_a_rows_recording_outside_its_folder_is_never_opened(sweep, tmp_path):
    from dynabarn.bench.results import recording_path

    secret = tmp_path / "secret.mcap"
    secret.write_bytes(b"not yours")
    for written in (str(secret), "../secret.mcap", 7, ["a"], {"a": 1}, "x\x00y", ""):
        assert recording_path({"recording": written}, sweep) is None, written
    link = sweep / "recordings" / "link.mcap"
    link.symlink_to(secret)
    try:
        assert recording_path({"recording": "recordings/link.mcap"}, sweep) is None
    finally:
        link.unlink()


# -- a report is a page that runs nothing it was given ----------------------------------------------


def _report_with_recording_named(sweep: Path, tmp_path: Path, name: str) -> tuple[Path, str]:
    copy = tmp_path / "named"
    shutil.copytree(sweep, copy)
    rows = _rows(copy)
    source = Path(rows[0]["recording"]).name
    (copy / "recordings" / source).rename(copy / "recordings" / name)
    rows[0]["recording"] = f"recordings/{name}"
    (copy / "results.jsonl").write_text("".join(json.dumps(r) + "\n" for r in rows))
    return copy, write_report(copy).read_text()


def test_the_replay_command_on_the_page_is_quoted_for_the_shell(sweep, tmp_path):
    """The command as shown, pasted into bash (with dynabarn-replay standing for a function
    that prints its arguments): no expansion runs, the path arrives whole."""
    name = "a$(touch${IFS}MARKER)`touch MARKER2`;touch MARKER3 'q'.mcap"
    copy, page = _report_with_recording_named(sweep, tmp_path, name)
    commands = [r["command"] for r in report_data(page)["recordings"]]
    assert commands and all(c.startswith("dynabarn-replay --web ") for c in commands)
    work = tmp_path / "paste"
    work.mkdir()
    for command in commands:
        script = "dynabarn-replay() { printf '%s\\n' \"$@\"; }\n" + command + "\n"
        proc = subprocess.run(["bash", "-c", script], cwd=work, capture_output=True, text=True, timeout=30)
        assert proc.returncode == 0, proc.stderr
        assert proc.stdout.splitlines()[0] == "--web"
        assert Path(proc.stdout.splitlines()[1]).name in {name, *(Path(r["recording"]).name for r in _rows(copy))}
    assert not list(work.iterdir()), "a shell expansion ran"


def test_every_url_on_the_page_is_a_relative_path_inside_the_folder(sweep, tmp_path):
    name = "javascript:void(document.title='PWNED')"
    copy = tmp_path / "js"
    shutil.copytree(sweep, copy)
    rows = _rows(copy)
    (copy / name).write_bytes((copy / "recordings" / Path(rows[0]["recording"]).name).read_bytes())
    rows[0]["recording"] = name  # a file of that name in the folder: the link must still be a path
    rows[1]["recording"] = "data:text/html,<script>alert(1)</script>"
    (copy / "results.jsonl").write_text("".join(json.dumps(r) + "\n" for r in rows))
    page = write_report(copy).read_text()
    assert_urls_stay_inside(page)
    hrefs = [r["href"] for r in report_data(page)["recordings"]]
    assert "./javascript%3Avoid%28document.title%3D%27PWNED%27%29" in hrefs and not any("data:" in h for h in hrefs)


def test_the_report_writes_its_stills_only_into_its_own_folder(sweep, tmp_path):
    copy = tmp_path / "linked"
    shutil.copytree(sweep, copy)
    shutil.rmtree(copy / STILLS)
    elsewhere = tmp_path / "elsewhere"
    elsewhere.mkdir()
    (copy / STILLS).symlink_to(elsewhere, target_is_directory=True)
    page = write_report(copy).read_text()
    assert not list(elsewhere.iterdir())
    assert "no stills were drawn" in page


@pytest.mark.parametrize(
    "damage",
    [
        "{",
        "[]",
        '{"ok": true}',
        '{"when": 1, "checked": 1, "identical": 1, "ok": true, "differences": [], "notes": []}',
    ],
)
def test_a_damaged_verification_is_shown_as_such(damage, sweep, tmp_path):
    copy = tmp_path / "damaged"
    shutil.copytree(sweep, copy)
    (copy / "verification.json").write_text(damage)
    assert "verification.json is damaged" in write_report(copy).read_text()


def test_odd_row_fields_never_break_the_report(sweep, tmp_path):
    """A lone surrogate, mixed text and number world ids, a recording that is a number: the
    report is written, the odd text shown as text."""

    def odd(row):
        row.update(reason="\ud800<script>alert(1)</script>", world_id="two hundred", recording=7)

    copy = _forged(sweep, tmp_path, odd)
    page = write_report(copy).read_bytes().decode("utf-8")
    assert "<script>alert(1)</script>" not in page
    # Text in the data block, which the page shows as text (textContent), never as markup.
    assert any(r.endswith("<script>alert(1)</script>") for r in report_data(page)["episodes"]["reason"])


@pytest.mark.slow
@pytest.mark.skipif(chromium() is None, reason="needs Debian's chromium: sudo make system-deps")
def test_a_javascript_link_clicked_in_chromium_runs_nothing(sweep):
    """The page's policy admits its own script (sorting works) and nothing else: a
    `javascript:` link put on the page and clicked leaves the page as it was."""
    import time

    with Browser() as browser:
        browser.open((sweep / REPORT).resolve().as_uri())
        deadline = time.monotonic() + 30
        while browser.evaluate("document.readyState") != "complete" and time.monotonic() < deadline:
            time.sleep(0.2)
        title = browser.evaluate("document.title")
        browser.evaluate(
            "(() => { const a = document.createElement('a'); a.id = 'bad';"
            " a.href = \"javascript:void(document.title='PWNED')\"; a.textContent = 'x';"
            " document.body.appendChild(a); a.click(); })()"
        )
        time.sleep(1.0)
        assert browser.evaluate("document.title") == title != "PWNED"
        # A recorded episode's panel links its MCAP file as a file beside the page.
        browser.evaluate("document.querySelector('td.cell.collision, td.cell.timeout').click()")
        assert browser.evaluate("document.getElementById('episode-mcap').protocol") == "file:"


# -- the current folder never supplies code ---------------------------------------------------------


def _plant(folder: Path, entry_points: str, modules: dict[str, str]) -> None:
    info = folder / "planted-1.0.dist-info"
    info.mkdir()
    (info / "METADATA").write_text("Metadata-Version: 2.1\nName: planted\nVersion: 1.0\n")
    (info / "entry_points.txt").write_text(textwrap.dedent(entry_points))
    for name, text in modules.items():
        (folder / f"{name}.py").write_text(textwrap.dedent(text))


def test_python_m_dynabarn_imports_nothing_from_the_current_folder(tmp_path):
    marker = tmp_path / "MARKER"
    _plant(
        tmp_path,
        "[dynabarn.planners]\nplanted = planted_mod:P\n[dynabarn.commands]\nplanted = planted_mod:main\n",
        {"planted_mod": f"import pathlib\npathlib.Path({str(marker)!r}).touch()\nP = None\ndef main(a): return 0\n"},
    )
    env = {k: v for k, v in os.environ.items() if k not in ("PYTHONSAFEPATH", "PYTHONPATH")}
    run = [sys.executable, "-m", "dynabarn", "run", "--world", "137", "--planner", "planted", "--no-log"]
    proc = subprocess.run(run, cwd=tmp_path, env=env, capture_output=True, text=True, timeout=120)
    assert proc.returncode == 2 and "unknown planner 'planted'" in proc.stderr, proc.stderr
    proc = subprocess.run([sys.executable, "-m", "dynabarn", "planted"], cwd=tmp_path, env=env, capture_output=True)
    assert proc.returncode == 2 and not marker.exists()


# -- one writer per world set --------------------------------------------------------------------


def test_a_second_writer_of_a_set_is_refused_while_the_first_writes(tmp_path):
    """While one process holds a set's index lock (as certify, generate and import do), a
    second certify or generate into that set is refused in one line and the index is unchanged."""
    from dynabarn.worldset import index_locked

    folder = tmp_path / "set"
    shutil.copytree(SHIPPED_WORLDS, folder, ignore=shutil.ignore_patterns("world_[12]*.xml"))
    index = json.loads((folder / "index.json").read_text())
    index["worlds"] = [e for e in index["worlds"] if (folder / e["file"]).is_file()]
    (folder / "index.json").write_text(json.dumps(index))
    before = (folder / "index.json").read_bytes()
    with index_locked(folder):
        for argv in (["certify", str(folder), "--worlds", "0", "--trials", "1"], ["generate", "--out", str(folder)]):
            proc = subprocess.run(
                [str(Path(sys.executable).parent / "dynabarn-worlds"), *argv],
                capture_output=True,
                text=True,
                timeout=300,
            )
            assert proc.returncode == 2 and "another dynabarn-worlds" in proc.stderr, proc.stderr
            assert proc.stderr.count("\n") == 1
    assert (folder / "index.json").read_bytes() == before
    assert not (folder / ".index.lock").exists()


def test_generate_replaces_only_what_it_wrote_unless_forced(tmp_path):
    from dynabarn.worlds.profiles import get_profile_set
    from dynabarn.worldset import check_not_foreign, generate_worlds, read_index

    out = tmp_path / "set"
    generate_worlds(get_profile_set("table1"), out, world_ids=[0, 1])
    generate_worlds(get_profile_set("table1"), out, world_ids=[0, 1])  # its own files: rewritten
    (out / "world_002.xml").write_text("mine")
    with pytest.raises(DynabarnError, match=r"world_002\.xml: not written by dynabarn"):
        generate_worlds(get_profile_set("table1"), out, world_ids=[0, 1, 2])
    assert (out / "world_002.xml").read_text() == "mine"
    generate_worlds(get_profile_set("table1"), out, world_ids=[0, 1, 2], force=True)
    assert (out / "world_002.xml").read_text() != "mine"
    (out / "index.json").write_text("not an index")
    with pytest.raises(DynabarnError, match="not written by dynabarn"):
        check_not_foreign(out, ["world_000.xml"], read_index)


def test_a_world_swapped_in_a_set_is_refused_before_a_sweep(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    folder = tmp_path / "set"
    shutil.copytree(SHIPPED_WORLDS, folder)
    shutil.copy(folder / "world_201.xml", folder / "world_200.xml")
    line = one_clear_line("bench", ["--set", str(folder), "--worlds", "200", "--out", "out"])
    assert "world_200.xml: not the bytes its index.json lists" in line


def test_certify_verify_names_records_whose_flags_contradict_their_trials(tmp_path):
    from dynabarn.worldset import certificate_problem, own_certificates

    folder = tmp_path / "set"
    folder.mkdir()
    shutil.copy(SHIPPED_WORLDS / "world_000.xml", folder)
    index = json.loads((SHIPPED_WORLDS / "index.json").read_text())
    entry = index["worlds"][0]
    trials = [{"seed": 0, "certified": True, "arrival": 9.0, "reason": "", "oracle": True}]
    entry["certificates"] = {
        "barn": {"sha256": entry["sha256"], "trials": trials, "certified": False, "certified_trials": 0}
    }
    index["worlds"] = [entry]
    (folder / "index.json").write_text(json.dumps(index))
    assert certificate_problem(entry["certificates"]["barn"]) and not own_certificates(entry)
    proc = subprocess.run(
        [_script("dynabarn-worlds"), "certify", str(folder), "--verify"], capture_output=True, text=True, timeout=300
    )
    assert proc.returncode == 1, proc.stderr
    assert "world_000.xml: its barn certificate: certified False contradicts its trials" in proc.stdout


# -- extensions fail alone ----------------------------------------------------------------------------


@pytest.fixture
def broken_extensions(tmp_path) -> dict[str, str]:
    """An installed package (on PYTHONPATH) whose import format and behaviour raise on load,
    whose planner exits on import and whose recording topic raises every tick."""
    _plant(
        tmp_path,
        """\
        [dynabarn.importers]
        badfmt = broken_mod:X
        [dynabarn.behaviors]
        badbeh = broken_mod:Y
        [dynabarn.planners]
        exiter = exit_mod:P
        [dynabarn.topics]
        badtopic = topic_mod:T
        """,
        {
            "broken_mod": "raise RuntimeError('boom')\n",
            "exit_mod": "import sys\nsys.exit(0)\n",
            "topic_mod": """\
                from dynabarn.recording.topics import Topic
                def _boom(tick):
                    raise ValueError("topic bug")
                T = Topic("/boom", "dynabarn.Boom", "10 Hz", "x", json_schema={"type": "object"}, per_tick=_boom)
                """,
        },
    )
    return {**os.environ, "PYTHONPATH": str(tmp_path)}


def _script(name: str) -> str:
    return str(Path(sys.executable).parent / name)


def test_a_broken_extension_is_named_once_and_breaks_nothing_else(broken_extensions, tmp_path):
    proc = subprocess.run(
        [_script("dynabarn-worlds"), "show", "137"], env=broken_extensions, capture_output=True, text=True, timeout=120
    )
    assert proc.returncode == 0, proc.stderr
    assert "world import format 'badfmt' failed to load" in proc.stderr and "Traceback" not in proc.stderr
    assert proc.stderr.count("badfmt") == 1 and proc.stderr.count("badbeh") == 1
    proc = subprocess.run(
        [_script("dynabarn-worlds"), "stats", "paper60", "--worlds", "0"],
        env=broken_extensions,
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert proc.returncode == 0 and "Traceback" not in proc.stderr, proc.stderr


def test_a_planner_that_exits_on_import_is_reported(broken_extensions):
    proc = subprocess.run(
        [_script("dynabarn-run"), "--world", "137", "--planner", "exiter", "--no-log"],
        env=broken_extensions,
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert proc.returncode == 2 and "it exited on import" in proc.stderr, proc.stderr


def test_a_topic_that_raises_ends_its_recording_whole_and_the_run_fails(broken_extensions, tmp_path):
    from dynabarn.recording import read_recording

    log = tmp_path / "r.mcap"
    proc = subprocess.run(
        [_script("dynabarn-run"), "--world", "137", "--planner", "straight", "--log", str(log)],
        env=broken_extensions,
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert proc.returncode == 1, proc.stderr
    assert "recording topic /boom raised ValueError: topic bug" in proc.stderr
    assert not read_recording(log).truncated


# -- DAgger's checkpoints -----------------------------------------------------------------------------


def test_a_dagger_checkpoint_without_its_configuration_is_refused(tmp_path):
    require("torch", "learn")
    (tmp_path / "state.pt").write_bytes(b"anything")
    line = one_clear_line("train", ["dagger", "--out", str(tmp_path), "--iterations", "1"])
    assert "no config.json" in line


# -- property tests ---------------------------------------------------------------------------------

hypothesis = require("hypothesis", "test")
from hypothesis import HealthCheck, given, settings  # noqa: E402
from hypothesis import strategies as st  # noqa: E402

FUZZ = settings(
    max_examples=80, deadline=None, derandomize=True, suppress_health_check=[HealthCheck.too_slow], database=None
)
JSON = st.recursive(
    st.none() | st.booleans() | st.integers() | st.floats() | st.text(max_size=20),
    lambda inner: st.lists(inner, max_size=4) | st.dictionaries(st.text(max_size=8), inner, max_size=4),
    max_leaves=12,
)


@pytest.mark.slow
@FUZZ
@given(
    planner=st.text(max_size=20),
    config=JSON,
    world=st.text(max_size=20),
    protocol=st.text(max_size=12),
    tail=st.text(max_size=30),
)
def test_keys_parse_or_are_one_error(planner, config, world, protocol, tail):
    key = f"{planner}|{json.dumps(config)}|{world}|{protocol}|{tail}"
    try:
        parts = parse_key(key)
    except DynabarnError:
        return
    assert isinstance(parts["config"], dict) and parts["world"].endswith(".xml")
    assert "/" not in parts["world"] and "/" not in parts["protocol"]


@pytest.fixture(scope="module")
def report_rows(sweep) -> list[dict]:
    return _rows(sweep)


@pytest.mark.slow
@FUZZ
@given(
    field=st.sampled_from(["reason", "world", "world_id", "recording", "difficulty", "planner", "time", "seed"]),
    value=JSON | st.text(alphabet=st.characters(codec="utf-8"), max_size=40),
)
def test_report_fields_never_break_the_page(field, value, report_rows, sweep, tmp_path_factory):
    from dynabarn.bench.report import render_report
    from dynabarn.bench.results import is_row

    rows = [dict(report_rows[0], **{field: value}), *report_rows[1:]]
    rows = [r for r in rows if is_row(r)]  # what read_results hands the report
    if not rows:
        return
    page = render_report(sweep, rows)
    assert_urls_stay_inside(page)


@pytest.mark.slow
@FUZZ
@given(edits=st.dictionaries(st.sampled_from(["low_count", "high_count", "waypoints", "name", "description"]), JSON))
def test_profiles_are_taken_or_are_one_profile_error(edits):
    from dynabarn.errors import ProfileError
    from dynabarn.worlds.profile_file import profile_from_dict
    from dynabarn.worlds.profile_limits import MAX_OBSTACLE_COUNT
    from dynabarn.worlds.profiles import get_profile_set

    data = {**get_profile_set("table1").to_dict(), **edits}
    try:
        profile = profile_from_dict(data, default_name="p", source={})
    except ProfileError:
        return
    assert max(profile.profile_set.high_count) <= MAX_OBSTACLE_COUNT


# -- the vector environment's workers -----------------------------------------------------------------


@pytest.mark.slow
def test_a_killed_vector_environment_takes_its_workers_with_it_quietly(tmp_path):
    """SIGKILL to a process stepping `DynaBARNVectorEnv`: its workers end with it (a
    parent-death signal), and none prints a traceback on the pipe that broke."""
    require("gymnasium", "learn")
    import time

    from tests.conftest import cmdline, processes_carrying, tagged_environment
    from tests.test_fuzz import _wait_for

    script = tmp_path / "vec.py"
    script.write_text(
        textwrap.dedent(
            """
            import numpy as np
            from dynabarn.learn.vector_env import DynaBARNVectorEnv

            if __name__ == "__main__":
                env = DynaBARNVectorEnv(4, workers=2)
                env.reset(seed=0)
                print("stepping", flush=True)
                while True:
                    env.step(np.zeros((4, 2), np.float32))
            """
        )
    )
    token, env = tagged_environment()
    env["PYTHONPATH"] = str(REPO)
    log = tmp_path / "stderr.txt"
    with open(log, "wb") as err:
        proc = subprocess.Popen([sys.executable, str(script)], env=env, stdout=subprocess.PIPE, stderr=err)
        try:
            assert proc.stdout.readline().strip() == b"stepping"
            time.sleep(1.0)
        finally:
            proc.kill()
            proc.wait()
        assert _wait_for(lambda: not processes_carrying(token), 30), [cmdline(p) for p in processes_carrying(token)]
    assert "Traceback" not in log.read_text(errors="replace"), log.read_text(errors="replace")
