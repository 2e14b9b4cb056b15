"""Building ROS 2 packages from fetched sources with colcon, into a prefix outside the
package: the sources checked against their release (`find_sources`), a build that is done
once for the same sources, packages and CMake arguments (`colcon_build`, its record written
last), and the command line of such a build (`build_command`). Used by `ros2_build` (the
core) and `nav2_build` (Nav2, an overlay on it)."""

from __future__ import annotations

import argparse
import hashlib
import re
import shlex
import shutil
import sys
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

from dynabarn.errors import DynabarnError
from dynabarn.ros.nav_build import debian_env, read_marker, run_logged, write_marker

COLCON = "colcon-common-extensions==0.3.0"
"""colcon from PyPI (Debian has none), in the prefix's own virtual environment."""


def setup_script(workspace: Path) -> Path:
    """The prefix's `setup.bash`, which a stack's shell sources."""
    return workspace / "install" / "setup.bash"


@dataclass(frozen=True)
class Download:
    """A source that a package's CMake would download (FetchContent), fetched with the rest
    instead: the build points `FETCHCONTENT_SOURCE_DIR_<CONTENT>` at its folder, so nothing
    is downloaded while building. Not a ROS package (no package.xml): its version is checked
    by a line of one of its files."""

    repository: str
    version: str
    content: str
    """FetchContent's name for it (`fetchcontent_declare(NAME ...)`)."""
    version_file: str
    version_text: str
    """Text `version_file` holds at this version."""


def repos_file(repositories: dict[str, tuple[str, str]], downloads: dict[str, Download] | None = None) -> str:
    """The repositories (and the downloads) as a vcstool file (`vcs import SRC < FILE`)."""
    lines = ["repositories:"]
    every = {**repositories, **{name: (d.repository, d.version) for name, d in (downloads or {}).items()}}
    for name, (repository, version) in every.items():
        url = f"https://github.com/{repository}.git"
        lines += [f"  {name}:", "    type: git", f"    url: {url}", f"    version: {version}"]
    return "\n".join(lines) + "\n"


def _package_versions(tree: Path) -> dict[str, str]:
    """name -> version of every package.xml under `tree` (the first folder down that has one)."""
    found = {}
    for xml in sorted(tree.rglob("package.xml")):
        text = xml.read_text(errors="replace")
        name, version = re.search(r"<name>\s*([^<\s]+)", text), re.search(r"<version>\s*([^<\s]+)", text)
        if name and version:
            found[name.group(1)] = version.group(1)
    return found


def find_sources(
    source: Path,
    repositories: dict[str, tuple[str, str]],
    *,
    release: str,
    module: str,
    downloads: dict[str, Download] | None = None,
) -> dict[str, Path]:
    """Each repository's folder in `source` (by its name, or vcstool's ORG/NAME), checked:
    every one present, each of its packages at the release's version, each download's
    version line in place. One line naming what is missing or other."""
    if not source.is_dir():
        raise DynabarnError(f"{source}: no such folder (fetch the sources: python -m dynabarn.ros.{module} --repos)")

    def folder_of(name: str, repository: str) -> Path | None:
        return next((p for p in (source / name, source / repository) if p.is_dir()), None)

    folders, other, missing = {}, [], []
    for name, download in (downloads or {}).items():
        folder = folder_of(name, download.repository)
        marker = folder / download.version_file if folder is not None else None
        if marker is None or not marker.is_file():
            missing.append(name)
        elif download.version_text not in marker.read_text(errors="replace"):
            other.append(f"{name} (not {download.version}: {download.version_file} lacks {download.version_text!r})")
        else:
            folders[name] = folder
    for name, (repository, version) in repositories.items():
        folder = folder_of(name, repository)
        versions = _package_versions(folder) if folder is not None else {}
        if not versions:
            missing.append(name)
            continue
        found = sorted({v for v in versions.values() if v != version})
        if found:
            other.append(f"{name} ({', '.join(found)}, not {version})")
        folders[name] = folder
    if other or missing:
        shown = other[:4] + ([f"{len(missing)} missing ({', '.join(missing[:4])}{', ...' if len(missing) > 4 else ''})"]
                             if missing else [])  # fmt: skip
        raise DynabarnError(f"{source}: not the sources of {release}: {'; '.join(shown)}")
    return folders


def sources_digest(folders: dict[str, Path]) -> str:
    """sha256 over every source file's path and bytes: what decides whether a build is current."""
    digest = hashlib.sha256()
    for name, folder in sorted(folders.items()):
        for path in sorted(p for p in folder.rglob("*") if p.is_file()):
            digest.update(f"{name}/{path.relative_to(folder)}\0".encode())
            digest.update(path.read_bytes())
    return digest.hexdigest()


