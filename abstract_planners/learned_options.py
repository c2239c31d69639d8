"""A learned policy over options as a Sokoban planner.

`OptionPolicyPlanner` plays a policy trained with RL on `hier_agents.
learning.option_env.OptionEnv` (`python -m hier_agents.learning.train_options`): ``plan(state)``
proposes ONE legal move, the subgoal `OptionEnv` itself builds for an action::

    Subgoal(action=(move,), state=state.apply(move), plan=())

so the option layer runs the ball skill on it and asks again after it. The
policy sees the state as `OptionEnv` encodes it (`encode_sokoban`: walls,
pads, boxes, player planes) through `policy_input`, and its logits are
masked to the legal moves (it never proposes an illegal one).

Optionally (``prune_dead=True``, or ``meta["prune_dead_pushes"]`` in the
checkpoint) the mask also drops the pushes that would put a box on a dead
cell (`live_cells`: a cell from which no pad can be reached by pushing, e.g.
a corner): a hand-written rule on top of the learned policy, applied at play
time only (an earlier policy, approach B in `results/option_policy/`, needed
it to reach 85% on level 2). The shipped file does not set it: the shipped
planner is the learned policy alone.

By name: ``--planner learned:PATH`` (a checkpoint file or a training run's
directory) and ``--planner learned`` (the shipped
``abstract_planners/learned/options.pt``), see `hier_agents.modular.components`.

The network (`OptionPolicyNet`) is shared with the trainer:

* **input** (`policy_input`): the ``(4, H, W)`` planes re-centred on the
  player (an egocentric crop of ``2 * radius + 1`` cells a side; cells off
  the grid read as walls) plus a fifth plane, boxes on pads. Centring makes
  a move mean the same thing wherever the player stands, which is most of
  what there is to learn about walking;
* **actor**: four 3x3 convolutions (16, 32, 32 stride 2, 32 stride 2
  channels), a 128-unit layer and a 4-way policy head (moves ``U D L R``);
  the **critic** (training only, not in the policy file) is a copy of that
  body with a value head.

Checkpoint format (``torch.save`` dict, ``format == "option-policy/1"``):
``net`` (constructor arguments), ``state_dict``, ``grid_shape``, ``moves``
and ``meta`` (training counts). The trainer's resumable ``checkpoint.pt``
holds the same keys under ``policy``; both load here.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import torch
from torch import nn

from abstract_planners.base import Planner, Subgoal
from abstract_planners.sokoban import MOVES, SokobanState

__all__ = [
    "FORMAT",
    "OptionPolicyNet",
    "OptionPolicyPlanner",
    "SHIPPED",
    "dead_push_mask",
    "encode_state",
    "live_cells",
    "load_option_policy",
    "policy_input",
    "save_option_policy",
]

FORMAT = "option-policy/1"
#: The shipped policy (``--planner learned``).
SHIPPED = Path(__file__).resolve().parent / "learned" / "options.pt"


def encode_state(state: SokobanState, shape) -> np.ndarray:
    """``(4, H, W)`` planes walls, pads, boxes, player: the layout of
    `hier_agents.learning.option_env.encode_sokoban` (tested equal), without importing
    the environment side."""
    planes = np.zeros((4, *shape), np.float32)
    for k, cells in enumerate((state.walls, state.targets, state.boxes, (state.player,))):
        for r, c in cells:
            if 0 <= r < shape[0] and 0 <= c < shape[1]:
                planes[k, r, c] = 1.0
    return planes


def policy_input(planes: np.ndarray, radius: int) -> np.ndarray:
    """Egocentric network input of a batch of ``(N, 4, H, W)`` planes (walls,
    pads, boxes, player, as `hier_agents.learning.option_env.encode_sokoban` makes them):
    ``(N, 5, 2r+1, 2r+1)`` float32 centred on the player, off-grid cells walls,
    the fifth plane boxes on pads."""
    planes = np.asarray(planes, np.float32)
    if planes.ndim == 3:
        planes = planes[None]
    n, _, height, width = planes.shape
    size = 2 * radius + 1
    padded = np.zeros((n, 4, height + 2 * radius, width + 2 * radius), np.float32)
    padded[:, 0] = 1.0
    padded[:, :, radius : radius + height, radius : radius + width] = planes
    out = np.empty((n, 5, size, size), np.float32)
    for k in range(n):
        flat = int(np.argmax(planes[k, 3]))
        row, col = divmod(flat, width)
        out[k, :4] = padded[k, :, row : row + size, col : col + size]
    out[:, 4] = out[:, 1] * out[:, 2]
    return out


def _conv_body(radius: int, hidden: int) -> nn.Sequential:
    body = nn.Sequential(
        nn.Conv2d(5, 16, 3, padding=1),
        nn.ReLU(),
        nn.Conv2d(16, 32, 3, padding=1),
        nn.ReLU(),
        nn.Conv2d(32, 32, 3, stride=2, padding=1),
        nn.ReLU(),
        nn.Conv2d(32, 32, 3, stride=2, padding=1),
        nn.ReLU(),
        nn.Flatten(),
    )
    with torch.no_grad():
        flat = body(torch.zeros(1, 5, 2 * radius + 1, 2 * radius + 1)).shape[1]
    body = nn.Sequential(*body, nn.Linear(flat, hidden), nn.ReLU())
    for layer in body:  # ReLU-preserving scale (PyTorch's default init shrinks activations)
        if isinstance(layer, (nn.Conv2d, nn.Linear)):
            nn.init.orthogonal_(layer.weight, 2**0.5)
            assert layer.bias is not None  # built with a bias (the default)
            nn.init.zeros_(layer.bias)
    return body


class OptionPolicyNet(nn.Module):
    """Actor and critic CNNs over `policy_input` (module docstring); separate
    bodies, so that the value loss does not swamp the policy's gradient. The
    planner needs the actor only (the critic is not saved in policy files)."""

    def __init__(self, radius: int = 6, hidden: int = 128, actions: int = 4) -> None:
        super().__init__()
        self.radius, self.hidden, self.actions = int(radius), int(hidden), int(actions)
        self.actor = _conv_body(self.radius, self.hidden)
        self.policy = nn.Linear(hidden, actions)
        critic_body = _conv_body(self.radius, self.hidden)  # built first, as before
        value_head = nn.Linear(hidden, 1)
        self.critic = nn.Sequential(critic_body, value_head)
        nn.init.orthogonal_(self.policy.weight, 0.01)
        nn.init.zeros_(self.policy.bias)
        nn.init.orthogonal_(value_head.weight, 1.0)
        nn.init.zeros_(value_head.bias)

    def config(self) -> dict:
        return {"radius": self.radius, "hidden": self.hidden, "actions": self.actions}

    def logits(self, x: torch.Tensor, mask: torch.Tensor | None = None) -> torch.Tensor:
        """Policy logits of a ``policy_input`` batch; ``mask`` (N, 4) nonzero
        where a move is legal (masked logits are -1e8)."""
        logits = self.policy(self.actor(x))
        if mask is not None:
            logits = torch.where(mask.bool(), logits, torch.full_like(logits, -1e8))
        return logits

    def value(self, x: torch.Tensor) -> torch.Tensor:
        return self.critic(x).squeeze(-1)

    def forward(self, x: torch.Tensor, mask: torch.Tensor | None = None):
        """(masked logits, value)."""
        return self.logits(x, mask), self.value(x)


def save_option_policy(
    net: OptionPolicyNet, path, *, grid_shape, meta: dict, half: bool = False
) -> None:
    """Writes the planner's checkpoint (``half``: float16 weights, half the size)."""
    weights = {
        k: (v.detach().half() if half and v.is_floating_point() else v.detach()).clone()
        for k, v in net.state_dict().items()
        if not k.startswith("critic.")
    }
    torch.save(
        {
            "format": FORMAT,
            "net": net.config(),
            "state_dict": weights,
            "grid_shape": [int(v) for v in grid_shape],
            "moves": "".join(MOVES),
            "meta": dict(meta),
        },
        path,
    )


