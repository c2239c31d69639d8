"""Actor-learner throughput against the bare environment, same configuration.

    python benchmarks/learner_speed.py [--env mujoban/level1] [--agent expert-planner]
                                      [--frames 200000] [--actors 2] [--envs-per-actor 16]
                                      [--batch-size N] [--backend local|ray] [--json PATH]

1. **Bare environment**: ``envs.load(ENV)`` with the run's cameras (off by
   default), uniform random actions, one process: control steps per second
   (the best of three runs).
2. **Actor-learner**: `hier_agents.impala.learner.train` for ``--frames``
   environment frames into a temporary log directory; its throughput is the
   frames the learner consumed per wall-clock second between its first and
   last log lines (start-up -- process spawn, imports -- excluded), as
   written in ``progress.jsonl``.

Prints a table and, with ``--json``, writes {"env", "agent",
"learner_frames_per_s", "env_steps_per_s", "ratio", ...}.
"""

from __future__ import annotations

import argparse
import json
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from _common import write_json  # noqa: E402

import numpy as np  # noqa: E402

import envs  # noqa: E402


def bare_env_steps_per_s(name: str, cameras: bool, steps: int, seed: int = 0,
                         repeats: int = 3) -> float:
    """Best of ``repeats`` runs of ``steps`` random steps (resets included):
    the highest rate, so the ratio against it is the conservative one."""
    overrides = {} if cameras else {k: None for k in envs.overrides(name)
                                    if k.endswith("_camera")}
    env = envs.load(name, seed=seed, **overrides)
    spec = env.action_spec()
    rng = np.random.default_rng(seed)
    rates = []
    for _ in range(repeats):
        env.reset()
        done = 0
        start = time.perf_counter()
        while done < steps:
            timestep = env.step(rng.uniform(spec.minimum, spec.maximum))
            done += 1
            if timestep.last():
                env.reset()
        rates.append(done / (time.perf_counter() - start))
    env.close()
    return max(rates)


def learner_frames_per_s(args) -> dict:
    from hier_agents.impala.learner import TrainConfig, train

    with tempfile.TemporaryDirectory() as logdir:
        config = TrainConfig(env=args.env, condition=args.agent, steps=args.frames,
                             actors=args.actors, envs_per_actor=args.envs_per_actor,
                             backend=args.backend, logdir=logdir,
                             batch_size=args.batch_size, cameras=args.cameras,
                             seed=args.seed, log_every_s=2.0, checkpoint_every_s=1e9,
                             progress=False)
        start = time.perf_counter()
        counters = train(config)
        total_s = time.perf_counter() - start
        lines = [json.loads(line) for line in open(Path(logdir) / "progress.jsonl")]
    if len(lines) < 2:
        raise SystemExit(f"only {len(lines)} log lines: raise --frames for a steady-state rate")
    first, last = lines[0], lines[-1]
    steady = (last["frames"] - first["frames"]) / (last["wall_s"] - first["wall_s"])
    return {"learner_frames_per_s": steady, "frames": counters["frames"],
            "updates": counters["updates"], "total_s": total_s,
            "overall_frames_per_s": counters["frames"] / total_s,
            "policy_lag_updates": last.get("perf/policy_lag")}


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--env", default="mujoban/level1")
    parser.add_argument("--agent", default="expert-planner")
    parser.add_argument("--frames", type=int, default=200_000)
    parser.add_argument("--actors", type=int, default=2)
    parser.add_argument("--envs-per-actor", type=int, default=16)
    parser.add_argument("--batch-size", type=int, default=None)
    parser.add_argument("--backend", default="local")
    parser.add_argument("--cameras", action="store_true")
    parser.add_argument("--bare-steps", type=int, default=10_000)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--json", type=Path)
    args = parser.parse_args(argv)
    if args.env not in envs.names():
        parser.error(f"unknown environment {args.env!r}; known: {', '.join(envs.names())}")

    bare = bare_env_steps_per_s(args.env, args.cameras, args.bare_steps, args.seed)
    print(f"bare {args.env} (cameras {'on' if args.cameras else 'off'}): {bare:,.0f} steps/s",
          flush=True)
    learner = learner_frames_per_s(args)
    row = {"env": args.env, "agent": args.agent, "cameras": args.cameras,
           "actors": args.actors, "envs_per_actor": args.envs_per_actor,
           "backend": args.backend, "env_steps_per_s": bare, **learner,
           "ratio": learner["learner_frames_per_s"] / bare}
    print(f"{'env':<18} {'agent':<15} {'env steps/s':>11} {'learner frames/s':>16} "
          f"{'ratio':>6} {'updates':>7}")
    print(f"{row['env']:<18} {row['agent']:<15} {bare:>11,.0f} "
          f"{row['learner_frames_per_s']:>16,.0f} {row['ratio']:>6.2f} {row['updates']:>7}")
    if args.json:
        write_json(args.json, row)
    return 0


if __name__ == "__main__":
    sys.exit(main())
