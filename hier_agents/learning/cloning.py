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

__all__ = ["collect", "fit", "clone"]


def collect(spec, frames: int, seed: int, *, actor=None, noise: float = 0.2,
            estimator: str | None = None, t_abs: int | None = None):
    """``frames`` steps of a `SkillEnv` of ``spec`` driven by the teacher
    (``actor`` None) or by ``actor.mean`` (a torch module's method), with
    Gaussian ``noise`` (std, policy units) on the action; every observation
    labelled with the teacher's action. Returns (observations [F, obs],
    labels [F, act], simulated control steps)."""
    from hier_agents.learning.skill_env import SkillEnv
    env = SkillEnv(spec, seed=seed, estimator=estimator, t_abs=t_abs)
    rng = np.random.default_rng(seed + 1)
    xs, ys = [], []
    try:
        obs, info = env.reset(seed=seed)
        for _ in range(int(frames)):
            xs.append(obs)
            ys.append(info["expert_action"])
            if actor is None:
                action = info["expert_action"]
            else:
                with torch.no_grad():
                    action = actor.mean(torch.as_tensor(obs)[None])[0].numpy()
            action = np.clip(action + noise * rng.standard_normal(len(action)), -1, 1)
            obs, _, terminated, truncated, info = env.step(action)
            if terminated or truncated:
                obs, info = env.reset()
        sim_steps = env.sim_steps
    finally:
        env.close()
    return np.asarray(xs, np.float32), np.asarray(ys, np.float32), int(sim_steps)


def fit(agent, xs, ys, epochs: int, lr: float = 1e-3, log=print) -> float:
    """Regresses ``agent.mean`` on the labels (MSE; only ``agent.actor``'s
    parameters move). Returns the last epoch's mean squared error."""
    x = torch.as_tensor(xs, dtype=torch.float32)
    y = torch.as_tensor(ys, dtype=torch.float32)
    opt = torch.optim.Adam(agent.actor.parameters(), lr=lr)
    n, mse = len(x), float("nan")
    for epoch in range(int(epochs)):
        perm = torch.randperm(n)
        total = 0.0
        for k in range(0, n, 256):
            idx = perm[k:k + 256]
            loss = ((agent.mean(x[idx]) - y[idx]) ** 2).mean()
            opt.zero_grad()
            loss.backward()
            opt.step()
            total += loss.item() * len(idx)
        mse = total / max(n, 1)
        if epoch % 10 == 9 or epoch == epochs - 1:
            log(f"fit epoch {epoch + 1}/{epochs}: mse {mse:.5f} on {n} frames")
    return mse


def clone(agent, spec, *, frames: int, seed: int, dagger_frames: int = 0,
          dagger_rounds: int = 1, epochs: int = 60, noise: float = 0.2,
          dagger_noise: float = 0.1, estimator: str | None = None, log=print) -> tuple[int, int]:
    """Behaviour cloning on ``frames`` frames of the noisy teacher, then
    ``dagger_rounds`` rounds of ``dagger_frames`` frames each driven by the
    cloned policy (noise ``dagger_noise``), labelled by the teacher, refitted
    on all data so far. Returns (agent frames, simulated control steps)."""
    log(f"behaviour cloning: {frames} frames of the {spec.name} skill's teacher "
        f"(noise {noise})")
    xs, ys, sim_steps = collect(spec, frames, seed + 1, noise=noise, estimator=estimator)
    fit(agent, xs, ys, epochs, log=log)
    total = int(frames)
    for r in range(int(dagger_rounds) if dagger_frames > 0 else 0):
        log(f"DAgger round {r + 1}/{dagger_rounds}: {dagger_frames} frames of the cloned "
            f"policy, labelled by the teacher")
        xd, yd, sim_d = collect(spec, dagger_frames, seed + 3 + 2 * r, actor=agent,
                                noise=dagger_noise, estimator=estimator)
        xs, ys = np.concatenate([xs, xd]), np.concatenate([ys, yd])
        fit(agent, xs, ys, epochs, log=log)
        total += int(dagger_frames)
        sim_steps += sim_d
    return total, sim_steps
