"""The README's modular-agent results table, printed from committed JSON.

    python benchmarks/agent_table.py [--dir results/agent]

Reads every ``hier_agents.run --json`` file under ``DIR`` and
``DIR/push-planner`` (observation-only rows; the latter with the exact
push solver, ``--planner sokoban-solver``, instead of MuJoBan's default, the
execution-time planner) and ``DIR/oracle`` (privileged rows) and
prints a Markdown table: one row per file, observation-only rows first,
each naming its estimator and whether it read the simulator. Nothing is
measured here; every number comes from a file that records its command,
commit and date.
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

from _common import cli, make_parser, prog  # noqa: E402

PROG = prog(__file__)

#: MuJoBan's default planner (`hier_agents.modular.components.PLANNERS`); rows name any other.
DEFAULT_MUJOBAN_PLANNER = "sokoban-solver:time"

#: The paper's best end-to-end RL result per environment (Mirza et al. 2020).
PAPER = {
    "mujoban/level1": "100%",
    "mujoban/level1-pegs": "100%",
    "mujoban/level2": "100%",
    "mujoban/level2-pegs": "99.8%",
    "mujoban/level3": "99.9%",
    "mujoban/level3-pegs": "94.8%",
    "mujoban/level4": "99.5%",
    "mujoban/level4-pegs": "78.2%",
    "mujoban/level5": "97.7%",
    "mujoban/level5-pegs": "54.6%",
    "mujogo/7x7": "about 60% (expert planner)",
}


def _pct(rate, interval) -> str:
    return f"{100 * rate:.1f}% [{100 * interval[0]:.1f}, {100 * interval[1]:.1f}]"


def row(path: Path) -> str:
    s = json.loads(path.read_text())
    name = s["env"]
    levels = [a for a in s.get("provenance", {}).get("command", "").split() if a.endswith(".txt")]
    label = f"`{name}`" + (
        f" on `{Path(levels[0]).name}` (first {s['episodes']})" if levels else ""
    )
    if s.get("planner") not in (None, DEFAULT_MUJOBAN_PLANNER, "-") and name.startswith("mujoban"):
        label += f", planner `{s['planner']}`"
    options = s.get("env_options") or {}
    if options:
        label += " with " + ", ".join(f"`{k}={v}`" for k, v in options.items())
    if "win_rate" in s:
        result = (
            f"won {_pct(s['win_rate'], s['win_interval'])}, drawn "
            f"{100 * s['draw_rate']:.0f}%, lost {100 * s['loss_rate']:.0f}%"
        )
    else:
        result = _pct(s["success_rate"], s["success_interval"])
    estimator = s.get("estimator", "?") + (" (**privileged**)" if s.get("privileged") else "")
    if estimator == "board":  # the board games' estimator that reads the referee's record
        estimator = "board (game record)"
    sub = s.get("subgoal_success_rate")
    speed = s.get("control_steps_per_s")
    paper = "-" if levels or options else PAPER.get(name, "-")
    failures = ", ".join(f"{k} {v}" for k, v in sorted(s.get("episode_failures", {}).items()))
    return (
        f"| {label} | {estimator} | {result} | {s['mean_steps']:.0f} | "
        f"{'-' if sub is None else f'{100 * sub:.1f}%'} | "
        f"{'-' if speed is None else f'{speed:.0f}'} | {failures or '-'} | {paper} |"
    )


def _order(path: Path):
    text = path.stem
    return (not text.startswith("mujoban"), "boxoban" in text, text)


def _main(argv=None) -> int:
    parser = make_parser(__file__, __doc__)
    parser.add_argument(
        "--dir",
        type=Path,
        default=Path("results/agent"),
        help="the folder of hier_agents.run --json files",
    )
    args = parser.parse_args(argv)
    if not args.dir.is_dir():
        raise cli.UsageError(f"--dir {str(args.dir)!r} is not a folder")
    files = sorted(args.dir.glob("*.json"), key=_order)
    oracle = sorted((args.dir / "oracle").glob("*.json"), key=_order)
    files += sorted((args.dir / "push-planner").glob("*.json"), key=_order)
    if not files and not oracle:
        raise cli.UsageError(f"no JSON files under {args.dir}")
    lines = []
    for path in files + oracle:
        try:
            lines.append(row(path))
        except (ValueError, KeyError, TypeError) as exc:
            raise cli.UsageError(
                f"{path} is not a hier_agents.run --json summary ({type(exc).__name__}: {exc})"
            ) from None
    print(
        "| environment | estimator | solved / won [95% CI] | mean steps | subgoal success "
        "| control steps / s | unsolved because | paper's best RL agent |"
    )
    print("| --- | --- | --- | --- | --- | --- | --- | --- |")
    print("\n".join(lines))
    return 0


def main(argv=None) -> int:
    """Prints the table; bad input: one line on stderr, exit status 2."""
    return cli.run_main(PROG, _main, argv)


if __name__ == "__main__":
    sys.exit(main())
