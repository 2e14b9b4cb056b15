"""Demonstration collection: a person drives the Jackal in MuJoCo's viewer.

The paper's pipeline recorded people driving a Jackal in Gazebo with a joystick into ROS
bags. Here: MuJoCo's passive viewer (a follow camera, the goal region drawn), the keyboard
(or a gamepad when pygame sees one), the episode run by the same loop and judged by the
same protocol as any planner, and an MCAP recording written as it goes with the runner's
topics plus the raw input on `/teleop/input`. The simulation is paced to real time.

Keys (GLFW codes in the viewer's key callback):
- Up / Down: forward speed +- one step; Left / Right: turn rate +- one step;
- Space: stop (v = w = 0);
- 1 / 2: slow mode (0.1 m/s and 0.3 rad/s steps, at most 1 m/s) / fast mode (0.25 m/s and
  0.6 rad/s steps, up to the Jackal's 2 m/s), like the original gamepad's two buttons;
- Escape (or closing the window): end the episode early.
A gamepad's left stick sets v and w directly; its buttons 0 and 1 choose slow and fast.
"""

from __future__ import annotations

import json
import threading
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from dynabarn.files import file_name_part
from dynabarn.interfaces import EndEpisode, EpisodeInfo, Observation, Planner
from dynabarn.recording import McapRecorder, Topic
from dynabarn.recording.schemas import number, obj

INPUT = Topic(
    "/teleop/input",
    "dynabarn.TeleopInput",
    "10 Hz",
    "the operator's input: keys pressed since the last tick, the command set, the mode, a gamepad's axes",
    json_schema=obj(
        "the operator's input at one control tick",
        {
            "keys": {"type": "array", "items": {"type": "string"}},
            "v": number("forward speed set [m/s]"),
            "w": number("yaw rate set [rad/s]"),
            "mode": {"enum": ["slow", "fast"]},
            "gamepad": {"type": ["object", "null"], "description": "axes and buttons, null without a gamepad"},
        },
        ("keys", "v", "w", "mode", "gamepad"),
    ),
)
MANIFEST = "manifest.jsonl"

KEY_UP, KEY_DOWN, KEY_LEFT, KEY_RIGHT = 265, 264, 263, 262
KEY_SPACE, KEY_ESCAPE, KEY_1, KEY_2 = 32, 256, 49, 50
KEY_NAMES = {
    KEY_UP: "up", KEY_DOWN: "down", KEY_LEFT: "left", KEY_RIGHT: "right",
    KEY_SPACE: "space", KEY_ESCAPE: "escape", KEY_1: "slow", KEY_2: "fast",
}  # fmt: skip

MODES = {"slow": (0.1, 0.3, 1.0), "fast": (0.25, 0.6, 2.0)}
"""mode -> (v step [m/s], w step [rad/s], v max [m/s])."""


class OperatorStop(EndEpisode):
    """The operator ended the episode (Escape or closed window)."""

    REASON = "ended by the operator"


@dataclass
class TeleopState:
    """The command the operator has set, changed by key presses (from the viewer's thread)."""

    v: float = 0.0
    w: float = 0.0
    mode: str = "slow"
    stop_requested: bool = False
    pending: list[str] = field(default_factory=list)
    lock: threading.Lock = field(default_factory=threading.Lock)

    def press(self, keycode: int) -> None:
        name = KEY_NAMES.get(keycode)
        if name is None:
            return
        with self.lock:
            dv, dw, vmax = MODES[self.mode]
            if name == "up":
                self.v = min(self.v + dv, vmax)
            elif name == "down":
                self.v = max(self.v - dv, -0.5)
            elif name == "left":
                self.w = min(self.w + dw, 3.14)
            elif name == "right":
                self.w = max(self.w - dw, -3.14)
            elif name == "space":
                self.v = self.w = 0.0
            elif name in ("slow", "fast"):
                self.mode = name
                self.v = min(self.v, MODES[name][2])
            elif name == "escape":
                self.stop_requested = True
            self.pending.append(name)

    def take(self) -> tuple[float, float, str, list[str], bool]:
        with self.lock:
            keys, self.pending = self.pending, []
            return self.v, self.w, self.mode, keys, self.stop_requested


class Gamepad:
    """The first joystick pygame finds, if any (pygame is optional)."""

    def __init__(self) -> None:
        self.joystick = None
        try:
            import os

            os.environ.setdefault("SDL_VIDEODRIVER", "dummy")
            import pygame

            pygame.init()
            pygame.joystick.init()
            if pygame.joystick.get_count():
                self.joystick = pygame.joystick.Joystick(0)
                self.joystick.init()
            self._pygame = pygame
        except Exception:  # no pygame, no SDL: keyboard only
            self.joystick = None

    @property
    def name(self) -> str | None:
        return self.joystick.get_name() if self.joystick is not None else None

    def poll(self, state: TeleopState) -> dict | None:
        if self.joystick is None:
            return None
        self._pygame.event.pump()
        axes = [float(self.joystick.get_axis(i)) for i in range(min(2, self.joystick.get_numaxes()))]
        buttons = [int(self.joystick.get_button(i)) for i in range(min(2, self.joystick.get_numbuttons()))]
        with state.lock:
            if buttons and buttons[0]:
                state.mode = "slow"
            if len(buttons) > 1 and buttons[1]:
                state.mode = "fast"
            vmax = MODES[state.mode][2]
            if len(axes) == 2:
                state.v = float(np.clip(-axes[1] * vmax, -0.5, vmax))
                state.w = float(np.clip(-axes[0] * 3.14, -3.14, 3.14))
        return {"axes": axes, "buttons": buttons}


