"""Learning curves of `hier_agents.train` runs: training statistics and evaluations.

    python benchmarks/learning_curve.py RUN [RUN ...] [--every-frames 1000000]
                                        [--eval-episodes N] [--stochastic] [--seed S]
                                        [--json PATH]

For each run directory (a ``--logdir`` of `hier_agents.train`):

1. **Training curve**, from its ``scalars.jsonl``: one row per
   ``--every-frames`` frames (the last log line at or before each mark, and
   the run's last line): wall minutes, the success rate and return of the
   last 100 training episodes (actions sampled from the policy, as trained),
   episode length and auxiliary subgoals reached per episode.
2. **Evaluation curve** (``--eval-episodes N``): every kept checkpoint
   (``checkpoints/frames-*.pt``, written by ``--keep-checkpoints``) and the
   final ``checkpoint.pt`` play N episodes on the same seed through
   `hier_agents.run` (the policy's mean; ``--stochastic`` samples), giving the
   success rate with its 95% Wilson interval. For MuJoBan planner
   conditions it also measures the **target sensitivity**: along one
   greedy episode, the policy's mean action is computed for each of the four
   possible target moves (the ``planner_action`` one-hot) from the same
   observation and core state; the spread (standard deviation across the
   four, averaged over actions and steps) is ~0 for a policy that ignores
   the planner's target.

Prints the tables and, with ``--json``, writes
``{"runs": [{"logdir", "env", "condition", "settings", "training": [...],
"evaluation": [...]}]}`` (``settings``: the run's `SETTINGS` from its config).
"""

from __future__ import annotations

import json
import re
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from _common import cli, make_parser, prog, write_json  # noqa: E402
from hier_agents.learning.rundir import SCALARS  # noqa: E402

PROG = prog(__file__)


def training_curve(logdir: Path, every: int) -> list[dict]:
    path = logdir / SCALARS
    if not path.exists():
        path = logdir / "progress.jsonl"  # runs written before the shared run directory
    if not path.exists():
        raise SystemExit(f"{logdir}: no {SCALARS} (is it a hier_agents.train --logdir?)")
    lines = [json.loads(line) for line in open(path) if line.strip()]
    if not lines:
        return []
    picked, mark, i = [], every, 0
    while mark < lines[-1]["frames"] + every:
        while i + 1 < len(lines) and lines[i + 1]["frames"] <= mark:
            i += 1
        if lines[i]["frames"] <= mark and (not picked or picked[-1] is not lines[i]):
            picked.append(lines[i])
        mark += every
    if picked[-1] is not lines[-1]:
        picked.append(lines[-1])
    return [
        {
            "frames": line["frames"],
            "wall_min": line.get("wall_s", 0.0) / 60.0,
            "train_success_rate": line.get("episodes/success_rate"),
            "train_return": line.get("episodes/return"),
            "episode_steps": line.get("episodes/steps"),
            "subgoals_reached": line.get("episodes/subgoals_reached"),
            "episodes": line.get("episodes/count"),
        }
        for line in picked
    ]


def target_sensitivity(path: Path, seed: int, steps: int = 300) -> float | None:
    """Spread of the greedy action across the four MuJoBan target moves (see above)."""
    import numpy as np
    import torch

    from hier_agents.baselines.impala.agent_env import AgentEnv
    from hier_agents.baselines.impala.checkpoints import load_checkpoint, net_from_checkpoint

    ckpt = load_checkpoint(path)
    config = ckpt["config"]
    net, spec = net_from_checkpoint(ckpt)
    if spec.planner_action_dim == 0:
        return None
    k = spec.planner_action_dim
    with AgentEnv(
        config["env"],
        config["condition"],
        seed=seed,
        cameras=config["cameras"],
        image_size=config["image_size"],
        state=config.get("state", False),
        t_abs=config["t_abs"],
        abs_reward=config["abs_reward"],
        **config.get("env_overrides", {}),
    ) as env:
        obs = env.reset()
        state, first, spreads = net.initial_state(k), np.ones(k, bool), []
        for _ in range(steps):
            batch = {name: np.repeat(v[None], k, axis=0) for name, v in obs.items()}
            batch["planner_action"] = np.eye(k, dtype=np.float32)
            with torch.no_grad():
                actions, _, state = net.act(batch, first, state, deterministic=True)
            first[:] = False
            spreads.append(float(actions.std(axis=0).mean()))
            target = obs["planner_action"]
            # Step with the action of the actual target (the first move's without one).
            result = env.step(actions[int(target.argmax()) if target.any() else 0])
            if result.last:
                break
            obs = result.obs
    return float(np.mean(spreads))


