import pytest

import dynabarn


def test_star_import_exposes_everything_in_all():
    namespace: dict = {}
    exec("from dynabarn import *", namespace)
    missing = [name for name in dynabarn.__all__ if name not in namespace]
    assert not missing


def test_importing_the_package_changes_no_global_state():
    # Names load on first use: `import dynabarn` neither imports MuJoCo nor sets MUJOCO_GL.
    import subprocess
    import sys

    code = (
        "import os, sys; os.environ.pop('MUJOCO_GL', None); import dynabarn, dynabarn.cli;"
        "print('mujoco' in sys.modules, 'MUJOCO_GL' in os.environ, dynabarn.WorldSpec.__name__)"
    )
    env = {k: v for k, v in __import__("os").environ.items() if k != "MUJOCO_GL"}
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env, check=True)
    assert out.stdout.split() == ["False", "False", "WorldSpec"]


def _pages() -> list:
    from pathlib import Path

    root = Path(dynabarn.__file__).parent.parent
    return [root / "README.md", *sorted((root / "docs").rglob("*.md"))]


def _blocks(text: str) -> list[tuple[str, str]]:
    """The fenced code blocks of a markdown page: (language, code)."""
    blocks, lang, lines = [], None, []
    for line in text.splitlines():
        if lang is None and line.startswith("```"):
            lang, lines = line[3:].strip(), []
        elif lang is not None and line.startswith("```"):
            blocks.append((lang, "\n".join(lines) + "\n"))
            lang = None
        elif lang is not None:
            lines.append(line)
    assert lang is None, "a code block is not closed"
    return blocks


def _python_blocks(page) -> list[str]:
    return [code for lang, code in _blocks(page.read_text()) if lang == "python"]


PAGES_WITH_PYTHON = [page for page in _pages() if _python_blocks(page)]
EXPECTED_OUTPUT = {  # what a page's examples print, where they print something to check
    "README.md": "world_137 | wander | barn | seed 0:",
    "planner.md": "world_137 | wander | barn | seed 0:",
    "worlds.md": "my_world | dwa | barn | seed 0:",
    "training.md": "inputs",
}


def test_the_documentation_has_python_examples():
    names = {page.name for page in PAGES_WITH_PYTHON}
    assert set(EXPECTED_OUTPUT) <= names and len(PAGES_WITH_PYTHON) >= 5, names


@pytest.mark.parametrize("page", PAGES_WITH_PYTHON, ids=lambda p: p.name)
def test_every_python_block_runs_as_written(page, tmp_path, monkeypatch, capsys):
    """Every ```python block of the README and of the documentation runs as written, page by
    page (a page's blocks share one namespace, as a reader would run them in order)."""
    from tests.conftest import require

    blocks = _python_blocks(page)
    if any("gymnasium" in code for code in blocks):
        require("gymnasium", "learn")
    monkeypatch.chdir(tmp_path)
    namespace = {"__name__": f"__{page.stem}__"}
    for code in blocks:
        exec(compile(code, str(page), "exec"), namespace)
    out = capsys.readouterr().out
    if page.name in EXPECTED_OUTPUT:
        assert EXPECTED_OUTPUT[page.name] in out, out
    if page.name == "worlds.md":
        assert (tmp_path / "my_world.xml").is_file()


def test_every_command_line_of_the_readme_and_the_docs_parses():
    """Every `dynabarn-*` line of a shell (or plain) code block is one the command's parser
    accepts: the pages show no option a command does not have."""
    import shlex

    from dynabarn.cli.dispatch import COMMANDS

    checked, wrong = 0, []
    for page in _pages():
        for _, block in (b for b in _blocks(page.read_text()) if b[0] in ("", "bash")):
            for line in block.replace("\\\n", " ").splitlines():
                if not line.lstrip().startswith("dynabarn-"):
                    continue
                words = shlex.split(line, comments=True)
                ends = [k for k, w in enumerate(words) if w in ("&&", "||", ";", "|")]
                words = words[: ends[0]] if ends else words  # the first command of a chain
                name = words[0].removeprefix("dynabarn-")
                checked += 1
                if name not in COMMANDS:
                    wrong.append(f"{page.parent.name}/{page.name}: unknown command: {line.strip()}")
                    continue
                module = __import__(f"dynabarn.cli.{name}", fromlist=["build_parser"])
                try:
                    module.build_parser().parse_args(words[1:])
                except SystemExit:
                    wrong.append(f"{page.parent.name}/{page.name}: does not parse: {line.strip()}")
    assert not wrong, "\n".join(wrong)
    assert checked >= 30


def test_every_command_chooses_mujocos_opengl_platform_before_mujoco_is_imported():
    """MuJoCo reads MUJOCO_GL once, when first imported: on a machine without a display,
    each command's parser sets EGL before anything it imports brings MuJoCo in (else
    `--video` dies in MuJoCo's renderer)."""
    from dynabarn.cli.dispatch import COMMANDS
    from tests.conftest import run_headless

    code = (
        "import importlib.abc, os, sys\n"
        "seen = []\n"
        "class Watch(importlib.abc.MetaPathFinder):\n"
        "    def find_spec(self, name, path=None, target=None):\n"
        "        if name == 'mujoco' and not seen:\n"
        "            seen.append(os.environ.get('MUJOCO_GL'))\n"
        "sys.meta_path.insert(0, Watch())\n"
        "import importlib\n"
        "importlib.import_module('dynabarn.cli.' + sys.argv[1]).build_parser()\n"
        "print(seen[0] if seen else 'not imported')\n"
    )
    for name in COMMANDS:
        proc = run_headless(code.replace("sys.argv[1]", repr(name)))
        assert proc.returncode == 0, proc.stderr
        assert proc.stdout.strip() in ("egl", "not imported"), (name, proc.stdout)


def test_the_command_table_is_pyprojects_scripts():
    """A command is added in one module (`dynabarn/cli/NAME.py` with NAME_main, listed in
    `cli.__all__`); `[project.scripts]` must name exactly those, each at its module."""
    import tomllib

    from dynabarn.cli.dispatch import COMMANDS
    from tests.conftest import REPO

    scripts = tomllib.loads((REPO / "pyproject.toml").read_text())["project"]["scripts"]
    expected = {f"dynabarn-{name}": f"dynabarn.cli.{name}:{name}_main" for name in COMMANDS}
    assert scripts == expected
    for name, main in COMMANDS.items():
        assert main.__module__ == f"dynabarn.cli.{name}" and main.__name__ == f"{name}_main"


def test_the_command_table_is_the_documentations_navigation():
    """Each command has its page (`docs/commands/NAME.md`, its options generated from its
    parser by the `<!-- cli: NAME -->` marker) and that page is in mkdocs.yml's navigation
    under Commands, in the same order as `[project.scripts]`; no page for a command that is
    not one."""
    import re
    import tomllib

    from dynabarn.cli.dispatch import COMMANDS
    from tests.conftest import REPO

    nav = re.findall(r"^\s+- dynabarn-(\w+): commands/(\w+)\.md$", (REPO / "mkdocs.yml").read_text(), re.M)
    scripts = list(tomllib.loads((REPO / "pyproject.toml").read_text())["project"]["scripts"])
    assert [f"dynabarn-{name}" for name, _ in nav] == scripts
    assert all(name == page for name, page in nav) and {name for name, _ in nav} == set(COMMANDS)
    pages = {p.stem for p in (REPO / "docs" / "commands").glob("*.md")}
    assert pages == set(COMMANDS)
    for name in COMMANDS:
        assert f"<!-- cli: {name} -->" in (REPO / "docs" / "commands" / f"{name}.md").read_text(), name