def load_option_policy(path, device: str = "cpu") -> tuple[OptionPolicyNet, dict]:
    """(network in eval mode, checkpoint dict) from a policy file, a trainer
    ``checkpoint.pt`` or a training run's directory.

    Raises:
      FileNotFoundError: nothing at ``path`` (or no policy in the directory).
      ValueError: the file is not an option-policy checkpoint or does not fit.
    """
    path = Path(path)
    if path.is_dir():
        for name in ("option_policy.pt", "checkpoint.pt"):
            if (path / name).is_file():
                path = path / name
                break
        else:
            raise FileNotFoundError(
                f"no option_policy.pt or checkpoint.pt in {path} (train one "
                f"with python -m hier_agents.learning.train_options)"
            )
    if not path.is_file():
        raise FileNotFoundError(
            f"no option-policy checkpoint at {path} (train one with "
            f"python -m hier_agents.learning.train_options, or use "
            f"--planner learned for the shipped one)"
        )
    try:
        data = torch.load(path, map_location=device, weights_only=True)
    except Exception as exc:  # noqa: BLE001 - any unreadable file gets the same message
        raise ValueError(f"{path} is not a readable torch checkpoint: {exc}") from None
    if isinstance(data, dict) and "policy" in data and isinstance(data["policy"], dict):
        data = data["policy"]  # the trainer's resumable checkpoint
    if not isinstance(data, dict) or data.get("format") != FORMAT:
        found = data.get("format") if isinstance(data, dict) else type(data).__name__
        raise ValueError(
            f"{path} is not an option-policy checkpoint (format {FORMAT!r} "
            f"expected, found {found!r}); it must come from "
            f"python -m hier_agents.learning.train_options"
        )
    if data.get("moves") != "".join(MOVES):
        raise ValueError(
            f"{path}: the policy's moves {data.get('moves')!r} are not {''.join(MOVES)!r}"
        )
    net = OptionPolicyNet(**data["net"])
    try:
        weights = {
            k: v.float() if v.is_floating_point() else v for k, v in data["state_dict"].items()
        }
        missing, unexpected = net.load_state_dict(weights, strict=False)
        missing = [k for k in missing if not k.startswith("critic.")]
        if missing or unexpected:
            raise RuntimeError(f"missing {missing}, unexpected {unexpected}")
    except (RuntimeError, AttributeError, TypeError) as exc:
        raise ValueError(
            f"{path}: the weights do not fit the network {data['net']}: {exc}"
        ) from None
    net.to(device).eval()
    return net, data


