"""One vocabulary for worlds and outputs (issue 56): `--set NAME --world ID` wherever one
world is named, `--set` beside the positional set, `--out` a folder and a file named by its
own option; the old spellings still work for one release, with a one-line note."""

from __future__ import annotations

import pytest

from dynabarn.cli import run_main, worlds_main
from dynabarn.cli.common import add_renamed, make_parser


def test_a_tier_world_runs_and_shows_by_set_and_id(capsys):
    assert run_main(["--set", "tier-combined", "--world", "210", "--planner", "stop", "--no-log"]) == 0
    assert capsys.readouterr().out.startswith("world_210 | stop | barn")
    assert worlds_main(["show", "--set", "tier-combined", "--world", "210"]) == 0
    out = capsys.readouterr().out
    assert out.startswith("world_210") and "tier-combined" in out
    assert worlds_main(["show", "world_137"]) == 0  # the positional spelling stays
    capsys.readouterr()


@pytest.mark.parametrize(
    "argv, message",
    [
        (["--set", "tier-combined", "--world", "99999", "--no-log"], "not in set 'tier-combined'"),
        (["--set", "tier-combined", "--world", "some/file.xml", "--no-log"], "with --set, a world id or name"),
        (["--set", "nowhere", "--world", "1", "--no-log"], "unknown world set 'nowhere'"),
    ],
)
def test_a_world_not_in_its_set_is_one_line(argv, message):
    from tests.test_fuzz import one_clear_line

    assert message in one_clear_line("run", argv)


def test_show_and_certify_name_exactly_one_world_or_set():
    from tests.test_fuzz import one_clear_line

    assert "name one world" in one_clear_line("worlds", ["show"])
    assert "name one world" in one_clear_line("worlds", ["show", "world_1", "--world", "2"])
    assert "name one world set" in one_clear_line("worlds", ["certify"])


def test_an_old_spelling_still_works_and_says_its_new_name(capsys):
    parser = make_parser("dynabarn-x", "x")
    parser.add_argument("--video", default=None)
    add_renamed(parser, "--out", "--video", "video")
    assert parser.parse_args(["--out", "v.mp4"]).video == "v.mp4"
    assert capsys.readouterr().err.strip() == "note: --out is now --video; the old spelling goes in the next release"
    assert "--out" not in parser.format_help()  # not in --help, nor in the docs' option tables
    from dynabarn.cli.train import build_parser

    args = build_parser().parse_args(["dagger", "--out", "x", "--profile-sets", "table1"])
    assert args.profiles == "table1" and "--profile-sets is now --profiles" in capsys.readouterr().err


def test_a_required_option_is_given_by_either_spelling(capsys):
    from pathlib import Path

    from dynabarn.cli.render import build_parser

    assert build_parser().parse_args(["rec.mcap", "--out", "v.mp4"]).video == Path("v.mp4")
    assert build_parser().parse_args(["rec.mcap", "--video", "v.mp4"]).video == Path("v.mp4")
    capsys.readouterr()
    with pytest.raises(SystemExit) as stop:
        build_parser().parse_args(["rec.mcap"])
    assert stop.value.code == 2 and "required: --video" in capsys.readouterr().err
