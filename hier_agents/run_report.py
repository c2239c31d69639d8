"""The results of `hier_agents.run`: the JSON-able summary of the episodes
played (`summarize`), the printed table (`format_table`) and the progress
bar's postfix (`postfix`). Episode rows are the dicts `hier_agents.run`
records (``return``, ``steps``, ``wall_s``, ``solved`` or ``outcome``, ...).
"""

from __future__ import annotations

import numpy as np

from physics_planning.cli import plural
from hier_agents.modular.agent import OptionStats
from hier_agents.modular.families import adapter
from hier_agents.stats import wilson_interval

__all__ = ["summarize", "format_table", "postfix"]


def postfix(rows, fam) -> dict:
    """The progress bar's postfix: solved (MuJoBan) or won (board games) of ``rows``."""
    if not adapter(fam).games:
        return {"solved": f"{sum(r['solved'] for r in rows)}/{len(rows)}"}
    return {"wins": f"{sum(r['outcome'] == 'win' for r in rows)}/{len(rows)}"}


def summarize(env_name, fam, rows, totals: OptionStats, seed) -> dict:
    """The JSON-able summary of episode ``rows`` (dicts as the episode runner
    plays them, `hier_agents.agents.runner`) of family ``fam``: rates with
    95% Wilson intervals, means, subgoal counters (``totals``), failure
    reasons, per-episode rows. All rates and means are None when no episode
    was played. Who played is the caller's to add."""
    n = len(rows)
    out = {"env": env_name, "episodes": n, "seed": seed}
    if n == 0:  # e.g. interrupted before the first episode ended
        for key in (
            ("success_rate",)
            if not adapter(fam).games
            else ("win_rate", "draw_rate", "loss_rate", "success_rate")
        ):
            out[key] = None
        out.update(
            mean_return=None,
            mean_steps=None,
            subgoal_success_rate=None,
            subgoals={},
            episode_failures={},
            errors=0,
            wall_s=None,
            control_steps_per_s=None,
            rows=[],
        )
        return out
    if not adapter(fam).games:
        solved = sum(r["solved"] for r in rows)
        out["success_rate"] = solved / n
        out["success_interval"] = wilson_interval(solved, n)
        solved_steps = [r["steps"] for r in rows if r["solved"]]
        out["mean_steps_solved"] = float(np.mean(solved_steps)) if solved_steps else None
    else:
        for outcome in ("win", "draw", "loss"):
            count = sum(r["outcome"] == outcome for r in rows)
            out[f"{outcome}_rate"] = count / n
            out[f"{outcome}_interval"] = wilson_interval(count, n)
        out["success_rate"] = out["win_rate"]
        estimates = sum(r.get("estimates", 0) for r in rows)
        wrong = sum(r.get("wrong_estimates", 0) for r in rows)
        out["estimate_accuracy"] = 1.0 - wrong / estimates if estimates else None
    out["mean_return"] = float(np.mean([r["return"] for r in rows]))
    out["mean_steps"] = float(np.mean([r["steps"] for r in rows]))
    rate = totals.success_rate
    out["subgoal_success_rate"] = None if rate != rate else rate  # NaN is not JSON
    out["subgoals"] = {
        "issued": totals.issued,
        "reached": totals.reached,
        "failed": totals.failed,
        "cut_off": totals.cut_off,
        "unfinished": totals.unfinished,
        "failures": totals.failures,
        "estimation_failures": totals.estimation_failures,
    }
    reasons: dict[str, int] = {}
    for row in rows:
        if "failure_reason" in row:
            kind = row["failure_reason"].split(":", 1)[0]
            reasons[kind] = reasons.get(kind, 0) + 1
    out["episode_failures"] = reasons
    out["errors"] = sum("error" in row for row in rows)
    out["wall_s"] = float(np.mean([r["wall_s"] for r in rows]))
    wall = sum(r["wall_s"] for r in rows)
    out["control_steps_per_s"] = sum(r["steps"] for r in rows) / wall if wall > 0 else None
    out["rows"] = rows
    return out


def _pct(rate, interval) -> str:
    """``rate`` and its interval (fractions) as percentages."""
    return f"{100 * rate:5.1f}% [{100 * interval[0]:5.1f}, {100 * interval[1]:5.1f}]"


def format_table(summary: dict) -> str:
    """The printed results table of a `hier_agents.run.run` summary."""
    from hier_agents.agents import kind_of

    who = kind_of(summary.get("agent", "modular")).describe(summary)
    lines = [
        f"{summary['env']}: {who}, {plural(summary['episodes'], 'episode')}, seed {summary['seed']}"
    ]
    if summary.get("levels"):
        lines.append(f"  levels from {summary['levels']}")
    if summary.get("env_options"):
        lines.append(
            "  env options  " + ", ".join(f"{k}={v!r}" for k, v in summary["env_options"].items())
        )
    if summary.get("interrupted"):
        lines.append(
            f"  INTERRUPTED (Ctrl-C): {summary['episodes']} of "
            f"{plural(summary.get('episodes_requested', '?'), 'episode')} played"
        )
    if not summary["episodes"]:
        return "\n".join(lines)
    if "win_rate" in summary:
        lines.append(f"  win   {_pct(summary['win_rate'], summary['win_interval'])}")
        lines.append(f"  draw  {_pct(summary['draw_rate'], summary['draw_interval'])}")
        lines.append(f"  loss  {_pct(summary['loss_rate'], summary['loss_interval'])}")
    else:
        lines.append(
            "  solved            " + _pct(summary["success_rate"], summary["success_interval"])
        )
    lines.append(f"  mean return       {summary['mean_return']:.2f}")
    lines.append(f"  mean steps        {summary['mean_steps']:.1f}")
    if summary["subgoal_success_rate"] is not None:
        lines.append(
            f"  subgoal success   {100 * summary['subgoal_success_rate']:.1f}% "
            f"({summary['subgoals']['reached']}/{summary['subgoals']['issued']} issued)"
        )
    else:
        lines.append("  subgoal success   - (no subgoals)")
    if summary.get("estimate_accuracy") is not None:
        lines.append(
            f"  estimated board   {100 * summary['estimate_accuracy']:.2f}% of steps "
            f"right (the referee's board and player to move)"
        )
    if summary.get("episode_failures"):
        lines.append(
            "  unsolved because  "
            + ", ".join(f"{k} x{v}" for k, v in sorted(summary["episode_failures"].items()))
        )
    if summary.get("errors"):
        first = next(r["error"] for r in summary["rows"] if "error" in r)
        lines.append(
            f"  errors            {plural(summary['errors'], 'episode')} ended by "
            f"an error (first: {first[:120]})"
        )
    lines.append(f"  wall s / episode  {summary['wall_s']:.2f}")
    shares = (summary.get("profile") or {}).get("shares")
    if shares and summary.get("episodes"):
        lines.append(
            "  time spent in     "
            + ", ".join(
                f"{name} {100 * share:.0f}%" for name, share in shares.items() if share is not None
            )
        )
    if summary.get("control_steps_per_s"):
        lines.append(
            f"  control steps / s {summary['control_steps_per_s']:.0f} "
            f"(environment and agent, one process)"
        )
    return "\n".join(lines)
