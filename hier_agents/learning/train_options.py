"""Train a policy over options with PPO on `OptionEnv`; play it as a planner.

    python -m hier_agents.learning.train_options ENV[,ENV...] --steps N --logdir DIR
        [--envs K] [--seed S] [--resume] [--skill learned-ball] [--estimator camera]
        [--cpu-minutes M] [--abstract-steps A] [--eval-episodes E] ...
    python -m hier_agents.run mujoban/level2 --planner learned:DIR/option_policy.pt

One environment step is one *option* (`hier_agents.learning.option_env.OptionEnv`): a
Sokoban move ``U``/``D``/``L``/``R`` that the ball skill carries out in MuJoCo
(walk one cell, or push a box one cell) until it succeeds, fails or ``t_abs``
= 50 control steps pass; the observation is the estimator's abstract state
(the default ``camera`` estimator: observation-only). Written top to bottom,
in the CleanRL spirit:

* **Environments**: ``--envs`` (default 2) copies of `OptionEnv` in a
  gymnasium ``AsyncVectorEnv`` (one process each, torch on one thread,
  same-step autoreset). ``ENV`` may list several environments separated by
  commas; they are dealt to the copies in turn (``mujoban/level1,
  mujoban/level2`` with 2 copies: one of each; that is the curriculum of
  the shipped policy: both levels at once, no schedule). Training
  environments are seeded from ``1000 * (seed + 1)`` (plus the update
  count on ``--resume``), so their levels are not those of the evaluation
  runs (``hier_agents.run`` seeds 0 and the held-out 10000).
* **Policy** (`abstract_planners.learned_options.OptionPolicyNet`): a small
  CNN over the planes re-centred on the player (a 13x13 egocentric crop, a
  fifth plane "box on pad"), a policy head over the 4 moves with
  **invalid-action masking** (``info["action_mask"]``: illegal moves get
  logit -1e8, so they are never sampled and get no gradient), a value head.
* **Semi-MDP returns**: an option that took ``d`` control steps
  (``info["duration"]``) discounts what follows it by ``gamma ** d``
  (``--gamma`` per control step, default 0.995, also the discount
  `OptionEnv` applies inside the option). GAE(lambda=0.95) uses the same
  per-step factor: ``delta_t = r_t + gamma^d_t V(s_t+1) - V(s_t)``,
  ``A_t = delta_t + gamma^d_t lambda A_t+1``. Truncated episodes (the
  900-step time limit) bootstrap from the critic on their final state.
* **Reward** = the environment's (via OptionEnv: +1 when a box comes onto a
  pad, -1 when one leaves, +10 when the level is solved) **plus potential-
  based shaping** (Ng et al. 1999, in its semi-MDP form, which leaves the
  optimal policy unchanged): ``F = gamma^d Phi(s') - Phi(s)`` with
  ``Phi(s) = -(--shape-box * sum over boxes off pads of the box's distance
  to the nearest pad + --shape-player * the player's walking distance to a
  cell next to a box off its pad)`` (defaults 1.0 and 0.1; ``Phi`` of a
  solved state is 0, and of a terminal state 0). The box distance
  (``--box-distance``) is by default the **walking** distance around walls
  (``walk``); ``push`` counts the pushes that would bring the box alone onto
  a pad (a reverse search from the pads), so that a push onto a dead cell (a
  corner, a wall without a pad) costs about -20 at once. ``push`` was tried
  to teach deadlock avoidance and learned *slower* (level-2 greedy solve
  rate on abstract levels after 150k steps: 53% against 81% with ``walk``;
  ``results/option_policy/README.md``). Computed in the
  environment worker from the estimated abstract state (``info["potential"]``).
* **PPO**: rollouts of ``--rollout`` (default 64) options per copy, 4 epochs
  of 4 minibatches, clip 0.2, Adam 5e-4 (linearly decayed over the phase's
  steps: ``--abstract-steps`` or ``--steps``), entropy 0.01, value 0.5,
  gradient norm 0.5, advantages normalised per minibatch.
* **Optional abstract warm start** (``--abstract-steps A``, default 0: off):
  before any physics, PPO runs the same network for ``A`` option steps on
  `AbstractOptionEnv`, the same levels generated without MuJoCo (the
  planners' own Sokoban model, `abstract_planners.sokoban.SokobanState`;
  the environment's rewards; every option assumed to last
  ``--abstract-duration`` = 18 control steps, the measured mean, and the
  900-step limit as 50 options). Its CPU time counts in the budget; its
  steps are counted apart (``abstract_steps``) and are **not** control
  frames: no physics ran. It is a documented curriculum stage, reported
  separately from pure-OptionEnv training.

**The shipped policy** (``--planner learned``, ``abstract_planners/learned/
options.pt``, 366 KB; figures in ``results/option_policy/``) is approach "D":
400,384 abstract warm-start steps, then 4,096 OptionEnv option steps (86,264
control frames, camera estimator, learned ball skill), 15.9 CPU minutes in
all, one command::

    python -m hier_agents.learning.train_options mujoban/level1,mujoban/level2 --abstract-steps 400000 \
        --steps 4000 --cpu-minutes 55 --envs 2 --seed 1 --skill learned-ball --eval-episodes 0 \
        --logdir runs/options_D

It is the learned policy alone (no ``prune_dead_pushes``). Approach "B"
(150,528 abstract steps, 6,912 OptionEnv steps) needed the hand-written
dead-push rule at play time to pass 85% on level 2; its figures are kept in
``results/option_policy/approach_B/``.

Budget and counts, in ``DIR/checkpoint.pt`` and ``DIR/summary.json``:
option steps on OptionEnv, **control frames** (the sum of the options'
durations: environment frames, the figure equal-budget comparisons use),
abstract steps, CPU seconds of this process and of its environment workers
(user + system, read from ``/proc`` while they run; ``resource.getrusage``
of the children at the end as a check), wall seconds, the skill (for
``learned-ball`` also its own training frames from its checkpoint's
metadata), the seed and the command. ``--cpu-minutes M`` stops training
once M CPU minutes (all processes, the abstract stage included) are spent.

Logs: a tqdm bar (solved rate of the last 100 episodes); TensorBoard scalars
in ``DIR`` and the same in ``DIR/progress.csv``. Checkpoints every
``--save-every`` updates and at the end: ``DIR/checkpoint.pt`` (to
``--resume``: network, optimiser, counters, random states) and
``DIR/option_policy.pt`` (the planner's file, ~360 KB). Evaluation at the
end (``--eval-episodes``, default 100 per environment, 0 to skip): the
greedy policy as the planner of the modular agent (`hier_agents.run`,
held-out seed 10000, same skill and estimator), solved rate with a 95%
Wilson interval, in ``summary.json``.
"""

