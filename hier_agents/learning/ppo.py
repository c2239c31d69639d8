"""Proximal policy optimisation over gymnasium vector environments.

The pieces, each usable alone:

* `make_vector_env`: a Sync/Async vector env in the autoreset mode the
  collector needs (``SAME_STEP``; gymnasium's default is ``NEXT_STEP``).
* `masked_categorical`, `diag_gaussian`: the two action distributions
  (discrete with an action mask; continuous with a state-independent log-std).
* `RolloutCollector`: ``steps`` steps of every environment with the policy,
  handling autoreset (final observations and infos), action masks
  (``info["action_mask"]``), durations (``info["duration"]``, default 1) and
  truncation (the critic's value of the final observation is kept as a
  bootstrap).
* `gae`: generalised advantage estimation where a step of duration ``d`` is
  discounted by ``gamma ** d`` (semi-MDP options; ``d = 1`` for plain steps).
* `ppo_update`: clipped-surrogate epochs over minibatches (value loss,
  entropy bonus, gradient-norm clip, per-minibatch advantage normalisation).
* `iteration`: learning-rate anneal, collect, GAE, update: one PPO iteration.
* Budgets: `iterations` (the whole iterations a budget buys, refusing one
  that buys none) and `critic_warmup` (critic-only iterations that leave at
  least one actor update); `add_arguments` / `config_from_args`: the PPO
  flags every trainer shares.

The policy is any object with ``policy_dist(obs, mask) -> Distribution``
(``log_prob``/``entropy`` of shape ``[B]``: use the two helpers) and
``value(obs) -> Tensor [B]``; its parameters are the optimiser's. Nothing
here knows about a particular environment.
"""

from __future__ import annotations

import argparse
import dataclasses
from typing import Callable, Protocol, overload

import gymnasium as gym
import numpy as np
import torch
from torch import nn

from physics_planning.cli import (
    UsageError,
    fraction,
    non_negative_float,
    positive_float,
    positive_int,
)

SAME_STEP = gym.vector.AutoresetMode.SAME_STEP

#: The logit given to actions whose mask entry is 0 (probability 0, no gradient).
MASKED_LOGIT = -1e8


class ActorCritic(Protocol):
    """What PPO needs of a network (an ``nn.Module`` in practice)."""

    def policy_dist(
        self, obs: torch.Tensor, mask: torch.Tensor | None
    ) -> torch.distributions.Distribution: ...

    def value(self, obs: torch.Tensor) -> torch.Tensor: ...


def make_vector_env(thunks, asynchronous: bool = False, context: str | None = None):
    """A vector env of ``thunks`` (callables making one env each) with same-step
    autoreset; ``asynchronous``: one worker process per env (``context``: the
    multiprocessing start method, e.g. ``"forkserver"``)."""
    if asynchronous:
        return gym.vector.AsyncVectorEnv(thunks, autoreset_mode=SAME_STEP, context=context)
    return gym.vector.SyncVectorEnv(thunks, autoreset_mode=SAME_STEP)


def masked_categorical(
    logits: torch.Tensor, mask: torch.Tensor | None = None
) -> torch.distributions.Categorical:
    """Categorical over ``logits [B, A]``; where ``mask [B, A]`` is 0 the logit
    becomes `MASKED_LOGIT` (never sampled, no gradient). A row with no legal
    action is the caller's error (the result is then uniform)."""
    if mask is not None:
        logits = torch.where(mask.bool(), logits, torch.full_like(logits, MASKED_LOGIT))
    return torch.distributions.Categorical(logits=logits)


def diag_gaussian(mean: torch.Tensor, log_std: torch.Tensor) -> torch.distributions.Distribution:
    """Diagonal Gaussian over ``mean [B, A]`` with ``log_std [A]`` (state-independent,
    usually an ``nn.Parameter``); ``log_prob`` and ``entropy`` sum over the A dims."""
    normal = torch.distributions.Normal(mean, log_std.exp().expand_as(mean))
    return torch.distributions.Independent(normal, 1)


