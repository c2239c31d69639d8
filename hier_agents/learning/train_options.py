"""Train a policy over options with PPO on `OptionEnv`; play it as a planner.

    python -m hier_agents.learning.train_options ENV[,ENV...] --option-steps N --logdir DIR
        [--envs K] [--seed S] [--resume] [--skill learned-ball] [--estimator camera]
        [--cpu-minutes M] [--abstract-steps A] [--eval-episodes E] ...
        (--option-steps and --logdir are required)
    python -m hier_agents.run mujoban/level2 --planner learned:DIR/option_policy.pt

One environment step is one *option* (`hier_agents.learning.option_env.OptionEnv`): a
Sokoban move ``U``/``D``/``L``/``R`` that the ball skill carries out in MuJoCo
(walk one cell, or push a box one cell) until it succeeds, fails or ``t_abs``
= 50 control steps pass; the observation is the estimator's abstract state
(the default ``camera`` estimator: observation-only).

* **Environments**: ``--envs`` (default 2) copies of `OptionEnv` in a
  gymnasium ``AsyncVectorEnv`` (one process each, torch on one thread,
  same-step autoreset). ``ENV`` may list several environments separated by
  commas; they are dealt to the copies in turn (``mujoban/level1,
  mujoban/level2`` with 2 copies: one of each; the curriculum of the shipped
  policy: both levels at once, no schedule). Training environments are
  seeded from ``1000 * (seed + 1)`` (plus the update count on ``--resume``),
  so their levels are not those of the evaluation runs (``hier_agents.run``
  seeds 0 and the held-out 10000).
* **Policy** (`abstract_planners.learned_options.OptionPolicyNet`): a small
  CNN over the planes re-centred on the player (a 13x13 egocentric crop, a
  fifth plane "box on pad"), a policy head over the 4 moves with
  invalid-action masking (``info["action_mask"]``), a value head.
* **PPO** (`hier_agents.learning.ppo`): semi-MDP GAE(lambda=0.95), an
  option of ``d`` control steps (``info["duration"]``) discounting what
  follows by ``gamma ** d`` (``--gamma`` per control step, 0.995, also the
  discount `OptionEnv` applies inside the option); truncated episodes (the
  900-step limit) bootstrap from the critic. Rollouts of ``--rollout`` (64)
  options per copy, 4 epochs of 4 minibatches, clip 0.2, Adam 5e-4 decayed
  linearly (floor 5%) over the phase's steps, entropy 0.01, value 0.5,
  gradient norm 0.5.
* **Reward** = the environment's (+1 when a box comes onto a pad, -1 when
  one leaves, +10 when the level is solved) **plus potential-based shaping**
  in its semi-MDP form (Ng et al. 1999; the optimal policy is unchanged),
  added by the `Shaped` wrapper (`hier_agents.learning.option_shaping`):
  ``F = gamma^d Phi(s') - Phi(s)``, ``Phi(s) = -(--shape-box * sum over
  boxes off pads of the box's distance to the nearest pad + --shape-player *
  the player's walking distance to a cell next to a box off its pad)`` (1.0
  and 0.1; ``Phi`` of a solved or terminal state is 0). ``--box-distance
  walk`` (default) is the walking distance around walls; ``push`` counts
  the pushes that bring the box alone onto a pad (dead cells far). ``push``
  learned *slower* (level-2 greedy solve rate on abstract levels after 150k
  steps: 53% against 81% with ``walk``; ``results/option_policy/README.md``).
* **Optional abstract warm start** (``--abstract-steps A``, default 0): PPO
  first runs the same network for ``A`` option steps on `AbstractOptionEnv`
  (the same levels without MuJoCo: the planners' Sokoban model, the
  environment's rewards, every option lasting ``--abstract-duration`` = 18
  control steps, the measured mean, and the 900-step limit as 50 options).
  Its CPU time counts in the budget; its steps are counted apart
  (``abstract_steps``), not as control frames.
* **Budgets**: each phase runs PPO updates until its step count reaches its
  budget (overshooting by less than one update: ``--envs x --rollout``
  option steps, ``--abstract-envs x --rollout`` abstract steps); a phase's
  budget is 0 (skipped) or at least one update, and at least one phase has
  one, so every accepted run updates the policy.

**The shipped policy** (``--planner learned``, ``abstract_planners/learned/
options.pt``; figures in ``results/option_policy/``) is approach "D":
400,384 abstract warm-start steps, then 4,096 OptionEnv option steps (86,264
control frames, camera estimator, learned ball skill), 15.9 CPU minutes::

    python -m hier_agents.learning.train_options mujoban/level1,mujoban/level2 \
        --abstract-steps 400000 --option-steps 4000 --cpu-minutes 55 --envs 2 --seed 1 \
        --skill learned-ball --eval-episodes 0 --logdir runs/options_D

It is the learned policy alone (no ``prune_dead_pushes``); approach "B"
(150,528 abstract steps, 6,912 OptionEnv steps, ``results/option_policy/
approach_B/``) needed the hand-written dead-push rule at play time.

The run directory (`hier_agents.learning.rundir`; a fresh run refuses one
that holds a run, ``--resume`` needs one): ``config.json``,
``checkpoint.pt`` every ``--save-every`` updates, at the end and on Ctrl-C
(network, optimiser, counters, random states; ``--resume`` continues it),
``option_policy.pt`` (the planner's file, ~360 KB), ``scalars.jsonl`` and
TensorBoard events, a progress bar on stderr, and ``summary.json``: option
steps, **control frames** (the options' summed durations: the figure
equal-budget comparisons use), abstract steps, CPU seconds of this process
and of its environment workers (read from ``/proc``; ``resource.getrusage``
of the children as a check), wall seconds, the skill (for ``learned-ball``
its own training frames), the seed and the commands. ``--cpu-minutes M``
stops training once M CPU minutes (all processes) are spent. Evaluation at
the end (``--eval-episodes``, 100 per environment, 0 to skip): the greedy
policy as the modular agent's planner (`hier_agents.run`, held-out seed
10000), solved rate with a 95% Wilson interval, in ``summary.json``.
"""

