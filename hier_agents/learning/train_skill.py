"""Train a skill with PPO on its option environment.

    python -m hier_agents.learning.train_skill ball --steps N --logdir DIR [--envs K] [--seed S]
                                           [--resume] [--bc-steps M] [--eval-episodes E]
    python -m hier_agents.learning.train_skill ball --evaluate [PATH] [--estimator camera]
                                           [--eval-episodes E] [--json OUT]

Trains `skills.learned.LearnedBallSkill`'s controller (the map from the
carrot and speed target to [roll, steer]; see `skills.learned.ball` for what
is learned and what stays geometric) on `hier_agents.learning.skill_env.
BallOptionEnv` (one episode = one walk-then-push option; +1 when the
subgoal is reached, -1 for disturbing boxes, -0.002 per step). Written
top to bottom in one file, in the CleanRL spirit:

1. **Behaviour-cloning warm start** (``--bc-steps``, default 20000 frames,
   0 to start from scratch): the scripted controller (`skills.ball`'s
   yaw-rate and roll loops) drives the option environment with Gaussian
   noise on its actions (std 0.2, so that the data covers its own
   recoveries); the actor's mean regresses the scripted action of every
   visited observation (60 epochs, MSE). Then one round of **DAgger**
   (``--dagger-steps``, default 20000): the cloned policy drives (noise
   0.1, options cut at 50 steps and continued, as the option layer does),
   its states are labelled with the scripted action and the actor is
   refitted on both sets. These frames count in the budget.
2. **PPO** (``--steps`` frames, the BC and DAgger frames included): ``--envs``
   environments in a gymnasium vector env (same-step autoreset),
   rollouts of 256 steps per environment, GAE(0.99, 0.95), clipped
   surrogate (0.1), 5 epochs of 4 minibatches, Adam 1e-4, a Gaussian policy
   with a state-independent std (initially 0.2 after BC, 0.6 from scratch);
   the first 3 iterations after BC train only the critic (a fresh critic's
   advantages would otherwise undo the warm start). Truncated options
   (``t_abs``) bootstrap from the critic. Measured (``results/
   learned_ball``): after the warm start PPO keeps the option success at
   the scripted controller's level but does not raise it, and a long
   fine-tune (130k PPO frames, no DAgger) *lowered* the solve rate of
   full camera-estimator runs (79% on level-5 with pegs against 100% for
   BC alone): the sparse reward says nothing about how precisely a box
   is kept on its line, and the policy mean drifts. The shipped policy
   has 40k PPO frames.
3. **Evaluation** (``--eval-episodes``, default 100): the deterministic
   policy (the mean) on held-out scenes (level-5 with pegs from seeds the
   training never uses), option success with a 95% Wilson interval, printed
   as a table and written with the rest to ``DIR/summary.json``: frames
   (agent steps, and all simulated control steps including the scripted
   fast-forwards that make the scenes), wall time, CPU time, success.

Logs: a progress bar with the option success of the last 100 options;
TensorBoard scalars in ``DIR`` (``torch.utils.tensorboard``) and the same
in ``DIR/progress.csv``. Checkpoints: ``DIR/checkpoint.pt`` (everything to
resume: networks, optimiser, counters, random states) every
``--save-every`` iterations and at the end, and ``DIR/ball_policy.pt`` (the
actor only, the format `skills.learned.load_policy` reads; ~25 KB).
``--resume`` continues from ``DIR/checkpoint.pt`` (the BC phase is skipped
when it was done).

``--evaluate [PATH]`` only evaluates a policy (default: the shipped one)
against the scripted controller on the same held-out scenes, with the
``--estimator`` given (``oracle``, privileged, or ``camera``,
observation-only), and writes ``--json``.

Use the trained policy with ``--skill learned-ball`` after copying
``DIR/ball_policy.pt`` to ``skills/learned/ball_policy.pt`` (or
``LearnedBallSkill(policy=PATH)``).
"""

from __future__ import annotations

import argparse
import csv
import json
import math
import os
import random
import sys
import time
from pathlib import Path