@dataclasses.dataclass
class PPOConfig:
    """Hyperparameters. ``gamma`` is per unit of duration (per control step for
    options); ``lr_floor`` is the annealed LR's lowest fraction of ``lr``."""

    gamma: float = 0.99
    lam: float = 0.95
    clip: float = 0.2
    epochs: int = 4
    minibatches: int = 4
    lr: float = 3e-4
    anneal_lr: bool = False
    lr_floor: float = 0.0
    vf_coef: float = 0.5
    ent_coef: float = 0.0
    max_grad_norm: float = 0.5
    norm_adv: bool = True


def add_arguments(parser, **defaults) -> None:
    """Adds the PPO flags (``--rollout --epochs --minibatches --lr --[no-]anneal-lr
    --gamma --lam --clip --ent-coef --vf-coef --max-grad-norm``) to an argparse
    ``parser``; ``defaults`` override `PPOConfig`'s (and ``rollout``, default 128)."""
    base = {**dataclasses.asdict(PPOConfig()), "rollout": 128, **defaults}
    add = parser.add_argument
    add(
        "--rollout",
        type=positive_int,
        default=base["rollout"],
        help="steps per environment per update",
    )
    add("--epochs", type=positive_int, default=base["epochs"], help="PPO epochs per update")
    add(
        "--minibatches",
        type=positive_int,
        default=base["minibatches"],
        help="minibatches per epoch",
    )
    add("--lr", type=positive_float, default=base["lr"], help="Adam learning rate")
    add(
        "--anneal-lr",
        action=argparse.BooleanOptionalAction,
        default=base["anneal_lr"],
        help="anneal the learning rate linearly over the budget",
    )
    add("--gamma", type=fraction, default=base["gamma"], help="discount per control step")
    add("--lam", type=fraction, default=base["lam"], help="GAE lambda")
    add("--clip", type=positive_float, default=base["clip"], help="PPO ratio clip")
    add("--ent-coef", type=non_negative_float, default=base["ent_coef"], help="entropy bonus")
    add("--vf-coef", type=non_negative_float, default=base["vf_coef"], help="value-loss weight")
    add(
        "--max-grad-norm",
        type=positive_float,
        default=base["max_grad_norm"],
        help="gradient-norm clip",
    )


def iterations(budget: int, per_iteration: int, what: str, fix: str) -> int:
    """The whole PPO iterations a budget buys: ``budget // per_iteration``
    (steps; the trainer's unit).

    Raises:
      UsageError: ``0 < budget < per_iteration``, a budget that
        cannot pay for one update: ``"{what} is less than one PPO update
        ({per_iteration} steps); {fix}"`` (``what`` names the budget, ``fix``
        the smallest one that works).
    """
    if 0 < budget < per_iteration:
        raise UsageError(f"{what} is less than one PPO update ({per_iteration} steps); {fix}")
    return max(budget, 0) // per_iteration


def critic_warmup(iterations: int, warmup: int) -> int:
    """Critic-only iterations at the start of a budget of ``iterations``:
    ``warmup``, but at most ``iterations - 1``, so that at least one iteration
    of the budget updates the actor (0 for an empty budget)."""
    return max(0, min(int(warmup), int(iterations) - 1))


def config_from_args(args, **fixed) -> PPOConfig:
    """The `PPOConfig` of flags added by `add_arguments` (``fixed``: fields
    without a flag, e.g. ``lr_floor``)."""
    return PPOConfig(
        gamma=args.gamma,
        lam=args.lam,
        clip=args.clip,
        epochs=args.epochs,
        minibatches=args.minibatches,
        lr=args.lr,
        anneal_lr=args.anneal_lr,
        vf_coef=args.vf_coef,
        ent_coef=args.ent_coef,
        max_grad_norm=args.max_grad_norm,
        **fixed,
    )


@dataclasses.dataclass
class EpisodeEnd:
    """One finished episode: its env index, how it ended, its undiscounted
    return and length (in steps), summed duration, and the info of its last step."""

    env: int
    terminated: bool
    truncated: bool
    ret: float
    length: int
    duration: float
    info: dict


