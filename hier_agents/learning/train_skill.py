"""Train any learned skill: behaviour cloning, DAgger, then PPO, on its spec.

    python -m hier_agents.learning.train_skill SPEC --frames N --logdir DIR [--envs K]
        [--seed S] [--resume] [--bc-frames M] [--dagger-frames D] [--dagger-rounds R]
        (--frames and --logdir are required for training)
    python -m hier_agents.learning.train_skill SPEC --evaluate [PATH] [--estimator E]
        [--eval-episodes E] [--json OUT]

``SPEC`` names a `hier_agents.learning.skill_spec.SkillSpec` (``ball``,
``arm``): the skill, its scenes, its success rule and its teacher. The
trainer knows nothing else about the skill:

1. **Warm start** (`hier_agents.learning.cloning.clone`): ``--bc-frames``
   frames of the teacher with Gaussian action noise, the actor's mean
   regressed on the teacher's actions; then ``--dagger-rounds`` rounds of
   ``--dagger-frames`` frames driven by the cloned policy, labelled by the
   teacher, refitted on everything. These frames count in the budget
   (``--bc-frames 0``: no warm start).
2. **PPO** (`hier_agents.learning.ppo`) on the rest of ``--frames``:
   ``--envs`` `SkillEnv` copies in a vector env (same-step autoreset),
   ``--rollout`` steps per copy per iteration (``envs x rollout`` frames),
   as many whole iterations as the budget pays for (it is met to within one
   iteration), GAE, the clipped update, a Gaussian policy with a
   state-independent std (``--log-std``). After a warm start the first
   ``--critic-warmup`` iterations train only the critic (a fresh critic's
   advantages would undo the warm start), but never all of them: at least
   one iteration of the budget updates the actor. ``--frames`` equal to the
   warm start's frames skips PPO; a budget below the warm start, or leaving
   PPO less than one iteration, is refused (the message names the smallest
   that works).
3. **Evaluation** (``--eval-episodes``): the deterministic policy (the mean)
   on the spec's held-out scenes (seed `HELDOUT_SEED`), option success with
   a 95% Wilson interval, printed and written to ``DIR/summary.json``.

The run directory (`hier_agents.learning.rundir`; a fresh run refuses a
directory that holds one, ``--resume`` needs one): ``config.json``,
``checkpoint.pt`` (atomic; everything to resume bit-identically: networks,
optimiser, counters, random states; the vector env restarts from a seed at
every checkpoint), ``scalars.jsonl`` + TensorBoard, a progress bar, Ctrl-C
saves and stops; ``DIR/<skill>_policy.pt``: the actor in the format
`skills.learned.policy.load_policy` reads. Use it with ``--skill
learned-<skill>`` after copying it over the spec's ``checkpoint`` (or pass the
path to the skill).

``--evaluate [PATH]`` evaluates a checkpoint (default: the shipped one)
against the teacher on the same held-out scenes and writes ``--json``.
"""

from __future__ import annotations

import json
import math
import sys
import time
from pathlib import Path

import numpy as np
import torch
from torch import nn

from physics_planning.cli import (
    Parser,
    UsageError,
    choice,
    existing_file,
    fraction,
    non_negative_float,
    non_negative_int,
    output_file,
    plural,
    positive_int,
    run_main,
)
from hier_agents.learning import ppo
from hier_agents.learning.cloning import clone, warm_start_frames
from hier_agents.learning.rundir import RunDir, seed_everything
from hier_agents.learning.skill_env import SkillEnv
from hier_agents.learning.skill_spec import spec as spec_named
from hier_agents.stats import wilson_interval

__all__ = ["Agent", "export_policy", "evaluate", "train", "main", "HELDOUT_SEED"]

#: Seeds of the held-out evaluation scenes (training uses ``--seed``).
HELDOUT_SEED = 10_000
PROG = "python -m hier_agents.learning.train_skill"


def mlp(sizes, out_std: float) -> nn.Sequential:
    """tanh MLP with orthogonal initialisation (last layer scaled by ``out_std``)."""
    layers: list[nn.Module] = []
    for j, (a, b) in enumerate(zip(sizes[:-1], sizes[1:])):
        linear = nn.Linear(a, b)
        last = j == len(sizes) - 2
        nn.init.orthogonal_(linear.weight, out_std if last else math.sqrt(2))
        nn.init.zeros_(linear.bias)
        layers += [linear] if last else [linear, nn.Tanh()]
    return nn.Sequential(*layers)


