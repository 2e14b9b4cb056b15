"""Fit the difficulty calibration (issue 43, item 4) from the committed results and write
`dynabarn/bench/calibration.json` and `docs/assets/calibration.png`.

    python benchmarks/calibration.py --root DIR

Every results folder in `FOLDERS` whose worlds' files are found under the repository or
`--root` (the imported release's 60 and the mixed and shaped worlds are not part of the
repository: generate or import them there with the commands of docs/results.md) gives its
worlds' outcomes per rung; `dynabarn.bench.calibration` fits each rung on four fifths of
the worlds and scores it on the fifth held back. Worlds with reactive obstacles are left
out: their schedules are not what happened.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

from dynabarn.bench.calibration import CALIBRATION_FILE, RUNGS, by_rung, calibrate, gather, predict, slack_by_world
from dynabarn.files import write_atomically
from dynabarn.worldset import read_index

ROOT = Path(__file__).resolve().parents[1]
FOLDERS = (
    "paper60_barn",
    "original60_barn",
    "unseen_barn",
    "mixed_hard_barn",
    "shaped_hard_barn",
    "tier_dense_barn",
    "tier_fast_barn",
    "tier_mixed_barn",
    "tier_combined_barn",
    "mixed_easy_medium_barn",
)
FIGURE = ROOT / "docs" / "assets" / "calibration.png"


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--root", type=Path, default=ROOT, help="where world files outside the repository are")
    args = parser.parse_args(argv)
    indexes = []
    for folder in (ROOT / "generated_worlds", args.root / "imported_worlds"):
        if (folder / "index.json").is_file():
            indexes.append(read_index(folder))
    slack = slack_by_world(indexes)
    worlds = []
    for root in dict.fromkeys((ROOT, args.root)):
        worlds += gather([ROOT / "results" / f for f in FOLDERS], root, slack)
    seen: dict[str, object] = {}
    for w in worlds:  # a world found under both roots: once
        seen.setdefault(w.sha256, w)
    worlds = list(seen.values())
    counts = by_rung(worlds)
    calibration = calibrate(worlds) | {"worlds": len(worlds), "results": list(FOLDERS)}
    write_atomically(CALIBRATION_FILE, json.dumps(calibration, indent=1, sort_keys=True) + "\n")
    print(f"{len(worlds)} worlds; per rung: {counts}")
    for rung, fit in calibration["rungs"].items():
        print(
            f"{rung:<18} worlds {fit['worlds']:>4} held back {fit['held_back']:>3}  Spearman {fit['spearman']:+.2f} "
            f"(ceiling {fit['spearman_ceiling']:+.2f})  "
            f"AUC {fit['auc']:.2f}  (crossings per minute alone: {fit['spearman_baseline']:+.2f})"
        )
    _draw(worlds, calibration)
    print(f"wrote {CALIBRATION_FILE} and {FIGURE}")
    return 0


def _draw(worlds, calibration) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    rungs = [r for r in RUNGS if r in calibration["rungs"]]
    fig, axes = plt.subplots(2, (len(rungs) + 1) // 2, figsize=(3.2 * ((len(rungs) + 1) // 2), 6.4), squeeze=False)
    for ax, rung in zip(axes.ravel(), rungs, strict=False):
        fit = calibration["rungs"][rung]
        test = [w for w in worlds if rung in w.outcomes and w.held_back]
        p = [predict(fit, w.features) for w in test]
        rate = [w.outcomes[rung][0] / w.outcomes[rung][1] for w in test]
        ax.scatter(p, rate, s=8, alpha=0.6)
        ax.plot([0, 1], [0, 1], color="grey", lw=0.8, ls="--")
        ax.set_title(f"{rung}\nSpearman (difficulty) {fit['spearman']:+.2f}, AUC {fit['auc']:.2f}", fontsize=9)
        ax.set_xlim(-0.02, 1.02)
        ax.set_ylim(-0.02, 1.02)
    for ax in axes.ravel()[len(rungs) :]:
        ax.axis("off")
    fig.supxlabel("predicted success (held-back worlds)")
    fig.supylabel("actual success")
    fig.tight_layout()
    fig.savefig(FIGURE, dpi=110, metadata={"Software": None})
    plt.close(fig)


if __name__ == "__main__":
    sys.exit(main())