@dataclasses.dataclass
class Rollout:
    """``T`` steps of ``N`` envs, time-major ``[T, N, ...]``. ``dones[t]``: the
    episode ended at step t; ``bootstrap[t]``: V(final obs) where it was
    truncated (else 0); ``next_value [N]``: V of the observations after the
    last step; ``masks`` None when the envs give no ``action_mask``."""

    obs: torch.Tensor
    masks: torch.Tensor | None
    actions: torch.Tensor
    logp: torch.Tensor
    values: torch.Tensor
    rewards: torch.Tensor
    durations: torch.Tensor
    dones: torch.Tensor
    bootstrap: torch.Tensor
    next_value: torch.Tensor
    episodes: list
    last_info: dict

    @property
    def size(self) -> int:
        return self.rewards.numel()


def _as_obs(obs) -> torch.Tensor:
    return torch.as_tensor(np.asarray(obs), dtype=torch.float32)


def _env_info(infos: dict, k: int) -> dict:
    """Env ``k``'s entries of a vector env's dict-of-arrays info."""
    out = {}
    for key, value in infos.items():
        if key.startswith("_") or not infos.get(f"_{key}", np.ones(k + 1, bool))[k]:
            continue
        out[key] = _env_info(value, k) if isinstance(value, dict) else value[k]
    return out


def _per_step(info: dict, key: str, done: np.ndarray, default: float) -> np.ndarray:
    """``info[key]`` of the step just taken; with same-step autoreset the
    entries of finished envs are in ``info["final_info"]``."""
    n = len(done)
    out = np.asarray(info[key], np.float64).copy() if key in info else np.full(n, default)
    if done.any() and key in info.get("final_info", {}):
        final = np.asarray(info["final_info"][key], np.float64)
        out[done] = final[done]
    return out


class RolloutCollector:
    """Steps ``envs`` (a gymnasium ``VectorEnv`` in ``SAME_STEP`` autoreset mode)
    with ``policy``, ``steps`` steps per `collect`. ``obs_fn`` maps a batch of
    raw observations (numpy) to the network's input tensor (default: float32).

    Raises:
      ValueError: the vector env autoresets in another mode.
    """

    def __init__(
        self,
        envs,
        policy: ActorCritic,
        steps: int,
        obs_fn: Callable[[np.ndarray], torch.Tensor] = _as_obs,
    ) -> None:
        mode = envs.metadata.get("autoreset_mode", getattr(envs, "autoreset_mode", None))
        if mode != SAME_STEP:
            raise ValueError(
                f"RolloutCollector needs autoreset_mode=SAME_STEP, the vector env "
                f"has {mode!r} (use ppo.make_vector_env)"
            )
        self.envs, self.policy, self.steps, self.obs_fn = envs, policy, int(steps), obs_fn
        self.n = envs.num_envs
        # The network's input and action mask after the last step (set by `reset`).
        self._obs: torch.Tensor | None = None
        self._mask: torch.Tensor | None = None

    def reset(self, seed: int | None = None) -> None:
        """Resets every env (``seed``: env k gets ``seed + k``) and the episode tallies."""
        obs, info = self.envs.reset(seed=seed)
        self._obs, self._mask = self.obs_fn(obs), self._mask_of(info)
        self._ret, self._len, self._dur = np.zeros(self.n), np.zeros(self.n, int), np.zeros(self.n)

    @staticmethod
    def _mask_of(info: dict) -> torch.Tensor | None:
        return (
            None
            if "action_mask" not in info
            else torch.as_tensor(np.asarray(info["action_mask"], np.float32))
        )

    def collect(self) -> Rollout:
        """``steps`` steps of every env (calls `reset` first if it never ran)."""
        if self._obs is None:
            self.reset()
        assert self._obs is not None  # set by `reset`
        buf: dict[str, list] = {
            k: []
            for k in (
                "obs",
                "masks",
                "actions",
                "logp",
                "values",
                "rewards",
                "durations",
                "dones",
                "bootstrap",
            )
        }
        episodes, info = [], {}
        for _ in range(self.steps):
            with torch.no_grad():
                dist = self.policy.policy_dist(self._obs, self._mask)
                action = dist.sample()
                buf["logp"].append(dist.log_prob(action))
                buf["values"].append(self.policy.value(self._obs).reshape(self.n))
            buf["obs"].append(self._obs)
            buf["masks"].append(self._mask)
            buf["actions"].append(action)
            obs, reward, terminated, truncated, info = self.envs.step(action.numpy())
            done = np.logical_or(terminated, truncated)
            duration = _per_step(info, "duration", done, 1.0)
            buf["rewards"].append(torch.as_tensor(reward, dtype=torch.float32))
            buf["durations"].append(torch.as_tensor(duration, dtype=torch.float32))
            buf["dones"].append(torch.as_tensor(done, dtype=torch.float32))
            buf["bootstrap"].append(self._bootstrap(info, terminated, truncated))
            self._ret += reward
            self._len += 1
            self._dur += duration
            for k in np.flatnonzero(done):
                episodes.append(
                    EpisodeEnd(
                        int(k),
                        bool(terminated[k]),
                        bool(truncated[k]),
                        float(self._ret[k]),
                        int(self._len[k]),
                        float(self._dur[k]),
                        _env_info(info.get("final_info", {}), int(k)),
                    )
                )
                self._ret[k], self._len[k], self._dur[k] = 0.0, 0, 0.0
            self._obs, self._mask = self.obs_fn(obs), self._mask_of(info)
        with torch.no_grad():
            next_value = self.policy.value(self._obs).reshape(self.n)
        masks = buf.pop("masks")  # None without action masks; the rest tensors
        stack = {k: torch.stack(v) for k, v in buf.items()}
        return Rollout(
            **stack,
            masks=None if masks[0] is None else torch.stack(masks),
            next_value=next_value,
            episodes=episodes,
            last_info=info,
        )

    def _bootstrap(self, info: dict, terminated, truncated) -> torch.Tensor:
        """V(final observation) of the envs truncated at this step, 0 elsewhere."""
        out = torch.zeros(self.n)
        cut = np.flatnonzero(np.logical_and(truncated, np.logical_not(terminated)))
        if len(cut):
            final = np.stack([np.asarray(info["final_obs"][k]) for k in cut])
            with torch.no_grad():
                out[torch.as_tensor(cut)] = self.policy.value(self.obs_fn(final)).reshape(-1)
        return out


