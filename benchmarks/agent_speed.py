"""The observation-only modular agent's speed against the environment alone.

    python benchmarks/agent_speed.py [--env mujoban/level5-pegs] [--episodes 20]
        [--steps 3000] [--rounds 2] [--baseline REF] [--json PATH]

Per round and per code tree, as a user runs them (each a fresh process):

* the agent: ``python -m hier_agents.run ENV --episodes N --profile --json``
  (the default agent: camera estimator, planner, skill); its control steps/s
  are the episodes' steps over their summed wall time (start-up and
  environment building excluded), with the shares of that time per section
  (physics, render, estimator, planner, skill, other; `envs.profile`);
* the environment alone: ``python benchmarks/env_speed.py --envs ENV
  --cameras none --steps S`` (random actions held 10 steps, no camera): its
  control steps/s and the physics limit (raw ``mj_step`` on the same model).

``ratio`` is the agent's steps/s over the environment alone's, measured in
the same round. With ``--baseline REF`` the same two measurements also run
from a git worktree of commit REF (made in a temporary folder, removed
after), alternating with the current tree in every round, so that both see
the same machine load: ``x_baseline`` is the current agent's steps/s over
the baseline's, round by round. Nothing else should run on the machine.

Prints a table and, with --json, writes ``{"provenance", "env", "episodes",
"steps", "rounds": [...], "summary": {...}}``.
"""

from __future__ import annotations

import json
import sys
import tempfile
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from _common import (
    env_cli,
    baseline_worktree,
    cli,
    make_parser,
    prog,
    remove_worktree,  # noqa: E402
    run_in_tree,
    write_json,
)

PROG = prog(__file__)
ROOT = Path(__file__).resolve().parents[1]
SECTIONS = ("physics", "render", "estimator", "planner", "skill")


def measure_agent(tree: Path, env_name: str, episodes: int, seed: int, tmp: Path) -> dict:
    """The default modular agent's control steps/s over its episodes' wall
    time, solved share and time shares per section, played from ``tree``."""
    out = tmp / "agent.json"
    run_in_tree(
        tree,
        [
            sys.executable,
            "-m",
            "hier_agents.run",
            env_name,
            "--episodes",
            str(episodes),
            "--seed",
            str(seed),
            "--profile",
            "--json",
            str(out),
        ],
        timeout=3600,
    )
    summary = json.loads(out.read_text())
    rows = summary["rows"]
    steps = sum(r["steps"] for r in rows)
    wall = sum(r["wall_s"] for r in rows)
    spent = {name: sum(r.get("profile_s", {}).get(name, 0.0) for r in rows) for name in SECTIONS}
    shares = {name: round(t / wall, 4) for name, t in spent.items()}
    shares["other"] = round(max(0.0, 1.0 - sum(spent.values()) / wall), 4)
    return {
        "steps_per_s": round(steps / wall, 1),
        "steps": steps,
        "wall_s": round(wall, 2),
        "success_rate": summary["success_rate"],
        "shares": shares,
        "estimator": summary.get("estimator"),
    }


def measure_env(tree: Path, env_name: str, steps: int, tmp: Path) -> dict:
    """The environment alone without cameras and its physics limit
    (`benchmarks/env_speed.py`), from ``tree``."""
    out = tmp / "env.json"
    run_in_tree(
        tree,
        [
            sys.executable,
            "benchmarks/env_speed.py",
            "--envs",
            env_name,
            "--cameras",
            "none",
            "--steps",
            str(steps),
            "--json",
            str(out),
        ],
        timeout=1800,
    )
    row = json.loads(out.read_text())["rows"][0]
    return {
        "steps_per_s": row["steps_per_s"],
        "physics_limit_steps_per_s": row["physics_limit_steps_per_s"],
    }


def _mean(values):
    return round(sum(values) / len(values), 3)


def summarize(rounds: list[dict]) -> dict:
    """Per tree: mean agent and environment steps/s and ratio over rounds;
    with a baseline, the mean of the per-round ``x_baseline``."""
    out = {}
    for tree in rounds[0]["trees"]:
        rows = [r["trees"][tree] for r in rounds]
        out[tree] = {
            "agent_steps_per_s": _mean([r["agent"]["steps_per_s"] for r in rows]),
            "env_steps_per_s": _mean([r["env"]["steps_per_s"] for r in rows]),
            "physics_limit_steps_per_s": _mean(
                [r["env"]["physics_limit_steps_per_s"] for r in rows]
            ),
            "ratio": _mean([r["ratio"] for r in rows]),
            "success_rate": _mean([r["agent"]["success_rate"] for r in rows]),
            "shares": {
                k: _mean([r["agent"]["shares"][k] for r in rows])
                for k in rows[0]["agent"]["shares"]
            },
        }
    if "baseline" in out:
        out["x_baseline"] = _mean([r["x_baseline"] for r in rounds])
    return out


