"""V-trace targets (Espeholt et al. 2018) and the paper's one- or two-head IMPALA loss.

V-trace, for an unroll of length ``T`` (time-major ``[T, B]``), with
``rho_t = pi(a_t|x_t) / mu(a_t|x_t)`` (target over behaviour policy),
``rhobar_t = min(clip_rho, rho_t)``, ``c_t = min(clip_c, rho_t)`` and
``delta_t = rhobar_t (r_t + gamma_t V(x_{t+1}) - V(x_t))``::

    v_s = V(x_s) + sum_{t=s}^{T-1} (prod_{i=s}^{t-1} gamma_i c_i) delta_t

computed here by the equivalent backward recursion
``v_s - V(x_s) = delta_s + gamma_s c_s (v_{s+1} - V(x_{s+1}))`` with
``v_T = V(x_T)`` (the bootstrap value). The policy-gradient advantage is
``min(clip_pg_rho, rho_s) (r_s + gamma_s v_{s+1} - V(x_s))``.

``gamma_t`` is the per-step discount: the discount factor times ``1 - done``,
so a terminal step cuts both the bootstrap and the trace.

`impala_loss` is the actor-critic loss. With one value head it is the usual
IMPALA loss. With two (the planner conditions, paper eqs. 1-2) V-trace runs
separately for the environment and the auxiliary abstract-task streams (same
importance weights, each with its own rewards, discounts and value head), the
policy gradient uses the sum of both advantages, and both baselines are
trained.
"""

from __future__ import annotations

from typing import NamedTuple

import torch

from hier_agents.baselines.impala.network import gaussian_entropy, gaussian_log_prob


class VTrace(NamedTuple):
    """``vs``: V-trace value targets ``[T, B]``; ``pg_advantages``: ``[T, B]``."""

    vs: torch.Tensor
    pg_advantages: torch.Tensor


def _clip(rhos: torch.Tensor, bound: float | None) -> torch.Tensor:
    return rhos if bound is None else torch.clamp(rhos, max=float(bound))


@torch.no_grad()
def vtrace(
    log_rhos: torch.Tensor,
    discounts: torch.Tensor,
    rewards: torch.Tensor,
    values: torch.Tensor,
    bootstrap_value: torch.Tensor,
    *,
    clip_rho: float | None = 1.0,
    clip_pg_rho: float | None = 1.0,
    clip_c: float | None = 1.0,
    weight_pg: bool = True,
) -> VTrace:
    """V-trace targets and policy-gradient advantages (no gradients flow).

    ``log_rhos``: ``log pi(a_t|x_t) - log mu(a_t|x_t)``; ``discounts``:
    ``gamma_t`` (zero at terminations); ``rewards``: ``r_t``; ``values``:
    ``V(x_t)`` -- all ``[T, B]``. ``bootstrap_value``: ``V(x_T)`` ``[B]``.
    A clip of None means no truncation. ``weight_pg`` False leaves the
    advantages without their importance weight ``min(clip_pg_rho, rho_s)``
    (a clipped surrogate weighs them itself).
    """
    log_rhos, discounts, rewards, values, bootstrap_value = (
        x.detach().to(torch.float32)
        for x in (log_rhos, discounts, rewards, values, bootstrap_value)
    )
    rhos = torch.exp(log_rhos)
    clipped_rhos = _clip(rhos, clip_rho)
    cs = _clip(rhos, clip_c)
    values_next = torch.cat([values[1:], bootstrap_value.unsqueeze(0)], dim=0)
    deltas = clipped_rhos * (rewards + discounts * values_next - values)
    decay = discounts * cs

    # v_s - V(x_s), backwards from the end of the unroll.
    corrections = torch.empty_like(values)
    acc = torch.zeros_like(bootstrap_value)
    for t in range(values.shape[0] - 1, -1, -1):
        acc = deltas[t] + decay[t] * acc
        corrections[t] = acc
    vs = values + corrections

    vs_next = torch.cat([vs[1:], bootstrap_value.unsqueeze(0)], dim=0)
    pg_advantages = rewards + discounts * vs_next - values
    if weight_pg:
        pg_advantages = _clip(rhos, clip_pg_rho) * pg_advantages
    return VTrace(vs, pg_advantages)


def _value_streams(streams, log_rhos, baseline_cost: float, stats: dict, kw: dict):
    """The V-trace advantages summed over the value ``streams`` (name, values,
    bootstrap, rewards, discounts) and their baseline loss; each stream's
    parts go into ``stats``."""
    advantages = torch.zeros_like(log_rhos)
    baseline_loss = log_rhos.new_zeros(())
    for name, values, boot, rewards, discounts in streams:
        targets = vtrace(log_rhos, discounts, rewards, values, boot, **kw)
        advantages = advantages + targets.pg_advantages
        part = 0.5 * baseline_cost * (targets.vs - values).square().mean()
        baseline_loss = baseline_loss + part
        stats[f"baseline_loss_{name}"] = float(part.detach())
        stats[f"advantage_{name}"] = float(targets.pg_advantages.mean())
        stats[f"vs_{name}"] = float(targets.vs.mean())
        stats[f"value_{name}"] = float(values.detach().mean())
    return advantages, baseline_loss