class Agent(nn.Module):
    """Actor (features -> policy action mean) and critic, two hidden layers
    each; a Gaussian policy with a state-independent log-std."""

    def __init__(
        self, obs_dim: int, action_dim: int, hidden: int = 64, log_std: float = -0.5
    ) -> None:
        super().__init__()
        self.actor = mlp([obs_dim, hidden, hidden, action_dim], 0.01)
        self.critic = mlp([obs_dim, hidden, hidden, 1], 1.0)
        self.log_std = nn.Parameter(torch.full((action_dim,), float(log_std)))

    def mean(self, obs: torch.Tensor) -> torch.Tensor:
        return self.actor(obs)

    def value(self, obs: torch.Tensor) -> torch.Tensor:
        return self.critic(obs).squeeze(-1)

    def policy_dist(self, obs: torch.Tensor, mask=None):
        return ppo.diag_gaussian(self.mean(obs), self.log_std)


def export_policy(agent: Agent, features, path: Path, meta: dict) -> None:
    """The actor in the checkpoint format of `skills.learned.policy`."""
    actor = {k: v.detach().clone() for k, v in agent.actor.state_dict().items()}
    torch.save({"actor": actor, "features": tuple(features), "meta": meta}, path)


def teacher_policy(obs, info) -> np.ndarray | None:
    """The skill's teacher: the environment's ``expert_action`` (None where
    the teacher cannot plan: the evaluation then holds still)."""
    return info.get("expert_action")


def evaluate(
    spec,
    policy,
    episodes: int,
    *,
    seed: int = HELDOUT_SEED,
    estimator: str | None = None,
    t_abs: int | None = None,
    progress: bool = False,
) -> dict:
    """Option success of ``policy(obs, info) -> policy action`` on
    ``episodes`` held-out options of ``spec``: counts, rate, 95% Wilson
    interval, mean steps of the reached ones, failures by reason kind."""
    env = SkillEnv(spec, estimator=estimator, t_abs=t_abs, heldout=True, seed=seed)
    successes, steps = 0, []
    reasons: dict[str, int] = {}  # failures by reason kind
    bar = None
    if progress:
        from hier_agents.learning.rundir import progress_bar

        bar = progress_bar(episodes, desc="eval", unit="option")
    obs, info = env.reset(seed=seed)
    for _ in range(episodes):
        done = False
        while not done:
            action = policy(obs, info)
            if action is None:
                action = np.zeros(env.action_space.shape, np.float32)
            obs, _, terminated, truncated, info = env.step(action)
            done = terminated or truncated
        successes += info["is_success"]
        if info["is_success"]:
            steps.append(info["steps"])
        else:
            kind = (info["reason"] or info["status"]).split(":", 1)[0]
            reasons[kind] = reasons.get(kind, 0) + 1
        if bar is not None:
            bar.update(1)
        obs, info = env.reset()
    if bar is not None:
        bar.close()
    privileged = env.privileged
    env.close()
    low, high = wilson_interval(successes, episodes)
    return {
        "episodes": episodes,
        "successes": int(successes),
        "success": successes / episodes,
        "wilson_low": low,
        "wilson_high": high,
        "mean_steps_success": float(np.mean(steps)) if steps else None,
        "failures": reasons,
        "estimator": env.estimator_name,
        "privileged": privileged,
        "t_abs": env.t_abs,
        "seed": seed,
    }


def print_table(rows: dict) -> None:
    print(f"{'policy':<26} {'options':>7} {'success':>8} {'95% Wilson':>17} {'steps':>6}  failures")
    for name, r in rows.items():
        steps = "-" if r["mean_steps_success"] is None else f"{r['mean_steps_success']:.0f}"
        fails = ", ".join(f"{k} {v}" for k, v in r["failures"].items())
        print(
            f"{name:<26} {r['episodes']:>7} {100 * r['success']:>7.1f}% "
            f"[{100 * r['wilson_low']:>5.1f}%, {100 * r['wilson_high']:>5.1f}%] {steps:>6}  "
            f"{fails}"
        )


