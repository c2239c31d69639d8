"""The building blocks of `hier_agents.baselines.impala.network.ImpalaNet`
(see that module's docstring for the architecture): the residual image
encoder (`ResidualBlock`, `ResNetGroup`, `ImageEncoder`), the planner-input
encoder (`PlannerEncoder`) and the LSTM core with episode resets
(`LSTMCore`). Tensors are time-major or flattened ``T * B`` as each class
says; all are importable from `hier_agents.baselines.impala.network`.
"""

from __future__ import annotations

import math
from typing import Sequence

import numpy as np
import torch
from torch import nn
from torch.nn import functional as F

__all__ = [
    "ENCODING_SIZE",
    "PLANNER_CHANNELS",
    "ResidualBlock",
    "ResNetGroup",
    "ImageEncoder",
    "PlannerEncoder",
    "LSTMCore",
]

#: Size of each input's encoding (before the cores).
ENCODING_SIZE = 256
#: Output channels of the planner encoder's convolution.
PLANNER_CHANNELS = 100


# -- encoders ---------------------------------------------------------------------------------


class ResidualBlock(nn.Module):
    """``x + conv(relu(conv(relu(x))))`` with 3x3 convolutions keeping the shape."""

    def __init__(self, channels: int):
        super().__init__()
        self.conv0 = nn.Conv2d(channels, channels, 3, padding=1)
        self.conv1 = nn.Conv2d(channels, channels, 3, padding=1)

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        # The second ReLU may work in place: a convolution's backward needs its input, not
        # its output. The first may not (x is also the residual).
        return x + self.conv1(F.relu(self.conv0(F.relu(x)), inplace=True))


class ResNetGroup(nn.Module):
    """conv 3x3 (padding 1) -> max-pool 3x3 stride 2 (padding 1) -> 2 residual blocks.

    Halves the spatial size (rounding up): 96 -> 48.
    """

    def __init__(self, in_channels: int, out_channels: int, num_blocks: int = 2):
        super().__init__()
        self.conv = nn.Conv2d(in_channels, out_channels, 3, padding=1)
        self.pool = nn.MaxPool2d(3, stride=2, padding=1)
        self.blocks = nn.Sequential(*(ResidualBlock(out_channels) for _ in range(num_blocks)))

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        return self.blocks(self.pool(self.conv(x)))


class ImageEncoder(nn.Module):
    """One camera: the paper's residual network, then flatten + linear 256 + ReLU.

    Input ``[N, 3, H, W]`` uint8 (or float already in [0, 1]); output
    ``[N, 256]``. ``feature_shape`` is the residual network's output shape
    (``(32, 12, 12)`` for 96x96 images).

    Memory: with gradients on and more than `CHUNK` images (a learner batch:
    the paper's 128 unrolls of 101 steps), the images go through in chunks
    of `CHUNK` whose activations are recomputed in the backward pass
    (``torch.utils.checkpoint``) instead of kept: the same values and
    gradients, one chunk's activations in memory instead of the whole
    batch's (tens of GB at 96x96).
    """

    #: Images per recomputed chunk of a training batch.
    CHUNK = 512

    def __init__(
        self, image_shape: Sequence[int], channels=(16, 32, 32), out_size: int = ENCODING_SIZE
    ):
        super().__init__()
        groups, c_in = [], int(image_shape[0])
        for c_out in channels:
            groups.append(ResNetGroup(c_in, c_out))
            c_in = c_out
        self.resnet = nn.Sequential(*groups)
        with torch.no_grad():  # flat size for this image size
            probe = self.resnet(torch.zeros(1, *(int(s) for s in image_shape)))
        self.feature_shape = tuple(probe.shape[1:])
        self.linear = nn.Linear(int(np.prod(self.feature_shape)), out_size)

    def forward(self, images: torch.Tensor) -> torch.Tensor:
        n = images.shape[0]
        if torch.is_grad_enabled() and n > self.CHUNK:
            from torch.utils.checkpoint import checkpoint

            return torch.cat(
                [
                    checkpoint(self._encode, images[i : i + self.CHUNK], use_reentrant=False)
                    for i in range(0, n, self.CHUNK)
                ]
            )
        return self._encode(images)

    def _encode(self, images: torch.Tensor) -> torch.Tensor:
        x = images.to(torch.float32)
        if images.dtype == torch.uint8:
            x = x * (1.0 / 255.0)
        # Channels-last (NHWC) memory makes oneDNN's CPU convolutions about 1.5x faster
        # here; the flatten below still reads the map in (C, H, W) order.
        x = x.contiguous(memory_format=torch.channels_last)
        x = F.relu(self.resnet(x))  # the table's final 12x12 ReLU
        return F.relu(self.linear(x.flatten(1)))