from __future__ import annotations

import argparse
import csv
import json
import math
import os
import random
import resource
import shlex
import sys
import time
from collections import deque
from pathlib import Path

import gymnasium as gym
import numpy as np
import torch
from torch import nn

from abstract_planners.learned_options import (OptionPolicyNet, policy_input,
                                               save_option_policy)
from abstract_planners.sokoban import MOVES, SokobanState
from hier_agents.stats import wilson_interval

#: Seed of the end-of-training evaluation (hier_agents.run seeds its environment with it).
HELDOUT_SEED = 10_000
#: Control steps per option assumed by the abstract warm start (measured mean, level 1-2).
ABSTRACT_DURATION = 18
#: The MuJoBan time limit in control steps (45 s of 0.05 s).
TIME_LIMIT_STEPS = 900


# -- shaping potential ------------------------------------------------------------------------

_STEPS = ((-1, 0), (1, 0), (0, -1), (0, 1))


def _bfs(starts, free) -> dict:
    """Walking distances from ``starts`` over the cells for which ``free(cell)``."""
    dist = {cell: 0 for cell in starts}
    frontier = list(starts)
    while frontier:
        nxt = []
        for r, c in frontier:
            for dr, dc in _STEPS:
                cell = (r + dr, c + dc)
                if cell not in dist and free(cell):
                    dist[cell] = dist[(r, c)] + 1
                    nxt.append(cell)
        frontier = nxt
    return dist


_PAD_DISTANCES: dict = {}


def _push_distances(state: SokobanState, floor) -> dict:
    """Pushes needed to bring a lone box from each cell onto the nearest pad
    (other boxes ignored): a reverse search from the pads, a box at ``p``
    reaching ``p + d`` with the player at ``p - d``. Cells missing from the
    result are dead: no pad can be reached from them."""
    dist = {cell: 0 for cell in state.targets}
    frontier = list(state.targets)
    while frontier:
        nxt = []
        for r, c in frontier:
            for dr, dc in _STEPS:
                before, player = (r - dr, c - dc), (r - 2 * dr, c - 2 * dc)
                if before not in dist and floor(before) and floor(player):
                    dist[before] = dist[(r, c)] + 1
                    nxt.append(before)
        frontier = nxt
    return dist


def potential(state: SokobanState, box_weight: float, player_weight: float,
              box_distance: str = "push") -> float:
    """Phi(s) of the module docstring (0 for a solved state)."""
    loose = state.boxes - state.targets
    if not loose:
        return 0.0
    height, width = state.height, state.width

    def floor(cell):
        return cell not in state.walls and 0 <= cell[0] < height and 0 <= cell[1] < width

    key = (state.walls, state.targets, box_distance)
    to_pad = _PAD_DISTANCES.get(key)
    if to_pad is None:
        if len(_PAD_DISTANCES) > 4096:
            _PAD_DISTANCES.clear()
        to_pad = _PAD_DISTANCES[key] = (_push_distances(state, floor) if box_distance == "push"
                                        else _bfs(state.targets, floor))
    far = height + width
    box_term = sum(to_pad.get(box, far) for box in loose)
    player_term = 0.0
    if player_weight:
        beside = {(r + dr, c + dc) for r, c in loose for dr, dc in _STEPS}
        walk = _bfs([state.player], lambda cell: floor(cell) and cell not in state.boxes)
        player_term = min((walk[c] for c in beside if c in walk), default=far)
    return -(box_weight * box_term + player_weight * player_term)