_STEPS = {"U": (-1, 0), "D": (1, 0), "L": (0, -1), "R": (0, 1)}


def live_cells(state: SokobanState) -> frozenset:
    """Cells from which a lone box can still be pushed onto some pad (walls
    only; a reverse search from the pads: a box at ``p`` reaches ``p + d``
    with the player at ``p - d``). A box pushed onto any other cell (a corner,
    along a wall without a pad) is deadlocked for good."""

    def floor(cell):
        r, c = cell
        return cell not in state.walls and 0 <= r < state.height and 0 <= c < state.width

    live = set(state.targets)
    frontier = list(state.targets)
    while frontier:
        nxt = []
        for r, c in frontier:
            for dr, dc in _STEPS.values():
                before, player = (r - dr, c - dc), (r - 2 * dr, c - 2 * dc)
                if before not in live and floor(before) and floor(player):
                    live.add(before)
                    nxt.append(before)
        frontier = nxt
    return frozenset(live)


def dead_push_mask(state: SokobanState, legal: np.ndarray, cache: dict | None = None) -> np.ndarray:
    """``legal`` without the pushes that would put a box on a dead cell (see
    `live_cells`); unchanged if that would leave no move."""
    key = (state.walls, state.targets)
    live = cache.get(key) if cache is not None else None
    if live is None:
        live = live_cells(state)
        if cache is not None:
            if len(cache) > 1024:
                cache.clear()
            cache[key] = live
    keep = legal.copy()
    r, c = state.player
    for k, move in enumerate(MOVES):
        dr, dc = _STEPS[move]
        if legal[k] and (r + dr, c + dc) in state.boxes and (r + 2 * dr, c + 2 * dc) not in live:
            keep[k] = 0
    return keep if keep.any() else legal