class PlannerEncoder(nn.Module):
    """Abstract planes ``[N, C, H, W]`` -> conv 4x4 (``channels``, the paper's
    100, "same") + ReLU -> linear 256 + ReLU.

    "Same" padding for the even kernel: one zero row/column before and two
    after (TensorFlow's convention), so a 3x3 board stays 3x3.

    Speed: the flattened conv output is large (channels * H * W: 10,000 for
    100 channels on a 10x10 MuJoBan grid), so the linear layer dominates the whole network's
    cost without cameras. The planner planes stay the same for many steps
    (the abstract state and target change rarely), so for ``N >= 64`` rows
    the encoder runs on the distinct rows only and copies their encodings
    back (``deduplicate``; exact: same outputs, gradients summed over the
    copies).
    """

    min_rows_to_deduplicate = 64
    #: Encodings kept for inference (see `forward`).
    cache_size = 4096

    def __init__(
        self,
        shape: Sequence[int],
        out_size: int = ENCODING_SIZE,
        channels: int = PLANNER_CHANNELS,
    ):
        super().__init__()
        c, h, w = (int(s) for s in shape)
        if int(channels) < 1:
            raise ValueError(f"channels must be >= 1, got {channels!r}")
        self.pad = nn.ZeroPad2d((1, 2, 1, 2))  # (left, right, top, bottom)
        self.conv = nn.Conv2d(c, int(channels), 4)
        self.linear = nn.Linear(int(channels) * h * w, out_size)
        self.deduplicate = True
        self._cache: dict[bytes, torch.Tensor] = {}
        self._cache_key: tuple = ()

    def _weights_version(self) -> tuple:
        # In-place changes (optimizer steps, load_state_dict) bump a tensor's _version.
        return tuple((id(p), p._version) for p in self.parameters())

    def _encode_cached(self, planes: torch.Tensor) -> torch.Tensor:
        """Inference only: each distinct row is encoded once per weights version.

        Actors see the same planner planes for a whole sub-episode (up to
        T_abs steps), so almost every step is a cache hit and the channels * H * W
        -> 256 linear layer drops out of the actors' per-step cost.
        """
        version = self._weights_version()
        if version != self._cache_key or len(self._cache) > self.cache_size:
            self._cache, self._cache_key = {}, version
        flat = planes.reshape(planes.shape[0], -1).contiguous()
        keys = [row.numpy().tobytes() for row in flat]
        missing = [i for i, k in enumerate(dict.fromkeys(keys)) if k not in self._cache]
        if missing:
            unique = list(dict.fromkeys(keys))
            rows = torch.stack([flat[keys.index(unique[i])] for i in missing])
            encoded = self._encode(rows.view(-1, *planes.shape[1:]))
            for j, i in enumerate(missing):
                self._cache[unique[i]] = encoded[j]
        return torch.stack([self._cache[k] for k in keys])

    def _encode(self, planes: torch.Tensor) -> torch.Tensor:
        x = F.relu(self.conv(self.pad(planes)), inplace=True)
        return F.relu(self.linear(x.flatten(1)))

    def forward(self, planes: torch.Tensor) -> torch.Tensor:
        planes = planes.to(torch.float32)
        n = planes.shape[0]
        if not torch.is_grad_enabled() and planes.device.type == "cpu":
            return self._encode_cached(planes)
        if self.deduplicate and n >= self.min_rows_to_deduplicate:
            rows, inverse = torch.unique(planes.reshape(n, -1), dim=0, return_inverse=True)
            if rows.shape[0] < n:
                return self._encode(rows.view(-1, *planes.shape[1:]))[inverse]
        return self._encode(planes)


# -- recurrent cores --------------------------------------------------------------------------


class LSTMCore(nn.Module):
    """A single-layer LSTM that zeroes its state where an episode begins.

    ``forward(x [T, B, in], first [T, B] bool, (h, c) [B, H] each) -> (out
    [T, B, H], (h, c))``. Where ``first[t, b]`` is True, column ``b``'s state
    is zeroed before step ``t``. The input projection ``W_ih x + b`` runs as one
    matrix product over all ``T * B`` steps; only ``W_hh h`` loops over time.
    Gate layout is (input, forget, output, cell) so one sigmoid covers three
    gates. Initialisation: uniform(+-1/sqrt(H)) as for torch's LSTM.
    """

    def __init__(self, input_size: int, hidden_size: int):
        super().__init__()
        self.hidden_size = hidden_size
        self.input_proj = nn.Linear(input_size, 4 * hidden_size)
        self.weight_hh = nn.Parameter(torch.empty(4 * hidden_size, hidden_size))
        bound = 1.0 / math.sqrt(hidden_size)
        for p in (self.input_proj.weight, self.input_proj.bias, self.weight_hh):
            nn.init.uniform_(p, -bound, bound)

    def forward(
        self,
        x: torch.Tensor,
        first: torch.Tensor,
        state: tuple[torch.Tensor, torch.Tensor],
        *,
        keep_state_after: int | None = None,
    ):
        """See the class docstring. With ``keep_state_after=k`` the returned
        state is the one after step ``k`` (not after the last step)."""
        T, B = x.shape[:2]
        H = self.hidden_size
        gates_x = self.input_proj(x.reshape(T * B, -1)).view(T, B, 4 * H)
        # unbind, not gates_x[t]: indexing would make autograd build a full-size zero
        # gradient per step (T x slower backward); unbind stacks the step gradients once.
        steps = gates_x.unbind(0)
        keep = (~first).to(x.dtype).unsqueeze(-1).unbind(0)  # T x [B, 1]
        w_hh = self.weight_hh.t()
        h, c = state
        outs = []
        kept = None
        for t in range(T):
            h = h * keep[t]
            c = c * keep[t]
            gates = torch.addmm(steps[t], h, w_hh)
            sig = torch.sigmoid(gates[:, : 3 * H])
            i, f, o = sig[:, :H], sig[:, H : 2 * H], sig[:, 2 * H :]
            c = f * c + i * torch.tanh(gates[:, 3 * H :])
            h = o * torch.tanh(c)
            outs.append(h)
            if t == keep_state_after:
                kept = (h, c)
        return torch.stack(outs), (kept if kept is not None else (h, c))