class Shaped(gym.Wrapper):
    """Adds ``info["potential"]`` (Phi of the estimated abstract state)."""

    def __init__(self, env, box_weight: float, player_weight: float, box_distance: str = "push"):
        super().__init__(env)
        self.weights = (float(box_weight), float(player_weight), box_distance)

    def _with_potential(self, info):
        info["potential"] = potential(self.env.unwrapped.abstract_state, *self.weights)
        return info

    def reset(self, **kwargs):
        obs, info = self.env.reset(**kwargs)
        return obs, self._with_potential(info)

    def step(self, action):
        obs, reward, terminated, truncated, info = self.env.step(action)
        return obs, reward, terminated, truncated, self._with_potential(info)


# -- the abstract warm-start environment ---------------------------------------------------

def difficulty_of(env_name: str) -> int:
    """``mujoban/level2`` (or ``-pegs``) -> 2."""
    tail = env_name.split("/", 1)[-1]
    if not tail.startswith("level"):
        raise ValueError(f"the abstract warm start needs generated levels "
                         f"(mujoban/levelN), got {env_name!r}")
    return int(tail[len("level"):].split("-")[0])


class AbstractOptionEnv(gym.Env):
    """`OptionEnv`'s interface without physics: generated levels of one
    difficulty padded into the 10x10 arena as MuJoBan pads them, moves applied
    by `SokobanState`, MuJoBan's rewards, every option lasting ``duration``
    control steps (see the module docstring)."""

    metadata = {"render_modes": []}

    def __init__(self, env_name: str, seed: int, duration: int = ABSTRACT_DURATION,
                 gamma: float = 0.995):
        from envs.mujoban.sources import ARENA_SHAPE
        self.difficulty = difficulty_of(env_name)
        self.shape = ARENA_SHAPE
        self.duration, self.gamma = int(duration), float(gamma)
        self.max_options = TIME_LIMIT_STEPS // self.duration
        self.rng = np.random.default_rng(seed)
        self.action_space = gym.spaces.Discrete(len(MOVES))
        self.observation_space = gym.spaces.Box(0.0, 1.0, (4, *self.shape), np.float32)
        self.abstract_state = None

    def reset(self, *, seed=None, options=None):
        from envs.mujoban import generator
        super().reset(seed=seed)
        if seed is not None:
            self.rng = np.random.default_rng(seed)
        level = generator.generate_level(self.difficulty, rng=self.rng).padded(*self.shape)
        self.abstract_state = SokobanState.from_level(level)
        self.options = 0
        return self._obs(), self._info(0)

    def step(self, action):
        state, move = self.abstract_state, MOVES[int(action)]
        if not state.is_legal(move):
            raise ValueError(f"illegal move {move!r} (the trainer masks them)")
        new = state.apply(move)
        on = len(new.boxes & new.targets) - len(state.boxes & state.targets)
        solved = new.is_solved()
        # The reward arrives at the option's last control step.
        reward = (self.gamma ** (self.duration - 1)) * (on + (10.0 if solved else 0.0))
        self.abstract_state = new
        self.options += 1
        truncated = not solved and self.options >= self.max_options
        return self._obs(), float(reward), bool(solved), bool(truncated), \
            self._info(self.duration)

    def _obs(self):
        from hier_agents.learning.option_env import encode_sokoban
        return encode_sokoban(self.abstract_state, self.shape)

    def _info(self, duration):
        state = self.abstract_state
        return {"duration": duration,
                "action_mask": np.array([state.is_legal(m) for m in MOVES], np.int8)}


# -- environments ------------------------------------------------------------------------------

def make_option_env(env_name: str, seed: int, args):
    def thunk():
        torch.set_num_threads(1)
        from hier_agents.learning.option_env import OptionEnv
        env = OptionEnv(env_name, skill=args.skill, estimator=args.estimator, seed=seed,
                        gamma=args.gamma, t_abs=args.t_abs)
        return Shaped(env, args.shape_box, args.shape_player, args.box_distance)
    return thunk


def make_abstract_env(env_name: str, seed: int, args):
    def thunk():
        env = AbstractOptionEnv(env_name, seed, args.abstract_duration, args.gamma)
        return Shaped(env, args.shape_box, args.shape_player, args.box_distance)
    return thunk