def _mean_policy(agent: Agent):
    def act(obs, info=None):
        with torch.no_grad():
            return (
                agent.mean(torch.as_tensor(obs, dtype=torch.float32)[None])[0].clamp(-1, 1).numpy()
            )

    return act


def evaluate_only(args, spec) -> int:
    """``--evaluate``: a checkpoint against the teacher, on the same scenes."""
    from skills.learned.policy import load_policy

    path = spec.checkpoint if args.evaluate is True else Path(args.evaluate)
    skill = spec.make_skill(None)
    policy = load_policy(path, skill.FEATURES)
    kw = dict(estimator=args.estimator, t_abs=args.t_abs, progress=True)
    t0, c0 = time.perf_counter(), time.process_time()
    rows = {
        "learned (deterministic)": evaluate(
            spec, lambda obs, info: np.clip(policy(obs), -1, 1), args.eval_episodes, **kw
        ),
        "teacher": evaluate(spec, teacher_policy, args.eval_episodes, **kw),
    }
    print(
        f"{path} on {plural(args.eval_episodes, 'held-out option')} of {spec.name} (seed "
        f"{HELDOUT_SEED}, "
        f"estimator {rows['teacher']['estimator']}"
        f"{', PRIVILEGED' if rows['teacher']['privileged'] else ', observation-only'})"
    )
    print_table(rows)
    if args.json:
        from hier_agents.provenance import provenance

        args.json.write_text(
            json.dumps(
                {
                    "skill": spec.name,
                    "policy": str(path),
                    "policy_meta": policy.meta,
                    "rows": rows,
                    "wall_s": round(time.perf_counter() - t0, 1),
                    "cpu_s": round(time.process_time() - c0, 1),
                    "provenance": provenance(),
                },
                indent=2,
                default=str,
            )
            + "\n"
        )
        print(f"wrote {args.json}")
    return 0


def _vector_env(spec, args, seed: int):
    thunks = [
        (lambda k=k: SkillEnv(spec, seed=seed + k, estimator=args.estimator, t_abs=args.t_abs))
        for k in range(args.envs)
    ]
    return ppo.make_vector_env(thunks, asynchronous=args.async_envs)


def budget(args) -> tuple[int, int, int]:
    """The budget ``args.frames`` split: (warm-start frames, PPO iterations of
    ``args.envs * args.rollout`` frames, critic-only iterations among them).

    Raises:
      UsageError: a budget below the warm start's frames, or leaving PPO
        frames that do not pay for one iteration (the message names the
        smallest budget that works).
    """
    warm = warm_start_frames(args.bc_frames, args.dagger_frames, args.dagger_rounds)
    per_iter = args.envs * args.rollout
    if args.frames < warm:
        raise UsageError(
            f"--frames {args.frames} is less than the warm start's "
            f"{plural(warm, 'frame')} (--bc-frames + --dagger-rounds x "
            f"--dagger-frames); give --frames >= {warm}"
        )
    if warm:
        what = (
            f"the PPO budget (--frames {args.frames} minus the warm start's {warm}: "
            f"{plural(args.frames - warm, 'frame')})"
        )
        fix = (
            f"give --frames {warm} (the warm start only) or >= {warm + per_iter}, or a "
            f"smaller --envs x --rollout"
        )
    else:
        what = f"--frames {args.frames}"
        fix = f"give --frames >= {per_iter}, or a smaller --envs x --rollout"
    iterations = ppo.iterations(args.frames - warm, per_iter, what, fix)
    return warm, iterations, ppo.critic_warmup(iterations, args.critic_warmup) if warm else 0


