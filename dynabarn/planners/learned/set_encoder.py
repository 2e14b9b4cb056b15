"""The `set` student network: each kind of input through the layer that suits it.

The first students (`mlp`) read the feature vector of `features.FeatureConfig` as one flat
vector through three fully connected layers (750,000 weights). This network splits it as
`FeatureConfig.layout` says (a departure from Fig. 4, named where its numbers are):

- **the scans as a short film**: the current scan, min-pooled as the history frames are
  (`history_pool` beams to one: the nearest return is what avoidance needs), stacked with
  the K earlier frames as channels and read by two strided 1D convolutions along the beams.
  A convolution sees the same motion at every bearing the same way, where a dense layer has
  to learn it once per beam; the frames' differences are where obstacles move. With
  `static_map`, the known map's pooled ranges are one more channel: where the scan reads
  shorter than the map, something the map does not hold is there.
- **the tracks as a set** (Deep Sets, Zaheer et al. 2017): one small network applied to
  every track slot, its outputs of empty slots zeroed, then pooled by maximum and by mean
  over the slots. The output does not depend on the order of the tracks, and a track in
  slot 7 counts as much as one in slot 0 (the flat network saw the nearest K in fixed
  slots, each slot learned apart).
- the local goal and the measured velocity as they are.

A head of two ReLU layers reads the three together. About a third of the flat network's
weights (the call's network part is cheaper by as much).
"""

from __future__ import annotations

import itertools

import torch
from torch import nn

from dynabarn.planners.learned.features import TRACK_FIELDS, FeatureConfig

SCAN_CHANNELS = (16, 32)
"""Output channels of the two convolutions (kernel 5, stride 2 each)."""
SCAN_FEATURES = 128
TRACK_FEATURES = 64
"""Width of the per-track network; the set gives twice this (max and mean)."""
HEAD = (256, 128)


def _relu_mlp(sizes: list[int]) -> nn.Sequential:
    layers: list[nn.Module] = []
    for a, b in itertools.pairwise(sizes):
        layers += [nn.Linear(a, b), nn.ReLU()]
    return nn.Sequential(*layers)


class SetEncoderNet(nn.Module):
    """Feature vector (batch, FeatureConfig.size()) -> (batch, n_out): tanh-bounded where
    `bounded` (a regressed action), else logits."""

    def __init__(self, features: FeatureConfig, n_out: int, *, bounded: bool) -> None:
        super().__init__()
        lay = self.layout = features.layout()
        frames = 1 + features.history + (1 if lay["static_map"] else 0)
        self.pool = features.history_pool
        c1, c2 = SCAN_CHANNELS
        self.scan = nn.Sequential(
            nn.Conv1d(frames, c1, 5, stride=2, padding=2),
            nn.ReLU(),
            nn.Conv1d(c1, c2, 5, stride=2, padding=2),
            nn.ReLU(),
            nn.Flatten(),
        )
        with torch.no_grad():
            flat = self.scan(torch.zeros(1, frames, lay["pooled"])).shape[1]
        self.scan_out = _relu_mlp([flat, SCAN_FEATURES])
        self.track = _relu_mlp([TRACK_FIELDS, TRACK_FEATURES, TRACK_FEATURES]) if lay["tracks"] else None
        width = SCAN_FEATURES + 2 + (2 if lay["velocity"] else 0) + (2 * TRACK_FEATURES if lay["tracks"] else 0)
        self.head = nn.Sequential(_relu_mlp([width, *HEAD]), nn.Linear(HEAD[-1], n_out))
        if bounded:
            self.head.append(nn.Tanh())

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        lay = self.layout
        n, pooled = lay["beams"], lay["pooled"]
        scan = x[:, :n]
        pad = pooled * self.pool - n
        if pad:  # beams beyond the last whole pool read as far away (as `Features` pads them)
            scan = torch.cat([scan, scan.new_ones(x.shape[0], pad)], dim=1)
        now = -nn.functional.max_pool1d(-scan[:, None, :], self.pool)  # min-pooled, (batch, 1, pooled)
        a, b = lay["history"]
        if lay["static_map"]:  # the map's channel right after the history frames, as the vector holds them
            b = lay["static_map"][1]
        film = torch.cat([now, x[:, a:b].reshape(x.shape[0], -1, pooled)], dim=1) if b > a else now
        parts = [self.scan_out(self.scan(film)), x[:, n : n + 2]]
        if lay["velocity"]:
            a, b = lay["velocity"]
            parts.append(x[:, a:b])
        if self.track is not None:
            a, b = lay["tracks"]
            slots = x[:, a:b].reshape(x.shape[0], -1, TRACK_FIELDS)
            present = slots[:, :, TRACK_FIELDS - 1 :]
            h = self.track(slots) * present  # an empty slot adds nothing to either pool
            count = present.sum(dim=1).clamp(min=1.0)
            parts += [h.amax(dim=1), h.sum(dim=1) / count]
        return self.head(torch.cat(parts, dim=1))
