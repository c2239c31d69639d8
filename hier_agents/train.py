"""Train the paper's end-to-end agent (IMPALA-style actor-critic, V-trace).

    python -m hier_agents.train mujoban/level1 --condition expert-planner --frames 2000000
    python -m hier_agents.train mujoban/level1 --condition vanilla --frames 2000000 --logdir runs/vanilla
    python -m hier_agents.train mujoxo/mixture --condition random-planner --actors 2 --backend ray
    tensorboard --logdir runs                       # the curves
    python -m hier_agents.run mujoban/level1 --agent checkpoint:runs/impala   # evaluate

Agents (the paper's conditions): ``vanilla`` (environment reward, one value
head), ``random-planner`` and ``expert-planner`` (current and target abstract
states as inputs, an auxiliary reward when the planner's transition is
reached within ``T_abs`` = 50 steps, a second value head with its own
discount). Cameras are off by default (proprioception and, for the planner
conditions, the abstract state); ``--cameras`` feeds the paper's 96x96 RGB
views through the residual network (much slower on a CPU).

Running the same command again with the same ``--logdir`` resumes from its
checkpoint (saved every ``--checkpoint-every`` seconds, at the end and on
Ctrl-C). ``--backend ray`` runs the actors as Ray actors (a local Ray
instance, or ``--ray-address auto`` for a cluster made with ``ray start``).
"""

from __future__ import annotations

import argparse
import json
import sys

import envs
from hier_agents.baselines.impala.agent_env import CONDITIONS


class _Formatter(argparse.RawDescriptionHelpFormatter, argparse.ArgumentDefaultsHelpFormatter):
    """The module docstring as written, and every flag's default."""


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(prog="python -m hier_agents.train",
                                     description=__doc__.split("\n\n")[0],
                                     formatter_class=_Formatter,
                                     epilog=__doc__.split("\n\n", 1)[1])
    parser.add_argument("env", help="environment name, e.g. mujoban/level1")
    parser.add_argument("--condition", default="vanilla",
                        help=f"the training condition: one of {list(CONDITIONS)}")
    parser.add_argument("--frames", type=int, default=1_000_000,
                        help="environment frames (control steps) to train for, in total")
    parser.add_argument("--actors", type=int, default=2, help="actor processes / Ray actors")
    parser.add_argument("--envs-per-actor", type=int, default=32,
                        help="environments stepped together by one actor (one batched policy call)")
    parser.add_argument("--backend", default="local", help="local or ray")
    parser.add_argument("--ray-address", default=None,
                        help="join a running Ray cluster (e.g. auto); default: start one")
    parser.add_argument("--logdir", default="runs/impala")
    parser.add_argument("--unroll-length", type=int, default=100)
    parser.add_argument("--batch-size", type=int, default=None,
                        help="unrolls per update (default: the paper's 128 MuJoBan, 64 board games)")
    parser.add_argument("--learning-rate", type=float, default=3e-4)
    parser.add_argument("--entropy-cost", type=float, default=1e-3)
    parser.add_argument("--abs-reward", type=float, default=1.0,
                        help="auxiliary reward for reaching the planner's target")
    parser.add_argument("--cameras", action="store_true", help="feed 96x96 camera images")
    parser.add_argument("--state", action="store_true",
                        help="feed the current abstract state at every step (MuJoBan: "
                             "full_entity_layer, privileged; not in the paper)")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--checkpoint-every", type=float, default=300.0, help="seconds")
    parser.add_argument("--keep-checkpoints", action="store_true",
                        help="also keep every checkpoint as LOGDIR/checkpoints/frames-N.pt "
                             "(for benchmarks/learning_curve.py)")
    parser.add_argument("--log-every", type=float, default=10.0,
                        help="seconds between TensorBoard / scalars.jsonl rows")
    parser.add_argument("--no-progress", action="store_true")
    args = parser.parse_args(argv)

    if args.env not in envs.names():
        parser.error(f"unknown environment {args.env!r}; known: {', '.join(envs.names())}")
    if args.condition not in CONDITIONS:
        parser.error(f"unknown condition {args.condition!r}; valid: {', '.join(CONDITIONS)}")
    if args.backend not in ("local", "ray"):
        parser.error(f"unknown backend {args.backend!r}; valid: local, ray")
    from hier_agents.baselines.impala.learner import TrainConfig, train

    config = TrainConfig(env=args.env, condition=args.condition, steps=args.frames,
                         actors=args.actors, envs_per_actor=args.envs_per_actor,
                         backend=args.backend, ray_address=args.ray_address,
                         logdir=args.logdir, unroll_length=args.unroll_length,
                         batch_size=args.batch_size, learning_rate=args.learning_rate,
                         entropy_cost=args.entropy_cost, abs_reward=args.abs_reward,
                         cameras=args.cameras, state=args.state, seed=args.seed,
                         checkpoint_every_s=args.checkpoint_every, log_every_s=args.log_every,
                         keep_checkpoints=args.keep_checkpoints,
                         progress=not args.no_progress)
    try:
        config.validate()
    except ValueError as exc:
        parser.error(str(exc))
    counters = train(config)
    counters.pop("last_stats", None)
    print(json.dumps(counters, indent=2))
    return 0


if __name__ == "__main__":
    sys.exit(main())
