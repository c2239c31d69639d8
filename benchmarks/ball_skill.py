"""Solve rate of the Sokoban solver + MuJoBan ball skill, per environment.

    python benchmarks/ball_skill.py [--envs NAME ...] [--episodes N] [--seed S]
                                    [--t-abs T] [--json PATH]

Each episode runs the option layer (`hier_agents.modular.agent.ModularAgent`)
with the physical walker:

1. estimate the scene: by default with the privileged ``oracle`` (the
   simulator's positions and the task's rounded cells), which isolates the
   skill; ``--estimator camera`` for the observation-only agent (every row
   says which, and ``privileged``);
2. plan: ``SokobanSolverPlanner.next_push(state)`` (the walk to the next box
   and its push; the solver caches its solution, so replanning along it is
   free, and it re-solves after a deviation); when the estimate is already
   solved but the episode is not (a box rounds onto its pad without covering
   it), the empty subgoal ``Subgoal(action=(), state=state)``, on which the
   skill centres the boxes;
3. run `skills.ball.BallSkill` on the subgoal until it reports success or
   failure or ``--t-abs`` (50) control steps passed, then go back to 1.

An episode is solved when the environment reports every pad covered within
its 900-step (45 s) limit.

Environment names: the registry's ``mujoban/level1`` ... ``mujoban/level5``
and ``-pegs`` variants (generated levels, a fresh one per episode from
``--seed``), and ``boxoban/<file>`` or ``boxoban/<file>-pegs`` for a shipped
Boxoban file (``envs/mujoban/data/boxoban/<file>.txt``) played in file
order from its first level (shown in MuJoBan's level-5 arena).

Per environment the table shows: episodes; solved %; its 95% Wilson score
interval; mean and 95th percentile of the control steps of the solved
episodes (of the 900 allowed); the subgoal success rate (subgoals the skill
reported reached / subgoals that ended: reached, failed or cut off at
T_abs); wall-clock seconds per episode; the most frequent skill failure
kinds. ``--json`` writes ``{"provenance", "rows"}``, rows with keys env, estimator,
privileged, episodes, solved,
solved_pct, wilson_low, wilson_high, mean_steps_solved, p95_steps_solved,
subgoals, subgoals_reached, subgoals_failed, subgoals_cut,
subgoal_success_rate, failures (kind -> count), no_plan (reason -> count),
mean_plan_moves (moves of the first solution), wall_s_per_episode.

The planner runs with its default 10 s budget per solve; the wall time
includes solving. The default run (12 rows of 100 episodes) takes several
minutes: with the original physics (1 ms steps) a level-5 episode takes ~1 s
of wall time, a level-1 episode ~0.04 s; ``--episodes 30`` for a quick look.
"""

from __future__ import annotations

import sys
import time
from collections import Counter
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from _common import env_cli, cli, make_parser, prog, write_json  # noqa: E402

import numpy as np  # noqa: E402
from tqdm import tqdm  # noqa: E402

import envs  # noqa: E402
from hier_agents.boundary import BoundaryEnv  # noqa: E402
from envs.mujoban.levels import BOXOBAN_DIR  # noqa: E402
from hier_agents.modular.components import check, is_privileged, make_agent  # noqa: E402
from hier_agents.modular.options import T_ABS  # noqa: E402
from hier_agents.learning.skills.ball import make_source_env  # noqa: E402
from hier_agents.stats import wilson_interval  # noqa: E402

PROG = prog(__file__)
MUJOBAN = [f"mujoban/level{d}{p}" for p in ("", "-pegs") for d in range(1, 6)]
BOXOBAN = ["boxoban/unfiltered-valid-000", "boxoban/unfiltered-valid-000-pegs"]


def make_env(name: str, seed: int, estimator: str = "oracle"):
    """The environment of a benchmark name (see the module docstring), with
    the cameras the estimator reads (none for the oracle); the option
    environments' `make_source_env`."""
    return make_source_env(name, seed, estimator)


def run_episode(view, agent) -> dict:
    """One episode of the option layer (`hier_agents.modular.agent.ModularAgent`:
    estimate -> plan -> skill); returns its counters."""
    timestep = view.reset()
    agent.reset(view.description(), timestep)
    steps = 0
    plan_moves = None
    while not timestep.last():
        action = agent.act(timestep)
        if agent.gave_up is not None:
            break
        if plan_moves is None and agent.subgoal is not None:
            plan_moves = len(agent.subgoal.action) + len(agent.subgoal.plan)
        timestep = view.step(action)
        steps += 1
    if agent.gave_up is None:
        agent.end_episode(timestep)
    stats = agent.episode_stats
    no_plan = agent.gave_up.split(":", 1)[0] if agent.gave_up else None
    return {
        "steps": steps,
        "issued": stats.issued,
        "reached": stats.reached,
        "failed": stats.failed,
        "cut": stats.cut_off + stats.unfinished,
        "failures": Counter(stats.failures),
        "no_plan": no_plan,
        "plan_moves": plan_moves,
    }