def gae(
    rewards: torch.Tensor,
    values: torch.Tensor,
    discounts: torch.Tensor,
    dones: torch.Tensor,
    next_value: torch.Tensor,
    lam: float,
    bootstrap: torch.Tensor | None = None,
) -> tuple[torch.Tensor, torch.Tensor]:
    """Advantages and returns (``[T, N]`` each) of time-major ``[T, N]`` inputs:
    ``delta_t = r_t + discounts_t * (V_t+1 * (1 - dones_t) + bootstrap_t) - V_t``,
    ``A_t = delta_t + discounts_t * lam * (1 - dones_t) * A_t+1``; ``discounts_t``
    = gamma ** duration_t, ``V_T = next_value [N]``, ``bootstrap_t`` = V(final
    obs) of an episode truncated at t (0 otherwise); returns = A + V."""
    steps = rewards.shape[0]
    if bootstrap is None:
        bootstrap = torch.zeros_like(rewards)
    adv = torch.zeros_like(rewards)
    running = torch.zeros_like(next_value)
    for t in reversed(range(steps)):
        following = next_value if t == steps - 1 else values[t + 1]
        live = 1.0 - dones[t]
        delta = rewards[t] + discounts[t] * (following * live + bootstrap[t]) - values[t]
        running = delta + discounts[t] * lam * live * running
        adv[t] = running
    return adv, adv + values


def advantages(rollout: Rollout, gamma: float, lam: float) -> tuple[torch.Tensor, torch.Tensor]:
    """`gae` of a rollout, step t discounted by ``gamma ** durations[t]``."""
    discounts = torch.pow(torch.as_tensor(gamma, dtype=torch.float32), rollout.durations)
    return gae(
        rollout.rewards,
        rollout.values,
        discounts,
        rollout.dones,
        rollout.next_value,
        lam,
        rollout.bootstrap,
    )


@overload
def _flat(x: torch.Tensor, steps_envs: int) -> torch.Tensor: ...


@overload
def _flat(x: None, steps_envs: int) -> None: ...


@overload
def _flat(x: torch.Tensor | None, steps_envs: int) -> torch.Tensor | None: ...