def _ppo(spec, agent, optimizer, state, run, args, save) -> None:
    """PPO iterations until ``args.frames`` frames (the counters in
    ``state``); the first `budget` critic-only iterations after a warm start
    train the critic alone, unless an earlier iteration of the run already
    updated the actor."""
    cfg, per_iter = ppo.config_from_args(args), args.envs * args.rollout
    _, _, warmup = budget(args)
    if state["frames"] + per_iter > args.frames:
        return
    envs = _vector_env(spec, args, args.seed * 1000 + 100)
    collector = ppo.RolloutCollector(envs, agent, args.rollout)
    collector.reset(seed=args.seed * 1000 + 100 + state["iteration"])
    recent: list = []
    sim_before = np.zeros(args.envs)
    bar = run.progress(
        args.frames,
        initial=min(state["frames"], args.frames),
        unit="frame",
        desc=f"ppo {spec.name}",
    )
    try:
        while state["frames"] + per_iter <= args.frames and not run.stop_requested:
            critic_only = (
                state["bc_frames"] > 0
                and state["actor_iterations"] == 0
                and state["ppo_iterations"] < warmup
            )
            left = 1.0 - state["frames"] / max(args.frames, 1)
            rollout, stats = ppo.iteration(collector, optimizer, cfg, left, actor=not critic_only)
            sim_now = np.asarray(rollout.last_info.get("sim_steps", sim_before), float)
            state["sim_steps"] += int(np.maximum(sim_now - sim_before, 0).sum())
            sim_before = sim_now
            recent = (recent + [bool(e.info.get("is_success")) for e in rollout.episodes])[-100:]
            state["frames"] += per_iter
            state["iteration"] += 1
            state["ppo_iterations"] += 1
            state["actor_iterations"] += 0 if critic_only else 1
            success = float(np.mean(recent)) if recent else float("nan")
            run.log(
                state["frames"],
                {
                    "option_success": success,
                    "options": len(recent),
                    "sim_steps": state["sim_steps"],
                    "actor": not critic_only,
                    "std": agent.log_std.exp().mean().item(),
                    **stats,
                },
            )
            bar.update(per_iter)
            bar.set_postfix(success=f"{success:.2f}")
            if state["iteration"] % args.save_every == 0:
                save()
                collector.reset(seed=args.seed * 1000 + 100 + state["iteration"])
                sim_before = np.zeros(args.envs)
    finally:
        envs.close()


def train(args, command: str = PROG) -> dict:
    """Trains ``args.spec``'s skill (module docstring; ``args`` as `parse_args`
    gives them, ``command`` recorded in the policy's meta); returns the summary.

    Raises:
      UsageError: a budget `budget` refuses; ``args.logdir`` is a file, holds a
        run without ``args.resume`` or another run (another spec, width, seed,
        envs or rollout, or another trainer's) with it, or holds none with
        it (`RunDir`); all before anything is trained.
    """
    spec = spec_named(args.spec)
    budget(args)
    config = {k: (str(v) if isinstance(v, Path) else v) for k, v in vars(args).items()}
    run = RunDir(
        args.logdir,
        config,
        resume=args.resume,
        trainer=PROG,
        fixed=("spec", "hidden", "seed", "envs", "rollout"),
    )
    probe = spec.make_skill(None)
    seed_everything(args.seed)
    torch.set_num_threads(1)
    agent = Agent(
        len(probe.FEATURES),
        probe.ACTION_DIM,
        args.hidden,
        args.log_std if args.log_std is not None else (-1.6 if args.bc_frames > 0 else -0.5),
    )
    optimizer = torch.optim.Adam(agent.parameters(), lr=args.lr, eps=1e-5)
    state = _restore(run, agent, optimizer, args)
    policy_path = Path(args.logdir) / f"{spec.name}_policy.pt"
    save = _saver(run, agent, optimizer, state, probe.FEATURES, policy_path, spec, args, command)
    with run, run.interruptible():
        if args.bc_frames > 0 and state["bc_frames"] == 0:
            _warm_start(agent, spec, state, args)
            save()
        _ppo(spec, agent, optimizer, state, run, args, save)
        save()
        summary = _summary(spec, agent, state, args, policy_path)
        run.log(
            int(state["frames"]),
            {"eval_option_success": summary["eval"]["learned (deterministic)"]["success"]},
        )
    (Path(args.logdir) / "summary.json").write_text(json.dumps(summary, indent=2) + "\n")
    print(f"summary: {Path(args.logdir) / 'summary.json'}")
    return summary


def _restore(run, agent, optimizer, args) -> dict:
    """The training counters, fresh or, with a checkpoint in ``run``, loaded
    from it together with ``agent`` and ``optimizer``'s states."""
    state = {
        "iteration": 0,
        "ppo_iterations": 0,
        "actor_iterations": 0,
        "frames": 0,
        "sim_steps": 0,
        "bc_frames": 0,
        "wall_s": 0.0,
    }
    saved = run.load()
    if saved is not None:
        agent.load_state_dict(saved["agent"])
        optimizer.load_state_dict(saved["optimizer"])
        state.update(saved["state"])
        print(
            f"resumed {args.logdir}: iteration {state['iteration']}, "
            f"{plural(state['frames'], 'frame')}"
        )
    return state