from __future__ import annotations

import json
import math
import resource
import shlex
import sys
import time
from collections import deque
from pathlib import Path

import numpy as np
import torch
from torch import nn

from abstract_planners.learned_options import OptionPolicyNet, policy_input, save_option_policy
from abstract_planners.sokoban import MOVES
from physics_planning.cli import (
    Parser,
    UsageError,
    choice,
    non_negative_float,
    non_negative_int,
    plural,
    positive_float,
    positive_int,
    run_main,
)
from hier_agents.learning import ppo
from hier_agents.learning.option_shaping import (
    ABSTRACT_DURATION,  # noqa: F401 (re-exported)
    TIME_LIMIT_STEPS,  # noqa: F401
    AbstractOptionEnv,  # noqa: F401
    Shaped,  # noqa: F401
    difficulty_of,  # noqa: F401
    potential,  # noqa: F401
)

# (the shaping, the abstract environment and the vector environments live in
# option_shaping and option_workers; their names stay importable from here)
from hier_agents.learning.option_workers import (
    CpuClock,
    WorkerClock,  # noqa: F401
    make_abstract_env,  # noqa: F401
    make_option_env,  # noqa: F401
    make_vector,
)
from hier_agents.learning.rundir import RunDir, seed_everything
from hier_agents.modular.options import T_ABS
from hier_agents.stats import wilson_interval

#: Seed of the end-of-training evaluation (hier_agents.run seeds its environment with it).
HELDOUT_SEED = 10_000
PROG = "python -m hier_agents.learning.train_options"


