"""IMPALA checkpoints: reading them, the kept copies a comparison ships, and
the network and observations they hold.

`load_checkpoint` reads a run's ``checkpoint.pt`` (or any kept copy
``checkpoints/frames-N.pt``) and refuses files that are not this trainer's;
`net_from_checkpoint` rebuilds its network; `kept_copy` is the policy-only,
float16 copy `hier_agents.baselines.impala.learner` keeps at each budget;
`observed` is what the run's agent saw.
"""

from __future__ import annotations

from pathlib import Path

from physics_planning.cli import UsageError
from hier_agents.learning.rundir import CHECKPOINT, KEPT

KEPT_CHECKPOINTS = KEPT  # folder of `keep_checkpoints` copies, frames-N.pt
#: What a kept copy ``frames-N.pt`` leaves out: only resuming reads them, and a
#: run resumes from ``checkpoint.pt`` alone (a kept copy is for evaluation:
#: `load_checkpoint`, `net_from_checkpoint`; it is what a comparison ships).
KEPT_WITHOUT = ("optimizer", "rng")


def kept_copy(data: dict) -> dict:
    """A kept copy of checkpoint ``data`` (also of a kept copy: the same):
    a policy, for evaluation. It has no `KEPT_WITHOUT` and no value weights
    (`network.VALUE_PARTS`; ``"policy_only": True``), and its weights are
    stored as float16: an eighth of a full checkpoint's bytes for the
    comparison's MuJoBan row (1.5 MB against 12.3 MB).
    `net_from_checkpoint` loads them as float32, so every evaluation of a
    kept copy plays the same rounded weights. Training resumes from the run's
    full ``checkpoint.pt``, not from a kept copy."""
    import torch

    from hier_agents.baselines.impala.network import VALUE_PARTS

    lean = {k: v for k, v in data.items() if k not in KEPT_WITHOUT}
    lean["model"] = {
        name: t.to(torch.float16) if t.is_floating_point() else t
        for name, t in data["model"].items()
        if not name.startswith(VALUE_PARTS)
    }
    lean["policy_only"] = True
    return lean


#: The trainer recorded in its run directories (`RunDir`'s ``trainer``).
TRAINER = "python -m hier_agents.train"


def load_checkpoint(path: str | Path) -> dict:
    """The checkpoint of a `train` run: ``path`` is its file or its run directory.

    Raises:
      FileNotFoundError: no checkpoint there.
      UsageError: the file is not a checkpoint of this trainer (unreadable, or
        another trainer's: no ``model``, ``input_spec``, ``config`` or
        ``counters``).
    """
    import torch

    path = Path(path)
    if path.is_dir():
        path = path / CHECKPOINT
    if not path.exists():
        raise FileNotFoundError(f"no checkpoint at {path}")
    try:
        ckpt = torch.load(path, map_location="cpu", weights_only=False)
    except Exception as exc:  # noqa: BLE001 - whatever is wrong with the file, it is the input
        raise UsageError(f"{path} is not a readable checkpoint ({type(exc).__name__})") from None
    missing = [
        k
        for k in ("model", "input_spec", "config", "counters")
        if not isinstance(ckpt, dict) or k not in ckpt
    ]
    if missing:
        raise UsageError(
            f"{path} is not a checkpoint of {TRAINER} (it has no {', '.join(missing)})"
        )
    return ckpt


def _spec_from_dict(d: dict):
    from hier_agents.baselines.impala.agent_env import InputSpec

    d = dict(d)
    d["images"] = tuple((name, tuple(shape)) for name, shape in d["images"])
    for key in ("planner_shape", "state_shape"):
        if d.get(key) is not None:
            d[key] = tuple(d[key])
    return InputSpec(**d)


def net_from_checkpoint(ckpt: dict):
    """The trained `ImpalaNet` (eval mode, float32 weights, also from a kept
    copy's float16 ones) and its `InputSpec` from a checkpoint. A kept copy
    (``policy_only``) gives a network without value weights
    (``net.policy_only``: it acts, its values are not computed).

    Raises:
      RuntimeError: the weights do not fit the network the config describes.
    """
    from hier_agents.baselines.impala.network import VALUE_PARTS, net_for

    spec = _spec_from_dict(ckpt["input_spec"])
    net = net_for(spec, ckpt["config"])
    policy_only = bool(ckpt.get("policy_only", False))
    result = net.load_state_dict(ckpt["model"], strict=not policy_only)
    missing = [k for k in result.missing_keys if not k.startswith(VALUE_PARTS)]
    if result.unexpected_keys or missing:
        raise RuntimeError(
            f"the checkpoint's weights do not fit its network: missing {missing}, "
            f"unexpected {list(result.unexpected_keys)}"
        )
    net.policy_only = policy_only
    net.eval()
    return net, spec


def observed(config: dict, spec) -> tuple[list[str], bool]:
    """What a run's agent observed: (input keys, privileged), from its
    ``config.json`` when it recorded them, else inferred from its `InputSpec`
    (runs made before config.json recorded them)."""
    keys = config.get("observations")
    privileged = config.get("privileged")
    return (
        list(spec.keys) if keys is None else list(keys),
        bool(spec.privileged if privileged is None else privileged),
    )