import gymnasium
import numpy as np
import torch
from torch import nn

from hier_agents.learning.skill_env import HELDOUT_SOURCES, TRAIN_SOURCES, BallOptionEnv
from hier_agents.stats import wilson_interval
from skills.learned.ball import FEATURES, OBS_DIM, SIGN

#: Seeds of the held-out evaluation scenes start here (training uses ``--seed``).
HELDOUT_SEED = 10_000


# -- the networks ------------------------------------------------------------------------

def mlp(sizes, out_std: float) -> nn.Sequential:
    """tanh MLP with orthogonal initialisation (last layer scaled by ``out_std``)."""
    layers = []
    for j, (a, b) in enumerate(zip(sizes[:-1], sizes[1:])):
        linear = nn.Linear(a, b)
        last = j == len(sizes) - 2
        nn.init.orthogonal_(linear.weight, out_std if last else math.sqrt(2))
        nn.init.zeros_(linear.bias)
        layers.append(linear)
        if not last:
            layers.append(nn.Tanh())
    return nn.Sequential(*layers)


class Agent(nn.Module):
    """Actor and critic. The actor's network outputs the drive-frame
    [throttle, steer]; a fixed layer turns it into the raw [roll, steer]
    (``roll = -sign * throttle``, the sign being an observed feature)."""

    def __init__(self, hidden: int = 64, log_std: float = -0.5) -> None:
        super().__init__()
        self.actor = mlp([OBS_DIM, hidden, hidden, 2], 0.01)
        self.critic = mlp([OBS_DIM, hidden, hidden, 1], 1.0)
        self.log_std = nn.Parameter(torch.full((2,), float(log_std)))

    def mean(self, obs: torch.Tensor) -> torch.Tensor:
        out = self.actor(obs)
        sign = obs[:, SIGN]
        return torch.stack([-sign * out[:, 0], out[:, 1]], dim=1)

    def value(self, obs: torch.Tensor) -> torch.Tensor:
        return self.critic(obs).squeeze(-1)

    def dist(self, obs: torch.Tensor) -> torch.distributions.Normal:
        return torch.distributions.Normal(self.mean(obs), self.log_std.exp())


def export_policy(agent: Agent, path: Path, meta: dict) -> None:
    """The actor in the format `skills.learned.load_policy` reads."""
    actor = {k: v.detach().clone() for k, v in agent.actor.state_dict().items()}
    torch.save({"actor": actor, "features": FEATURES, "meta": meta}, path)


class TorchPolicy:
    """The deterministic policy for `evaluate`: raw [roll, steer] of an observation."""

    def __init__(self, agent: Agent) -> None:
        self.agent = agent

    def __call__(self, obs, info=None) -> np.ndarray:
        with torch.no_grad():
            mean = self.agent.mean(torch.as_tensor(obs, dtype=torch.float32)[None])[0]
        return mean.clamp(-1, 1).numpy()


def scripted_policy(obs, info) -> np.ndarray:
    """The scripted controller (the reference): the option env's expert action."""
    return info["expert_action"]


# -- evaluation ----------------------------------------------------------------------------

def evaluate(policy, episodes: int, seed: int = HELDOUT_SEED, sources=HELDOUT_SOURCES,
             estimator: str = "oracle", t_abs: int = 150, progress: bool = False) -> dict:
    """Option success of ``policy(obs, info) -> raw action`` on ``episodes``
    fresh held-out scenes (each a new level, a random number of scripted
    subgoals in). Returns counts, the rate and its 95% Wilson interval."""
    env = BallOptionEnv(sources, estimator=estimator, t_abs=t_abs, p_continue=0.0, seed=seed)
    successes, steps, reasons = 0, [], {}
    obs, info = env.reset(seed=seed)
    it = range(episodes)
    if progress:
        from tqdm import tqdm
        it = tqdm(it, desc="eval", unit="option", leave=False)
    for _ in it:
        done = False
        while not done:
            obs, _, terminated, truncated, info = env.step(policy(obs, info))
            done = terminated or truncated
        successes += info["is_success"]
        if info["is_success"]:
            steps.append(info["steps"])
        else:
            kind = (info["reason"] or "cut off at t_abs").split(":", 1)[0]
            reasons[kind] = reasons.get(kind, 0) + 1
        obs, info = env.reset()
    env.close()
    low, high = wilson_interval(successes, episodes)
    return {"episodes": episodes, "successes": int(successes),
            "success": successes / episodes, "wilson_low": low, "wilson_high": high,
            "mean_steps_success": float(np.mean(steps)) if steps else None,
            "failures": reasons, "sources": list(sources), "estimator": estimator,
            "privileged": estimator == "oracle", "t_abs": t_abs, "seed": seed}


