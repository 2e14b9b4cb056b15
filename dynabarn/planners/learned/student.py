"""The student of `dynabarn-train dagger`: a network over `Features`, and its file.

A network over the feature vector of `features.FeatureConfig`: a multilayer perceptron
(ReLU hidden layers) over the flat vector (`encoder="mlp"`), or the scans through
convolutions and the tracks as a set (`encoder="set"`, `set_encoder`); with one of two heads:

- `regress`: a tanh output, the normalised action of `DynaBARN-v0`, fitted by mean
  squared error;
- `classify`: one logit per command of the teacher's grid (`classes`, normalised actions;
  the oracle's 6 x 7 speeds and turn rates), fitted by cross-entropy, and the most likely
  command driven. The teacher chooses among a few candidates by search, so in a state
  where two of them are almost equally good the regression head averages them (swerving
  left and right averages to straight ahead), while the classifier keeps one.

Both are departures from the paper's Fig. 4 (tanh everywhere, 722 inputs, one regressed
action), named where their numbers are. The file keeps the feature configuration, the
head and `trained_on` (what it trained on, for the refusal check of
`trained_on.check_unseen`) beside the weights; it loads with
`torch.load(weights_only=True)`: no pickled code.
"""

from __future__ import annotations

import itertools
from pathlib import Path

import numpy as np
import torch
from torch import nn

from dynabarn.errors import DynabarnError
from dynabarn.planners.learned.features import FeatureConfig
from dynabarn.planners.learned.models import load_weights, read_blob, save_tensors
from dynabarn.planners.learned.set_encoder import SetEncoderNet
from dynabarn.planners.learned.spaces import ENCODERS, HEADS

STUDENT_FORMAT = "dynabarn-student-v1"
HIDDEN = (512, 256, 128)
MAX_CLASSES = 10_000


class StudentActor(nn.Module):
    """`forward` gives what the loss is taken of (the action, or the logits of a classifier);
    `act` the normalised action to drive."""

    def __init__(
        self,
        n_inputs: int,
        hidden: tuple[int, ...] = HIDDEN,
        classes: np.ndarray | None = None,
        *,
        encoder: str = "mlp",
        features: FeatureConfig | None = None,
    ) -> None:
        super().__init__()
        self.head = "regress" if classes is None else "classify"
        n_out = 2 if classes is None else len(classes)
        if encoder not in ENCODERS:
            raise DynabarnError(f"encoder {encoder!r}: use one of {', '.join(ENCODERS)}")
        self.encoder = encoder
        if encoder == "set":
            if features is None or features.size() != n_inputs:
                raise DynabarnError(f"the set encoder needs the features of its {n_inputs} inputs")
            self.net = SetEncoderNet(features, n_out, bounded=classes is None)
        else:
            self.net = _flat_mlp([n_inputs, *hidden, n_out], bounded=classes is None)
        self.n_inputs = n_inputs
        self.hidden = tuple(hidden)
        # The classes' actions travel with the weights (a buffer: in the state dict, not trained).
        if classes is None:
            self.classes: torch.Tensor | None = None
        else:
            self.register_buffer("classes", torch.as_tensor(np.asarray(classes, dtype=np.float32)))

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        return self.net(x)

    def act(self, x: torch.Tensor) -> torch.Tensor:
        """(batch, 2) normalised actions: the regressed one, or the most likely class's."""
        return self.action_of(self.net(x))

    def action_of(self, out: torch.Tensor) -> torch.Tensor:
        """The action of the network's output: itself (regression) or its likeliest class's."""
        if self.classes is None:
            return out
        return self.classes.to(out.dtype)[out.argmax(dim=-1)]

    def class_labels(self, actions: np.ndarray) -> np.ndarray:
        """The class index of each of the teacher's actions (N, 2); an action off the grid is
        refused (a teacher that does not choose among `classes` cannot be imitated this way)."""
        grid = self.classes.numpy().astype(np.float64)
        # The teacher's actions take a few distinct values: each is matched once (a dataset
        # of 280,000 rows against 42 classes at once would need several 190 MB temporaries).
        distinct, which = np.unique(np.asarray(actions, dtype=np.float64).reshape(-1, 2), axis=0, return_inverse=True)
        d = ((distinct[:, None, :] - grid[None]) ** 2).sum(-1)
        idx = d.argmin(axis=1)
        if len(idx) and float(np.sqrt(d[np.arange(len(idx)), idx]).max()) > 1e-4:
            raise DynabarnError("the teacher's actions are not on the classifier's command grid")
        return idx[which.reshape(-1)]


def _flat_mlp(sizes: list[int], *, bounded: bool) -> nn.Sequential:
    layers: list[nn.Module] = []
    for i, (a, b) in enumerate(itertools.pairwise(sizes)):
        layers.append(nn.Linear(a, b))
        if i < len(sizes) - 2:
            layers.append(nn.ReLU())
        elif bounded:
            layers.append(nn.Tanh())
    return nn.Sequential(*layers)


def student_for(features: FeatureConfig, classes: np.ndarray | None, encoder: str) -> StudentActor:
    """A new (untrained) student over `features` with the given head and encoder."""
    return StudentActor(features.size(), classes=classes, encoder=encoder, features=features)


def save_student(actor: StudentActor, path: Path, *, features: FeatureConfig, trained_on: dict, notes: dict) -> Path:
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    blob = {
        "format": STUDENT_FORMAT,
        "kind": "dagger",
        "n_inputs": actor.n_inputs,
        "hidden": list(actor.hidden),
        **({} if actor.classes is None else {"head": "classify", "classes": actor.classes.tolist()}),
        **({} if actor.encoder == "mlp" else {"encoder": actor.encoder}),
        "features": features.to_dict(),
        "trained_on": trained_on,
        "notes": notes,
        "state_dict": actor.state_dict(),
    }
    save_tensors(path, blob)
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
        head = blob.get("head", "regress")  # files before the classifier have no head: they regress
        if head not in HEADS:
            raise ValueError(f"head {head!r} is not one of {', '.join(HEADS)}")
        encoder = blob.get("encoder", "mlp")  # files before the set encoder have none: flat
        if encoder not in ENCODERS:
            raise ValueError(f"encoder {encoder!r} is not one of {', '.join(ENCODERS)}")
        classes = None
        if head == "classify":
            classes = np.asarray(blob["classes"], dtype=np.float32)
            if classes.ndim != 2 or classes.shape[1] != 2 or not 2 <= len(classes) <= MAX_CLASSES:
                raise ValueError(f"classes of shape {classes.shape}, not (k, 2) with 2 <= k <= {MAX_CLASSES}")
            if not (np.isfinite(classes).all() and np.abs(classes).max() <= 1.0):
                raise ValueError("classes outside the normalised actions [-1, 1]")
    except (KeyError, TypeError, ValueError) as exc:
        raise DynabarnError(f"{path}: malformed student header ({exc})") from None
    if not (1 <= len(hidden) <= 8 and all(1 <= h <= 4096 for h in hidden)):
        raise DynabarnError(f"{path}: hidden layers {hidden} out of range")
    if n_inputs != features.size():
        raise DynabarnError(f"{path}: {n_inputs} inputs, but its features make {features.size()}")
    actor = StudentActor(n_inputs, hidden, classes, encoder=encoder, features=features)
    actor = load_weights(actor, blob, path, "student")
    return actor, features, {k: v for k, v in blob.items() if k != "state_dict"}