class WorkerClock:
    """CPU seconds (user + system) of live worker processes, from /proc."""

    def __init__(self, pids):
        self.pids = list(pids)
        self.tick = os.sysconf("SC_CLK_TCK")
        self.last = {pid: 0.0 for pid in self.pids}

    def seconds(self) -> float:
        for pid in self.pids:
            try:
                with open(f"/proc/{pid}/stat") as f:
                    fields = f.read().rsplit(")", 1)[1].split()
                self.last[pid] = (int(fields[11]) + int(fields[12])) / self.tick
            except (OSError, IndexError, ValueError):
                pass  # exited: keep its last reading
        return sum(self.last.values())


def numpy_rng_state() -> dict:
    """NumPy's global random state in tensors (loadable with ``weights_only=True``)."""
    name, keys, pos, has_gauss, cached = np.random.get_state()
    return {"keys": torch.as_tensor(keys.astype(np.int64)), "pos": int(pos),
            "has_gauss": int(has_gauss), "cached": float(cached)}


def set_numpy_rng_state(saved) -> None:
    if not isinstance(saved, dict):  # np.random.get_state() itself
        np.random.set_state(saved)
        return
    np.random.set_state(("MT19937", saved["keys"].numpy().astype(np.uint32), saved["pos"],
                         saved["has_gauss"], saved["cached"]))


def skill_record(skill: str | None) -> dict:
    """The skill's name and, for learned-ball, its checkpoint's training counts."""
    record = {"name": skill or "ball"}
    if skill == "learned-ball":
        try:
            from skills.learned.ball import POLICY_PATH
            meta = torch.load(POLICY_PATH, map_location="cpu", weights_only=True).get("meta", {})
            record.update(checkpoint=str(POLICY_PATH), training_frames=meta.get("frames"),
                          training_sim_steps=meta.get("sim_steps"), meta=meta)
        except Exception as exc:  # noqa: BLE001 - a record, not a requirement
            record["meta_error"] = str(exc)
    return record


# -- PPO ---------------------------------------------------------------------------------------