def _saver(run, agent, optimizer, state, features, policy_path, spec, args, command):
    """The function that checkpoints the run and exports the policy to
    ``policy_path``, counting the wall time from now on top of ``state``'s."""
    t0, wall0 = time.perf_counter(), state["wall_s"]

    def save():
        state["wall_s"] = wall0 + time.perf_counter() - t0
        run.save(
            {"agent": agent.state_dict(), "optimizer": optimizer.state_dict(), "state": dict(state)}
        )
        export_policy(
            agent,
            features,
            policy_path,
            {
                "frames": state["frames"],
                "sim_steps": state["sim_steps"],
                "bc_frames": state["bc_frames"],
                "seed": args.seed,
                "spec": spec.name,
                "iteration": state["iteration"],
                "command": command,
                "trained_with": "hier_agents.learning.train_skill",
            },
        )

    return save


def _warm_start(agent, spec, state, args) -> None:
    """The warm start (`clone`): behaviour cloning and DAgger, its frames
    counted in ``state``."""
    frames, sim = clone(
        agent,
        spec,
        frames=args.bc_frames,
        seed=args.seed,
        dagger_frames=args.dagger_frames,
        epochs=args.bc_epochs,
        dagger_rounds=args.dagger_rounds,
        noise=args.bc_noise,
        noise_prob=args.bc_noise_prob,
        dagger_noise=args.dagger_noise,
        dagger_noise_prob=args.dagger_noise_prob,
        dagger_mix=args.dagger_mix,
        estimator=args.estimator,
    )
    state.update(bc_frames=frames, frames=frames, sim_steps=sim)


def _summary(spec, agent, state, args, policy_path) -> dict:
    rows = (
        {
            "learned (deterministic)": evaluate(
                spec,
                _mean_policy(agent),
                args.eval_episodes,
                estimator=args.estimator,
                t_abs=args.t_abs,
                progress=True,
            )
        }
        if args.eval_episodes
        else {}
    )
    if rows:
        print_table(rows)
    return {
        "spec": spec.name,
        "seed": args.seed,
        "envs": args.envs,
        "frames": state["frames"],
        "bc_frames": state["bc_frames"],
        "ppo_frames": state["frames"] - state["bc_frames"],
        "sim_steps": state["sim_steps"],
        "iterations": state["iteration"],
        "actor_iterations": state.get("actor_iterations", 0),
        "wall_s": round(state["wall_s"], 1),
        "eval": rows or {"learned (deterministic)": {"success": float("nan")}},
        "policy": str(policy_path),
        "torch": torch.__version__,
    }


def parse_args(argv=None):
    """The command line, checked before any work (`UsageError` or the
    parser's one-line error): the spec and estimator names, training's
    required ``--frames``/``--logdir`` and its `budget`, ``--evaluate``'s
    file, ``--json`` (its folder is created)."""
    p = Parser(
        PROG,
        description=__doc__.split("\n\n")[0],
        epilog="--frames and --logdir are required for training, not with --evaluate.",
    )
    _add_run_args(p)
    _add_warm_start_args(p)
    _add_ppo_args(p)
    _add_schedule_args(p)
    return _check_args(p.parse_args(argv))


def _add_run_args(parser: Parser) -> None:
    """The spec, the mode (training or ``--evaluate``), the run directory, the
    environments, the seed."""
    add = parser.add_argument
    add("spec", help="the skill spec (ball, arm)")
    add(
        "--frames",
        type=positive_int,
        default=None,
        help="training budget, required: agent control steps (warm start + PPO)",
    )
    add(
        "--logdir",
        type=Path,
        default=None,
        help="training's run directory, required (a fresh run refuses one that holds a run)",
    )
    add(
        "--evaluate",
        nargs="?",
        const=True,
        metavar="PATH",
        type=existing_file,
        help="evaluate a checkpoint (default: the shipped one) against the teacher",
    )
    add("--estimator", default=None, help="scene estimator (default: the spec's first)")
    add("--json", type=Path, help="--evaluate: write the results here")
    add("--envs", type=positive_int, default=2, help="vectorised environments")
    add("--async-envs", action="store_true", help="one process per environment")
    add("--seed", type=non_negative_int, default=0, help="seed of everything")
    add("--resume", action="store_true", help="continue LOGDIR/checkpoint.pt (required there)")