def measure(name: str, episodes: int, seed: int, t_abs: int, estimator: str = "oracle") -> dict:
    env = make_env(name, seed, estimator)
    privileged = is_privileged("mujoban", estimator)
    view = env if privileged else BoundaryEnv(env)
    with (
        env,
        make_agent(
            "mujoban/level1",
            view.description(),
            estimator=estimator,
            simulator=env if privileged else None,
            t_abs=t_abs,
        ) as agent,
    ):
        results = []
        t0 = time.perf_counter()
        for _ in tqdm(range(episodes), desc=name, unit="ep", leave=False):
            row = run_episode(view, agent)
            row["solved"] = bool(env.task.solved)
            results.append(row)
        wall = time.perf_counter() - t0
    solved = sum(r["solved"] for r in results)
    low, high = (100.0 * v for v in wilson_interval(solved, len(results)))
    reached = sum(r["reached"] for r in results)
    failed = sum(r["failed"] for r in results)
    cut = sum(r["cut"] for r in results)
    failures: Counter = Counter()
    for r in results:
        failures.update(r["failures"])
    no_plan = Counter(r["no_plan"] for r in results if r["no_plan"])
    solved_steps = [r["steps"] for r in results if r["solved"]]
    moves = [r["plan_moves"] for r in results if r["plan_moves"] is not None]
    return {
        "env": name,
        "estimator": estimator,
        "privileged": privileged,
        "episodes": len(results),
        "solved": solved,
        "solved_pct": 100.0 * solved / len(results),
        "wilson_low": round(low, 2),
        "wilson_high": round(high, 2),
        "mean_steps_solved": round(float(np.mean(solved_steps)), 1) if solved_steps else None,
        "p95_steps_solved": (
            round(float(np.percentile(solved_steps, 95)), 1) if solved_steps else None
        ),
        "subgoals": sum(r["issued"] for r in results),
        "subgoals_reached": reached,
        "subgoals_failed": failed,
        "subgoals_cut": cut,
        "subgoal_success_rate": round(reached / max(1, reached + failed + cut), 4),
        "failures": dict(failures.most_common()),
        "no_plan": dict(no_plan),
        "mean_plan_moves": round(float(np.mean(moves)), 1) if moves else None,
        "wall_s_per_episode": round(wall / len(results), 3),
    }


def check_source(name: str) -> str:
    """``name`` if it is a MuJoBan environment or ``boxoban/<file>[-pegs]``
    with ``<file>.txt`` in `BOXOBAN_DIR`; else `physics_planning.cli.UsageError`."""
    if name.startswith("boxoban/"):
        stem = name[len("boxoban/") :].removesuffix("-pegs")
        files = sorted(f"boxoban/{p.stem}" for p in BOXOBAN_DIR.glob("*.txt"))
        if not (BOXOBAN_DIR / f"{stem}.txt").is_file():
            raise cli.UsageError(
                f"unknown level source {name!r}{cli.close_hint(name, files)}; "
                f"valid: boxoban/<file>[-pegs] with <file> one of "
                f"{', '.join(p.split('/')[1] for p in files)}"
            )
        return name
    mujoban = [n for n in envs.names() if n.startswith("mujoban/")]
    return env_cli.environment(name, mujoban + ["boxoban/<file>[-pegs]"])


def _main(argv=None) -> int:
    parser = make_parser(__file__, __doc__)
    parser.add_argument(
        "--envs",
        nargs="+",
        default=MUJOBAN + BOXOBAN,
        metavar="NAME",
        help="MuJoBan environments or boxoban/<file>[-pegs] level files",
    )
    parser.add_argument(
        "--episodes", type=cli.positive_int, default=100, help="episodes per environment"
    )
    parser.add_argument("--seed", type=cli.non_negative_int, default=0, help="environment seed")
    parser.add_argument(
        "--t-abs",
        type=cli.positive_int,
        default=T_ABS,
        help="control steps before the agent re-estimates and replans",
    )
    parser.add_argument(
        "--estimator",
        default="oracle",
        help="oracle (privileged, isolates the skill), entity-layer "
        "(privileged) or camera (observation-only)",
    )
    parser.add_argument("--json", type=Path, help="write the rows here")
    args = parser.parse_args(argv)
    check("estimator", "mujoban", args.estimator)
    for name in args.envs:
        check_source(name)
    cli.output_file(args.json, "--json")
    header = (
        f"{'env':<34} {'eps':>4} {'solved%':>8} {'95% CI':>13} {'steps':>6} "
        f"{'p95':>5} {'subgoal%':>9} {'s/ep':>6}  failures"
    )
    print(header)
    print("-" * len(header))
    rows = []
    for name in args.envs:
        row = measure(name, args.episodes, args.seed, args.t_abs, args.estimator)
        rows.append(row)
        steps = "-" if row["mean_steps_solved"] is None else f"{row['mean_steps_solved']:.0f}"
        p95 = "-" if row["p95_steps_solved"] is None else f"{row['p95_steps_solved']:.0f}"
        top = ", ".join(f"{k} {v}" for k, v in list(row["failures"].items())[:3])
        if row["no_plan"]:
            top += "; no plan: " + ", ".join(f"{k} {v}" for k, v in row["no_plan"].items())
        print(
            f"{name:<34} {row['episodes']:>4} {row['solved_pct']:>7.1f}% "
            f"[{row['wilson_low']:>5.1f},{row['wilson_high']:>5.1f}] {steps:>6} {p95:>5} "
            f"{100 * row['subgoal_success_rate']:>8.1f}% {row['wall_s_per_episode']:>6.2f}  "
            f"{top}",
            flush=True,
        )
    if args.json:
        write_json(args.json, rows)
    return 0


def main(argv=None) -> int:
    """Measures, prints the table, writes ``--json``; bad input: one line on
    stderr, exit status 2."""
    return cli.run_main(PROG, _main, argv)


if __name__ == "__main__":
    sys.exit(main())