def evaluation_curve(
    logdir: Path, env: str, episodes: int, seed: int, stochastic: bool, workers: int = 1
) -> list[dict]:
    from hier_agents.baselines.impala.checkpoints import CHECKPOINT, KEPT_CHECKPOINTS
    from hier_agents.run import run

    def frames_of(p: Path) -> int:
        match = re.fullmatch(r"frames-(\d+)\.pt", p.name)
        return int(match.group(1)) if match else -1

    files = sorted(
        (p for p in (logdir / KEPT_CHECKPOINTS).glob("frames-*.pt") if frames_of(p) >= 0),
        key=frames_of,
    )
    if (logdir / CHECKPOINT).exists():
        files.append(logdir / CHECKPOINT)
    rows, seen = [], set()
    for path in files:
        summary = run(
            env,
            episodes,
            seed,
            agent=f"checkpoint:{path}",
            stochastic=stochastic,
            progress=False,
            workers=workers,
        )
        if summary["training_frames"] in seen:  # the final checkpoint is also kept
            continue
        seen.add(summary["training_frames"])
        lo, hi = summary.get("success_interval") or summary.get("win_interval")
        rows.append(
            {
                "frames": summary["training_frames"],
                "checkpoint": str(path),
                "success_rate": summary["success_rate"],
                "interval": [lo, hi],
                "mean_return": summary["mean_return"],
                "mean_steps": summary["mean_steps"],
                "subgoal_success_rate": summary["subgoal_success_rate"],
                "target_sensitivity": target_sensitivity(path, seed),
            }
        )
        print(
            f"  evaluated {path.name}: {100 * summary['success_rate']:.1f}% "
            f"[{100 * lo:.1f}, {100 * hi:.1f}]",
            file=sys.stderr,
            flush=True,
        )
    return rows


def _fmt(x, spec: str, scale: float = 1.0) -> str:
    return format("-", spec.split(".")[0]) if x is None else format(scale * x, spec)


def _pct_or_dash(x, width: int) -> str:
    return f"{'-':>{width}}" if x is None else f"{100 * x:>{width - 1}.1f}%"


