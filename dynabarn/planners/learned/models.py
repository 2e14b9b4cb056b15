"""The networks of the paper's Fig. 4, in PyTorch.

Actor: 722 inputs -> feature layers 512, 256, 128 -> actor layers 64, 32 -> 2 outputs, tanh
after every layer (the output in [-1, 1] is the normalised action of `DynaBARN-v0`).
Critic (TD3): the same layers on the state and action (724 inputs) with one output, the
value ("only the final layer of the actor network is modified to output the value").
Inputs are scaled inside the network (ranges / 30 m, local goal / lookahead), so
planners and datasets feed raw observations.

Policies are saved as plain state dicts with a small header, and loaded with
`torch.load(weights_only=True)`: no pickled code.
"""

from __future__ import annotations

import itertools
import warnings
from pathlib import Path

import torch
from torch import nn

from dynabarn.files import save_atomically

OBS_DIM = 722
ACT_DIM = 2
FEATURES = (512, 256, 128)
HEAD = (64, 32)
RANGE_MAX = 30.0
POLICY_FORMAT = "dynabarn-policy-v1"


def _mlp(sizes: list[int], *, out_activation: bool) -> nn.Sequential:
    layers: list[nn.Module] = []
    for i, (a, b) in enumerate(itertools.pairwise(sizes)):
        layers.append(nn.Linear(a, b))
        if i < len(sizes) - 2 or out_activation:
            layers.append(nn.Tanh())
    return nn.Sequential(*layers)


class ObsScale(nn.Module):
    def __init__(self, lookahead: float = 2.0) -> None:
        super().__init__()
        scale = torch.ones(OBS_DIM)
        scale[: OBS_DIM - 2] = 1.0 / RANGE_MAX
        scale[OBS_DIM - 2 :] = 1.0 / lookahead
        self.register_buffer("scale", scale)

    def forward(self, obs: torch.Tensor) -> torch.Tensor:
        return obs * self.scale


class Actor(nn.Module):
    def __init__(self, lookahead: float = 2.0) -> None:
        super().__init__()
        self.scale = ObsScale(lookahead)
        self.features = _mlp([OBS_DIM, *FEATURES], out_activation=True)
        self.head = _mlp([FEATURES[-1], *HEAD, ACT_DIM], out_activation=True)

    def forward(self, obs: torch.Tensor) -> torch.Tensor:
        return self.head(self.features(self.scale(obs)))


class Critic(nn.Module):
    def __init__(self, lookahead: float = 2.0) -> None:
        super().__init__()
        self.scale = ObsScale(lookahead)
        self.features = _mlp([OBS_DIM + ACT_DIM, *FEATURES], out_activation=True)
        self.head = _mlp([FEATURES[-1], *HEAD, 1], out_activation=False)

    def forward(self, obs: torch.Tensor, action: torch.Tensor) -> torch.Tensor:
        return self.head(self.features(torch.cat([self.scale(obs), action], dim=-1)))


def save_policy(actor: Actor, path: Path, *, kind: str, lookahead: float, notes: dict | None = None) -> Path:
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    blob = {
        "format": POLICY_FORMAT,
        "kind": kind,
        "lookahead": float(lookahead),
        "notes": dict(notes or {}),
        "state_dict": actor.state_dict(),
    }
    save_tensors(path, blob)
    return path


def save_tensors(path: Path, blob: dict) -> None:
    """`torch.save` into `path`, atomically (`files.save_atomically`); PyTorch's failure to
    write (a full disk, which its zip writer reports as a RuntimeError of several lines) is
    an OSError with one line, like any other failed write."""
    import errno

    def save(f) -> None:
        try:
            torch.save(blob, f)
        except RuntimeError as exc:
            first = (str(exc).strip().splitlines() or ["write failed"])[0][:160]
            raise OSError(errno.EIO, f"PyTorch could not write it ({first}; a full disk?)", str(path)) from None

    save_atomically(path, save)


def load_tensors(path: Path):
    """What `torch.save` wrote to `path`: every member's CRC checked first (PyTorch reads a
    zip without checking them, so a flipped byte loaded and drove), then tensors and plain
    data only (`weights_only`: a file never runs code). The one way this package reads a
    PyTorch file (policies, students, training checkpoints); raises on anything else."""
    import zipfile

    with zipfile.ZipFile(path) as archive:
        bad = archive.testzip()
    if bad is not None:
        raise zipfile.BadZipFile(f"{bad} is damaged (its CRC does not match)")
    with warnings.catch_warnings():  # PyTorch warns about a foreign file's pickle protocol
        warnings.simplefilter("ignore")
        return torch.load(path, map_location="cpu", weights_only=True)


def read_blob(path: Path, fmt: str) -> dict:
    """A policy file's dictionary (weights only, no pickled code), or one clear error."""
    from dynabarn.errors import DynabarnError

    path = Path(path)
    if not path.is_file():
        raise DynabarnError(f"policy file not found: {path}")
    try:
        blob = load_tensors(path)
    except Exception as exc:  # PyTorch's refusals run to a page; their first sentence says it
        first = str(exc).strip().split(". ")[0].splitlines()[0][:160] if str(exc).strip() else ""
        raise DynabarnError(f"{path}: not a loadable policy ({type(exc).__name__}: {first})") from None
    if not isinstance(blob, dict) or blob.get("format") != fmt:
        raise DynabarnError(f"{path}: not a {fmt} file")
    return blob


def load_policy(path: Path) -> tuple[Actor, dict]:
    """Load an actor saved by `save_policy` (weights only, no pickled code)."""
    from dynabarn.errors import DynabarnError

    path = Path(path)
    blob = read_blob(path, POLICY_FORMAT)
    lookahead = blob.get("lookahead", 2.0)
    if isinstance(lookahead, bool) or not isinstance(lookahead, int | float) or not 0.1 <= lookahead <= 30.0:
        raise DynabarnError(f"{path}: lookahead {lookahead!r} is not in [0.1, 30] m")
    actor = load_weights(Actor(lookahead), blob, path, "policy")
    return actor, {k: v for k, v in blob.items() if k != "state_dict"}


def load_weights(network: nn.Module, blob: dict, path: Path, what: str) -> nn.Module:
    """`network` with a policy file's weights, in evaluation mode, or one clear error."""
    from dynabarn.errors import DynabarnError

    try:
        network.load_state_dict(blob["state_dict"])
    except (KeyError, TypeError, RuntimeError, AttributeError) as exc:
        first = str(exc).strip().splitlines()[0] if str(exc).strip() else type(exc).__name__
        raise DynabarnError(f"{path}: its weights do not fit the {what} network ({first})") from None
    network.eval()
    return network