class OptionPolicyPlanner(Planner):
    """Plays a trained policy over options: one legal move per `plan`.

    Args:
      path: a checkpoint of `hier_agents.learning.train_options` (``option_policy.pt``,
        ``checkpoint.pt`` or the run's directory). Default: the shipped one.
      device: torch device.
      greedy: the most probable legal move (True) or a sample from the
        policy (False; ``seed`` seeds it, and ``reset(seed)`` reseeds it).
      prune_dead: also mask the pushes that put a box on a dead cell
        (`dead_push_mask`: a corner or a wall without a pad, a static
        deadlock). None: as the checkpoint's ``meta["prune_dead_pushes"]``
        says (False when absent).

    Raises (at construction): `FileNotFoundError` for a missing checkpoint,
    `ValueError` for a file that is not an option policy. ``plan`` raises
    `ValueError` for a state whose grid is not the policy's
    (``grid_shape`` in the checkpoint), a solved state or one with no legal move.
    """

    name = "learned"

    def __init__(
        self,
        path=None,
        device: str = "cpu",
        greedy: bool = True,
        seed: int | None = None,
        prune_dead: bool | None = None,
    ) -> None:
        self.path = Path(path) if path is not None else SHIPPED
        self.device = device
        self.greedy = bool(greedy)
        self.net, data = load_option_policy(self.path, device)
        self.grid_shape = tuple(int(v) for v in data["grid_shape"])
        self.meta = dict(data.get("meta", {}))
        self.prune_dead = bool(
            self.meta.get("prune_dead_pushes", False) if prune_dead is None else prune_dead
        )
        self._live_cache: dict = {}
        self._generator = torch.Generator(device="cpu")
        self.reset(seed if seed is not None else 0)

    @property
    def training_frames(self) -> int:
        """Control steps of physics simulated to train this policy (``meta["control_frames"]``).

        The option steps it took on the abstract Sokoban model
        (``meta["abstract_steps"]``, no physics) are not frames and are not
        counted here; comparisons report them beside (`abstract_steps`).
        """
        return int(self.meta.get("control_frames", 0))

    @property
    def abstract_steps(self) -> int:
        """Option steps trained on the abstract Sokoban model (no physics)."""
        return int(self.meta.get("abstract_steps", 0))

    def __repr__(self) -> str:
        return (
            f"OptionPolicyPlanner({str(self.path)!r}, greedy={self.greedy}, "
            f"prune_dead={self.prune_dead})"
        )

    def reset(self, seed: int | None = None) -> None:
        if seed is not None:
            self._generator.manual_seed(int(seed))

    def probabilities(self, state: SokobanState) -> np.ndarray:
        """The policy's probabilities of ``U D L R`` (zero for illegal moves)."""
        if not isinstance(state, SokobanState):
            state = SokobanState.from_level(state)
        shape = (state.height, state.width)
        if shape != self.grid_shape:
            raise ValueError(
                f"the state's grid is {shape[0]}x{shape[1]} but the policy "
                f"{self.path} was trained on {self.grid_shape[0]}x"
                f"{self.grid_shape[1]} grids"
            )
        mask = np.array([state.is_legal(m) for m in MOVES], np.float32)
        if not mask.any():
            raise ValueError(f"the player at {state.player} has no legal move")
        if self.prune_dead:
            mask = dead_push_mask(state, mask, self._live_cache)
        x = torch.as_tensor(
            policy_input(encode_state(state, shape), self.net.radius), device=self.device
        )
        with torch.no_grad():
            logits = self.net.logits(x, torch.as_tensor(mask[None], device=self.device))
            probs = torch.softmax(logits[0].float(), -1).cpu().numpy()
        probs = probs * mask
        return probs / probs.sum()

    def plan(self, state) -> Subgoal:
        """One legal move from ``state`` and the state it reaches."""
        if not isinstance(state, SokobanState):
            state = SokobanState.from_level(state)
        if state.is_solved():
            raise ValueError("the state is already solved: there is nothing to plan")
        probs = self.probabilities(state)
        if self.greedy:
            index = int(np.argmax(probs))
        else:
            index = int(torch.multinomial(torch.as_tensor(probs), 1, generator=self._generator)[0])
        move = MOVES[index]
        return Subgoal(
            action=(move,),
            state=state.apply(move),
            plan=(),
            info={"probability": float(probs[index])},
        )
