"""The walker's physical limit against the control steps the agent takes, per level.

    python benchmarks/physical_limit.py [--plans results/sokoban_solver_hard_time-planner.json]
        [--rows results/agent/boxoban_hard-001-200-pegs.json] [--json PATH]

1. **The limit**: the distance MuJoBan's walker covers from rest at full
   ``roll`` after each control step, on a straight open corridor
   (`envs.mujoban.behaviour.roll_distances`, the rows' environment settings,
   ``--limit-steps`` control steps; past them the walker is taken to hold its
   last step's speed, which it has reached by then: the last steps differ by
   under 0.1%), and how many control steps a quarter turn of its heading
   takes from rest at full ``steer`` (`envs.mujoban.behaviour.steer_angles`).
2. **A lower bound per level**: the control steps the walker needs to roll
   the length of the level's plan (its walking and pushing moves, one cell
   each, from ``--plans``: `benchmarks/sokoban_solver.py`'s record of the
   planner's first plan) in one straight run from rest, with no turn, no
   stop and no box to slow it. No body executes that plan faster, so the
   steps an agent takes over the bound (>= 1) measure the gap to the limit.
3. **Per level**: the control steps the agent took (``--rows``: a
   ``hier_agents.run`` summary whose episode ``e`` played level ``e`` of
   the same level file), solved or not, and the planner's own estimate.

Prints the limit (top speed, control steps to 90% of it, control steps to
roll the first cell) and, over the solved levels and over all (an unsolved
level counts its time limit, so its ratio is a floor), the medians of the
bound, the steps taken and steps / bound; ``--json`` writes
``{"provenance", "limit", "summary", "levels"}``.
"""

from __future__ import annotations

import json
import math
import sys
import tempfile
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from _common import cli, make_parser, prog, write_json  # noqa: E402

import numpy as np  # noqa: E402

import envs  # noqa: E402
from envs.mujoban import behaviour  # noqa: E402

PROG = prog(__file__)
ROOT = Path(__file__).resolve().parents[1]
#: The walker is at its top speed (to 0.1%) well before 140 control steps (7 s).
LIMIT_STEPS = 140


def walker_limit(env_name: str, env_options: dict, control_steps: int = LIMIT_STEPS) -> dict:
    """The walker of ``env_name`` (with ``env_options``) rolling from rest on
    `behaviour.CORRIDOR`: ``distances_m`` after each control step, the
    ``top_speed_mps`` (its last step's), ``steps_to_90pct`` of it,
    ``steps_first_cell``, ``steps_to_turn_90deg`` (its heading, from rest at
    full ``steer``), ``cell_m`` and ``control_timestep_s``."""
    with tempfile.TemporaryDirectory() as folder:
        level = Path(folder) / "corridor.txt"
        level.write_text(behaviour.level_text(behaviour.CORRIDOR))
        options = {**env_options, "levels": str(level), "grid_shape": behaviour.CORRIDOR_SHAPE}
        env = envs.load(env_name, seed=0, **envs.no_cameras(env_name), **options)
        try:
            env.reset()
            dt = float(env.control_timestep)
            substeps = round(dt / float(env.physics.model.opt.timestep))
            distances = behaviour.roll_distances(env.physics, control_steps, substeps)
            env.reset()
            turned = behaviour.steer_angles(env.physics, control_steps, substeps)
            cell = float(env.task.cell_size)
        finally:
            env.close()
    speeds = np.diff(distances, prepend=0.0) / dt
    top = float(speeds[-1])
    return {
        "env": env_name,
        "env_options": env_options,
        "control_timestep_s": dt,
        "cell_m": cell,
        "top_speed_mps": round(top, 4),
        "steps_to_90pct": int(np.argmax(speeds >= 0.9 * top)) + 1,
        "steps_first_cell": int(np.argmax(distances >= cell)) + 1,
        "steps_to_turn_90deg": int(np.argmax(turned >= math.pi / 2)) + 1,
        "distances_m": [round(float(x), 5) for x in distances],
    }


def bound_steps(limit: dict, cells: int) -> int:
    """Control steps to roll ``cells`` cells in a straight line from rest at
    full ``roll`` (`walker_limit`'s distances, then its top speed)."""
    distances = np.asarray(limit["distances_m"])
    target = cells * limit["cell_m"]
    if target <= distances[-1]:
        return int(np.argmax(distances >= target)) + 1
    per_step = limit["top_speed_mps"] * limit["control_timestep_s"]
    return len(distances) + math.ceil((target - distances[-1]) / per_step)