def skill_record(skill: str | None) -> dict:
    """The skill's name and, for learned-ball, its checkpoint's training counts."""
    record = {"name": skill or "ball"}
    if skill == "learned-ball":
        try:
            from skills.learned.ball import POLICY_PATH

            meta = torch.load(POLICY_PATH, map_location="cpu", weights_only=True).get("meta", {})
            record.update(
                checkpoint=str(POLICY_PATH),
                training_frames=meta.get("frames"),
                training_sim_steps=meta.get("sim_steps"),
                meta=meta,
            )
        except Exception as exc:  # noqa: BLE001 - a record, not a requirement
            record["meta_error"] = str(exc)
    return record


# -- PPO ---------------------------------------------------------------------------------------


class OptionActorCritic(nn.Module):
    """`OptionPolicyNet` as `ppo.ActorCritic` over `policy_input` tensors."""

    def __init__(self, net: OptionPolicyNet) -> None:
        super().__init__()
        self.net = net

    def policy_dist(self, x, mask):
        return ppo.masked_categorical(self.net.logits(x), mask)

    def value(self, x):
        return self.net.value(x)


def ppo_config(args) -> ppo.PPOConfig:
    return ppo.config_from_args(args, lr_floor=0.05)


def run_phase(phase, vec, names, policy, optimizer, state, args, *, target, run, cpu_now, save):
    """PPO on the vector env ``vec`` until ``state[phase count] >= target``, the
    CPU budget is spent or Ctrl-C. ``phase`` is ``"abstract"`` or ``"options"``."""
    count_key = "abstract_steps" if phase == "abstract" else "option_steps"
    collector = ppo.RolloutCollector(
        vec,
        policy,
        args.rollout,
        obs_fn=lambda obs: torch.as_tensor(policy_input(obs, args.radius)),
    )
    collector.reset(seed=state["env_seed"] + 7919 * state["updates"])
    cfg = ppo_config(args)
    recent = {name: deque(maxlen=100) for name in set(names)}
    lengths = deque(maxlen=100)
    bar = run.progress(target, min(state[count_key], target), desc=phase, unit="option")
    budget = args.cpu_minutes * 60 if args.cpu_minutes else math.inf
    while state[count_key] < target and cpu_now() < budget and not run.stop_requested:
        rollout, losses = ppo.iteration(
            collector, optimizer, cfg, fraction_left=1.0 - state[count_key] / max(target, 1)
        )
        for ep in rollout.episodes:
            recent[names[ep.env]].append(ep.terminated)
            lengths.append(ep.length)
            state["episodes"] += 1
            state["solved"] += int(ep.terminated)
        state[count_key] += rollout.size
        if phase == "options":
            state["control_frames"] += int(rollout.durations.sum().item())
        state["updates"] += 1
        state["cpu_s"] = cpu_now()
        solved = {name: (float(np.mean(r)) if r else float("nan")) for name, r in recent.items()}
        row = {
            "phase": phase,
            "update": state["updates"],
            "option_steps": state["option_steps"],
            "abstract_steps": state["abstract_steps"],
            "control_frames": state["control_frames"],
            "cpu_s": round(state["cpu_s"], 1),
            "episodes": state["episodes"],
            "mean_episode_options": float(np.mean(lengths)) if lengths else float("nan"),
            "mean_shaped_reward": float(rollout.rewards.mean()),
            **losses,
            **{f"solved/{name}": v for name, v in solved.items()},
        }
        run.log(state["abstract_steps"] + state["option_steps"], row, tb_prefix=f"{phase}/")
        bar.update(rollout.size)
        bar.set_postfix(
            {name.split("/")[-1]: f"{v:.2f}" for name, v in solved.items()}
            | {"cpu_min": f"{state['cpu_s'] / 60:.1f}"}
        )
        if state["updates"] % args.save_every == 0:
            save()
    state["last_solved"] = {name: (float(np.mean(r)) if r else None) for name, r in recent.items()}


# -- evaluation --------------------------------------------------------------------------------


