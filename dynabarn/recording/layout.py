"""The Foxglove layout shipped for recordings and live runs (`assets/foxglove/dynabarn.json`).

Built from the topic table with foxglove-sdk's layout classes: a 3D panel following the
robot's `base_link` in the `world` frame (scan, obstacles, walls, goal, plans, tracks), a top-down
3D panel of the whole arena, one plot per field the table marks for plotting, the episode's
result and the frame tree. Import the file in Foxglove (Layouts -> Import from file).
`python -m dynabarn.recording.layout --out assets/foxglove/dynabarn.json` regenerates it (a
test keeps it in step); from an installed package, `python -m dynabarn.recording.layout`
prints it.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import foxglove.layouts as fl

from dynabarn.recording.topic_registry import plotted
from dynabarn.recording.topics import FRAMES, RESULT, TOPICS

LAYOUT_FILE = Path(__file__).resolve().parents[2] / "assets" / "foxglove" / "dynabarn.json"
"""The shipped copy, in a checkout of the repository."""
SCENE_TOPICS = tuple(t for t in TOPICS if t.in_3d)
"""What the 3D panels draw (the frame tree on `/tf` places them): the table's `in_3d` topics."""
_SETTINGS = {
    "foxglove.SceneUpdate": lambda: fl.BaseRendererSceneUpdateTopicSettings(visible=True),
    "foxglove.LaserScan": lambda: fl.BaseRendererLaserScanTopicSettings(visible=True, point_size=4),
    "foxglove.PoseInFrame": lambda: fl.BaseRendererPoseTopicSettings(visible=True),
}
"""How a 3D panel draws a topic of each schema."""


def _scene(follow: str | None, camera: fl.ThreeDeeCameraState, title: str) -> fl.ThreeDeePanel:
    topics: dict = {t.name: _SETTINGS[t.schema]() for t in SCENE_TOPICS}
    return fl.ThreeDeePanel(
        title=title,
        config=fl.ThreeDeeConfig(
            fixed_frame=FRAMES[0],
            follow_tf=follow or FRAMES[0],
            follow_mode="follow-position" if follow else "follow-none",
            camera_state=camera,
            topics=topics,
        ),
    )


def foxglove_layout() -> fl.Layout:
    """The layout: scenes on the left, plots, result and frame tree on the right."""
    follow = _scene(
        FRAMES[2], fl.ThreeDeeCameraState(distance=12.0, perspective=True, phi=50.0, theta_offset=90.0), "robot"
    )
    arena = _scene(
        None,
        fl.ThreeDeeCameraState(distance=30.0, perspective=False, phi=0.0, target=(0.5, 0.0, 0.0), theta_offset=90.0),
        "arena (top)",
    )
    plots = [
        fl.SplitItem(
            content=fl.PlotPanel(config=fl.PlotConfig(paths=[fl.PlotSeries(value=f"{topic.name}.{name}", label=name)]))
        )
        for topic, name in plotted()
    ]
    result = fl.RawMessagesPanel(config=fl.RawMessagesConfig(topic_path=RESULT.name, expansion="all"))
    return fl.Layout(
        content=fl.SplitContainer(
            direction="row",
            items=[
                fl.SplitItem(
                    proportion=3,
                    content=fl.SplitContainer(
                        direction="column",
                        items=[fl.SplitItem(proportion=2, content=follow), fl.SplitItem(content=arena)],
                    ),
                ),
                fl.SplitItem(
                    proportion=2,
                    content=fl.SplitContainer(
                        direction="column",
                        items=[
                            *plots,
                            fl.SplitItem(content=result),
                            fl.SplitItem(content=fl.TransformTreePanel()),
                        ],
                    ),
                ),
            ],
        )
    )


def layout_json() -> str:
    """The layout file's text: indented, keys in a fixed order, a final newline."""
    return json.dumps(json.loads(foxglove_layout().to_json()), indent=2) + "\n"


def referenced_topics(layout: dict) -> set[str]:
    """Every topic a layout's panels name (3D topics, plot paths, raw messages)."""
    found: set[str] = set()

    def walk(node) -> None:
        if isinstance(node, dict):
            for key, value in node.items():
                if key == "topics" and isinstance(value, dict):
                    found.update(value)
                elif key in ("value", "topicPath") and isinstance(value, str) and value.startswith("/"):
                    found.add(value.split(".")[0])
                walk(value)
        elif isinstance(node, list):
            for item in node:
                walk(item)

    walk(layout)
    return found


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description="Print (or --out) the Foxglove layout for DynaBARN recordings.")
    parser.add_argument(
        "--out",
        type=Path,
        default=None,
        help="write it to this file (default: print it; the checkout's copy is assets/foxglove/dynabarn.json)",
    )
    args = parser.parse_args(argv)
    if args.out is not None:
        from dynabarn.files import write_atomically

        try:
            write_atomically(args.out, layout_json())
        except OSError as exc:
            print(f"error: cannot write {args.out}: {exc.strerror or exc}", file=sys.stderr)
            return 2
        print(f"wrote {args.out}")
    else:
        print(layout_json(), end="")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
