"""Roll out an environment with a random policy and report what happened.

    python -m envs                      # mujoban/level1, 3 episodes
    python -m envs mujoban/level5-pegs --episodes 10 --seed 1
    python -m envs --list
    python -m envs mujoban/level1 --env-option time_limit=5 --json out/rows.json

Prints a progress bar while running and a table of episodes (return, control
steps, solved, steps per second). The random policy holds each uniformly drawn
action for 10 control steps; it is a baseline for the environment, not an
agent (see `hier_agents` for agents). Bad input (an unknown name, a negative
seed, a bad ``--env-option``, an output path that cannot be written) ends the
command with one line on stderr and exit status 2 (`physics_planning.cli`).
"""

from __future__ import annotations

import sys
import time

import numpy as np
from tqdm import tqdm

import envs
from envs import cli as env_cli
from physics_planning import cli

PROG = "python -m envs"


def rollout(
    name: str, episodes: int, seed: int, cameras: bool, env_options: dict | None = None
) -> list[dict]:
    """Plays ``episodes`` random-policy episodes of environment ``name``
    (`envs.load` overrides ``env_options``; cameras off unless ``cameras``);
    returns one row per episode: episode, return, steps, solved, steps_per_s."""
    options = {**({} if cameras else envs.no_cameras(name)), **(env_options or {})}
    env = envs.load(name, seed=seed, **options)
    with env:  # closed (GL contexts, GNU Go) whatever happens
        spec = env.action_spec()
        rng = np.random.default_rng(seed)
        rows = []
        with tqdm(
            total=episodes * env.task.time_limit_steps,
            unit="step",
            desc=name,
            file=sys.stderr,
            disable=None,
        ) as bar:
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
                rows.append(
                    {
                        "episode": episode,
                        "return": ret,
                        "steps": steps,
                        # Solved (MuJoBan) or won (board games): a terminal
                        # step paying at least 1.
                        "solved": bool(timestep.discount == 0.0 and timestep.reward >= 1.0),
                        "steps_per_s": steps / wall,
                    }
                )
                bar.total -= env.task.time_limit_steps - steps
                bar.refresh()
    return rows


def _main(argv=None) -> int:
    parser = cli.Parser(
        PROG, description=__doc__.split("\n\n")[0], epilog="examples:\n" + __doc__.split("\n\n")[1]
    )
    parser.add_argument(
        "env", nargs="?", default="mujoban/level1", help="environment name (see --list)"
    )
    parser.add_argument("--episodes", type=cli.positive_int, default=3)
    parser.add_argument("--seed", type=cli.non_negative_int, default=0)
    parser.add_argument("--no-cameras", action="store_true", help="switch camera observations off")
    env_cli.add_env_option(parser)
    parser.add_argument(
        "--json", metavar="FILE", help="also write the rows to this file (its folder is created)"
    )
    parser.add_argument("--list", action="store_true", help="list environment names and exit")
    args = parser.parse_args(argv)
    if args.list:
        for name in envs.names():
            print(f"{name:<28} {envs.describe(name)}")
        return 0
    name = env_cli.environment(args.env)
    options = env_cli.env_options(name, args.env_option)
    out = cli.output_file(args.json, "--json")
    rows = rollout(name, args.episodes, args.seed, not args.no_cameras, options)
    print(f"\n{name}, random policy, seed {args.seed}")
    print(f"{'episode':>7} {'return':>8} {'steps':>6} {'success':>7} {'steps/s':>8}")
    for r in rows:
        print(
            f"{r['episode']:>7} {r['return']:>8.1f} {r['steps']:>6} {str(r['solved']):>7} "
            f"{r['steps_per_s']:>8.0f}"
        )
    solved = sum(r["solved"] for r in rows)
    print(
        f"solved or won {solved}/{len(rows)}, mean return "
        f"{np.mean([r['return'] for r in rows]):.2f}"
    )
    if out is not None:
        cli.write_json(
            out, {"env": name, "seed": args.seed, "env_options": options, "episodes": rows}
        )
        print(f"wrote {out}")
    return 0


def main(argv=None) -> int:
    """``python -m envs``: rolls out, prints the table, writes ``--json``;
    returns 0. Bad input: one line on stderr, `SystemExit` status 2."""
    return cli.run_main(PROG, _main, argv)


if __name__ == "__main__":
    sys.exit(main())