def print_table(rows: dict) -> None:
    print(f"{'policy':<26} {'options':>7} {'success':>8} {'95% Wilson':>17} {'steps':>6}  failures")
    for name, r in rows.items():
        steps = "-" if r["mean_steps_success"] is None else f"{r['mean_steps_success']:.0f}"
        fails = ", ".join(f"{k} {v}" for k, v in r["failures"].items())
        print(f"{name:<26} {r['episodes']:>7} {100 * r['success']:>7.1f}% "
              f"[{100 * r['wilson_low']:>5.1f}%, {100 * r['wilson_high']:>5.1f}%] {steps:>6}  "
              f"{fails}")


def evaluate_only(args) -> int:
    """``--evaluate``: a checkpoint against the scripted controller, same scenes."""
    from skills.learned.ball import POLICY_PATH, env_action, load_policy
    path = Path(args.evaluate) if args.evaluate else POLICY_PATH
    policy = load_policy(path)

    def learned(obs, info):
        return env_action(policy(obs), float(obs[SIGN]))

    t0, c0 = time.perf_counter(), time.process_time()
    print(f"evaluating {path} on {args.eval_episodes} held-out options "
          f"({', '.join(HELDOUT_SOURCES)}, seed {HELDOUT_SEED}, estimator {args.estimator}"
          f"{': privileged' if args.estimator == 'oracle' else ': observation-only'})")
    rows = {"learned (deterministic)": evaluate(learned, args.eval_episodes, t_abs=args.t_abs,
                                                estimator=args.estimator, progress=True),
            "scripted controller": evaluate(scripted_policy, args.eval_episodes,
                                            t_abs=args.t_abs, estimator=args.estimator,
                                            progress=True)}
    print_table(rows)
    if args.json:
        import torch as _torch
        meta = _torch.load(path, map_location="cpu", weights_only=True).get("meta", {})
        args.json.parent.mkdir(parents=True, exist_ok=True)
        from hier_agents.provenance import provenance
        root = Path(__file__).resolve().parents[1]
        shown = path.resolve()
        shown = shown.relative_to(root) if shown.is_relative_to(root) else shown
        args.json.write_text(json.dumps(
            {"policy": str(shown), "policy_meta": meta, "rows": rows,
             "wall_s": round(time.perf_counter() - t0, 1),
             "cpu_s": round(time.process_time() - c0, 1),
             "provenance": provenance()}, indent=2, default=str) + "\n")
        print(f"wrote {args.json}")
    return 0


# -- behaviour cloning warm start ----------------------------------------------------------

def collect(frames: int, seed: int, actor=None, noise: float = 0.2, t_abs: int = 150,
            p_continue: float = 0.7):
    """``frames`` steps of a `BallOptionEnv` driven by the scripted
    controller (``actor`` None) or by ``actor`` (an `Agent`'s mean), with
    Gaussian action noise; every observation labelled with the scripted
    action. Returns (observations, labels, simulated control steps)."""
    env = BallOptionEnv(seed=seed, t_abs=t_abs, p_continue=p_continue)
    rng = np.random.default_rng(seed + 1)
    xs, ys = [], []
    obs, info = env.reset(seed=seed)
    for _ in range(frames):
        xs.append(obs)
        ys.append(info["expert_action"])
        if actor is None:
            action = info["expert_action"]
        else:
            with torch.no_grad():
                action = actor.mean(torch.as_tensor(obs)[None])[0].numpy()
        action = np.clip(action + noise * rng.standard_normal(2), -1, 1)
        obs, _, terminated, truncated, info = env.step(action)
        if terminated or truncated:
            obs, info = env.reset()
    sim_steps = env.sim_steps
    env.close()
    return np.array(xs), np.array(ys), sim_steps