def _flat(x: torch.Tensor | None, steps_envs: int) -> torch.Tensor | None:
    return None if x is None else x.reshape(steps_envs, *x.shape[2:])


def ppo_update(
    policy: ActorCritic,
    optimizer: torch.optim.Optimizer,
    rollout: Rollout,
    adv: torch.Tensor,
    returns: torch.Tensor,
    cfg: PPOConfig,
    actor: bool = True,
) -> dict:
    """``cfg.epochs`` passes of ``cfg.minibatches`` shuffled minibatches
    (torch's global RNG) over the rollout; loss = clipped surrogate + vf_coef
    * 0.5 (V - return)^2 - ent_coef * entropy. ``actor`` False: the value loss
    only (parameters it does not reach keep ``grad`` None and do not move).
    Returns the mean policy_loss, value_loss, entropy, approx_kl, clip_frac."""
    n = rollout.size
    obs, masks = _flat(rollout.obs, n), _flat(rollout.masks, n)
    actions, logp_old = _flat(rollout.actions, n), rollout.logp.reshape(n)
    adv, returns = adv.reshape(n), returns.reshape(n)
    params = [p for group in optimizer.param_groups for p in group["params"]]
    size = max(1, n // cfg.minibatches)
    stats: dict[str, list] = {
        k: [] for k in ("policy_loss", "value_loss", "entropy", "approx_kl", "clip_frac")
    }
    for _ in range(cfg.epochs):
        order = torch.randperm(n)
        for start in range(0, n, size):
            idx = order[start : start + size]
            dist = policy.policy_dist(obs[idx], None if masks is None else masks[idx])
            ratio = (dist.log_prob(actions[idx]) - logp_old[idx]).exp()
            a = adv[idx]
            if cfg.norm_adv and len(idx) > 1:
                a = (a - a.mean()) / (a.std() + 1e-8)
            policy_loss = torch.max(-a * ratio, -a * ratio.clamp(1 - cfg.clip, 1 + cfg.clip)).mean()
            value_loss = 0.5 * (policy.value(obs[idx]).reshape(-1) - returns[idx]).pow(2).mean()
            entropy = dist.entropy().mean()
            loss = cfg.vf_coef * value_loss
            if actor:
                loss = loss + policy_loss - cfg.ent_coef * entropy
            optimizer.zero_grad(set_to_none=True)
            loss.backward()
            nn.utils.clip_grad_norm_([p for p in params if p.grad is not None], cfg.max_grad_norm)
            optimizer.step()
            with torch.no_grad():
                stats["policy_loss"].append(policy_loss.item())
                stats["value_loss"].append(value_loss.item())
                stats["entropy"].append(entropy.item())
                stats["approx_kl"].append(((ratio - 1) - ratio.log()).mean().item())
                stats["clip_frac"].append(((ratio - 1).abs() > cfg.clip).float().mean().item())
    return {k: float(np.mean(v)) for k, v in stats.items()}


def set_lr(optimizer: torch.optim.Optimizer, cfg: PPOConfig, fraction_left: float) -> float:
    """Sets (and returns) the LR: ``cfg.lr``, or with ``cfg.anneal_lr`` ``cfg.lr *
    max(fraction_left, cfg.lr_floor)`` (``fraction_left`` of the budget, 1 -> 0)."""
    lr = cfg.lr * max(fraction_left, cfg.lr_floor) if cfg.anneal_lr else cfg.lr
    for group in optimizer.param_groups:
        group["lr"] = lr
    return lr


def iteration(
    collector: RolloutCollector,
    optimizer: torch.optim.Optimizer,
    cfg: PPOConfig,
    fraction_left: float = 1.0,
    actor: bool = True,
) -> tuple[Rollout, dict]:
    """One PPO iteration of ``collector.policy``: LR, rollout, GAE, update.
    Returns the rollout and the update's statistics (plus ``lr``)."""
    lr = set_lr(optimizer, cfg, fraction_left)
    rollout = collector.collect()
    adv, returns = advantages(rollout, cfg.gamma, cfg.lam)
    stats = ppo_update(collector.policy, optimizer, rollout, adv, returns, cfg, actor=actor)
    return rollout, dict(stats, lr=lr)