def ppo_update(net, optimizer, batch, args) -> dict:
    """Clipped-surrogate epochs over one rollout; returns mean losses."""
    n = batch["obs"].shape[0]
    size = max(1, n // args.minibatches)
    stats = {"policy_loss": [], "value_loss": [], "entropy": [], "approx_kl": [],
             "clip_frac": []}
    for _ in range(args.epochs):
        order = torch.randperm(n)
        for start in range(0, n, size):
            idx = order[start:start + size]
            logits, value = net(batch["obs"][idx], batch["mask"][idx])
            dist = torch.distributions.Categorical(logits=logits)
            logp = dist.log_prob(batch["actions"][idx])
            ratio = (logp - batch["logp"][idx]).exp()
            adv = batch["adv"][idx]
            adv = (adv - adv.mean()) / (adv.std() + 1e-8) if len(idx) > 1 else adv
            policy_loss = torch.max(-adv * ratio,
                                    -adv * ratio.clamp(1 - args.clip, 1 + args.clip)).mean()
            value_loss = 0.5 * (value - batch["returns"][idx]).pow(2).mean()
            # Entropy over the legal moves only (masked logits have ~0 probability).
            probs = dist.probs
            entropy = -(probs * torch.log(probs.clamp_min(1e-12))).sum(-1).mean()
            loss = policy_loss + args.vf_coef * value_loss - args.ent_coef * entropy
            optimizer.zero_grad()
            loss.backward()
            nn.utils.clip_grad_norm_(net.parameters(), args.max_grad_norm)
            optimizer.step()
            with torch.no_grad():
                stats["policy_loss"].append(policy_loss.item())
                stats["value_loss"].append(value_loss.item())
                stats["entropy"].append(entropy.item())
                stats["approx_kl"].append(((ratio - 1) - ratio.log()).mean().item())
                stats["clip_frac"].append(((ratio - 1).abs() > args.clip).float().mean().item())
    return {k: float(np.mean(v)) for k, v in stats.items()}


def gae(rewards, values, discounts, dones, next_value, lam):
    """Semi-MDP GAE: ``discounts[t] = gamma ** duration_t``; ``dones[t]`` cuts
    the recursion (a truncated episode's bootstrap is already in its reward)."""
    steps = rewards.shape[0]
    adv = torch.zeros_like(rewards)
    running = torch.zeros_like(next_value)
    for t in reversed(range(steps)):
        following = next_value if t == steps - 1 else values[t + 1]
        live = 1.0 - dones[t]
        delta = rewards[t] + discounts[t] * following * live - values[t]
        running = delta + discounts[t] * lam * live * running
        adv[t] = running
    return adv, adv + values


def run_phase(phase, vec, names, net, optimizer, state, args, *, target, writer, csv_out,
              cpu_now, save, radius):
    """PPO on the vector env ``vec`` until ``state[phase count] >= target`` or the
    CPU budget is spent. ``phase`` is ``"abstract"`` or ``"options"``."""
    from tqdm import tqdm
    n_envs, n_steps = vec.num_envs, args.rollout
    count_key = "abstract_steps" if phase == "abstract" else "option_steps"
    obs_np, info = vec.reset(seed=state["env_seed"] + 7919 * state["updates"])
    pot = np.asarray(info["potential"], np.float64)
    mask = np.asarray(info["action_mask"], np.float32)
    recent = {name: deque(maxlen=100) for name in set(names)}
    lengths = deque(maxlen=100)
    ep_len = np.zeros(n_envs, int)
    bar = tqdm(total=target, initial=min(state[count_key], target), unit="option",
               desc=phase, dynamic_ncols=True, file=sys.stderr, mininterval=2)
    budget = args.cpu_minutes * 60 if args.cpu_minutes else math.inf
    lr0 = args.lr
    while state[count_key] < target and cpu_now() < budget:
        frac = 1.0 - state[count_key] / max(target, 1)
        for group in optimizer.param_groups:
            group["lr"] = lr0 * max(frac, 0.05) if args.anneal_lr else lr0
        buf = {k: [] for k in ("obs", "mask", "actions", "logp", "values", "rewards",
                               "discounts", "dones")}
        frames = 0
        for _ in range(n_steps):
            x = torch.as_tensor(policy_input(obs_np, radius))
            m = torch.as_tensor(mask)
            with torch.no_grad():
                logits, value = net(x, m)
                dist = torch.distributions.Categorical(logits=logits)
                action = dist.sample()
            obs_np, reward, terminated, truncated, info = vec.step(action.numpy())
            done = np.logical_or(terminated, truncated)
            duration = np.asarray(info["duration"], np.float64)
            new_pot = np.asarray(info["potential"], np.float64)
            if done.any():  # same-step autoreset: the ended step's info is in final_info
                final = info["final_info"]
                for k in np.flatnonzero(done):
                    duration[k] = final["duration"][k]
                    new_pot[k] = final["potential"][k]
            discount = args.gamma ** duration
            shaped = reward + discount * np.where(terminated, 0.0, new_pot) - pot
            if truncated.any():
                for k in np.flatnonzero(truncated & ~terminated):
                    last = policy_input(info["final_obs"][k][None], radius)
                    last_mask = torch.as_tensor(
                        np.asarray(info["final_info"]["action_mask"][k], np.float32)[None])
                    with torch.no_grad():
                        shaped[k] += discount[k] * net(torch.as_tensor(last), last_mask)[1][0]
            buf["obs"].append(x)
            buf["mask"].append(m)
            buf["actions"].append(action)
            buf["logp"].append(dist.log_prob(action))
            buf["values"].append(value)
            buf["rewards"].append(torch.as_tensor(shaped, dtype=torch.float32))
            buf["discounts"].append(torch.as_tensor(discount, dtype=torch.float32))
            buf["dones"].append(torch.as_tensor(done, dtype=torch.float32))
            frames += int(duration.sum())
            ep_len += 1
            for k in np.flatnonzero(done):
                recent[names[k]].append(bool(terminated[k]))
                lengths.append(int(ep_len[k]))
                ep_len[k] = 0
                state["episodes"] += 1
                state["solved"] += int(terminated[k])
            pot = np.asarray(info["potential"], np.float64)
            mask = np.asarray(info["action_mask"], np.float32)
        state[count_key] += n_envs * n_steps
        if phase == "options":
            state["control_frames"] += frames
        with torch.no_grad():
            _, next_value = net(torch.as_tensor(policy_input(obs_np, radius)),
                                torch.as_tensor(mask))
        rewards = torch.stack(buf["rewards"])
        values = torch.stack(buf["values"])
        adv, returns = gae(rewards, values, torch.stack(buf["discounts"]),
                           torch.stack(buf["dones"]), next_value, args.lam)
        batch = {"obs": torch.cat(buf["obs"]), "mask": torch.cat(buf["mask"]),
                 "actions": torch.cat(buf["actions"]), "logp": torch.cat(buf["logp"]),
                 "adv": adv.reshape(-1), "returns": returns.reshape(-1)}
        losses = ppo_update(net, optimizer, batch, args)
        state["updates"] += 1
        state["cpu_s"] = cpu_now()
        solved = {name: (float(np.mean(r)) if r else float("nan")) for name, r in recent.items()}
        row = {"phase": phase, "update": state["updates"], "option_steps": state["option_steps"],
               "abstract_steps": state["abstract_steps"],
               "control_frames": state["control_frames"], "cpu_s": round(state["cpu_s"], 1),
               "episodes": state["episodes"],
               "mean_episode_options": float(np.mean(lengths)) if lengths else float("nan"),
               "mean_shaped_reward": float(rewards.mean()), **losses,
               **{f"solved/{name}": v for name, v in solved.items()}}
        step = state["abstract_steps"] + state["option_steps"]
        if writer is not None:
            for key, value in row.items():
                if key not in ("phase", "update") and isinstance(value, (int, float)):
                    writer.add_scalar(f"{phase}/{key}", value, step)
        csv_out(row)
        bar.update(n_envs * n_steps)
        bar.set_postfix({name.split("/")[-1]: f"{v:.2f}" for name, v in solved.items()}
                        | {"cpu_min": f"{state['cpu_s'] / 60:.1f}"})
        if state["updates"] % args.save_every == 0:
            save()
    bar.close()
    state["last_solved"] = {name: (float(np.mean(r)) if r else None)
                            for name, r in recent.items()}


# -- evaluation --------------------------------------------------------------------------------

def evaluate(policy_path: Path, env_names, episodes: int, args) -> dict:
    """The greedy policy as the modular agent's planner, ``episodes`` held-out
    episodes per environment (`hier_agents.run`)."""
    from hier_agents.run import run
    out = {}
    for name in env_names:
        c0, t0 = time.process_time(), time.perf_counter()
        summary = run(name, episodes, HELDOUT_SEED, planner=f"learned:{policy_path}",
                      skill=args.skill, estimator=args.estimator, progress=True)
        solved = sum(r["solved"] for r in summary["rows"])
        low, high = wilson_interval(solved, episodes)
        out[name] = {"episodes": episodes, "solved": solved, "success_rate": solved / episodes,
                     "wilson_95": [low, high], "mean_steps": summary["mean_steps"],
                     "subgoal_success_rate": summary["subgoal_success_rate"],
                     "episode_failures": summary["episode_failures"], "seed": HELDOUT_SEED,
                     "cpu_s": round(time.process_time() - c0, 1),
                     "wall_s": round(time.perf_counter() - t0, 1)}
        print(f"{name}: solved {solved}/{episodes} = {100 * solved / episodes:.1f}% "
              f"[{100 * low:.1f}, {100 * high:.1f}] (95% Wilson), held-out seed {HELDOUT_SEED}")
    return out


# -- main --------------------------------------------------------------------------------------

def parse_args(argv=None):
    p = argparse.ArgumentParser(prog="python -m hier_agents.learning.train_options",
                                description=__doc__.split("\n\n")[0],
                                formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("env", help="environment(s), comma-separated (e.g. mujoban/level1,"
                               "mujoban/level2), dealt to the copies in turn")
    p.add_argument("--steps", type=int, required=True, help="option steps on OptionEnv")
    p.add_argument("--logdir", type=Path, required=True)
    p.add_argument("--envs", type=int, default=2, help="environment copies (processes)")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--resume", action="store_true", help="continue from DIR/checkpoint.pt")
    p.add_argument("--skill", default="learned-ball", help="skill name (default learned-ball)")
    p.add_argument("--estimator", default=None, help="estimator name (default camera)")
    p.add_argument("--cpu-minutes", type=float, default=None,
                   help="stop training after this many CPU minutes (all processes)")
    p.add_argument("--sync", action="store_true", help="SyncVectorEnv (one process; tests)")
    p.add_argument("--abstract-steps", type=int, default=0,
                   help="option steps of the abstract warm start (no physics; default 0)")
    p.add_argument("--abstract-envs", type=int, default=16)
    p.add_argument("--abstract-duration", type=int, default=ABSTRACT_DURATION)
    p.add_argument("--rollout", type=int, default=64, help="options per copy per update")
    p.add_argument("--epochs", type=int, default=4)
    p.add_argument("--minibatches", type=int, default=4)
    p.add_argument("--lr", type=float, default=5e-4)
    p.add_argument("--no-anneal-lr", dest="anneal_lr", action="store_false")
    p.add_argument("--gamma", type=float, default=0.995, help="discount per control step")
    p.add_argument("--lam", type=float, default=0.95)
    p.add_argument("--clip", type=float, default=0.2)
    p.add_argument("--ent-coef", type=float, default=0.01)
    p.add_argument("--vf-coef", type=float, default=0.5)
    p.add_argument("--max-grad-norm", type=float, default=0.5)
    p.add_argument("--shape-box", type=float, default=1.0)
    p.add_argument("--shape-player", type=float, default=0.1)
    p.add_argument("--box-distance", choices=("walk", "push"), default="walk",
                   help="shaping's box-to-pad distance: pushes (dead cells far) or walking")
    p.add_argument("--t-abs", type=int, default=50)
    p.add_argument("--radius", type=int, default=6, help="egocentric crop radius (cells)")
    p.add_argument("--hidden", type=int, default=128)
    p.add_argument("--save-every", type=int, default=10, help="updates between checkpoints")
    p.add_argument("--eval-episodes", type=int, default=100, help="per environment; 0: skip")
    args = p.parse_args(argv)
    if args.envs < 1 or args.rollout < 1 or args.steps < 0 or args.abstract_steps < 0:
        p.error("--envs and --rollout must be >= 1, --steps and --abstract-steps >= 0")
    return args


def main(argv=None) -> int:
    args = parse_args(argv)
    torch.set_num_threads(1)
    names = [n.strip() for n in args.env.split(",") if n.strip()]
    import envs as envs_module
    for name in names:
        if name not in envs_module.names() or not name.startswith("mujoban/"):
            raise SystemExit(f"train_options: {name!r} is not a MuJoBan environment "
                             f"(known: mujoban/level1 ... level5, -pegs)")
    args.logdir.mkdir(parents=True, exist_ok=True)
    ckpt_path = args.logdir / "checkpoint.pt"
    policy_path = args.logdir / "option_policy.pt"
    command = "python -m hier_agents.learning.train_options " + " ".join(
        shlex.quote(a) for a in (sys.argv[1:] if argv is None else argv))

    random.seed(args.seed)
    np.random.seed(args.seed)
    torch.manual_seed(args.seed)
    net = OptionPolicyNet(radius=args.radius, hidden=args.hidden)
    optimizer = torch.optim.Adam(net.parameters(), lr=args.lr, eps=1e-5)
    state = {"option_steps": 0, "control_frames": 0, "abstract_steps": 0, "updates": 0,
             "episodes": 0, "solved": 0, "cpu_s": 0.0, "wall_s": 0.0,
             "env_seed": 1000 * (args.seed + 1), "commands": []}
    if args.resume and ckpt_path.exists():
        try:
            data = torch.load(ckpt_path, map_location="cpu", weights_only=True)
        except Exception:  # noqa: BLE001 - an earlier version's file (NumPy state pickled)
            data = torch.load(ckpt_path, map_location="cpu", weights_only=False)
        net = OptionPolicyNet(**data["policy"]["net"])
        net.load_state_dict(data["policy"]["state_dict"])
        optimizer = torch.optim.Adam(net.parameters(), lr=args.lr, eps=1e-5)
        optimizer.load_state_dict(data["optimizer"])
        state.update(data["state"])
        torch.set_rng_state(data["torch_rng"])
        set_numpy_rng_state(data["numpy_rng"])
        print(f"resumed from {ckpt_path}: {state['option_steps']} option steps, "
              f"{state['control_frames']} control frames, {state['cpu_s'] / 60:.1f} CPU min")
    elif args.resume:
        print(f"no checkpoint at {ckpt_path}: starting afresh")
    state["commands"] = list(state.get("commands", [])) + [command]

    # CPU clock: this process + live workers (+ workers of earlier phases/runs).
    cpu_base, main0 = state["cpu_s"], time.process_time()
    wall0, t0 = state["wall_s"], time.perf_counter()
    clocks = []  # WorkerClocks of this run's vector envs

    def cpu_now() -> float:
        return cpu_base + time.process_time() - main0 + sum(c.seconds() for c in clocks)

    try:
        from torch.utils.tensorboard import SummaryWriter
        writer = SummaryWriter(str(args.logdir))
    except ImportError:
        print("tensorboard is not installed: logging to progress.csv only")
        writer = None
    csv_path = args.logdir / "progress.csv"
    fields = ["phase", "update", "option_steps", "abstract_steps", "control_frames", "cpu_s",
              "episodes", "mean_episode_options", "mean_shaped_reward", "policy_loss",
              "value_loss", "entropy", "approx_kl", "clip_frac"] + \
        [f"solved/{n}" for n in dict.fromkeys(names)]
    new_csv = not (args.resume and csv_path.exists())
    csv_file = open(csv_path, "w" if new_csv else "a", newline="")
    csv_writer = csv.DictWriter(csv_file, fieldnames=fields, extrasaction="ignore")
    if new_csv:
        csv_writer.writeheader()

    def csv_out(row):
        csv_writer.writerow(row)
        csv_file.flush()

    grid_shape = (10, 10)
    skill = skill_record(args.skill)

    def meta() -> dict:
        return {"trained_with": "hier_agents.learning.train_options", "envs": names,
                "option_steps": state["option_steps"], "control_frames": state["control_frames"],
                "abstract_steps": state["abstract_steps"], "updates": state["updates"],
                "cpu_s": round(state["cpu_s"], 1), "seed": args.seed, "skill": args.skill,
                "skill_training_frames": skill.get("training_frames"),
                "estimator": args.estimator or "camera", "gamma": args.gamma,
                "shaping": {"box": args.shape_box, "player": args.shape_player,
                            "box_distance": args.box_distance},
                "commands": state["commands"]}

    def save():
        state["cpu_s"] = cpu_now()
        state["wall_s"] = wall0 + time.perf_counter() - t0
        policy = {"format": "option-policy/1", "net": net.config(),
                  "state_dict": net.state_dict(), "grid_shape": list(grid_shape),
                  "moves": "".join(MOVES), "meta": meta()}
        tmp = ckpt_path.with_suffix(".tmp")
        torch.save({"policy": policy, "optimizer": optimizer.state_dict(), "state": state,
                    "args": {k: str(v) if isinstance(v, Path) else v
                             for k, v in vars(args).items()},
                    "torch_rng": torch.get_rng_state(), "numpy_rng": numpy_rng_state()},
                   tmp)
        os.replace(tmp, ckpt_path)
        save_option_policy(net, policy_path, grid_shape=grid_shape, meta=meta())

    common = dict(net=net, optimizer=optimizer, state=state, args=args, writer=writer,
                  csv_out=csv_out, cpu_now=cpu_now, save=save, radius=args.radius)
    interrupted = False
    try:
        # 1. Optional abstract warm start (no physics).
        if args.abstract_steps > state["abstract_steps"]:
            n = args.abstract_envs
            phase_names = [names[k % len(names)] for k in range(n)]
            vec = gym.vector.SyncVectorEnv(
                [make_abstract_env(phase_names[k], state["env_seed"] + 500 + k, args)
                 for k in range(n)], autoreset_mode=gym.vector.AutoresetMode.SAME_STEP)
            try:
                run_phase("abstract", vec, phase_names, target=args.abstract_steps, **common)
            finally:
                vec.close()
            save()
        # 2. PPO on OptionEnv.
        if args.steps > state["option_steps"] and (
                not args.cpu_minutes or cpu_now() < args.cpu_minutes * 60):
            phase_names = [names[k % len(names)] for k in range(args.envs)]
            seed0 = state["env_seed"] + state["updates"]
            thunks = [make_option_env(phase_names[k], seed0 + k, args) for k in range(args.envs)]
            if args.sync:
                vec = gym.vector.SyncVectorEnv(
                    thunks, autoreset_mode=gym.vector.AutoresetMode.SAME_STEP)
            else:
                vec = gym.vector.AsyncVectorEnv(
                    thunks, autoreset_mode=gym.vector.AutoresetMode.SAME_STEP,
                    context="forkserver")
                pids = [p.pid for p in vec.processes]
                try:  # the forkserver that forks the workers (imports once) counts too
                    from multiprocessing import forkserver
                    pids.append(forkserver._forkserver._forkserver_pid)
                except Exception:  # noqa: BLE001 - private API: best effort
                    pass
                clocks.append(WorkerClock([p for p in pids if p]))
            try:
                run_phase("options", vec, phase_names, target=args.steps, **common)
            finally:
                frozen = cpu_now()  # the workers' last reading, before they exit
                vec.close()
                cpu_base, main0, clocks[:] = frozen, time.process_time(), []
    except KeyboardInterrupt:
        interrupted = True
        print("interrupted: saving the checkpoint")
    save()
    csv_file.close()
    if writer is not None:
        writer.close()
    children = resource.getrusage(resource.RUSAGE_CHILDREN)
    summary = {"command": command, "commands": state["commands"], "envs": names,
               "seed": args.seed, "skill": skill, "estimator": args.estimator or "camera",
               "privileged": (args.estimator or "camera") in ("oracle", "entity-layer"),
               "option_steps": state["option_steps"], "control_frames": state["control_frames"],
               "abstract_steps": state["abstract_steps"], "updates": state["updates"],
               "episodes": state["episodes"], "training_solved_rate":
                   state["solved"] / state["episodes"] if state["episodes"] else None,
               "last_100_solved": state.get("last_solved"),
               "cpu_s": round(state["cpu_s"], 1), "cpu_minutes": round(state["cpu_s"] / 60, 2),
               "wall_s": round(state["wall_s"], 1),
               "check_rusage_this_run_s": {
                   "self": round(sum(resource.getrusage(resource.RUSAGE_SELF)[:2]), 1),
                   "children": round(children.ru_utime + children.ru_stime, 1)},
               "checkpoint": str(ckpt_path), "policy": str(policy_path),
               "hyperparameters": {k: (str(v) if isinstance(v, Path) else v)
                                   for k, v in vars(args).items()},
               "interrupted": interrupted}
    print(f"trained {state['option_steps']} option steps = {state['control_frames']} control "
          f"frames (+ {state['abstract_steps']} abstract steps) in {state['cpu_s'] / 60:.1f} "
          f"CPU minutes; policy {policy_path}")
    if args.eval_episodes > 0 and not interrupted:
        summary["evaluation"] = evaluate(policy_path, list(dict.fromkeys(names)),
                                         args.eval_episodes, args)
    from hier_agents.provenance import provenance
    summary["provenance"] = provenance()
    (args.logdir / "summary.json").write_text(json.dumps(summary, indent=2, default=str) + "\n")
    print(f"wrote {args.logdir / 'summary.json'}")
    return 130 if interrupted else 0


if __name__ == "__main__":
    sys.exit(main())
