"""The README's hero image (docs/assets/replay_world137_dwa.png): `dynabarn-replay --web` of
world 137 with DWA, in headless Chromium (the tests' DevTools harness, `tests/browser.py`),
shot once the scene is drawn and the viewer's start-up notices (software rasterizer,
container) have faded, so the picture shows the run and nothing else.

    python benchmarks/hero_image.py      # about a minute; needs chromium (make system-deps)
"""

from __future__ import annotations

import socket
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
OUT = ROOT / "docs" / "assets" / "replay_world137_dwa.png"
NOTICES_FADE = 30.0
"""Seconds after the scene appears before the shot: the viewer's notices are gone by then."""


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def main() -> int:
    sys.path.insert(0, str(ROOT))
    from dynabarn import EpisodeSpec, get_protocol, resolve_world, run_spec
    from dynabarn.files import write_atomically
    from tests.browser import Browser

    with tempfile.TemporaryDirectory() as tmp:
        recording = Path(tmp) / "world_137_dwa.mcap"
        run_spec(EpisodeSpec.make(resolve_world(137), "dwa", get_protocol("barn"), seed=0), record_to=recording)
        port, grpc = _free_port(), _free_port()
        command = [sys.executable, "-m", "dynabarn", "replay", str(recording), "--web", "--port", str(port)]
        proc = subprocess.Popen([*command, "--grpc-port", str(grpc)], stdout=subprocess.PIPE, text=True)
        try:
            url = proc.stdout.readline().strip()
            with Browser() as browser:
                browser.call(
                    "Emulation.setDeviceMetricsOverride", width=1400, height=800, deviceScaleFactor=1, mobile=False
                )
                browser.open(url)
                time.sleep(20.0)  # WebAssembly compiles in software first
                time.sleep(NOTICES_FADE)
                write_atomically(OUT, browser.screenshot())
        finally:
            proc.terminate()
            proc.wait(timeout=20)
    print(f"wrote {OUT}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
