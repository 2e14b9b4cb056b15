"""The student of `dynabarn-train dagger`: a network over `Features`, and its file.

A multilayer perceptron (ReLU hidden layers, tanh output: the normalised action of
`DynaBARN-v0`) over the feature vector of `features.FeatureConfig`. It is a departure
from the paper's Fig. 4 (tanh everywhere, 722 inputs), named where its numbers are. The
file keeps the feature configuration and `trained_on` (what it trained on, for the
refusal check of `trained_on.check_unseen`) beside the weights; it loads with
`torch.load(weights_only=True)`: no pickled code.
"""

from __future__ import annotations

import itertools
from pathlib import Path

import torch
from torch import nn

from dynabarn.errors import DynabarnError
from dynabarn.files import save_atomically
from dynabarn.planners.learned.features import FeatureConfig
from dynabarn.planners.learned.models import load_weights, read_blob

STUDENT_FORMAT = "dynabarn-student-v1"
HIDDEN = (512, 256, 128)


class StudentActor(nn.Module):
    def __init__(self, n_inputs: int, hidden: tuple[int, ...] = HIDDEN) -> None:
        super().__init__()
        layers: list[nn.Module] = []
        sizes = [n_inputs, *hidden, 2]
        for i, (a, b) in enumerate(itertools.pairwise(sizes)):
            layers.append(nn.Linear(a, b))
            layers.append(nn.ReLU() if i < len(sizes) - 2 else nn.Tanh())
        self.net = nn.Sequential(*layers)
        self.n_inputs = n_inputs
        self.hidden = tuple(hidden)

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        return self.net(x)


def save_student(actor: StudentActor, path: Path, *, features: FeatureConfig, trained_on: dict, notes: dict) -> Path:
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    blob = {
        "format": STUDENT_FORMAT,
        "kind": "dagger",
        "n_inputs": actor.n_inputs,
        "hidden": list(actor.hidden),
        "features": features.to_dict(),
        "trained_on": trained_on,
        "notes": notes,
        "state_dict": actor.state_dict(),
    }
    save_atomically(path, lambda f: torch.save(blob, f))
    return path


def load_student(path: Path) -> tuple[StudentActor, FeatureConfig, dict]:
    """(actor, its features, the header) of a file written by `save_student`."""
    path = Path(path)
    blob = read_blob(path, STUDENT_FORMAT)
    try:
        features = FeatureConfig.from_dict(blob["features"])
        hidden = tuple(int(h) for h in blob["hidden"])
        n_inputs = int(blob["n_inputs"])
        if not isinstance(blob["trained_on"], dict):
            raise TypeError("trained_on is not a mapping")
    except (KeyError, TypeError, ValueError) as exc:
        raise DynabarnError(f"{path}: malformed student header ({exc})") from None
    if not (1 <= len(hidden) <= 8 and all(1 <= h <= 4096 for h in hidden)):
        raise DynabarnError(f"{path}: hidden layers {hidden} out of range")
    if n_inputs != features.size():
        raise DynabarnError(f"{path}: {n_inputs} inputs, but its features make {features.size()}")
    actor = load_weights(StudentActor(n_inputs, hidden), blob, path, "student")
    return actor, features, {k: v for k, v in blob.items() if k != "state_dict"}