def _policy_loss(log_probs, behaviour_log_probs, advantages, normalize, clip_ratio, stats):
    """The policy-gradient term of `impala_loss` from the learner's
    ``log_probs`` and the actors' ``behaviour_log_probs`` ``[T, B]`` and the
    (detached) ``advantages`` ``[T, B]``: normalised over the batch when
    ``normalize``, PPO's clipped surrogate when ``clip_ratio > 0`` (then
    ``stats["ratio_clipped_fraction"]`` is set), else ``-mean(log_probs * A)``."""
    if normalize:
        advantages = (advantages - advantages.mean()) / (advantages.std() + 1e-8)
    if not clip_ratio:
        return -(log_probs * advantages).mean()
    ratio = torch.exp(log_probs - behaviour_log_probs)
    clipped = torch.clamp(ratio, 1.0 - clip_ratio, 1.0 + clip_ratio)
    stats["ratio_clipped_fraction"] = float(((ratio - 1).abs() > clip_ratio).float().mean())
    return -torch.minimum(ratio * advantages, clipped * advantages).mean()


def impala_loss(
    out,
    bootstrap,
    actions: torch.Tensor,
    behaviour_log_probs: torch.Tensor,
    rewards_env: torch.Tensor,
    discounts_env: torch.Tensor,
    rewards_abs: torch.Tensor | None = None,
    discounts_abs: torch.Tensor | None = None,
    *,
    baseline_cost: float = 0.5,
    entropy_cost: float = 1e-3,
    clip_rho: float | None = 1.0,
    clip_pg_rho: float | None = 1.0,
    clip_c: float | None = 1.0,
    normalize_advantages: bool = False,
    clip_ratio: float = 0.0,
):
    """The IMPALA actor-critic loss for one unroll batch; returns ``(loss, stats)``.

    ``out``: `NetOutput` for the ``T`` steps (``mean``, ``std`` ``[T, B, A]``,
    ``value_env`` and, for two heads, ``value_abs`` ``[T, B]``);
    ``bootstrap``: the same fields for the observation after the unroll (only
    ``value_env`` / ``value_abs`` ``[B]`` are read); ``actions`` ``[T, B, A]``
    and ``behaviour_log_probs`` ``[T, B]`` from the actors; rewards and
    discounts ``[T, B]`` (discounts already ``gamma * (1 - done)``). The abs
    stream is used only when ``out.value_abs`` is not None.

    ``loss = pg + baseline + entropy`` where, averaged over the ``T * B``
    steps (means rather than sums, so the scale does not depend on the batch
    or unroll size),

    * ``pg = -mean(log pi(a|x) * (A_env [+ A_abs]))`` with V-trace advantages
      ``A``; with ``clip_ratio`` ``eps > 0``, PPO's clipped surrogate instead,
      ``pg = -mean(min(rho A, clip(rho, 1 - eps, 1 + eps) A))`` with ``rho``
      the ratio of the learner's policy to the actors' (gradients flow
      through it; ``A`` then without its importance weight, which ``rho``
      carries); with ``normalize_advantages``, ``A`` is first shifted and
      scaled to mean 0 and standard deviation 1 over the batch;
    * ``baseline = 0.5 * baseline_cost * mean((vs_env - V_env)^2)
      [+ the same for abs]``;
    * ``entropy = -entropy_cost * mean(H(pi))`` (an entropy bonus).

    ``stats`` (floats): the loss and its parts, mean advantage(s), value
    target(s) and value(s), mean importance weight ``rho`` and the fraction
    clipped, policy entropy and mean std.
    """
    log_probs = gaussian_log_prob(out.mean, out.std, actions)
    log_rhos = log_probs.detach() - behaviour_log_probs
    kw = dict(clip_rho=clip_rho, clip_pg_rho=clip_pg_rho, clip_c=clip_c, weight_pg=not clip_ratio)

    streams = [("env", out.value_env, bootstrap.value_env, rewards_env, discounts_env)]
    if out.value_abs is not None:
        if rewards_abs is None or discounts_abs is None:
            raise ValueError("two value heads need rewards_abs and discounts_abs")
        streams.append(("abs", out.value_abs, bootstrap.value_abs, rewards_abs, discounts_abs))

    stats: dict[str, float] = {}
    advantages, baseline_loss = _value_streams(streams, log_rhos, baseline_cost, stats, kw)
    pg_loss = _policy_loss(
        log_probs, behaviour_log_probs, advantages, normalize_advantages, clip_ratio, stats
    )
    entropy = gaussian_entropy(out.std).mean()
    entropy_loss = -entropy_cost * entropy
    loss = pg_loss + baseline_loss + entropy_loss

    rhos = torch.exp(log_rhos)
    clip = clip_rho if clip_rho is not None else float("inf")
    parts = dict(
        loss=loss,
        pg_loss=pg_loss,
        baseline_loss=baseline_loss,
        entropy_loss=entropy_loss,
        entropy=entropy,
    )
    stats.update({name: float(value.detach()) for name, value in parts.items()})
    stats.update(
        std=float(out.std.detach().mean()),
        rho=float(rhos.mean()),
        rho_clipped_fraction=float((rhos > clip).float().mean()),
    )
    return loss, stats