def _main(argv=None) -> int:
    parser = make_parser(__file__, __doc__)
    parser.add_argument(
        "runs", nargs="+", type=Path, metavar="RUN", help="hier_agents.train --logdir folders"
    )
    parser.add_argument(
        "--every-frames",
        type=cli.positive_int,
        default=1_000_000,
        help="frames between curve points",
    )
    parser.add_argument(
        "--eval-episodes",
        type=cli.non_negative_int,
        default=0,
        help="episodes per kept checkpoint to evaluate (0: training curve only)",
    )
    parser.add_argument(
        "--stochastic",
        action="store_true",
        help="evaluation samples from the policy instead of taking its mean",
    )
    parser.add_argument("--seed", type=cli.non_negative_int, default=0)
    parser.add_argument(
        "--workers",
        type=cli.positive_int,
        default=1,
        help="processes playing the evaluation episodes at once (same rows)",
    )
    parser.add_argument("--json", type=Path, help="write the curves here")
    args = parser.parse_args(argv)
    for logdir in args.runs:
        if not any((logdir / name).is_file() for name in (SCALARS, "progress.jsonl")):
            raise cli.UsageError(
                f"{logdir} is not a hier_agents.train run directory (no {SCALARS} in it)"
            )
        if args.eval_episodes and not (logdir / "checkpoint.pt").is_file():
            raise cli.UsageError(
                f"{logdir}: no checkpoint.pt to evaluate yet "
                f"(drop --eval-episodes for the training curve)"
            )
    cli.output_file(args.json, "--json")

    from hier_agents.baselines.impala.checkpoints import load_checkpoint

    out = []
    for logdir in args.runs:
        try:
            config = load_checkpoint(logdir)["config"]
        except FileNotFoundError:  # a run still before its first checkpoint
            config = {
                k: "?"
                for k in (
                    "env",
                    "condition",
                    "batch_size",
                    "learning_rate",
                    "actors",
                    "envs_per_actor",
                )
            }
        result = {
            "logdir": str(logdir),
            "env": config["env"],
            "condition": config["condition"],
            "settings": {k: config.get(k, "?") for k in SETTINGS},
            "training": training_curve(logdir, args.every_frames),
            "evaluation": [],
        }
        if config["condition"] == "vanilla":  # no planner, no subgoals
            for row in result["training"]:
                row["subgoals_reached"] = None
        print(
            f"\n{logdir}: {config['env']} {config['condition']} "
            f"(batch {config['batch_size'] or 'paper'}, unroll {config['unroll_length']}, "
            f"action repeat {config.get('action_repeat', 1)}, lr {config['learning_rate']}, "
            f"{config['actors']} actors x {config['envs_per_actor']} envs)"
        )
        print(
            f"{'frames':>11} {'wall min':>8} {'train success':>13} {'return':>7} "
            f"{'ep steps':>8} {'subgoals/ep':>11}"
        )
        for r in result["training"]:
            print(
                f"{r['frames']:>11,} {r['wall_min']:>8.1f} "
                f"{_pct_or_dash(r['train_success_rate'], 13)} "
                f"{_fmt(r['train_return'], '>7.2f')} {_fmt(r['episode_steps'], '>8.0f')} "
                f"{_fmt(r['subgoals_reached'], '>11.2f')}"
            )
        if args.eval_episodes:
            result["evaluation"] = evaluation_curve(
                logdir, config["env"], args.eval_episodes, args.seed, args.stochastic, args.workers
            )
            mode = "sampled" if args.stochastic else "mean action"
            print(f"evaluation ({args.eval_episodes} episodes, seed {args.seed}, {mode}):")
            print(
                f"{'frames':>11} {'success % [95% CI]':>22} {'return':>7} {'steps':>7} "
                f"{'subgoal %':>9} {'target sensitivity':>18}"
            )
            for r in result["evaluation"]:
                lo, hi = r["interval"]
                print(
                    f"{r['frames']:>11,} {100 * r['success_rate']:>6.1f} "
                    f"[{100 * lo:5.1f},{100 * hi:5.1f}]   {r['mean_return']:>7.2f} "
                    f"{r['mean_steps']:>7.1f} {_pct_or_dash(r['subgoal_success_rate'], 9)} "
                    f"{_fmt(r['target_sensitivity'], '>18.4f')}"
                )
        out.append(result)
    if args.json:
        write_json(
            args.json,
            {
                "every_frames": args.every_frames,
                "eval_episodes": args.eval_episodes,
                "seed": args.seed,
                "stochastic": args.stochastic,
                "runs": out,
            },
        )
    return 0


#: The training settings each run's JSON entry repeats from its config.
SETTINGS = (
    "unroll_length",
    "batch_size",
    "passes",
    "action_repeat",
    "learning_rate",
    "optimizer",
    "normalize_advantages",
    "clip_ratio",
    "entropy_cost",
    "actors",
    "envs_per_actor",
    "seed",
    "state",
    "state_channels",
    "cameras",
    "steps",
)


def main(argv=None) -> int:
    """Reads (and evaluates) the runs, prints their curves, writes ``--json``;
    bad input: one line on stderr, exit status 2, before any evaluation."""
    return cli.run_main(PROG, _main, argv)


if __name__ == "__main__":
    sys.exit(main())