def behaviour_cloning(agent: Agent, frames: int, seed: int, dagger_frames: int = 0,
                      epochs: int = 60, log=print) -> tuple[int, int]:
    """Drives a `BallOptionEnv` with the noisy scripted controller for
    ``frames`` steps and regresses the actor's mean on its actions; then
    (DAgger, ``dagger_frames`` > 0) drives it with the cloned policy itself
    (options cut at 50 steps and continued, as the option layer does),
    labels those states with the scripted actions and refits on both.
    Returns (agent steps, simulated control steps)."""
    xs, ys, sim_steps = collect(frames, seed + 1)
    fit(agent, xs, ys, epochs, log)
    if dagger_frames > 0:
        log(f"DAgger: {dagger_frames} frames of the cloned policy, labelled by the scripted one")
        xd, yd, sim_d = collect(dagger_frames, seed + 3, actor=agent, noise=0.1, t_abs=50,
                                p_continue=0.9)
        fit(agent, np.concatenate([xs, xd]), np.concatenate([ys, yd]), epochs, log)
        sim_steps += sim_d
    return frames + dagger_frames, sim_steps


def fit(agent: Agent, xs, ys, epochs: int, log=print) -> None:
    """Regresses the actor's mean on the labels (mean squared error)."""
    x = torch.as_tensor(xs, dtype=torch.float32)
    y = torch.as_tensor(ys, dtype=torch.float32)
    opt = torch.optim.Adam(agent.actor.parameters(), lr=1e-3)
    n = len(x)
    for epoch in range(epochs):
        perm = torch.randperm(n)
        total = 0.0
        for k in range(0, n, 256):
            idx = perm[k:k + 256]
            loss = ((agent.mean(x[idx]) - y[idx]) ** 2).mean()
            opt.zero_grad()
            loss.backward()
            opt.step()
            total += loss.item() * len(idx)
        if epoch % 10 == 9 or epoch == epochs - 1:
            log(f"bc epoch {epoch + 1}/{epochs}: mse {total / n:.5f}")


# -- PPO ---------------------------------------------------------------------------------------

