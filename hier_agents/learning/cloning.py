"""Behaviour cloning and DAgger for learned skills, on any skill spec.

* `collect`: drive a `SkillEnv` for some frames with the skill's teacher or
  with a network's mean (Gaussian noise on either) and label every visited
  observation with the teacher's action (``info["expert_action"]``);
* `fit`: regress a network's mean on labelled observations (mean squared
  error, Adam, minibatches of 256);
* `clone`: the warm start the skill trainer runs before PPO: cloning on the
  noisy teacher's frames, then ``dagger_rounds`` rounds of DAgger (the cloned
  policy drives, the teacher labels, the network is refitted on everything).

Frames are agent control steps; ``sim_steps`` counts every simulated control
step including the scene sources' set-up (the honest budget).
"""

from __future__ import annotations

import numpy as np
import torch

__all__ = ["collect", "fit", "clone", "warm_start_frames"]


def collect(
    spec,
    frames: int,
    seed: int,
    *,
    actor=None,
    noise: float = 0.2,
    noise_prob: float = 1.0,
    mix: float = 1.0,
    estimator: str | None = None,
    t_abs: int | None = None,
):
    """``frames`` steps of a `SkillEnv` of ``spec``, every observation
    labelled with the teacher's action (``info["expert_action"]``; a step
    without one, where the teacher cannot plan, is not kept).

    Who acts: the teacher when ``actor`` is None; else at every step
    ``actor.mean`` (a torch module's method) with probability ``mix`` and the
    teacher otherwise (``mix=1``: the student alone, plain DAgger). Each
    option is noisy with probability ``noise_prob``: Gaussian ``noise`` (std,
    policy units) is added to every action it takes (the data then covers
    recoveries from the states noise leads to). Returns (observations
    [F, obs], labels [F, act], simulated control steps)."""
    from hier_agents.learning.skill_env import SkillEnv

    env = SkillEnv(spec, seed=seed, estimator=estimator, t_abs=t_abs)
    rng = np.random.default_rng(seed + 1)
    xs, ys = [], []
    try:
        obs, info = env.reset(seed=seed)
        noisy = rng.random() < noise_prob
        shape = env.action_space.shape
        assert shape is not None  # a Box: gymnasium types Space shapes Optional
        zero = np.zeros(shape, np.float32)
        for _ in range(int(frames)):
            label = info.get("expert_action")  # None where the teacher cannot plan
            if label is not None:
                xs.append(obs)
                ys.append(label)
            action = zero if label is None else label
            if actor is not None and (label is None or rng.random() < mix):
                with torch.no_grad():
                    action = actor.mean(torch.as_tensor(obs)[None])[0].numpy()
            if noisy:
                action = action + noise * rng.standard_normal(len(action))
            obs, _, terminated, truncated, info = env.step(np.clip(action, -1, 1))
            if terminated or truncated:
                obs, info = env.reset()
                noisy = rng.random() < noise_prob
        sim_steps = env.sim_steps
    finally:
        env.close()
    return np.asarray(xs, np.float32), np.asarray(ys, np.float32), int(sim_steps)


def fit(agent, xs, ys, epochs: int, lr: float = 1e-3, log=print) -> float:
    """Regresses ``agent.mean`` on the labels (MSE, Adam from ``lr`` with a
    cosine decay over the epochs, minibatches of 256; only ``agent.actor``'s
    parameters move). Returns the last epoch's mean squared error."""
    x = torch.as_tensor(xs, dtype=torch.float32)
    y = torch.as_tensor(ys, dtype=torch.float32)
    opt = torch.optim.Adam(agent.actor.parameters(), lr=lr)
    schedule = torch.optim.lr_scheduler.CosineAnnealingLR(opt, max(int(epochs), 1))
    n, mse = len(x), float("nan")
    for epoch in range(int(epochs)):
        perm = torch.randperm(n)
        total = 0.0
        for k in range(0, n, 256):
            idx = perm[k : k + 256]
            loss = ((agent.mean(x[idx]) - y[idx]) ** 2).mean()
            opt.zero_grad()
            loss.backward()
            opt.step()
            total += loss.item() * len(idx)
        schedule.step()
        mse = total / max(n, 1)
        if epoch % 10 == 9 or epoch == epochs - 1:
            log(f"fit epoch {epoch + 1}/{epochs}: mse {mse:.5f} on {n} frames")
    return mse


def warm_start_frames(frames: int, dagger_frames: int, dagger_rounds: int) -> int:
    """The agent frames `clone` spends with these arguments (0 when
    ``frames`` is 0: no warm start)."""
    if frames <= 0:
        return 0
    return int(frames) + (int(dagger_rounds) * int(dagger_frames) if dagger_frames > 0 else 0)


def clone(
    agent,
    spec,
    *,
    frames: int,
    seed: int,
    dagger_frames: int = 0,
    dagger_rounds: int = 1,
    epochs: int = 60,
    noise: float = 0.2,
    noise_prob: float = 1.0,
    dagger_noise: float = 0.1,
    dagger_noise_prob: float = 1.0,
    dagger_mix: float = 1.0,
    estimator: str | None = None,
    log=print,
) -> tuple[int, int]:
    """Behaviour cloning on ``frames`` frames of the teacher (options noisy with
    probability ``noise_prob``, std ``noise``), then ``dagger_rounds`` rounds
    of ``dagger_frames`` frames in which the cloned policy acts (per step with
    probability ``dagger_mix``, the teacher otherwise; noise
    ``dagger_noise`` on options noisy with probability ``dagger_noise_prob``),
    labelled by the teacher, refitted on all data so far (`collect`, `fit`).
    Returns (agent frames, simulated control steps); the agent frames are
    `warm_start_frames` of the arguments."""
    log(
        f"behaviour cloning: {frames} frames of the {spec.name} skill's teacher "
        f"(noise {noise} on {noise_prob:.0%} of the options)"
    )
    xs, ys, sim_steps = collect(
        spec, frames, seed + 1, noise=noise, noise_prob=noise_prob, estimator=estimator
    )
    fit(agent, xs, ys, epochs, log=log)
    total = int(frames)
    for r in range(int(dagger_rounds) if dagger_frames > 0 else 0):
        log(
            f"DAgger round {r + 1}/{dagger_rounds}: {dagger_frames} frames, the cloned "
            f"policy acting at {dagger_mix:.0%} of the steps, labelled by the teacher"
        )
        xd, yd, sim_d = collect(
            spec,
            dagger_frames,
            seed + 3 + 2 * r,
            actor=agent,
            noise=dagger_noise,
            noise_prob=dagger_noise_prob,
            mix=dagger_mix,
            estimator=estimator,
        )
        xs, ys = np.concatenate([xs, xd]), np.concatenate([ys, yd])
        fit(agent, xs, ys, epochs, log=log)
        total += int(dagger_frames)
        sim_steps += sim_d
    return total, sim_steps
