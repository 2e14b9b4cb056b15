"""Build hook: the wheel carries the repository's data as package data.

`generated_worlds/` (the 300 worlds and their index) and `assets/jackal/` (the robot they
name) live at the top of the checkout, as the product's layout says. A wheel copies both
into `dynabarn/data/` in the same relative layout, so a world's
`<model file="../assets/jackal/jackal.xml">` resolves in an installed package exactly as in
a checkout (`dynabarn.provenance.DATA_ROOT` finds either). Editable installs read them in
place. Everything else is declared in pyproject.toml.
"""

from pathlib import Path

from setuptools import setup
from setuptools.command.build_py import build_py

ROOT = Path(__file__).resolve().parent
SHIPPED_DATA = {"generated_worlds": ("world_*.xml", "index.json"), "assets/jackal": ("*",)}
"""Folder (relative to the checkout) -> the files of it that go into the wheel."""


class BuildPyWithData(build_py):
    def run(self) -> None:
        super().run()
        if self.editable_mode:
            return
        for folder, patterns in SHIPPED_DATA.items():
            files = sorted({f for pattern in patterns for f in (ROOT / folder).glob(pattern) if f.is_file()})
            if not files:
                raise SystemExit(f"setup.py: nothing to ship in {folder}/ (run `make worlds` first)")
            target = Path(self.build_lib) / "dynabarn" / "data" / folder
            self.mkpath(str(target))
            for f in files:
                self.copy_file(str(f), str(target / f.name))


setup(cmdclass={"build_py": BuildPyWithData})