def make_env(seed: int, t_abs: int):
    def thunk():
        return BallOptionEnv(TRAIN_SOURCES, t_abs=t_abs, seed=seed)
    return thunk


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("skill", choices=["ball"], help="the skill family to train")
    parser.add_argument("--steps", type=int, help="training frames (agent steps: BC + PPO)")
    parser.add_argument("--logdir", type=Path)
    parser.add_argument("--evaluate", nargs="?", const="", metavar="PATH",
                        help="only evaluate this policy checkpoint (default: the shipped one)")
    parser.add_argument("--estimator", default="oracle", choices=["oracle", "camera"],
                        help="the scene estimate of --evaluate (training uses the oracle)")
    parser.add_argument("--json", type=Path, help="--evaluate: write the results here")
    parser.add_argument("--envs", type=int, default=2, help="vectorised environments")
    parser.add_argument("--async-envs", action="store_true",
                        help="one process per environment (AsyncVectorEnv)")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--resume", action="store_true", help="continue from DIR/checkpoint.pt")
    parser.add_argument("--bc-steps", type=int, default=20_000,
                        help="behaviour-cloning warm-start frames (0: PPO from scratch)")
    parser.add_argument("--dagger-steps", type=int, default=20_000,
                        help="DAgger frames after BC (the cloned policy's own states, "
                             "labelled by the scripted controller)")
    parser.add_argument("--rollout", type=int, default=256, help="steps per env per iteration")
    parser.add_argument("--lr", type=float, default=1e-4)
    parser.add_argument("--t-abs", type=int, default=150)
    parser.add_argument("--save-every", type=int, default=5, help="iterations between checkpoints")
    parser.add_argument("--eval-episodes", type=int, default=100)
    parser.add_argument("--eval-scripted", action="store_true",
                        help="also evaluate the scripted controller on the same scenes")
    args = parser.parse_args(argv)
    if args.evaluate is not None:
        return evaluate_only(args)
    if args.steps is None or args.logdir is None:
        parser.error("training needs --steps and --logdir")

    args.logdir.mkdir(parents=True, exist_ok=True)
    random.seed(args.seed)
    np.random.seed(args.seed)
    torch.manual_seed(args.seed)
    torch.set_num_threads(1)
    gamma, lam, clip, epochs, minibatches = 0.99, 0.95, 0.1, 5, 4
    vf_coef, max_grad_norm, critic_warmup = 0.5, 0.5, 3

    agent = Agent(log_std=-1.6 if args.bc_steps > 0 else -0.5)
    optimizer = torch.optim.Adam(agent.parameters(), lr=args.lr, eps=1e-5)
    state = {"iteration": 0, "frames": 0, "sim_steps": 0, "bc_frames": 0, "bc_sim_steps": 0,
             "wall_s": 0.0, "cpu_s": 0.0, "ppo_iterations_after_bc": 0}
    ckpt_path = args.logdir / "checkpoint.pt"
    if args.resume and ckpt_path.exists():
        ckpt = torch.load(ckpt_path, weights_only=False)
        agent.load_state_dict(ckpt["agent"])
        optimizer.load_state_dict(ckpt["optimizer"])
        state.update(ckpt["state"])
        torch.set_rng_state(ckpt["torch_rng"])
        np.random.set_state(ckpt["numpy_rng"])
        print(f"resumed from {ckpt_path}: iteration {state['iteration']}, "
              f"{state['frames']} frames")
    elif args.resume:
        print(f"no checkpoint at {ckpt_path}: starting afresh")

    try:
        from torch.utils.tensorboard import SummaryWriter
        writer = SummaryWriter(str(args.logdir))
    except ImportError:  # tensorboard not installed: the CSV only
        print("tensorboard is not installed: logging to progress.csv only")
        writer = None
    csv_path = args.logdir / "progress.csv"
    new_csv = not csv_path.exists() or not args.resume
    csv_file = open(csv_path, "w" if new_csv else "a", newline="")
    csv_out = csv.writer(csv_file)
    if new_csv:
        csv_out.writerow(["iteration", "frames", "sim_steps", "wall_s", "option_success",
                          "options", "mean_return", "policy_loss", "value_loss", "std"])

    def log_scalar(name, value, step):
        if writer is not None:
            writer.add_scalar(name, value, step)

    t_start, cpu_start = time.perf_counter(), time.process_time()
    wall0, cpu0 = state["wall_s"], state["cpu_s"]

    def clocks():
        state["wall_s"] = wall0 + time.perf_counter() - t_start
        state["cpu_s"] = cpu0 + time.process_time() - cpu_start

    def save_checkpoint():
        clocks()
        torch.save({"agent": agent.state_dict(), "optimizer": optimizer.state_dict(),
                    "state": state, "args": vars(args) | {"logdir": str(args.logdir)},
                    "torch_rng": torch.get_rng_state(), "numpy_rng": np.random.get_state()},
                   ckpt_path)
        export_policy(agent, args.logdir / "ball_policy.pt",
                      {"frames": state["frames"], "sim_steps": state["sim_steps"],
                       "bc_frames": state["bc_frames"], "seed": args.seed,
                       "iteration": state["iteration"], "trained_with": "hier_agents.learning.train_skill"})

    # 1. Behaviour-cloning warm start (once).
    if args.bc_steps > 0 and state["bc_frames"] == 0:
        print(f"behaviour cloning on {args.bc_steps} frames of the noisy scripted controller")
        frames, sim = behaviour_cloning(agent, args.bc_steps, args.seed,
                                        dagger_frames=args.dagger_steps)
        state.update(bc_frames=frames, bc_sim_steps=sim, frames=frames, sim_steps=sim)
        save_checkpoint()

    # 2. PPO.
    n_envs, n_steps = args.envs, args.rollout
    vector = gymnasium.vector.AsyncVectorEnv if args.async_envs else \
        gymnasium.vector.SyncVectorEnv
    base_seed = args.seed * 1000 + 100 + state["iteration"]
    envs = vector([make_env(base_seed + k, args.t_abs) for k in range(n_envs)],
                  autoreset_mode=gymnasium.vector.AutoresetMode.SAME_STEP)
    obs_buf = torch.zeros((n_steps, n_envs, OBS_DIM))
    act_buf = torch.zeros((n_steps, n_envs, 2))
    logp_buf = torch.zeros((n_steps, n_envs))
    rew_buf = torch.zeros((n_steps, n_envs))
    done_buf = torch.zeros((n_steps, n_envs))  # the episode ended at this step
    val_buf = torch.zeros((n_steps, n_envs))
    boot_buf = torch.zeros((n_steps, n_envs))  # value of a truncated episode's final obs

    obs_np, _ = envs.reset(seed=base_seed)
    obs = torch.as_tensor(obs_np, dtype=torch.float32)
    sim_at_start = np.zeros(n_envs)
    sim_now = np.zeros(n_envs)
    recent, returns, ep_return = [], [], np.zeros(n_envs)
    iterations = max(0, math.ceil((args.steps - state["frames"]) / (n_envs * n_steps)))

    from tqdm import tqdm
    bar = tqdm(total=args.steps, initial=min(state["frames"], args.steps), unit="frame",
               desc="ppo", dynamic_ncols=True, file=sys.stdout, mininterval=5)
    for _ in range(iterations):
        # Rollout.
        for t in range(n_steps):
            with torch.no_grad():
                dist = agent.dist(obs)
                action = dist.sample()
                logp = dist.log_prob(action).sum(-1)
                value = agent.value(obs)
            obs_np, reward, terminated, truncated, info = envs.step(action.numpy())
            obs_buf[t], act_buf[t], logp_buf[t], val_buf[t] = obs, action, logp, value
            rew_buf[t] = torch.as_tensor(reward, dtype=torch.float32)
            done = np.logical_or(terminated, truncated)
            done_buf[t] = torch.as_tensor(done, dtype=torch.float32)
            boot_buf[t] = 0.0
            ep_return += reward
            sim_now = np.asarray(info["sim_steps"], float)
            if done.any():
                final_info, final_obs = info["final_info"], info["final_obs"]
                for k in np.nonzero(done)[0]:
                    recent.append(bool(final_info["is_success"][k]))
                    returns.append(ep_return[k])
                    ep_return[k] = 0.0
                    if truncated[k] and not terminated[k]:
                        with torch.no_grad():
                            last = torch.as_tensor(final_obs[k], dtype=torch.float32)[None]
                            boot_buf[t, k] = agent.value(last)[0]
                recent, returns = recent[-100:], returns[-100:]
            obs = torch.as_tensor(obs_np, dtype=torch.float32)
        state["frames"] += n_envs * n_steps
        state["sim_steps"] += int((sim_now - sim_at_start).sum())
        sim_at_start = sim_now.copy()

        # Generalised advantage estimation (truncations bootstrap from the critic).
        with torch.no_grad():
            next_value = agent.value(obs)
        advantages = torch.zeros_like(rew_buf)
        gae = torch.zeros(n_envs)
        for t in reversed(range(n_steps)):
            following = next_value if t == n_steps - 1 else val_buf[t + 1]
            not_done = 1.0 - done_buf[t]
            target = rew_buf[t] + gamma * (following * not_done + boot_buf[t])
            delta = target - val_buf[t]
            gae = delta + gamma * lam * not_done * gae
            advantages[t] = gae
        returns_buf = advantages + val_buf

        # Clipped-surrogate updates.
        b_obs, b_act = obs_buf.reshape(-1, OBS_DIM), act_buf.reshape(-1, 2)
        b_logp, b_adv, b_ret = logp_buf.reshape(-1), advantages.reshape(-1), returns_buf.reshape(-1)
        train_actor = args.bc_steps == 0 or state["ppo_iterations_after_bc"] >= critic_warmup
        batch = len(b_obs)
        mb = batch // minibatches
        for _ in range(epochs):
            perm = torch.randperm(batch)
            for k in range(0, batch, mb):
                idx = perm[k:k + mb]
                dist = agent.dist(b_obs[idx])
                logp = dist.log_prob(b_act[idx]).sum(-1)
                ratio = (logp - b_logp[idx]).exp()
                adv = b_adv[idx]
                adv = (adv - adv.mean()) / (adv.std() + 1e-8)
                policy_loss = torch.max(-adv * ratio,
                                        -adv * ratio.clamp(1 - clip, 1 + clip)).mean()
                value_loss = 0.5 * ((agent.value(b_obs[idx]) - b_ret[idx]) ** 2).mean()
                loss = vf_coef * value_loss + (policy_loss if train_actor else 0.0)
                optimizer.zero_grad()
                loss.backward()
                if not train_actor:  # critic warm-up: the actor and its std stay put
                    agent.log_std.grad = None
                    for p in agent.actor.parameters():
                        p.grad = None
                nn.utils.clip_grad_norm_(agent.parameters(), max_grad_norm)
                optimizer.step()
        state["iteration"] += 1
        state["ppo_iterations_after_bc"] += 1

        # Logging, checkpoints.
        clocks()
        success = float(np.mean(recent)) if recent else float("nan")
        mean_ret = float(np.mean(returns)) if returns else float("nan")
        std = agent.log_std.exp().mean().item()
        step = state["frames"]
        for name, value in (("charts/option_success", success), ("charts/mean_return", mean_ret),
                            ("losses/policy", policy_loss.item()),
                            ("losses/value", value_loss.item()), ("charts/std", std),
                            ("charts/sim_steps", state["sim_steps"]),
                            ("charts/frames_per_s", step / max(state["wall_s"], 1e-9))):
            log_scalar(name, value, step)
        csv_out.writerow([state["iteration"], step, state["sim_steps"], round(state["wall_s"], 1),
                          round(success, 4), len(recent), round(mean_ret, 4),
                          round(policy_loss.item(), 5), round(value_loss.item(), 5),
                          round(std, 4)])
        csv_file.flush()
        bar.update(min(n_envs * n_steps, args.steps - bar.n))
        bar.set_postfix(success=f"{success:.2f}", ret=f"{mean_ret:.2f}", std=f"{std:.2f}")
        if state["iteration"] % args.save_every == 0:
            save_checkpoint()
    bar.close()
    envs.close()
    save_checkpoint()

    # 3. Evaluation on held-out scenes.
    print(f"evaluating on {args.eval_episodes} held-out options "
          f"({', '.join(HELDOUT_SOURCES)}, seed {HELDOUT_SEED}, oracle estimator: privileged)")
    rows = {"learned (deterministic)": evaluate(TorchPolicy(agent), args.eval_episodes,
                                                t_abs=args.t_abs, progress=True)}
    if args.eval_scripted:
        rows["scripted controller"] = evaluate(scripted_policy, args.eval_episodes,
                                               t_abs=args.t_abs, progress=True)
    print_table(rows)
    clocks()
    summary = {"skill": args.skill, "seed": args.seed, "envs": n_envs,
               "frames": state["frames"], "bc_frames": state["bc_frames"],
               "ppo_frames": state["frames"] - state["bc_frames"],
               "sim_steps": state["sim_steps"], "iterations": state["iteration"],
               "wall_s": round(state["wall_s"], 1), "cpu_s": round(state["cpu_s"], 1),
               "eval": rows, "policy": str(args.logdir / "ball_policy.pt"),
               "torch": torch.__version__, "pid": os.getpid()}
    (args.logdir / "summary.json").write_text(json.dumps(summary, indent=2) + "\n")
    if writer is not None:
        writer.add_scalar("eval/option_success", rows["learned (deterministic)"]["success"],
                          state["frames"])
        writer.close()
    csv_file.close()
    print(f"summary: {args.logdir / 'summary.json'}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
