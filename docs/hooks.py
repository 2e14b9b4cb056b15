"""MkDocs hooks (`hooks:` in mkdocs.yml): the command pages' option reference, generated from
the commands' own argparse parsers at build time, so the site never says what `--help` does
not.

A page asks for it with a line `<!-- cli: run -->` (the command's name, as in
`dynabarn-run`); the hook puts the usage line and one table per (sub)command there.
"""

from __future__ import annotations

import argparse
import importlib
import re

MARKER = re.compile(r"^<!-- cli: (\w+) -->$", re.M)
API_MARKER = "<!-- api -->"


def _cell(text: str) -> str:
    """Table-safe text: pipes escaped, whitespace folded."""
    return " ".join(text.split()).replace("|", "\\|")


def _default(action: argparse.Action) -> str:
    if action.required or action.nargs == 0 or any(action.default is v for v in (None, False, argparse.SUPPRESS)):
        return ""
    if isinstance(action.default, list | tuple):
        return ", ".join(f"`{v}`" for v in action.default) if action.default else ""
    return f"`{action.default}`"


def _name(action: argparse.Action) -> str:
    if not action.option_strings:
        return f"`{action.metavar or action.dest}`"
    names = ", ".join(f"`{s}`" for s in action.option_strings)
    if action.nargs != 0:
        metavar = action.metavar or (("{" + ",".join(map(str, action.choices)) + "}") if action.choices else None)
        names += f" `{metavar or action.dest.upper()}`"
    return names


def _help(action: argparse.Action) -> str:
    text = action.help or ""
    if "%(" in text:
        text = text % {**vars(action), "prog": "", "default": action.default}
    return _cell(text)


def _usage(parser: argparse.ArgumentParser) -> str:
    """The usage lines without argparse's "usage: " and its indentation."""
    lines = parser.format_usage().strip().removeprefix("usage: ").splitlines()
    return "\n".join([lines[0], *(line.removeprefix(" " * len("usage: ")) for line in lines[1:])])


def _table(parser: argparse.ArgumentParser) -> str:
    rows = ["| option | default | meaning |", "|---|---|---|"]
    for action in parser._actions:
        if isinstance(action, argparse._HelpAction | argparse._VersionAction | argparse._SubParsersAction):
            continue
        if action.help == argparse.SUPPRESS:
            continue
        rows.append(f"| {_name(action)} | {_default(action)} | {_help(action)} |")
    return "\n".join(rows)


def _subparsers(parser: argparse.ArgumentParser) -> dict[str, argparse.ArgumentParser]:
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            return dict(action.choices)
    return {}


def command_reference(name: str) -> str:
    """The markdown reference of `dynabarn-<name>`, from its `build_parser()`."""
    module = importlib.import_module(f"dynabarn.cli.{name}")
    parser: argparse.ArgumentParser = module.build_parser()
    parts = ["## Options", "", f"Generated from `dynabarn-{name} --help`.", ""]
    subs = _subparsers(parser)
    if not subs:
        parts += ["```", _usage(parser), "```", "", _table(parser)]
        return "\n".join(parts) + "\n"
    parts += [_cell(parser.description or ""), ""]
    for sub_name, sub in subs.items():
        parts += [f"### `dynabarn-{name} {sub_name}`", "", _cell(sub.description or ""), ""]
        parts += ["```", _usage(sub), "```", "", _table(sub), ""]
    return "\n".join(parts) + "\n"


API_ORDER = (
    "dynabarn.planners",  # what a user writes first: a planner, and what it observes
    "dynabarn.sim",
    "dynabarn.protocol",
    "dynabarn.metrics",
    "dynabarn.worldset",
    "dynabarn.worlds.spec",
    "dynabarn.worlds.generate",
    "dynabarn.worlds.trajectory",
    "dynabarn.worlds.profiles",
    "dynabarn.worlds.schedule",
    "dynabarn.mjcf",
    "dynabarn.recording",
    "dynabarn.errors",
)
"""The API page's sections in the order a newcomer meets them; a module not listed comes last."""


def _api_rank(module: str) -> tuple[int, str]:
    return (API_ORDER.index(module) if module in API_ORDER else len(API_ORDER), module)


def api_reference() -> str:
    """mkdocstrings blocks for every name `dynabarn` exports, grouped by where it is defined,
    so the API page lists exactly `dynabarn.__all__`."""
    import dynabarn

    where = dynabarn._WHERE
    modules: dict[str, list[str]] = {}
    for name in dynabarn.__all__:
        modules.setdefault(where[name], []).append(name)
    parts = []
    for module, names in sorted(modules.items(), key=lambda item: _api_rank(item[0])):
        parts += [f"## `{module}`", ""]
        for name in names:
            parts += [f"::: {module}.{name}", "    options:", "      heading_level: 3", ""]
    return "\n".join(parts)


def on_page_markdown(markdown: str, page, config, files) -> str:
    if API_MARKER in markdown:
        markdown = markdown.replace(API_MARKER, api_reference())
    return MARKER.sub(lambda m: command_reference(m[1]), markdown)


def on_post_build(config) -> None:
    """Every leaderboard set's sweep report (`dynabarn.bench.report`), rendered from its
    committed results folder into the site's `reports/FOLDER.html`, where the leaderboard
    links them."""
    import sys
    from pathlib import Path

    root = Path(config["config_file_path"]).resolve().parent
    sys.path.insert(0, str(root / "benchmarks"))
    from leaderboard import REPORTS
    from readme_results import LEADERBOARD_SETS, RESULTS_DIR, STACK_GUESTS

    from dynabarn.bench.report import render_report
    from dynabarn.bench.results import RESULTS, read_results
    from dynabarn.files import write_atomically

    out = Path(config["site_dir"]) / REPORTS
    out.mkdir(parents=True, exist_ok=True)
    guests = [folder for rows in STACK_GUESTS.values() for folder, _, _ in rows]
    for folder in (*LEADERBOARD_SETS, *guests):
        rows = read_results(RESULTS_DIR / folder / RESULTS)
        if rows:
            # Only a complete verdict reaches the site: a local --verify that skipped rows says nothing of them.
            write_atomically(out / f"{folder}.html", render_report(RESULTS_DIR / folder, rows, site=True))