def evaluate(policy_path: Path, env_names, episodes: int, args) -> dict:
    """The greedy policy as the modular agent's planner, ``episodes`` held-out
    episodes per environment (`hier_agents.run`)."""
    from hier_agents.run import run

    out = {}
    for name in env_names:
        c0, t0 = time.process_time(), time.perf_counter()
        summary = run(
            name,
            episodes,
            HELDOUT_SEED,
            planner=f"learned:{policy_path}",
            skill=args.skill,
            estimator=args.estimator,
            progress=True,
        )
        solved = sum(r["solved"] for r in summary["rows"])
        low, high = wilson_interval(solved, episodes)
        out[name] = {
            "episodes": episodes,
            "solved": solved,
            "success_rate": solved / episodes,
            "wilson_95": [low, high],
            "mean_steps": summary["mean_steps"],
            "subgoal_success_rate": summary["subgoal_success_rate"],
            "episode_failures": summary["episode_failures"],
            "seed": HELDOUT_SEED,
            "cpu_s": round(time.process_time() - c0, 1),
            "wall_s": round(time.perf_counter() - t0, 1),
        }
        print(
            f"{name}: solved {solved}/{episodes} = {100 * solved / episodes:.1f}% "
            f"[{100 * low:.1f}, {100 * high:.1f}] (95% Wilson), held-out seed {HELDOUT_SEED}"
        )
    return out


# -- main --------------------------------------------------------------------------------------


def parse_args(argv=None):
    """The command line, each value's type and range checked (the parser's
    one-line error); `check_args` checks the rest."""
    p = Parser(PROG, description=__doc__.split("\n\n")[0])
    add = p.add_argument
    add(
        "env",
        help="environment(s), comma-separated (e.g. mujoban/level1,mujoban/level2), "
        "dealt to the copies in turn",
    )
    add(
        "--option-steps",
        type=non_negative_int,
        required=True,
        help="option steps on OptionEnv (the training budget; 0: the abstract warm start only)",
    )
    add(
        "--logdir",
        type=Path,
        required=True,
        help="the run directory (a fresh run refuses one that holds a run)",
    )
    add("--envs", type=positive_int, default=2, help="environment copies (processes)")
    add("--seed", type=non_negative_int, default=0, help="seed of the network, PPO and envs")
    add("--resume", action="store_true", help="continue LOGDIR/checkpoint.pt (required there)")
    add("--skill", default="learned-ball", help="skill name")
    add("--estimator", default=None, help="estimator name (default: camera)")
    add(
        "--cpu-minutes",
        type=positive_float,
        default=None,
        help="stop training after this many CPU minutes (all processes)",
    )
    add("--sync", action="store_true", help="SyncVectorEnv (one process; tests)")
    add(
        "--abstract-steps",
        type=non_negative_int,
        default=0,
        help="option steps of the abstract warm start (no physics)",
    )
    add("--abstract-envs", type=positive_int, default=16, help="abstract env copies")
    add(
        "--abstract-duration",
        type=positive_int,
        default=ABSTRACT_DURATION,
        help="control steps per abstract option",
    )
    ppo.add_arguments(
        p,
        rollout=64,
        epochs=4,
        minibatches=4,
        lr=5e-4,
        anneal_lr=True,
        gamma=0.995,
        lam=0.95,
        clip=0.2,
        ent_coef=0.01,
        vf_coef=0.5,
        max_grad_norm=0.5,
    )
    add("--shape-box", type=non_negative_float, default=1.0, help="shaping: box distance weight")
    add(
        "--shape-player",
        type=non_negative_float,
        default=0.1,
        help="shaping: player distance weight",
    )
    add(
        "--box-distance",
        default="walk",
        help="shaping's box-to-pad distance: walk (walking) or push (pushes; dead cells far)",
    )
    add("--t-abs", type=positive_int, default=T_ABS, help="control steps per option at most")
    add("--radius", type=positive_int, default=6, help="egocentric crop radius (cells)")
    add("--hidden", type=positive_int, default=128, help="network width")
    add("--save-every", type=positive_int, default=10, help="updates between checkpoints")
    add("--eval-episodes", type=non_negative_int, default=100, help="per environment; 0: skip")
    return p.parse_args(argv)


