"""Roll out an environment with a random policy and report what happened.

    python -m envs                      # mujoban/level1, 3 episodes
    python -m envs mujoban/level5-pegs --episodes 10 --seed 1
    python -m envs --list

Prints a progress bar while running and a table of episodes (return, control
steps, solved, steps per second). The random policy holds each uniformly drawn
action for 10 control steps; it is a baseline for the environment, not an
agent (see `hier_agents` for agents).
"""

from __future__ import annotations

import argparse
import json
import sys
import time

import numpy as np
from tqdm import tqdm

import envs


def rollout(name: str, episodes: int, seed: int, cameras: bool) -> list[dict]:
    env = envs.load(name, seed=seed, **({} if cameras else envs.no_cameras(name)))
    with env:  # closed (GL contexts, GNU Go) whatever happens
        spec = env.action_spec()
        rng = np.random.default_rng(seed)
        rows = []
        with tqdm(total=episodes * env.task.time_limit_steps, unit="step", desc=name,
                  file=sys.stderr, disable=None) as bar:
            for episode in range(episodes):
                timestep = env.reset()
                ret, steps, action = 0.0, 0, None
                start = time.perf_counter()
                while not timestep.last():
                    if steps % 10 == 0:
                        action = rng.uniform(spec.minimum, spec.maximum, size=spec.shape)
                    timestep = env.step(action)
                    ret += timestep.reward
                    steps += 1
                    bar.update(1)
                wall = time.perf_counter() - start
                rows.append({"episode": episode, "return": ret, "steps": steps,
                             # Solved (MuJoBan) or won (board games): a terminal
                             # step paying at least 1.
                             "solved": bool(timestep.discount == 0.0 and timestep.reward >= 1.0),
                             "steps_per_s": steps / wall})
                bar.total -= env.task.time_limit_steps - steps
                bar.refresh()
    return rows


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(prog="python -m envs", description=__doc__.split("\n\n")[0])
    parser.add_argument("env", nargs="?", default="mujoban/level1", help="environment name")
    parser.add_argument("--episodes", type=int, default=3)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--no-cameras", action="store_true", help="switch camera observations off")
    parser.add_argument("--json", help="also write the rows to this file")
    parser.add_argument("--list", action="store_true", help="list environment names and exit")
    args = parser.parse_args(argv)
    if args.list:
        for name in envs.names():
            print(f"{name:<28} {envs.describe(name)}")
        return 0
    if args.env not in envs.names():
        parser.error(f"unknown environment {args.env!r}; known: {', '.join(envs.names())}")
    if args.episodes < 1:
        parser.error("--episodes must be >= 1")
    rows = rollout(args.env, args.episodes, args.seed, not args.no_cameras)
    print(f"\n{args.env}, random policy, seed {args.seed}")
    print(f"{'episode':>7} {'return':>8} {'steps':>6} {'success':>7} {'steps/s':>8}")
    for r in rows:
        print(f"{r['episode']:>7} {r['return']:>8.1f} {r['steps']:>6} {str(r['solved']):>7} "
              f"{r['steps_per_s']:>8.0f}")
    solved = sum(r["solved"] for r in rows)
    print(f"solved or won {solved}/{len(rows)}, mean return {np.mean([r['return'] for r in rows]):.2f}")
    if args.json:
        with open(args.json, "w") as f:
            json.dump({"env": args.env, "seed": args.seed, "episodes": rows}, f, indent=2)
    return 0


if __name__ == "__main__":
    sys.exit(main())