def _shown(path: Path) -> str:
    """``path`` relative to the repository when inside it."""
    path = path.resolve()
    return str(path.relative_to(ROOT)) if path.is_relative_to(ROOT) else str(path)


def _median(values) -> float | None:
    values = list(values)
    return round(float(np.median(values)), 3) if values else None


def _main(argv=None) -> int:
    parser = make_parser(__file__, __doc__)
    parser.add_argument(
        "--plans",
        type=cli.existing_file,
        default=ROOT / "results" / "sokoban_solver_hard_time-planner.json",
        help="benchmarks/sokoban_solver.py's JSON: each level's plan features",
    )
    parser.add_argument(
        "--rows",
        type=cli.existing_file,
        default=ROOT / "results" / "agent" / "boxoban_hard-001-200-pegs.json",
        help="a hier_agents.run --json summary of the same level file",
    )
    parser.add_argument(
        "--limit-steps",
        type=cli.positive_int,
        default=LIMIT_STEPS,
        help="control steps of the roll from rest",
    )
    parser.add_argument("--json", type=Path, help="write the results here")
    args = parser.parse_args(argv)
    cli.output_file(args.json, "--json")
    plans, rows = json.loads(args.plans.read_text()), json.loads(args.rows.read_text())
    if Path(plans["levels_file"]).name != Path(rows.get("levels") or "").name:
        raise cli.UsageError(
            f"--plans is of {plans['levels_file']}, --rows of {rows.get('levels')}: "
            f"they must be of the same level file"
        )
    limit = walker_limit(rows["env"], dict(rows.get("env_options") or {}), args.limit_steps)
    # Both are in the level file's order: a plan's place in the list, as an
    # episode's index, is its level's position in the file.
    by_position = dict(enumerate(plans["levels"]))
    levels = []
    for row in rows["rows"]:
        plan = by_position.get(row["episode"])
        if plan is None or not plan.get("solved"):
            continue  # the planner found no plan for it
        cells = plan["features"]["walk"] + plan["features"]["push"]
        bound = bound_steps(limit, cells)
        levels.append(
            {
                "position": row["episode"],
                "level": plan["index"],
                "cells": cells,
                "bound_steps": bound,
                "estimated_steps": plan.get("estimated_steps"),
                "steps": row["steps"],
                "solved": bool(row["solved"]),
                "steps_over_bound": round(row["steps"] / bound, 3),
            }
        )
    if not levels:
        raise cli.UsageError("no level has both a plan in --plans and a row in --rows")

    def summary(chosen: list[dict]) -> dict:
        return {
            "levels": len(chosen),
            "median_bound_steps": _median(x["bound_steps"] for x in chosen),
            "median_steps": _median(x["steps"] for x in chosen),
            "median_steps_over_bound": _median(x["steps_over_bound"] for x in chosen),
            "median_estimate_over_bound": _median(
                x["estimated_steps"] / x["bound_steps"]
                for x in chosen
                if x["estimated_steps"] is not None
            ),
        }

    solved = [x for x in levels if x["solved"]]
    summaries = {"solved": summary(solved), "all": summary(levels)}
    per_step = limit["top_speed_mps"] * limit["control_timestep_s"] / limit["cell_m"]
    print(
        f"walker ({limit['env']}, {limit['control_timestep_s'] * 1000:.0f} ms control steps): "
        f"top speed {limit['top_speed_mps']:.2f} m/s ({per_step:.3f} cells a step), "
        f"90% of it after {limit['steps_to_90pct']} steps, the first cell after "
        f"{limit['steps_first_cell']} steps; a quarter turn from rest takes "
        f"{limit['steps_to_turn_90deg']} steps"
    )
    header = ("levels", "n", "bound", "steps", "steps/bound", "estimate/bound")
    print("{:<8} {:>4} {:>7} {:>7} {:>11} {:>14}".format(*header))
    for name, s in summaries.items():
        print(
            f"{name:<8} {s['levels']:>4} {s['median_bound_steps']:>7.0f} {s['median_steps']:>7.0f} "
            f"{s['median_steps_over_bound']:>11.2f} {s['median_estimate_over_bound']:>14.2f}"
        )
    print("(medians; an unsolved level counts the time limit, so its steps/bound is a floor)")
    if args.json:
        write_json(
            args.json,
            {
                "plans": _shown(args.plans),
                "rows": _shown(args.rows),
                "limit": limit,
                "summary": summaries,
                "levels": levels,
            },
        )
    return 0


def main(argv=None) -> int:
    """Measures, prints the table, writes ``--json``; bad input: one line on
    stderr, exit status 2, before anything is measured."""
    return cli.run_main(PROG, _main, argv)


if __name__ == "__main__":
    sys.exit(main())
