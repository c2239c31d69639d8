"""How long the modular agent's body takes to execute Sokoban plans, per level.

    python benchmarks/execution_time.py [--levels FILE] [--episodes N] [--seed S]
                                        [--estimator camera|oracle] [--no-pegs]
                                        [--planner sokoban-solver:time|sokoban-solver]
                                        [--fit] [--json PATH]

Plays the first ``--episodes`` levels of a Boxoban file in order (default:
the shipped ``medium-valid-000.txt``, 100 levels) in ``mujoban/level5-pegs``
(``--no-pegs``: ``mujoban/level5``) with the modular agent (default: the
observation-only ``camera`` estimator; ``oracle`` is privileged and says so),
a Sokoban planner (default: MuJoBan's, the execution-time planner
``sokoban-solver:time``; ``sokoban-solver`` is the exact push solver) and the
ball skill, through ``hier_agents.run`` (``--workers N`` plays levels in N
processes, with the same rows). Per level it records:

* ``pushes`` / ``moves``: of the planner's first plan from the start;
* ``features``: `abstract_planners.sokoban_time.plan_features` of that
  solution (walking moves, pushes, pushing strokes, turns);
* ``estimated_steps``: `estimate_steps` with the library's default weights;
* ``steps``: control steps the episode took (the 900-step limit if unsolved);
* ``steps_per_push`` (steps / pushes) and ``limit_share`` (steps / limit);
* ``solved`` and, if not, ``failure_reason``.

The table prints solved % with its 95% Wilson interval, the mean control
steps per push, and the distribution (median, p90, max) of the share of the
time limit used by solved levels. ``--fit`` also fits the time model's
weights to the measured steps of the solved levels (non-negative least
squares, `fit_weights`) and reports them with the fit's R^2. ``--json``
writes ``{"provenance", "summary", "rows"}``.
"""

from __future__ import annotations

import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from _common import env_cli, cli, make_parser, prog, write_json  # noqa: E402

import numpy as np  # noqa: E402

import envs  # noqa: E402
from abstract_planners.sokoban import SokobanState  # noqa: E402
from abstract_planners.sokoban_solver import solve  # noqa: E402
from abstract_planners.sokoban_time import (
    DEFAULT_WEIGHTS,
    FEATURES,
    estimate_steps,  # noqa: E402
    fit_weights,
    plan_features,
)
from envs.mujoban.levels import BOXOBAN_DIR, read_levels  # noqa: E402
from hier_agents.boundary import BoundaryEnv  # noqa: E402
from hier_agents.modular.components import PLANNERS, check, is_privileged, resolve  # noqa: E402
from hier_agents.modular.families import TIME_LIMIT_REASON  # noqa: E402
from hier_agents.run import run  # noqa: E402
from hier_agents.stats import wilson_interval  # noqa: E402

PROG = prog(__file__)

DEFAULT_LEVELS = BOXOBAN_DIR / "medium-valid-000.txt"


def plan_row(search, level) -> dict:
    """The planner's first plan of ``level`` from its start, searched
    abstractly: ``planned``, and if found ``pushes``, ``moves``, ``features``,
    ``estimated_steps``."""
    start = SokobanState.from_level(level)
    found = search(start) if search is not None else solve(start, time_limit=10.0)
    row = {"level": level.name, "planned": found.solved}
    if found.solved:
        features = plan_features(start, found.moves)
        row.update(
            pushes=found.pushes,
            moves=len(found.moves),
            features=features,
            estimated_steps=round(estimate_steps(features), 1),
        )
    return row


def played_row(row: dict, episode: dict, limit: int) -> dict:
    """``row`` (`plan_row`) completed with the played episode's
    (`hier_agents.run` row): ``solved``, ``steps``, ``limit_share``,
    ``wall_s``, ``steps_per_push`` and ``failure_reason``."""
    steps = int(episode["steps"])
    row.update(
        solved=bool(episode["solved"]),
        steps=steps,
        limit_share=round(steps / limit, 4),
        wall_s=round(episode["wall_s"], 3),
    )
    if row.get("pushes"):
        row["steps_per_push"] = round(steps / row["pushes"], 2)
    if not row["solved"]:
        row["failure_reason"] = episode.get("failure_reason", TIME_LIMIT_REASON)
    return row


