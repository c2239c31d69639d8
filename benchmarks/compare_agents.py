"""The modular agent and trained end-to-end agents side by side, same seeds.

    python benchmarks/compare_agents.py ENV [--episodes N] [--seed S]
                                        [--checkpoint PATH ...] [--random HOLD ...]
                                        [--stochastic] [--json PATH]

Agents: the modular agent (unless ``--no-modular``), every ``--checkpoint``
(its policy's mean; ``--stochastic`` samples instead) and uniformly random
actions held for each ``--random`` HOLD control steps (default 1 and 10: the
floor a trained agent must clear). Every agent plays ``--episodes`` episodes
in an environment built with the same ``--seed`` (the same level or opening
sequence as long as the environment's random draws do not depend on the
agent's play). One row per agent: success rate (MuJoBan: solved; board
games: won) with its 95% Wilson interval, draw and loss rates for board
games, mean control steps, mean return, wall seconds per episode and the
training frames the agent used (0 for the modular agent, which is not
trained).
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from _common import write_json  # noqa: E402

import envs  # noqa: E402
from hier_agents.run import run  # noqa: E402


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("env")
    parser.add_argument("--episodes", type=int, default=20)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--checkpoint", nargs="*", default=[],
                        help="hier_agents.train run directories or checkpoint files")
    parser.add_argument("--no-modular", action="store_true", help="leave the modular agent out")
    parser.add_argument("--random", type=int, nargs="*", default=[1, 10], metavar="HOLD",
                        help="random-action rows, one per hold (control steps per draw); "
                             "give the flag alone for none")
    parser.add_argument("--stochastic", action="store_true",
                        help="checkpoints sample from their policy instead of taking its mean")
    parser.add_argument("--json", type=Path)
    args = parser.parse_args(argv)
    if args.env not in envs.names():
        parser.error(f"unknown environment {args.env!r}; known: {', '.join(envs.names())}")
    if any(h < 1 for h in args.random):
        parser.error(f"--random holds must be >= 1, got {args.random}")
    agents = (([] if args.no_modular else ["modular"])
              + [f"checkpoint:{p}" for p in args.checkpoint]
              + [f"random:{h}" for h in args.random])
    if not agents:
        parser.error("nothing to compare: give --checkpoint PATH or drop --no-modular")
    rows = []
    for agent in agents:
        summary = run(args.env, args.episodes, args.seed, agent=agent,
                      stochastic=args.stochastic and agent.startswith("checkpoint:"))
        summary.pop("rows", None)
        summary.setdefault("training_frames", 0)
        rows.append(summary)
    board = "win_rate" in rows[0]
    names = [r["agent"] if r["agent"] == "modular" or r["agent"].startswith("random")
             else f"{r['agent']} ({r['condition']})" for r in rows]
    width = max(20, *map(len, names))
    head = (f"{'agent':<{width}} {'success % [95% CI]':>22} "
            + (f"{'draw %':>7} {'loss %':>7} " if board else "")
            + f"{'steps':>7} {'return':>7} {'s/ep':>6} {'train frames':>13}")
    print(head)
    print("-" * len(head))
    for name, r in zip(names, rows):
        lo, hi = r.get("success_interval") or r.get("win_interval")
        line = (f"{name:<{width}} {100 * r['success_rate']:>6.1f} [{100 * lo:5.1f},{100 * hi:5.1f}]"
                f"{'':>4} ")
        if board:
            line += f"{100 * r['draw_rate']:>7.1f} {100 * r['loss_rate']:>7.1f} "
        line += (f"{r['mean_steps']:>7.1f} {r['mean_return']:>7.2f} {r['wall_s']:>6.2f} "
                 f"{r['training_frames']:>13,}")
        print(line)
    if args.json:
        write_json(args.json, {"env": args.env, "episodes": args.episodes, "seed": args.seed,
                               "rows": rows})
    return 0


if __name__ == "__main__":
    sys.exit(main())
