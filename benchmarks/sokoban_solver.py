"""Solve every level of a Boxoban file with the abstract Sokoban solver.

    python benchmarks/sokoban_solver.py [--levels FILE] [--time-limit S]
                                        [--planner sokoban-solver|sokoban-solver:time]
                                        [--weight W] [--limit N] [--json PATH]

For each level this runs the planner's search with the given time limit
(10 s by default): ``sokoban-solver`` (the default) is the exact push solver
``abstract_planners.sokoban_solver.solve``; ``sokoban-solver:time`` is
MuJoBan's default planner, `abstract_planners.sokoban_time_solver.
TimeSolverPlanner` (the execution-time search at weight ``--weight``, 2 by
default, and the push solver, each with half the time; the plan estimated
faster), and it records whether it solved the level,
the wall time, nodes expanded, pushes and moves of the solution, its time
features and the control steps the ball skill is estimated to need for it
(`abstract_planners.sokoban_time`), and the reason (``solved`` /
``unsolvable`` / ``budget``). Every returned solution is
replayed through the rules by the solver itself.

A progress bar runs while solving; a line is printed for each level that was
not solved, then a summary table: levels, solved, solved %, median / p95 /
max milliseconds, mean nodes expanded, mean pushes, mean estimated control
steps and how many solutions are estimated to need more than MuJoBan's 900.
With --json the summary (keys total, solved, median_ms, p95_ms, max_ms,
mean_nodes, mean_pushes, mean_estimated_steps, over_time_limit,
time_limit_s, levels_file, planner, weight) and per-level rows (index, solved, ms, nodes,
pushes, moves, features, estimated_steps, reason) are written to PATH.

The default level file is the shipped ``unfiltered-valid-000.txt``; the
shipped ``medium-valid-000.txt`` is the harder set.
"""

from __future__ import annotations

import math
import statistics
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from _common import cli, make_parser, prog, write_json  # noqa: E402

from tqdm import tqdm  # noqa: E402

from abstract_planners.sokoban import SokobanState  # noqa: E402
from abstract_planners.sokoban_solver import solve  # noqa: E402
from abstract_planners.sokoban_time_solver import TimeSolverPlanner  # noqa: E402
from abstract_planners.sokoban_time import estimate_steps, plan_features  # noqa: E402
from envs.mujoban.levels import BOXOBAN_DIR, read_levels  # noqa: E402

PROG = prog(__file__)

DEFAULT_LEVELS = BOXOBAN_DIR / "unfiltered-valid-000.txt"


def percentile(values: list[float], q: float) -> float:
    """The ``q``-th percentile (0..100) of ``values``, nearest-rank method."""
    ordered = sorted(values)
    rank = max(1, math.ceil(q / 100.0 * len(ordered)))
    return ordered[rank - 1]


PLANNERS = ("sokoban-solver", "sokoban-solver:time")


def run(
    levels_file: Path,
    time_limit: float,
    limit: int | None = None,
    planner: str = "sokoban-solver",
    weight: float = 2.0,
) -> dict:
    if planner == "sokoban-solver":
        search = lambda state: solve(state, time_limit=time_limit)  # noqa: E731
    else:
        search = TimeSolverPlanner(time_limit=time_limit, weight=weight).search
    levels = read_levels(levels_file)
    if limit is not None:
        levels = levels[:limit]
    rows = []
    for position, level in enumerate(tqdm(levels, desc=levels_file.name, unit="level")):
        index = int(level.name) if level.name is not None and level.name.isdigit() else position
        start = SokobanState.from_level(level)
        result = search(start)
        row = {
            "index": index,
            "solved": result.solved,
            "ms": round(result.ms, 3),
            "nodes": result.nodes,
            "pushes": result.pushes,
            "moves": "".join(result.moves),
            "reason": result.reason,
        }
        if result.solved:
            features = plan_features(start, result.moves)
            row["features"] = features
            row["estimated_steps"] = round(estimate_steps(features), 1)
        rows.append(row)
        if not result.solved:
            tqdm.write(
                f"level {index}: not solved ({result.reason}) after "
                f"{result.ms:.0f} ms, {result.nodes} nodes"
            )
    ms = [row["ms"] for row in rows]
    solved = sum(row["solved"] for row in rows)
    return {
        "levels_file": str(levels_file),
        "time_limit_s": time_limit,
        "planner": planner,
        "weight": weight if planner != "sokoban-solver" else None,
        "total": len(rows),
        "solved": solved,
        "solved_pct": 100.0 * solved / len(rows) if rows else 0.0,
        "median_ms": statistics.median(ms) if ms else 0.0,
        "p95_ms": percentile(ms, 95) if ms else 0.0,
        "max_ms": max(ms) if ms else 0.0,
        "mean_nodes": statistics.fmean(row["nodes"] for row in rows) if rows else 0.0,
        "mean_pushes": (
            statistics.fmean(r["pushes"] for r in rows if r["solved"]) if solved else None
        ),
        "mean_estimated_steps": (
            statistics.fmean(r["estimated_steps"] for r in rows if r["solved"]) if solved else None
        ),
        "over_time_limit": sum(r.get("estimated_steps", 0) > 900 for r in rows),
        "levels": rows,
    }