def _add_warm_start_args(parser: Parser) -> None:
    """The warm start: behaviour cloning, then DAgger."""
    add = parser.add_argument
    add(
        "--bc-frames",
        type=non_negative_int,
        default=20_000,
        help="frames of the noisy teacher (0: no warm start)",
    )
    add("--bc-epochs", type=positive_int, default=60, help="epochs of every fit")
    add("--bc-noise", type=non_negative_float, default=0.2, help="action noise std (cloning)")
    add(
        "--bc-noise-prob", type=fraction, default=1.0, help="fraction of cloning options with noise"
    )
    add("--dagger-frames", type=non_negative_int, default=20_000, help="frames per DAgger round")
    add("--dagger-rounds", type=non_negative_int, default=1, help="DAgger rounds")
    add("--dagger-noise", type=non_negative_float, default=0.1, help="action noise std (DAgger)")
    add(
        "--dagger-noise-prob",
        type=fraction,
        default=1.0,
        help="fraction of DAgger options with noise",
    )
    add(
        "--dagger-mix",
        type=fraction,
        default=1.0,
        help="probability that the student (not the teacher) acts, per DAgger step",
    )


def _add_ppo_args(parser: Parser) -> None:
    """The policy and PPO."""
    add = parser.add_argument
    add("--hidden", type=positive_int, default=64, help="hidden units per layer")
    add(
        "--log-std",
        type=float,
        default=None,
        help="initial log-std (default: -1.6 after a warm start, else -0.5)",
    )
    ppo.add_arguments(
        parser,
        rollout=256,
        epochs=5,
        minibatches=4,
        lr=1e-4,
        anneal_lr=False,
        gamma=0.99,
        lam=0.95,
        clip=0.1,
        ent_coef=0.0,
        vf_coef=0.5,
        max_grad_norm=0.5,
    )
    add(
        "--critic-warmup",
        type=non_negative_int,
        default=3,
        help="critic-only PPO iterations after a warm start (at most all but one)",
    )


def _add_schedule_args(parser: Parser) -> None:
    """The option cut-off, checkpoints, the evaluation."""
    add = parser.add_argument
    add("--t-abs", type=positive_int, default=None, help="option cut-off (default: the spec's)")
    add("--save-every", type=positive_int, default=5, help="iterations between checkpoints")
    add(
        "--eval-episodes",
        type=non_negative_int,
        default=100,
        help="held-out options; 0: skip (at least 1 with --evaluate)",
    )


def _check_args(args):
    """Returns the parsed ``args`` once `parse_args`'s checks pass; raises
    `UsageError` otherwise."""
    from hier_agents.learning.skill_spec import SPECS

    try:
        spec = spec_named(args.spec)
    except ValueError:
        choice("skill spec", args.spec, sorted(SPECS))
        raise
    if args.estimator is not None:
        choice(f"estimator of the {spec.name} skill", args.estimator, spec.estimators)
    if args.evaluate is not None:
        if args.eval_episodes < 1:
            raise UsageError("--evaluate needs --eval-episodes >= 1")
        output_file(args.json, "--json")
        return args
    missing = [
        flag
        for flag, value in (("--frames", args.frames), ("--logdir", args.logdir))
        if value is None
    ]
    if missing:
        raise UsageError(f"training needs {' and '.join(missing)} (or --evaluate)")
    if args.json is not None:
        raise UsageError("--json goes with --evaluate (training writes LOGDIR/summary.json)")
    budget(args)
    return args


def _main(argv) -> int:
    args = parse_args(argv)
    if args.evaluate is not None:
        return evaluate_only(args, spec_named(args.spec))
    command = " ".join([PROG, *(sys.argv[1:] if argv is None else argv)])
    train(args, command)
    return 0


def main(argv=None) -> int:
    """``python -m hier_agents.learning.train_skill``: trains (or evaluates);
    exit status 0, 2 with one line on stderr for a bad input
    (`physics_planning.cli.run_main`)."""
    return run_main(PROG, _main, argv)


if __name__ == "__main__":
    sys.exit(main())
