"""Learned skills' policies: checkpoints and their numpy evaluation.

A skill checkpoint (written by ``python -m hier_agents.learning.train_skill``)
is a ``torch.save`` dict:

* ``"actor"``: the state dict of the mean network, a stack of
  ``nn.Linear`` layers (keys ``"<i>.weight"``, ``"<i>.bias"``) with tanh
  between them and a linear output;
* ``"features"``: the names of the observation's entries, in order (checked
  against the skill's on load: a checkpoint trained on other features is
  refused);
* ``"meta"``: how it was trained (``frames``: agent control steps learned
  from; ``sim_steps``: every control step simulated for it; the command).

At run time the network is evaluated in numpy (float64; ~10 us for 64x64).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

__all__ = ["NumpyPolicy", "load_policy"]


class NumpyPolicy:
    """The actor's mean network in numpy: ``policy(features) -> action``.

    ``state_dict``: an ``nn.Sequential`` of Linear layers' state dict (torch
    tensors or arrays); ``meta``: the checkpoint's training record.
    """

    def __init__(self, state_dict, meta: dict | None = None) -> None:
        self.meta = dict(meta or {})

        def arr(v):
            return np.asarray(v.detach().cpu().numpy() if hasattr(v, "detach") else v, np.float64)

        keys = sorted(
            {k.rsplit(".", 1)[0] for k in state_dict if k.endswith(".weight")},
            key=lambda k: int(k.split(".")[-1]),
        )
        if not keys:
            raise ValueError("the state dict has no Linear layers")
        self.layers = [(arr(state_dict[k + ".weight"]), arr(state_dict[k + ".bias"])) for k in keys]

    @property
    def obs_dim(self) -> int:
        return int(self.layers[0][0].shape[1])

    @property
    def action_dim(self) -> int:
        return int(self.layers[-1][0].shape[0])

    def __call__(self, obs) -> np.ndarray:
        h = np.asarray(obs, np.float64)
        for j, (w, b) in enumerate(self.layers):
            h = w @ h + b
            if j < len(self.layers) - 1:
                h = np.tanh(h)
        return h


def load_policy(path, features: tuple[str, ...]) -> NumpyPolicy:
    """The policy of the checkpoint at ``path``: a file, or the run directory
    of ``python -m hier_agents.learning.train_skill`` (its one
    ``<skill>_policy.pt``). Raises ``ValueError`` when its ``features`` are
    not ``features`` or a directory holds several policies, and
    ``FileNotFoundError`` when there is none."""
    import torch

    path = Path(path)
    if path.is_dir():
        found = sorted(path.glob("*_policy.pt"))
        if len(found) > 1:
            raise ValueError(
                f"{path} holds several skill checkpoints {[f.name for f in found]}; name one"
            )
        if found:
            path = found[0]
    if not path.is_file():
        raise FileNotFoundError(
            f"no skill checkpoint at {path}"
            + (" (no *_policy.pt in the folder)" if path.is_dir() else "")
        )
    ckpt = torch.load(path, map_location="cpu", weights_only=True)
    if tuple(ckpt.get("features", ())) != tuple(features):
        raise ValueError(
            f"{path}: checkpoint features {ckpt.get('features')} do not match "
            f"the skill's {tuple(features)}"
        )
    return NumpyPolicy(ckpt["actor"], ckpt.get("meta"))