def _colcon(workspace: Path, log) -> Path:
    """colcon in the prefix's virtual environment over Debian's Python (made once)."""
    venv = workspace / "tools"
    colcon = venv / "bin" / "colcon"
    if not colcon.exists():
        run_logged(["/usr/bin/python3", "-m", "venv", "--system-site-packages", str(venv)], log, env=debian_env())
        (venv / "COLCON_IGNORE").write_text("")  # colcon never takes the tools for packages
        run_logged([str(venv / "bin" / "pip"), "install", "-q", COLCON], log, env=debian_env())
    return colcon


def _folder_size(folder: Path) -> int:
    return sum(p.stat().st_size for p in folder.rglob("*") if p.is_file() and not p.is_symlink())


@dataclass(frozen=True)
class SourceEdit:
    """One change to a fetched file before it is built, where a release and Debian's
    libraries disagree; each says why, and the build's record holds it."""

    repository: str
    """The folder's name in the sources (a key of the repositories)."""
    file: str
    old: str
    new: str
    why: str


ARGUMENT_KEYS = ("cmake_args", "package_cmake_args", "source_edits")
"""The record's keys for a build's CMake arguments and source edits (each left out when
empty, so a record written before they were kept still describes a build without any)."""


def _arguments(
    cmake_args: tuple[str, ...], package_cmake_args: dict[str, tuple[str, ...]], edits: tuple[SourceEdit, ...]
) -> dict:
    """A build's CMake arguments and source edits as its record holds them."""
    given = {
        "cmake_args": list(cmake_args),
        "package_cmake_args": {k: list(v) for k, v in package_cmake_args.items()},
        "source_edits": [[f"{e.repository}/{e.file}", e.old, e.new] for e in edits],
    }
    return {key: value for key, value in given.items() if value}


def _prepare_sources(
    source: Path,
    src: Path,
    folders: dict[str, Path],
    ignored: tuple[str, ...],
    downloads: dict[str, Download],
    edits: tuple[SourceEdit, ...],
) -> list[str]:
    """`source` copied to the build's `src` (without .git), the `ignored` packages and the
    downloads hidden from colcon, the edits made; the CMake flags that give the downloads."""
    if src.exists():
        shutil.rmtree(src)
    shutil.copytree(source, src, symlinks=True, ignore=shutil.ignore_patterns(".git"))
    for package in ignored:
        for xml in src.rglob("package.xml"):
            if f"<name>{package}</name>" in xml.read_text(errors="replace"):
                (xml.parent / "COLCON_IGNORE").write_text("left out by dynabarn.ros\n")
    for edit in edits:
        path = src / folders[edit.repository].relative_to(source) / edit.file
        text = path.read_text()
        if edit.old not in text:
            raise DynabarnError(f"{edit.repository}/{edit.file}: the text to change is not there ({edit.old!r})")
        path.write_text(text.replace(edit.old, edit.new))
    # A download is CMake's source, not colcon's packages (mcap's tree holds Python ones).
    fetched = []
    for name, download in downloads.items():
        folder = src / folders[name].relative_to(source)
        (folder / "COLCON_IGNORE").write_text("a download, given to CMake by dynabarn.ros\n")
        fetched.append(f"-DFETCHCONTENT_SOURCE_DIR_{download.content.upper()}={folder}")
    return fetched


def _current(done: dict, digest: str, packages: tuple[str, ...], arguments: dict, workspace: Path) -> bool:
    """Whether the finished build `done` is of these sources, holds these packages and was
    built with these CMake arguments (`_arguments`)."""
    return (
        done.get("sources_sha256") == digest
        and set(packages) <= set(done.get("packages", ()))
        and {key: done[key] for key in ARGUMENT_KEYS if key in done} == arguments
        and setup_script(workspace).is_file()
    )