def print_summary(summary: dict) -> None:
    header = (
        "levels",
        "solved",
        "solved %",
        "median ms",
        "p95 ms",
        "max ms",
        "mean nodes",
        "mean pushes",
        "mean est. steps",
        "est. > 900",
    )
    pushes, est = summary["mean_pushes"], summary["mean_estimated_steps"]
    values = (
        str(summary["total"]),
        str(summary["solved"]),
        f"{summary['solved_pct']:.1f}",
        f"{summary['median_ms']:.1f}",
        f"{summary['p95_ms']:.1f}",
        f"{summary['max_ms']:.1f}",
        f"{summary['mean_nodes']:.0f}",
        "-" if pushes is None else f"{pushes:.1f}",
        "-" if est is None else f"{est:.0f}",
        str(summary["over_time_limit"]),
    )
    widths = [max(len(h), len(v)) for h, v in zip(header, values)]
    weight = "" if summary["weight"] is None else f", weight {summary['weight']}"
    print(
        f"\n{summary['levels_file']}: {summary['planner']}{weight} "
        f"(time limit {summary['time_limit_s']} s)"
    )
    print("  ".join(h.rjust(w) for h, w in zip(header, widths)))
    print("  ".join(v.rjust(w) for v, w in zip(values, widths)))


def _main(argv=None) -> int:
    parser = make_parser(__file__, __doc__)
    parser.add_argument(
        "--levels",
        type=cli.existing_file,
        default=DEFAULT_LEVELS,
        metavar="FILE",
        help="Boxoban level file",
    )
    parser.add_argument(
        "--time-limit", type=cli.positive_float, default=10.0, help="seconds per level"
    )
    parser.add_argument(
        "--planner",
        default="sokoban-solver",
        metavar="NAME",
        help=f"one of {', '.join(PLANNERS)} (default: sokoban-solver)",
    )
    parser.add_argument(
        "--weight",
        type=cli.positive_float,
        default=2.0,
        help="sokoban-solver:time: the weight of its A* heuristic (default 2)",
    )
    parser.add_argument(
        "--limit",
        type=cli.positive_int,
        default=None,
        help="solve only the first N levels (default: all)",
    )
    parser.add_argument("--json", type=Path, default=None, help="write results to PATH")
    args = parser.parse_args(argv)
    cli.choice("--planner", args.planner, PLANNERS)
    read_levels(args.levels)  # a malformed file fails here (LevelError: one line)
    cli.output_file(args.json, "--json")
    summary = run(args.levels, args.time_limit, args.limit, args.planner, args.weight)
    print_summary(summary)
    if args.json is not None:
        write_json(args.json, summary, indent=1)
    return 0 if summary["solved"] == summary["total"] else 1


def main(argv=None) -> int:
    """Solves the levels, prints the summary, writes ``--json``; returns 1
    unless every level was solved. Bad input: one line on stderr, exit status 2."""
    return cli.run_main(PROG, _main, argv)


if __name__ == "__main__":
    sys.exit(main())