def format_table(env_name: str, rounds: list[dict], summary: dict) -> str:
    lines = [
        f"{env_name}: control steps/s, agent (camera estimator) and environment alone (no camera)",
        f"  {'round':>5} {'tree':<9} {'agent':>8} {'env alone':>10} {'ratio':>6} "
        f"{'solved':>7}  shares",
    ]
    for i, r in enumerate(rounds):
        for tree, m in r["trees"].items():
            shares = " ".join(f"{k} {100 * v:.0f}%" for k, v in m["agent"]["shares"].items())
            lines.append(
                f"  {i + 1:>5} {tree:<9} {m['agent']['steps_per_s']:>8.1f} "
                f"{m['env']['steps_per_s']:>10.1f} {m['ratio']:>6.3f} "
                f"{100 * m['agent']['success_rate']:>6.1f}%  {shares}"
            )
    for tree in r["trees"]:
        s = summary[tree]
        lines.append(
            f"  {'mean':>5} {tree:<9} {s['agent_steps_per_s']:>8.1f} "
            f"{s['env_steps_per_s']:>10.1f} {s['ratio']:>6.3f}"
        )
    if "x_baseline" in summary:
        lines.append(f"  current agent / baseline agent: {summary['x_baseline']:.2f}x")
    return "\n".join(lines)


def _main(argv=None) -> int:
    parser = make_parser(__file__, __doc__)
    parser.add_argument("--env", default="mujoban/level5-pegs")
    parser.add_argument("--episodes", type=cli.positive_int, default=20)
    parser.add_argument(
        "--steps",
        type=cli.positive_int,
        default=3000,
        help="control steps of the environment-alone measurement",
    )
    parser.add_argument("--rounds", type=cli.positive_int, default=2)
    parser.add_argument("--seed", type=cli.non_negative_int, default=0)
    parser.add_argument(
        "--baseline", metavar="REF", help="also measure this git commit's code, alternating"
    )
    parser.add_argument("--json", type=Path, help="write the results here")
    args = parser.parse_args(argv)
    env_cli.environment(args.env)
    cli.output_file(args.json, "--json")
    with tempfile.TemporaryDirectory() as tmp_name:
        tmp = Path(tmp_name)
        trees = {"current": ROOT}
        if args.baseline:
            trees["baseline"] = baseline_worktree(args.baseline, tmp)
        try:
            rounds = []
            for i in range(args.rounds):
                record = {"trees": {}}
                for label, tree in trees.items():
                    print(
                        f"{PROG}: round {i + 1}/{args.rounds}, {label}", file=sys.stderr, flush=True
                    )
                    agent = measure_agent(tree, args.env, args.episodes, args.seed, tmp)
                    env = measure_env(tree, args.env, args.steps, tmp)
                    record["trees"][label] = {
                        "agent": agent,
                        "env": env,
                        "ratio": round(agent["steps_per_s"] / env["steps_per_s"], 4),
                    }
                if args.baseline:
                    record["x_baseline"] = round(
                        record["trees"]["current"]["agent"]["steps_per_s"]
                        / record["trees"]["baseline"]["agent"]["steps_per_s"],
                        4,
                    )
                rounds.append(record)
        finally:
            if args.baseline:
                remove_worktree(trees["baseline"])
    summary = summarize(rounds)
    print(format_table(args.env, rounds, summary))
    if args.json:
        write_json(
            args.json,
            {
                "env": args.env,
                "episodes": args.episodes,
                "steps": args.steps,
                "seed": args.seed,
                "baseline": args.baseline,
                "rounds": rounds,
                "summary": summary,
            },
        )
    return 0


def main(argv=None) -> int:
    """Measures and prints; exit status 0, 2 with one line on stderr for bad input."""
    return cli.run_main(PROG, _main, argv)


if __name__ == "__main__":
    sys.exit(main())