def colcon_build(
    workspace: Path,
    source: Path,
    folders: dict[str, Path],
    *,
    packages: tuple[str, ...],
    ignored: tuple[str, ...],
    record: dict,
    marker: str,
    what: str,
    jobs: int = 2,
    underlay: Path | None = None,
    cmake_args: tuple[str, ...] = (),
    package_cmake_args: dict[str, tuple[str, ...]] | None = None,
    downloads: dict[str, Download] | None = None,
    edits: tuple[SourceEdit, ...] = (),
) -> dict:
    """colcon over the checked sources `folders` of `source` into `workspace` (`install/`
    merged, `build/`, `build.log`, the marker written last), over the prefix `underlay`
    when given (its `setup.bash` sourced first), `package_cmake_args` {package: CMake
    arguments of its own} built alone after the rest, each of `downloads` given to CMake
    from its folder, the `edits` made to the copy that is built; `record` plus the packages,
    the sources' digest, size and seconds, with `rebuilt`. Nothing is built when the marker
    names the same sources, holds every package asked for and was built with the same
    arguments and edits."""
    if not Path("/usr/bin/python3").exists() or shutil.which("cmake") is None:
        raise DynabarnError("Debian's build tools are missing: `sudo make ros2-deps`")
    package_cmake_args = package_cmake_args or {}
    arguments = _arguments(cmake_args, package_cmake_args, edits)
    digest = sources_digest(folders)
    done = read_marker(workspace / marker)
    if done is not None and _current(done, digest, packages, arguments, workspace):
        return {**done, "rebuilt": False}
    workspace.mkdir(parents=True, exist_ok=True)
    (workspace / marker).unlink(missing_ok=True)
    src = workspace / "src"
    fetched = _prepare_sources(source, src, folders, ignored, downloads or {}, edits)
    log_path = workspace / "build.log"
    t0 = time.monotonic()
    with log_path.open("w") as log:
        colcon = _colcon(underlay or workspace, log)  # an overlay uses its underlay's colcon
        print(f"building {what} with colcon, {jobs} workers (log: {log_path})", file=sys.stderr)
        env = {**debian_env(), "PATH": f"{colcon.parent}:/usr/bin:/bin", "MAKEFLAGS": f"-j{jobs}"}
        common = [
            str(colcon), "build", "--base-paths", str(src), "--build-base", str(workspace / "build"),
            "--install-base", str(workspace / "install"), "--merge-install", "--parallel-workers", str(jobs),
            "--event-handlers", "console_direct-",
        ]  # fmt: skip
        flags = ["-DBUILD_TESTING=OFF", "-DTRACETOOLS_DISABLED=ON", "-DCMAKE_BUILD_TYPE=Release",
                 "-DPython3_EXECUTABLE=/usr/bin/python3", *fetched, *cmake_args]  # fmt: skip
        # Everything but the packages with flags of their own, then each of those alone.
        skip = ["--packages-skip", *package_cmake_args] if package_cmake_args else []
        runs = [[*common, "--packages-up-to", *packages, *skip, "--cmake-args", *flags]]
        runs += [[*common, "--packages-select", name, "--cmake-args", *flags, *extra]
                 for name, extra in package_cmake_args.items()]  # fmt: skip
        for command in runs:
            if underlay is not None:  # the underlay's environment (its packages, libraries) for colcon
                line = f"source {shlex.quote(str(setup_script(underlay)))} && exec {shlex.join(command)}"
                command = ["bash", "-c", line]
            run_logged(command, log, cwd=workspace, env=env)
    if not setup_script(workspace).is_file():
        raise DynabarnError(f"the build ended without {setup_script(workspace)}: see {log_path}")
    share = workspace / "install" / "share"
    info = {
        **record,
        "sources_sha256": digest,
        "packages": sorted(p.name for p in share.iterdir() if (p / "package.xml").is_file()),
        "install_bytes": _folder_size(workspace / "install"),
        **arguments,
        "jobs": jobs,
    }
    return {**write_marker(workspace / marker, info, t0), "rebuilt": True}


def build_command(
    argv: list[str] | None,
    *,
    prog: str,
    description: str,
    source_variable: str,
    workspace_env: str,
    default: Callable[[], Path],
    default_shown: str,
    repositories: dict[str, tuple[str, str]],
    build: Callable[[Path, Path, argparse.Namespace], dict],
    label: str,
    add_arguments: Callable[[argparse.ArgumentParser], None] | None = None,
    downloads: dict[str, Download] | None = None,
) -> int:
    """The command line of a colcon build of ours (`ros2_build`, `nav2_build`): --source,
    --workspace, --jobs, --repos, and what `add_arguments` adds; `build(workspace, source,
    args)` runs it. One line and exit 2 for bad input, a read-only or a full disk."""
    parser = argparse.ArgumentParser(prog=prog, description=description)
    parser.add_argument(
        "--source", type=Path, default=None, help=f"the folder of fetched repositories ({source_variable})"
    )
    parser.add_argument(
        "--workspace",
        type=Path,
        default=None,
        help=f"prefix to build in (default: ${workspace_env} or {default_shown})",
    )
    if add_arguments is not None:
        add_arguments(parser)
    parser.add_argument("--jobs", type=int, default=2, help="packages built at once, and compile jobs (default: 2)")
    parser.add_argument("--repos", action="store_true", help="print the repositories and versions as a vcstool file")
    args = parser.parse_args(argv)
    if args.repos:
        print(repos_file(repositories, downloads), end="")
        return 0
    if args.source is None:
        parser.error(f"--source ({source_variable}) is required: the folder of fetched repositories (see --repos)")
    if args.jobs < 1:
        parser.error("--jobs must be at least 1")
    workspace = (args.workspace or default()).expanduser().resolve()
    try:
        info = build(workspace, args.source.expanduser().resolve(), args)
    except (DynabarnError, OSError) as exc:  # a read-only or full disk: one line too
        print(f"error: {exc}", file=sys.stderr)
        return 2
    what = f"built in {info['seconds']:.0f} s" if info["rebuilt"] else "already built from these sources"
    print(f"{label}: {len(info['packages'])} packages, {info['install_bytes'] / 1e6:.0f} MB, {what}: {workspace}")
    return 0
