"""The student's network in numpy, for one decision at a time (`NumpyStudent`).

A decision is a batch of one through some two dozen small operations. PyTorch spends
about 10 µs of its own on each (TorchScript a little less), more than the arithmetic; on a
busy machine its intra-op threads wait on each other as well. numpy's own cost per
operation is a few µs, so the `dagger` planner evaluates its network here: the same weights
in float64, the same layers in the same order, read from the trained PyTorch module when
the planner loads (training, batches and the GPU stay in PyTorch). Only the order of the
additions inside a matrix product (and a regressing head's tanh, numpy's own) can differ
from PyTorch's kernels, as they already differ between PyTorch's kernels on different
CPUs: outputs agree to about 1e-13, far inside the runner's command resolution, and the
chosen command is the same (`tests/test_student_set.py` holds both).

The convolutions run as one gather and one matrix product each ("im2col"), on signals kept
as (length, channels) in buffers that live as long as the planner; nothing is allocated per
call but each convolution's gathered windows and the small outputs of each layer.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
from torch import nn

from dynabarn.planners.learned.features import TRACK_FIELDS
from dynabarn.planners.learned.set_encoder import SetEncoderNet


def _array(t) -> np.ndarray:
    return np.ascontiguousarray(t.detach().cpu().numpy(), dtype=np.float64)


class _Dense:
    """`nn.Linear` on (..., in): x @ W^T + b."""

    def __init__(self, layer: nn.Linear) -> None:
        self.weight_t = _array(layer.weight.T)
        self.bias = _array(layer.bias)

    def __call__(self, x: np.ndarray) -> np.ndarray:
        y = x @ self.weight_t
        y += self.bias
        return y


class _Conv:
    """`nn.Conv1d` (zero padding, no dilation or groups) on a signal of (length, channels):
    the padded signal in a kept buffer, each output position's window gathered by a fixed
    index, then one matrix product."""

    def __init__(self, layer: nn.Conv1d, length: int) -> None:
        (k,), (stride,), (pad,) = layer.kernel_size, layer.stride, layer.padding
        if layer.dilation != (1,) or layer.groups != 1 or layer.padding_mode != "zeros":
            raise ValueError(f"no numpy form for {layer}")
        channels, out = layer.in_channels, layer.out_channels
        self.length, self.pad = length, pad
        self.out_length = (length + 2 * pad - k) // stride + 1
        self.padded = np.zeros((length + 2 * pad, channels))
        start = np.arange(self.out_length)[:, None] * stride + np.arange(k)[None, :]  # (out, k)
        self.window = (start[:, :, None] * channels + np.arange(channels)).reshape(self.out_length, k * channels)
        # (out_ch, in_ch, k) -> rows in the window's (k, in_ch) order
        self.weight = _array(layer.weight.permute(2, 1, 0).reshape(k * channels, out))
        self.bias = _array(layer.bias)

    def __call__(self, x: np.ndarray) -> np.ndarray:
        self.padded[self.pad : self.pad + self.length] = x
        y = self.padded.ravel()[self.window] @ self.weight
        y += self.bias
        return y


def _relu(y: np.ndarray) -> np.ndarray:
    return np.maximum(y, 0.0, out=y)


def _flatten(y: np.ndarray) -> np.ndarray:
    """(length, channels) as PyTorch flattens (channels, length)."""
    return y.T.ravel()


def _modules(seq: nn.Module) -> list[nn.Module]:
    if isinstance(seq, nn.Sequential):
        return [m for child in seq for m in _modules(child)]
    return [seq]


def _chain(seq: nn.Module, length: int | None = None) -> Callable[[np.ndarray], np.ndarray]:
    """A `nn.Sequential` of Linear, Conv1d, ReLU, Tanh and Flatten as one numpy function
    (`length`: the signal's length where it starts with a convolution)."""
    steps: list[Callable[[np.ndarray], np.ndarray]] = []
    for m in _modules(seq):
        if isinstance(m, nn.Linear):
            steps.append(_Dense(m))
        elif isinstance(m, nn.Conv1d):
            conv = _Conv(m, length)
            length = conv.out_length
            steps.append(conv)
        elif isinstance(m, nn.ReLU):
            steps.append(_relu)
        elif isinstance(m, nn.Tanh):
            steps.append(np.tanh)
        elif isinstance(m, nn.Flatten):
            steps.append(_flatten)
        else:
            raise ValueError(f"no numpy form for {type(m).__name__}")

    def run(x: np.ndarray) -> np.ndarray:
        for step in steps:
            x = step(x)
        return x

    return run


class _SetForward:
    """`SetEncoderNet.forward` for one feature vector (keep the two alike: the test compares)."""

    def __init__(self, net: SetEncoderNet) -> None:
        lay = net.layout
        self.n, self.pooled, self.pool = lay["beams"], lay["pooled"], net.pool
        self.velocity, self.tracks = lay["velocity"], lay["tracks"]
        # The history frames, then the map's pooled ranges where given: contiguous in the
        # vector, each one more channel of the film.
        a, b = lay["history"]
        self.history = (a, lay["static_map"][1] if lay["static_map"] else b)
        frames = 1 + (self.history[1] - self.history[0]) // self.pooled
        # Beams beyond the last whole pool read as far away (1.0), as the network pads them.
        self.scan = np.ones(self.pooled * self.pool)
        self.film = np.empty((self.pooled, frames))
        self.scan_net = _chain(nn.Sequential(net.scan, net.scan_out), self.pooled)
        self.track_net = _chain(net.track) if net.track is not None else None
        self.head = _chain(net.head)

    def __call__(self, x: np.ndarray) -> np.ndarray:
        n, pooled = self.n, self.pooled
        self.scan[:n] = x[:n]
        self.film[:, 0] = self.scan.reshape(pooled, self.pool).min(axis=1)
        a, b = self.history
        if b > a:
            self.film[:, 1:] = x[a:b].reshape(-1, pooled).T
        parts = [self.scan_net(self.film), x[n : n + 2]]
        if self.velocity:
            parts.append(x[self.velocity[0] : self.velocity[1]])
        if self.track_net is not None:
            slots = x[self.tracks[0] : self.tracks[1]].reshape(-1, TRACK_FIELDS)
            present = slots[:, TRACK_FIELDS - 1 :]
            h = self.track_net(slots)
            h *= present  # an empty slot adds nothing to either pool
            parts += [h.max(axis=0), h.sum(axis=0) / max(float(present.sum()), 1.0)]
        return self.head(np.concatenate(parts))


class NumpyStudent:
    """A `StudentActor`'s `act` for one feature vector (n_inputs,) -> normalised action (2,):
    the regressed action, or the likeliest class's. The planner runs each call on one BLAS
    thread (`PolicyFilePlanner._one_decision`)."""

    def __init__(self, actor: nn.Module) -> None:
        net = actor.net
        self.forward = _SetForward(net) if isinstance(net, SetEncoderNet) else _chain(net)
        self.classes = None if actor.classes is None else _array(actor.classes)

    def __call__(self, x: np.ndarray) -> np.ndarray:
        out = self.forward(np.asarray(x, dtype=np.float64))
        if self.classes is None:
            return out
        return self.classes[int(np.argmax(out))]