class TeleopPlanner(Planner):
    """A 'planner' whose commands come from a person; logs every input to the recording."""

    name = "teleop"

    def __init__(
        self,
        state: TeleopState | None = None,
        recorder: McapRecorder | None = None,
        gamepad: Gamepad | None = None,
        operator: str = "human",
    ):
        self.state = state if state is not None else TeleopState()
        self.recorder = recorder
        self.gamepad = gamepad if gamepad is not None else Gamepad()
        self.operator = operator

    def recording_options(self) -> dict:
        """The operator's input channel, and who drove: every input is on the recording."""
        return {"extra_channels": (INPUT,), "extra_metadata": {"source": "human", "operator": self.operator}}

    def attach_recording(self, recorder: McapRecorder) -> None:
        self.recorder = recorder

    def report(self) -> dict:
        """The gamepad that drove, if any."""
        return {"gamepad": self.gamepad.name if self.gamepad is not None else None}

    def reset(self, info: EpisodeInfo) -> None:
        self.info = info

    def act(self, obs: Observation) -> tuple[float, float]:
        pad = self.gamepad.poll(self.state) if self.gamepad is not None else None
        v, w, mode, keys, stop = self.state.take()
        if self.recorder is not None:
            self.recorder.log_json(INPUT.name, obs.time, {"keys": keys, "v": v, "w": w, "mode": mode, "gamepad": pad})
        if stop:
            raise OperatorStop(OperatorStop.REASON)
        return v, w


def next_demo_path(demos_dir: Path, world: str, operator: str) -> Path:
    """demos/<world>_<operator>_<NNN>.mcap, the first number not taken."""
    demos_dir.mkdir(parents=True, exist_ok=True)
    stem = f"{file_name_part(world)}_{file_name_part(operator)}"  # names never leave demos_dir
    k = 1
    while (demos_dir / f"{stem}_{k:03d}.mcap").exists():
        k += 1
    return demos_dir / f"{stem}_{k:03d}.mcap"


def listed_files(demos_dir: Path) -> set[str]:
    """The recordings `demos_dir`'s manifest lists, read as untrusted input: a line that is
    not a JSON object with a string `file` is one `DynabarnError` naming it."""
    from dynabarn.errors import DynabarnError

    path = demos_dir / MANIFEST
    if not path.is_file():
        return set()
    try:
        lines = path.read_text().splitlines()
    except (OSError, UnicodeDecodeError) as exc:
        raise DynabarnError(f"{path}: cannot read it ({exc})") from None
    listed = set()
    for line_no, line in enumerate(lines, start=1):
        if not line.strip():
            continue
        try:
            entry = json.loads(line)
        except (ValueError, RecursionError):
            entry = None
        if not isinstance(entry, dict) or not isinstance(entry.get("file"), str):
            raise DynabarnError(f"{path}:{line_no}: not a manifest entry (a JSON object with a file name)")
        listed.add(entry["file"])
    return listed


def append_manifest(demos_dir: Path, entry: dict) -> None:
    with (demos_dir / MANIFEST).open("a") as f:
        f.write(json.dumps(entry, sort_keys=True) + "\n")


def run_teleop(
    world_path: Path,
    protocol,
    out: Path,
    *,
    operator: str = "human",
    seed: int = 0,
    speed: float = 1.0,
):
    """Open the viewer, run one episode driven by the operator, record it; returns the result."""
    from dynabarn.live.viewer import MujocoViewer
    from dynabarn.planners.registry import PLANNERS, register_planner
    from dynabarn.runner import EpisodeSpec, run_spec

    if "teleop" not in PLANNERS:
        register_planner(TeleopPlanner)  # this process's alone: the operator's keys reach only it
    viewers: list = []

    def watch(sim, planner: TeleopPlanner) -> tuple:
        """The operator's window on the compiled world: their keys drive; closing it ends
        the episode as Escape does."""
        sim.reset(protocol.spawn)
        viewer = MujocoViewer(
            sim,
            goal_tolerance=protocol.goal_tolerance,
            rate=speed,
            key_callback=planner.state.press,
            own_keys=False,
            closed_reason=OperatorStop.REASON,
        )
        viewers.append(viewer)
        viewer.open()
        return (viewer,)

    try:
        spec = EpisodeSpec.make(world_path, "teleop", protocol, config={"operator": operator}, seed=seed)
        run = run_spec(spec, record_to=out, on_built=watch)
    finally:
        for viewer in viewers:
            viewer.close()
    return run.result, run.planner_report["gamepad"]