def check_args(args) -> list[str]:
    """The environment names of ``args.env``, after checking ``args``.

    Raises:
      UsageError: a name that is not a MuJoBan environment, an unknown skill,
        estimator or box distance (each with the closest valid name), or a
        budget that buys no update."""
    import envs as envs_module
    from hier_agents.modular.components import ESTIMATORS, SKILLS

    names = [n.strip() for n in args.env.split(",") if n.strip()]
    if not names:
        raise UsageError("no environment given")
    mujoban = [n for n in envs_module.names() if n.startswith("mujoban/")]
    for name in names:
        choice("MuJoBan environment", name, mujoban)
    if args.skill not in SKILLS["mujoban"]:
        choice("MuJoBan skill", args.skill, list(SKILLS["mujoban"]))
    if args.estimator is not None and args.estimator not in ESTIMATORS["mujoban"]:
        choice("MuJoBan estimator", args.estimator, list(ESTIMATORS["mujoban"]))
    choice("--box-distance", args.box_distance, ("walk", "push"))
    if args.option_steps == 0 and args.abstract_steps == 0:
        raise UsageError("nothing to train: --option-steps and --abstract-steps are both 0")
    for flag, steps, copies in (
        ("--option-steps", args.option_steps, "--envs"),
        ("--abstract-steps", args.abstract_steps, "--abstract-envs"),
    ):
        per_update = (args.envs if copies == "--envs" else args.abstract_envs) * args.rollout
        ppo.iterations(
            steps,
            per_update,
            f"{flag} {steps}",
            f"give {flag} 0 or >= {per_update} ({copies} x --rollout)",
        )
    return names


def meta(state, args, names, skill) -> dict:
    """The policy file's training record."""
    return {
        "trained_with": "hier_agents.learning.train_options",
        "envs": names,
        "option_steps": state["option_steps"],
        "control_frames": state["control_frames"],
        "abstract_steps": state["abstract_steps"],
        "updates": state["updates"],
        "cpu_s": round(state["cpu_s"], 1),
        "seed": args.seed,
        "skill": args.skill,
        "skill_training_frames": skill.get("training_frames"),
        "estimator": args.estimator or "camera",
        "gamma": args.gamma,
        "shaping": {
            "box": args.shape_box,
            "player": args.shape_player,
            "box_distance": args.box_distance,
        },
        "commands": state["commands"],
    }


def train(run: RunDir, args, names, command: str):
    """Both phases in ``run``; returns (state counters, the skill record)."""
    seed_everything(args.seed)
    net = OptionPolicyNet(radius=args.radius, hidden=args.hidden)
    optimizer = torch.optim.Adam(net.parameters(), lr=args.lr, eps=1e-5)
    state = {
        "option_steps": 0,
        "control_frames": 0,
        "abstract_steps": 0,
        "updates": 0,
        "episodes": 0,
        "solved": 0,
        "cpu_s": 0.0,
        "wall_s": 0.0,
        "env_seed": 1000 * (args.seed + 1),
        "commands": [],
    }
    data = run.load()  # after the network is built: its RNG states continue
    if data is not None:
        net.load_state_dict(data["policy"]["state_dict"])
        optimizer.load_state_dict(data["optimizer"])
        state.update(data["state"])
        print(
            f"resumed from {run.checkpoint_path}: {plural(state['option_steps'], 'option step')}"
            f", {plural(state['control_frames'], 'control frame')}, "
            f"{state['cpu_s'] / 60:.1f} CPU min"
        )
    state["commands"] = list(state.get("commands", [])) + [command]
    clock, wall0, t0 = CpuClock(state["cpu_s"]), state["wall_s"], time.perf_counter()
    skill = skill_record(args.skill)

    def save():
        state["cpu_s"] = clock.now()
        state["wall_s"] = wall0 + time.perf_counter() - t0
        record = meta(state, args, names, skill)
        policy = {
            "format": "option-policy/1",
            "net": net.config(),
            "state_dict": net.state_dict(),
            "grid_shape": [10, 10],
            "moves": "".join(MOVES),
            "meta": record,
        }
        run.save({"policy": policy, "optimizer": optimizer.state_dict(), "state": state})
        save_option_policy(net, run.path / "option_policy.pt", grid_shape=(10, 10), meta=record)

    policy = OptionActorCritic(net)
    with run.interruptible():
        for phase, target in (("abstract", args.abstract_steps), ("options", args.option_steps)):
            count = state["abstract_steps" if phase == "abstract" else "option_steps"]
            spent = args.cpu_minutes and clock.now() >= args.cpu_minutes * 60
            if target <= count or spent or run.stop_requested:
                continue
            vec, phase_names, pids = make_vector(phase, names, state, args)
            if pids:
                clock.workers.append(WorkerClock(pids))
            try:
                run_phase(
                    phase,
                    vec,
                    phase_names,
                    policy,
                    optimizer,
                    state,
                    args,
                    target=target,
                    run=run,
                    cpu_now=clock.now,
                    save=save,
                )
            finally:
                clock.freeze()
                vec.close()
            save()
    return state, skill