def summarise(rows: list[dict], fit: bool) -> dict:
    n = len(rows)
    solved = [r for r in rows if r["solved"]]
    shares = [r["limit_share"] for r in solved]
    per_push = [r["steps_per_push"] for r in rows if "steps_per_push" in r]
    out = {
        "levels": n,
        "solved": len(solved),
        "success_rate": len(solved) / n,
        "success_interval": wilson_interval(len(solved), n),
        "mean_steps_per_push": float(np.mean(per_push)) if per_push else None,
        "mean_steps_per_push_solved": (
            float(np.mean([r["steps_per_push"] for r in solved if "steps_per_push" in r]))
            if solved
            else None
        ),
        "limit_share_solved": (
            {
                "median": float(np.median(shares)),
                "p90": float(np.percentile(shares, 90)),
                "max": float(np.max(shares)),
            }
            if shares
            else None
        ),
        "default_weights": dict(DEFAULT_WEIGHTS),
    }
    with_plan = [r for r in solved if "features" in r]
    if with_plan:
        est = np.array([r["estimated_steps"] for r in with_plan])
        got = np.array([r["steps"] for r in with_plan])
        out["estimate_error_solved"] = {
            "mean": float(np.mean(est - got)),
            "mean_abs": float(np.mean(np.abs(est - got))),
        }
    if fit and len(with_plan) > len(FEATURES) + 1:
        weights = fit_weights([r["features"] for r in with_plan], [r["steps"] for r in with_plan])
        pred = np.array([estimate_steps(r["features"], weights) for r in with_plan])
        got = np.array([r["steps"] for r in with_plan], float)
        r2 = 1.0 - float(np.sum((got - pred) ** 2) / np.sum((got - got.mean()) ** 2))
        out["fitted_weights"] = {k: round(v, 3) for k, v in weights.items()}
        out["fit_r2"] = round(r2, 4)
    return out


def _main(argv=None) -> int:
    parser = make_parser(__file__, __doc__)
    parser.add_argument(
        "--levels", type=Path, default=DEFAULT_LEVELS, metavar="FILE", help="a Boxoban level file"
    )
    parser.add_argument(
        "--episodes", type=cli.positive_int, default=100, help="levels from the file's start"
    )
    parser.add_argument("--seed", type=cli.non_negative_int, default=0)
    parser.add_argument("--estimator", default="camera", help="a MuJoBan estimator")
    parser.add_argument(
        "--planner",
        default=None,
        help="sokoban-solver:time (estimated time; the default) or "
        "sokoban-solver (the exact push solver)",
    )
    parser.add_argument("--no-pegs", action="store_true")
    parser.add_argument("--fit", action="store_true", help="fit the time model's weights")
    parser.add_argument(
        "--workers",
        type=cli.positive_int,
        default=1,
        help="processes playing the levels at once (hier_agents.run --workers; the same rows)",
    )
    parser.add_argument("--json", type=Path, help="write the summary and rows here")
    args = parser.parse_args(argv)
    name = "mujoban/level5" if args.no_pegs else "mujoban/level5-pegs"
    env_cli.levels_file(name, args.levels)
    check("estimator", "mujoban", args.estimator)
    check("planner", "mujoban", args.planner)
    privileged = is_privileged("mujoban", args.estimator)
    cli.output_file(args.json, "--json")
    levels = read_levels(args.levels)[: args.episodes]
    # The planner's own search, built from the public description as the agent's is.
    probe = envs.load(name, seed=args.seed, levels=str(args.levels), **envs.no_cameras(name))
    try:
        description = BoundaryEnv(probe).description()
    finally:
        probe.close()
    planner = resolve("planner", "mujoban", args.planner).factory(description, args.seed)
    search = getattr(planner, "search", None)
    plans = [plan_row(search, level) for level in levels]
    played = run(
        name,
        len(levels),
        args.seed,
        levels=str(args.levels),
        estimator=args.estimator,
        planner=args.planner,
        workers=args.workers,
    )
    rows = [
        played_row(plan, episode, description.time_limit_steps)
        for plan, episode in zip(plans, played["rows"])
    ]
    summary = summarise(rows, args.fit)
    planner = args.planner or next(iter(PLANNERS["mujoban"]))
    summary.update(
        env=name,
        levels_file=args.levels.name,
        estimator=args.estimator,
        planner=planner,
        privileged=privileged,
        seed=args.seed,
    )
    low, high = summary["success_interval"]
    print(
        f"{args.levels.name}, first {len(rows)} levels, {name}, planner {planner}, "
        f"estimator {args.estimator}{' (PRIVILEGED)' if privileged else ''}"
    )
    print(
        f"  solved              {100 * summary['success_rate']:.1f}% "
        f"[{100 * low:.1f}, {100 * high:.1f}]"
    )
    if summary["mean_steps_per_push"] is not None:
        print(
            f"  steps per push      {summary['mean_steps_per_push']:.1f} (all levels), "
            f"{summary['mean_steps_per_push_solved']:.1f} (solved)"
        )
    if summary["limit_share_solved"]:
        share = summary["limit_share_solved"]
        print(
            f"  share of the limit  median {100 * share['median']:.0f}%, "
            f"p90 {100 * share['p90']:.0f}%, max {100 * share['max']:.0f}% (solved levels)"
        )
    if "estimate_error_solved" in summary:
        err = summary["estimate_error_solved"]
        print(
            f"  estimate - measured mean {err['mean']:+.0f}, mean |.| {err['mean_abs']:.0f} "
            f"steps (default weights)"
        )
    if "fitted_weights" in summary:
        print(f"  fitted weights      {summary['fitted_weights']} (R^2 {summary['fit_r2']:.2f})")
    if args.json:
        write_json(args.json, {"summary": summary, "rows": rows})
    return 0


def main(argv=None) -> int:
    """Plays the levels, prints the summary, writes ``--json``; bad input: one
    line on stderr, exit status 2, before anything is played."""
    return cli.run_main(PROG, _main, argv)


if __name__ == "__main__":
    sys.exit(main())
