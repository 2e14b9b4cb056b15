from __future__ import annotations

import os

# MuJoCo picks its OpenGL platform when first imported: offscreen EGL unless a display is set
# (dynabarn/__init__.py does the same, but a test module may import mujoco before dynabarn).
if "MUJOCO_GL" not in os.environ and not os.environ.get("DISPLAY"):
    os.environ["MUJOCO_GL"] = "egl"

import json
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parent.parent
REFERENCE = REPO.parent / "shared" / "reference"

_LOG_KEY = pytest.StashKey[tuple[int, int] | None]()

REQUIRE_ALL = os.environ.get("DYNABARN_REQUIRE_ALL") == "1"
"""Set by `.ci/run`, which installs every extra and Debian package: a test skipped for a
missing install is then a failure. Skips for what no install brings stay skips."""
SKIPS_NO_INSTALL_BRINGS = (
    "reference data",  # the original release's data (../shared/reference) is not distributed
    "on this CPU",  # a CPU feature the machine lacks
    "make ros-nav",  # move_base built from source: fetched from GitHub, which CI does not reach
    "make ros-teb",  # teb_local_planner and g2o built from source: the same
    "make ros2-core",  # ROS 2 Jazzy built from fetched sources: the same
    "make nav2",  # Nav2 built from fetched sources over it: the same
)


MUJOCO_LOG = REPO / "MUJOCO_LOG.TXT"
"""Where MuJoCo writes its warnings when a test runs in the repository's folder."""


def _mujoco_log_state() -> tuple[int, int] | None:
    return (MUJOCO_LOG.stat().st_size, MUJOCO_LOG.stat().st_mtime_ns) if MUJOCO_LOG.exists() else None


def pytest_sessionstart(session):
    session.config.stash[_LOG_KEY] = _mujoco_log_state()


def pytest_sessionfinish(session, exitstatus):
    """A MuJoCo warning during the suite (a world or scene that compiles with a conflict, a
    model that warns while stepping) fails it: the file it leaves names the warning."""
    if _mujoco_log_state() != session.config.stash.get(_LOG_KEY, None):
        reporter = session.config.pluginmanager.get_plugin("terminalreporter")
        if reporter is not None:
            reporter.write_line(f"MuJoCo wrote warnings into {MUJOCO_LOG} during the tests:", red=True)
            reporter.write_line(MUJOCO_LOG.read_text()[-2000:])
        session.exitstatus = pytest.ExitCode.TESTS_FAILED


def require(module: str, extra: str):
    """Import `module`, or skip with the command that installs it (`extra`: the extra of
    pyproject.toml that brings it)."""
    return pytest.importorskip(module, reason=f"needs {module}: pip install -e '.[{extra}]' (make test installs it)")


def tagged_environment() -> tuple[str, dict[str, str]]:
    """(token, environment): an environment for a test's child processes carrying a token of
    its own, which `processes_carrying` then finds in them and everything they start."""
    import time

    value = f"{os.getpid()}_{time.monotonic_ns()}"
    return f"DYNABARN_TEST_TAG={value}", {**os.environ, "DYNABARN_TEST_TAG": value}


def processes_carrying(token: str) -> list[int]:
    """Pids of the processes whose environment holds `token` ("NAME=value"): what a test
    started and everything that started (environments are inherited, new sessions or not),
    never what else runs on the machine."""
    found = []
    for environ in Path("/proc").glob("[0-9]*/environ"):
        try:
            if token.encode() in environ.read_bytes():
                found.append(int(environ.parent.name))
        except OSError:  # gone meanwhile, or not ours to read
            continue
    return found


def cmdline(pid: int) -> str:
    try:
        return Path(f"/proc/{pid}/cmdline").read_bytes().replace(b"\0", b" ").decode(errors="replace")
    except OSError:
        return str(pid)


def run_headless(code: str):
    """`code` in a fresh interpreter as on a machine without a display, where nobody set
    MUJOCO_GL (the tests' own choice of EGL is taken away)."""
    import subprocess
    import sys

    env = {k: v for k, v in os.environ.items() if k not in ("MUJOCO_GL", "DISPLAY", "WAYLAND_DISPLAY")}
    return subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env, timeout=120)


@pytest.hookimpl(hookwrapper=True)
def pytest_runtest_makereport(item, call):
    outcome = yield
    report = outcome.get_result()
    if not (REQUIRE_ALL and report.skipped) or hasattr(report, "wasxfail"):
        return
    reason = str(report.longrepr[2] if isinstance(report.longrepr, tuple) else report.longrepr)
    if not any(allowed in reason for allowed in SKIPS_NO_INSTALL_BRINGS):
        report.outcome = "failed"
        report.longrepr = f"skipped, but DYNABARN_REQUIRE_ALL=1 says everything is installed: {reason}"


@pytest.fixture(scope="session")
def release_json() -> dict:
    path = REFERENCE / "dynabarn60.json"
    if not path.is_file():
        pytest.skip("reference data ../shared/reference/dynabarn60.json not present")
    return json.loads(path.read_text())


@pytest.fixture(scope="session")
def release_path(release_json) -> Path:
    return REFERENCE / "dynabarn60.json"


@pytest.fixture(scope="session")
def barn_json() -> dict:
    path = REFERENCE / "barn300_static.json"
    if not path.is_file():
        pytest.skip("reference data ../shared/reference/barn300_static.json not present")
    return json.loads(path.read_text())


@pytest.fixture
def display():
    """An Xvfb display of its own (1280x800), for tests of real windows; skips without Xvfb."""
    import shutil
    import subprocess

    if not (shutil.which("Xvfb") and shutil.which("xdotool")):
        pytest.skip("needs Debian's Xvfb and xdotool: sudo make system-deps")
    # Xvfb picks a free display itself and writes its number to the pipe once it listens
    # (tests running in parallel never race for the same number).
    read_end, write_end = os.pipe()
    xvfb = subprocess.Popen(
        ["Xvfb", "-displayfd", str(write_end), "-screen", "0", "1280x800x24", "-nolisten", "tcp"],
        stderr=subprocess.DEVNULL,
        pass_fds=(write_end,),
    )
    os.close(write_end)
    with os.fdopen(read_end) as pipe:
        number = pipe.readline().strip()  # empty when Xvfb died before listening
    if not number:
        xvfb.wait(timeout=10)
        pytest.fail(f"Xvfb did not start (exit status {xvfb.returncode})")
    yield f":{number}"
    xvfb.terminate()
    xvfb.wait(timeout=10)
