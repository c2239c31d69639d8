"""The paper's actor-critic network (appendix "Other experimental details").

`ImpalaNet(spec, two_values=...)` maps a time-major batch of observations to
a diagonal Gaussian policy and one or two value estimates:

* **images** (one encoder per camera, uint8 ``(3, H, W)`` scaled to [0, 1]):
  the simplified residual network of the paper's table "residual network
  architecture" -- three groups of [conv 3x3 (16, 32, 32 channels, padding 1)
  -> max-pool 3x3 stride 2 (padding 1, so 96 -> 48 -> 24 -> 12) -> two
  residual blocks (ReLU, conv 3x3, ReLU, conv 3x3, plus the block's input)],
  then a ReLU. No normalisation layers. The table stops at the 12x12 ReLU; to
  feed the recurrent cores we flatten that map and add a linear layer with 256
  units and a ReLU (the same width as the other encoders). The flat size is
  found at construction by a dummy pass, so any image size works.
* **proprioception** (float ``(P,)``): ``arcsinh`` (tames large magnitudes),
  then one linear layer with 256 units and a ReLU.
* **planner state** (float ``(C, H, W)`` planes, planner conditions only): one
  4x4 convolution with 100 channels and a ReLU, flattened, then a linear layer
  with 256 units and a ReLU. The paper does not give the padding. A 4x4
  "valid" convolution would not fit a 3x3 tic-tac-toe board, so we use
  "same" padding as TensorFlow defines it for an even kernel: 1 row/column of
  zeros before and 2 after, so the output keeps the board's H x W.
* **planner action** (float one-hot ``(K,)``, MuJoBan expert conditions):
  concatenated as is.
* **state** (float ``(C, H, W)`` planes, the current abstract state at every
  step, only when the environment observes it: ``AgentEnv(state=True)``,
  not in the paper): an encoder of the planner state's shape (its own
  weights) with ``state_channels`` convolution channels (the planner
  encoder's 100 unless told; fewer make a smaller linear layer).

All encodings are concatenated and fed to two separate LSTM cores: a value
core (256 units) and a policy core (128 units). The policy head turns the
policy core's output into ``mean = tanh(linear)`` and ``variance = 0.1 + 0.9
* sigmoid(linear)`` (so variance lies in [0.1, 1]); ``std = sqrt(variance)``.
The value head(s) read the value core: ``value_env`` always, ``value_abs``
(the auxiliary abstract-task value) when ``two_values``.

Speed (CPU): the encoders and the cores' input projections run once over
all ``T * B`` steps; only the recurrent part of the LSTMs loops over ``T``.
Images go through the convolutions in channels-last memory (faster oneDNN
kernels), and the planner encoder, the costliest part without cameras,
encodes only the distinct planner inputs of a batch (they repeat for many
steps); both are exact.

The encoders and the LSTM core are in
`hier_agents.baselines.impala.network_parts` (importable from here).
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING, NamedTuple

import numpy as np
import torch
from torch import nn
from torch.nn import functional as F

from hier_agents.baselines.impala.network_parts import (
    ENCODING_SIZE,  # noqa: F401
    PLANNER_CHANNELS,
    ImageEncoder,
    LSTMCore,
    PlannerEncoder,
    ResidualBlock,  # noqa: F401
    ResNetGroup,  # noqa: F401
)

if TYPE_CHECKING:  # the network needs only the spec's fields, not its module
    from hier_agents.baselines.impala.agent_env import InputSpec

VALUE_CORE_SIZE = 256
POLICY_CORE_SIZE = 128
MIN_VARIANCE = 0.1
#: Parameter-name prefixes of the value side (the value core and heads), which
#: acting does not use.
VALUE_PARTS = ("value_core.", "value_env_head.", "value_abs_head.")
_LOG_2PI = math.log(2.0 * math.pi)


class NetOutput(NamedTuple):
    """Network outputs, time-major.

    ``mean``, ``std``: ``[T, B, A]`` Gaussian policy parameters;
    ``value_env``: ``[T, B]`` value of the environment reward stream (None
    when run with ``with_value=False``);
    ``value_abs``: ``[T, B]`` value of the auxiliary (abstract-task) reward
    stream, or None for a single-value (vanilla) network.
    """

    mean: torch.Tensor
    std: torch.Tensor
    value_env: torch.Tensor | None
    value_abs: torch.Tensor | None


# -- the network ------------------------------------------------------------------------------


def _writable(x):
    """A read-only numpy array (e.g. from Ray's object store) copied, so torch does not warn."""
    if isinstance(x, np.ndarray) and not x.flags.writeable:
        return x.copy()
    return x


def _module_key(name: str) -> str:
    """A camera name usable as a ModuleDict key (no dots)."""
    return name.replace(".", "_")


class ImpalaNet(nn.Module):
    """The paper's actor-critic: encoders -> value LSTM (256) and policy LSTM (128) -> heads.

    ``spec`` (`InputSpec`) says which inputs exist and their shapes;
    ``two_values`` adds the auxiliary-task value head ``value_abs`` (planner
    conditions). See the module docstring for the layers.

    Core state: a tuple ``(h_value, c_value, h_policy, c_policy)`` of
    ``[B, 256]``, ``[B, 256]``, ``[B, 128]``, ``[B, 128]`` float tensors.

    ``policy_only`` is True for a network loaded without its value weights
    (`VALUE_PARTS`; a kept checkpoint, `checkpoints.kept_copy`): it acts
    (`act`, `forward` with ``with_value=False``), and `forward` with the
    values raises RuntimeError.
    """

    def __init__(
        self, spec: "InputSpec", *, two_values: bool, state_channels: int = PLANNER_CHANNELS
    ):
        super().__init__()
        self.spec = spec
        self.two_values = bool(two_values)
        self.action_dim = int(spec.action_dim)
        if self.action_dim < 1:
            raise ValueError(f"action_dim must be >= 1, got {spec.action_dim!r}")

        size = 0
        self.cameras = [(name, _module_key(name)) for name, _ in spec.images]
        self.image_encoders = nn.ModuleDict(
            {_module_key(name): ImageEncoder(tuple(shape)) for name, shape in spec.images}
        )
        size += ENCODING_SIZE * len(self.cameras)
        self.proprio_encoder = None
        if spec.proprio_dim > 0:
            self.proprio_encoder = nn.Linear(int(spec.proprio_dim), ENCODING_SIZE)
            size += ENCODING_SIZE
        self.planner_encoder = None
        if spec.planner_shape is not None:
            self.planner_encoder = PlannerEncoder(tuple(spec.planner_shape))
            size += ENCODING_SIZE
        size += int(spec.planner_action_dim)
        self.state_encoder = None
        state_shape = getattr(spec, "state_shape", None)
        if state_shape is not None:
            self.state_encoder = PlannerEncoder(tuple(state_shape), channels=state_channels)
            size += ENCODING_SIZE
        if size == 0:
            raise ValueError(f"{spec} gives the network no input")
        self.encoding_size = size

        self.value_core = LSTMCore(size, VALUE_CORE_SIZE)
        self.policy_core = LSTMCore(size, POLICY_CORE_SIZE)
        self.mean_head = nn.Linear(POLICY_CORE_SIZE, self.action_dim)
        self.variance_head = nn.Linear(POLICY_CORE_SIZE, self.action_dim)
        self.value_env_head = nn.Linear(VALUE_CORE_SIZE, 1)
        self.value_abs_head = nn.Linear(VALUE_CORE_SIZE, 1) if self.two_values else None
        self.policy_only = False

    # -- state ------------------------------------------------------------------------------

    def initial_state(self, batch_size: int) -> tuple[torch.Tensor, ...]:
        """Zero core state for ``batch_size`` columns (see the class docstring)."""
        device = self.mean_head.weight.device
        z = lambda n: torch.zeros(batch_size, n, device=device)  # noqa: E731
        return (z(VALUE_CORE_SIZE), z(VALUE_CORE_SIZE), z(POLICY_CORE_SIZE), z(POLICY_CORE_SIZE))

    # -- forward ----------------------------------------------------------------------------

    def encode(self, obs: dict[str, torch.Tensor], n: int) -> torch.Tensor:
        """Concatenated encodings ``[n, encoding_size]`` of observations flattened to ``n`` rows."""
        parts = []
        for name, key in self.cameras:
            img = obs[name]
            parts.append(self.image_encoders[key](img.reshape(n, *img.shape[-3:])))
        if self.proprio_encoder is not None:
            x = obs["proprio"].reshape(n, -1).to(torch.float32)
            parts.append(F.relu(self.proprio_encoder(torch.asinh(x))))
        if self.planner_encoder is not None:
            planes = obs["planner"]
            parts.append(self.planner_encoder(planes.reshape(n, *planes.shape[-3:])))
        if self.spec.planner_action_dim > 0:
            parts.append(obs["planner_action"].reshape(n, -1).to(torch.float32))
        if self.state_encoder is not None:
            planes = obs["state"]
            parts.append(self.state_encoder(planes.reshape(n, *planes.shape[-3:])))
        return parts[0] if len(parts) == 1 else torch.cat(parts, dim=1)

    def forward(
        self,
        obs: dict[str, torch.Tensor],
        first: torch.Tensor,
        state: tuple[torch.Tensor, ...] | None = None,
        *,
        with_value: bool = True,
        value_state_after: int | None = None,
        value_chain=None,
    ):
        """Runs ``T`` steps for ``B`` columns.

        ``obs``: dict of ``[T, B, ...]`` tensors (keys as in `InputSpec`);
        ``first``: bool ``[T, B]``, True where the observation begins an
        episode (that column's core state is zeroed before the step);
        ``state``: core state before ``obs[0]`` (None: zeros).
        Returns ``(NetOutput, new_state)`` with ``new_state`` after ``obs[T-1]``.

        ``with_value=False`` skips the value core (actors only need the
        policy): the values are None and the value-core state is returned
        unchanged. ``value_state_after=k`` returns the value-core state after
        step ``k`` instead (the learner carries it to the stream's next unroll).
        ``value_chain[j] = i`` (with ``value_state_after``) starts column
        ``j``'s value core from column ``i``'s state after step ``k`` instead
        of ``state`` (``-1``: from ``state``): consecutive unrolls of one
        stream in one batch. The value core then runs column group by column
        group, in chain order.
        """
        if with_value and self.policy_only:
            raise RuntimeError(
                "this network was loaded from a policy-only checkpoint (a kept copy): "
                "it has no value weights; call it with with_value=False"
            )
        T, B = first.shape
        if state is None:
            state = self.initial_state(B)
        first = first.to(torch.bool)
        x = self.encode(obs, T * B).view(T, B, -1)
        p_out, (hp, cp) = self.policy_core(x, first, (state[2], state[3]))
        mean = torch.tanh(self.mean_head(p_out))
        variance = MIN_VARIANCE + (1.0 - MIN_VARIANCE) * torch.sigmoid(self.variance_head(p_out))
        std = torch.sqrt(variance)
        if not with_value:
            return NetOutput(mean, std, None, None), (state[0], state[1], hp, cp)
        if value_chain is None or all(int(i) < 0 for i in value_chain):
            v_out, (hv, cv) = self.value_core(
                x, first, (state[0], state[1]), keep_state_after=value_state_after
            )
        else:
            v_out, (hv, cv) = self._chained_value_core(
                x, first, state, value_state_after, [int(i) for i in value_chain]
            )
        value_env = self.value_env_head(v_out).squeeze(-1)
        abs_head = self.value_abs_head  # None unless two_values
        value_abs = abs_head(v_out).squeeze(-1) if abs_head is not None else None
        return NetOutput(mean, std, value_env, value_abs), (hv, cv, hp, cp)

    def _chained_value_core(
        self, x, first, state, after, chain
    ) -> tuple[torch.Tensor, tuple[torch.Tensor, torch.Tensor]]:
        if after is None:
            raise ValueError("value_chain needs value_state_after")
        B = x.shape[1]
        depth = [0] * B
        for j in range(B):
            i, d = chain[j], 0
            while i >= 0:
                if d > B:
                    raise ValueError(f"value_chain {chain} has a cycle")
                d, i = d + 1, chain[i]
            depth[j] = d
        outs: list = [None] * B
        hs: list = [None] * B
        cs: list = [None] * B
        for d in range(max(depth) + 1):
            cols = [j for j in range(B) if depth[j] == d]
            # Chained states are detached: each unroll is its own truncated-BPTT window.
            h0 = torch.stack([state[0][j] if chain[j] < 0 else hs[chain[j]].detach() for j in cols])
            c0 = torch.stack([state[1][j] if chain[j] < 0 else cs[chain[j]].detach() for j in cols])
            out, (h, c) = self.value_core(
                x[:, cols], first[:, cols], (h0, c0), keep_state_after=after
            )
            for n, j in enumerate(cols):
                outs[j], hs[j], cs[j] = out[:, n], h[n], c[n]
        return torch.stack(outs, dim=1), (torch.stack(hs), torch.stack(cs))

    @torch.no_grad()
    def act(
        self,
        obs: dict,
        first,
        state: tuple[torch.Tensor, ...],
        *,
        deterministic: bool = False,
        generator: torch.Generator | None = None,
        policy_only: bool = False,
    ):
        """One step for ``B`` environments, for actors and evaluation (no gradients).

        ``obs``: dict of numpy arrays or tensors with leading batch ``B``;
        ``first``: bool ``[B]``; ``state``: core state. Samples ``a ~ N(mean,
        std)`` with ``generator`` (or returns ``mean`` when ``deterministic``).
        Returns ``(actions float32 [B, A], log_probs float32 [B], new_state)``;
        actions are unclipped (the environment clips) and ``log_probs`` are
        those of the returned actions under the policy. ``policy_only`` (always,
        for a `policy_only` network) skips the value core (its state is passed
        through unchanged).
        """
        device = self.mean_head.weight.device
        batch = {
            k: torch.as_tensor(_writable(v), device=device).unsqueeze(0) for k, v in obs.items()
        }
        first_t = torch.as_tensor(np.asarray(first), dtype=torch.bool, device=device).view(1, -1)
        with_value = not (policy_only or self.policy_only)
        out, new_state = self.forward(batch, first_t, state, with_value=with_value)
        mean, std = out.mean[0], out.std[0]
        if deterministic:
            actions = mean
        else:
            noise = torch.randn(
                mean.shape, generator=generator, dtype=mean.dtype, device=mean.device
            )
            actions = mean + std * noise
        log_probs = gaussian_log_prob(mean, std, actions)
        return (
            actions.cpu().numpy().astype(np.float32, copy=False),
            log_probs.cpu().numpy().astype(np.float32, copy=False),
            new_state,
        )


def net_for(spec: "InputSpec", config) -> ImpalaNet:
    """The `ImpalaNet` a run's configuration asks for.

    ``config``: a `TrainConfig` or its saved form (a checkpoint's
    ``config`` dict). ``condition`` other than ``"vanilla"`` adds the
    auxiliary value head; ``state_channels`` (absent in runs saved before it
    existed: the paper's 100) sizes the state encoder.
    """
    fields = config if isinstance(config, dict) else vars(config)
    return ImpalaNet(
        spec,
        two_values=fields["condition"] != "vanilla",
        state_channels=int(fields.get("state_channels", PLANNER_CHANNELS)),
    )


# -- Gaussian helpers -------------------------------------------------------------------------


def gaussian_log_prob(mean: torch.Tensor, std: torch.Tensor, actions: torch.Tensor) -> torch.Tensor:
    """Log density of ``actions`` under the diagonal Gaussian, summed over the last (action) dim.

    ``[..., A]`` inputs -> ``[...]`` (e.g. ``[T, B]``).
    """
    z = (actions - mean) / std
    return (-0.5 * z.square() - torch.log(std) - 0.5 * _LOG_2PI).sum(-1)


def gaussian_entropy(std: torch.Tensor) -> torch.Tensor:
    """Entropy of the diagonal Gaussian, summed over the last dim: ``[..., A] -> [...]``."""
    return (0.5 + 0.5 * _LOG_2PI + torch.log(std)).sum(-1)