def _main(argv) -> int:
    args = parse_args(argv)
    torch.set_num_threads(1)
    names = check_args(args)
    command = (
        PROG + " " + " ".join(shlex.quote(a) for a in (sys.argv[1:] if argv is None else argv))
    )
    run = RunDir(
        args.logdir, vars(args), resume=args.resume, fixed=("radius", "hidden"), trainer=PROG
    )
    try:
        state, skill = train(run, args, names, command)
    finally:
        run.close()
    interrupted = run.stop_requested
    policy_path = args.logdir / "option_policy.pt"
    children = resource.getrusage(resource.RUSAGE_CHILDREN)
    estimator = args.estimator or "camera"
    summary = {
        "command": command,
        "commands": state["commands"],
        "envs": names,
        "seed": args.seed,
        "skill": skill,
        "estimator": estimator,
        "privileged": estimator in ("oracle", "entity-layer"),
        **{
            k: state[k]
            for k in ("option_steps", "control_frames", "abstract_steps", "updates", "episodes")
        },
        "training_solved_rate": state["solved"] / state["episodes"] if state["episodes"] else None,
        "last_100_solved": state.get("last_solved"),
        "cpu_s": round(state["cpu_s"], 1),
        "cpu_minutes": round(state["cpu_s"] / 60, 2),
        "wall_s": round(state["wall_s"], 1),
        "check_rusage_this_run_s": {
            "self": round(sum(resource.getrusage(resource.RUSAGE_SELF)[:2]), 1),
            "children": round(children.ru_utime + children.ru_stime, 1),
        },
        "checkpoint": str(run.checkpoint_path),
        "policy": str(policy_path),
        "hyperparameters": run.config,
        "interrupted": interrupted,
    }
    print(
        f"trained {plural(state['option_steps'], 'option step')} = "
        f"{plural(state['control_frames'], 'control frame')} (+ "
        f"{plural(state['abstract_steps'], 'abstract step')}) in "
        f"{state['cpu_s'] / 60:.1f} CPU minutes; policy {policy_path}"
    )
    if args.eval_episodes > 0 and not interrupted:
        summary["evaluation"] = evaluate(
            policy_path, list(dict.fromkeys(names)), args.eval_episodes, args
        )
    from hier_agents.provenance import provenance

    summary["provenance"] = provenance()
    (args.logdir / "summary.json").write_text(json.dumps(summary, indent=2, default=str) + "\n")
    print(f"wrote {args.logdir / 'summary.json'}")
    return 130 if interrupted else 0


def main(argv=None) -> int:
    """``python -m hier_agents.learning.train_options``: trains, evaluates,
    writes ``LOGDIR/summary.json``; exit status 0, 130 when interrupted, 2
    with one line on stderr for a bad input (`physics_planning.cli.run_main`)."""
    return run_main(PROG, _main, argv)


if __name__ == "__main__":
    sys.exit(main())
