"""Run the modular agent (estimator + planner + skill) and print a results table.

    python -m hier_agents.run                                  # small default: mujoban/level3
    python -m hier_agents.run mujoban/level5-pegs --episodes 100 --json out.json
    python -m hier_agents.run mujoxo/mixture --episodes 50
    python -m hier_agents.run mujogo/7x7 --episodes 20 --video go.mp4
    python -m hier_agents.run mujoban/level5 --planner random      # swap a part
    python -m hier_agents.run mujoban/level5 --estimator oracle    # privileged upper bound
    python -m hier_agents.run mujoban/level1 --agent checkpoint:runs/impala   # a trained agent
    python -m hier_agents.run mujoban/level1 --agent random        # uniform random actions
    python -m hier_agents.run mujoban/level1 --agent random:10     # ... each held 10 steps

The modular agent sits behind the observation boundary: it is given the
task's public description (``env.description()``) and timesteps. The
default estimators are observation-only (MuJoBan: ``camera``, the top
camera and proprioception; board games: ``board``); ``--estimator oracle``
or ``entity-layer`` read the simulator and every table and JSON says
``privileged``.

Runs never abort: an episode the agent gives up (the planner finds no plan,
e.g. after a box was pushed into a deadlock) ends as a failure with its
reason (``failure_reason`` in the episode's row); any error inside an episode
(environment reset, estimator, planner, skill, GTP engine) ends that episode
with ``error`` ("Type: message") and ``failure_reason`` ("error: ...") in its
row, counted in the table and in ``errors``; the next episode goes on; a
diverging simulation ends its episode. Ctrl-C ends the run with the table
(and ``--json``) of the episodes played (``interrupted``: true, exit code
130). The environment and the agent (planner, skill, estimator) are closed
whatever happened, so no GNU Go process outlives a run.

MuJoBan rows report the solved fraction; board games win/draw/loss rates. All
rates carry 95% Wilson intervals. JSON keys: env, episodes, estimator,
privileged, success_rate, win_rate, draw_rate, loss_rate (board games),
mean_return, mean_steps, subgoal_success_rate, episode_failures (reason ->
count), wall_s, control_steps_per_s, plus planner, skill, seed and per-episode rows.
"""

from __future__ import annotations

import argparse
import ast
import json
import sys
import time

import numpy as np
from tqdm import tqdm

import envs
from hier_agents.boundary import BoundaryEnv
from hier_agents.modular.components import (ESTIMATORS, PLANNERS, SKILLS, env_overrides,
                                    estimator_name, family, is_privileged, make_agent)
from hier_agents.modular.agent import OptionStats
from hier_agents.stats import wilson_interval

DEFAULT_ENV = "mujoban/level3"
DEFAULT_EPISODES = 5


def run(env_name: str, episodes: int, seed: int = 0, *, planner: str | None = None,
        skill: str | None = None, estimator: str | None = None, levels: str | None = None,
        video: str | None = None, progress: bool = True, agent: str = "modular",
        stochastic: bool = False, env_options: dict | None = None) -> dict:
    """Plays ``episodes`` episodes; returns the JSON-able summary.

    ``agent`` is ``"modular"`` (estimator + planner + skill),
    ``"checkpoint:PATH"`` (a trained end-to-end agent, `hier_agents.train`;
    its policy's mean, or samples with ``stochastic``) or ``"random"``
    (uniformly random actions). ``env_options`` are extra `envs.load`
    keyword overrides for the modular agent's environment (e.g.
    ``{"physics_timestep": 0.005}``); the summary records them.
    """
    fam = family(env_name)
    env_options = dict(env_options or {})
    if agent != "modular":
        if env_options:
            raise ValueError("env_options apply to the modular agent only")
        return _run_policy(env_name, fam, episodes, seed, agent, levels, video, progress,
                           stochastic)
    # A diverging simulation ends its episode (reward 0) instead of the run.
    overrides = {**env_overrides(env_name, estimator), "raise_on_physics_error": False,
                 **env_options}
    if levels is not None:
        if fam != "mujoban":
            raise ValueError("--levels only applies to mujoban environments")
        overrides["levels"] = levels
    totals = OptionStats()
    rows, frames = [], []
    interrupted = False
    env = made = None
    bar = tqdm(total=episodes, unit="episode", desc=env_name, file=sys.stderr,
               disable=not progress)
    try:
        env = envs.load(env_name, seed=seed, **overrides)
        privileged = is_privileged(fam, estimator)
        # An observation-only agent sees the environment through the boundary
        # (no simulator, no ground-truth layers); the harness keeps `env` to judge.
        view = env if privileged else BoundaryEnv(env)
        description = view.description()
        # The agent gets the public description and timesteps; only a privileged
        # estimator is handed the simulator, on purpose.
        made = make_agent(env_name, description, planner=planner, skill=skill,
                          estimator=estimator, seed=seed, simulator=env if privileged else None)
        for episode in range(episodes):
            row, stats = _play_episode(env, view, made, description, fam, episode, seed,
                                       frames if video and episode == 0 else None)
            rows.append(row)
            totals.add(stats)
            bar.update(1)
            bar.set_postfix(_postfix(rows, fam))
    except KeyboardInterrupt:
        # Ctrl-C: the episodes played so far make the table (the one under way is dropped).
        interrupted = True
    finally:
        bar.close()
        try:
            if made is not None:
                made.close()
        finally:
            if env is not None:
                env.close()
    if video and frames:
        import imageio.v2 as imageio
        imageio.mimwrite(video, frames, fps=int(round(1 / env.control_timestep)),
                         macro_block_size=1)
    summary = _summary(env_name, fam, rows, totals, seed, planner, skill)
    summary["training_frames"] = training_frames(made)
    summary["estimator"] = estimator_name(fam, estimator)
    summary["privileged"] = is_privileged(fam, estimator)
    summary["env_options"] = env_options
    summary["episodes_requested"] = episodes
    summary["interrupted"] = interrupted
    return summary


def training_frames(agent) -> int:
    """Environment frames spent training the learned parts of a modular agent.

    The sum of the parts' ``training_frames`` (a learned skill's, a learned
    planner's); 0 for scripted parts. Frames, not wall time: what
    `benchmarks/compare_agents.py` puts beside the end-to-end agents' frames.
    """
    if agent is None:
        return 0
    parts = (getattr(agent, "planner", None), getattr(agent, "skill", None),
             getattr(agent, "estimator", None))
    return int(sum(int(getattr(part, "training_frames", 0) or 0) for part in parts))


def _play_episode(env, view, agent, description, fam, episode, seed, frames):
    """One episode; any error inside it (reset, estimator, planner, skill, GTP
    engine) ends it with ``error`` and ``failure_reason`` in its row.
    Returns (row, the agent's subgoal counters for it)."""
    start = time.perf_counter()
    timestep, ret, steps, reason, error, started = None, 0.0, 0, None, None, False
    try:
        timestep = view.reset()
        agent.reset(description, timestep, seed=seed * 100_003 + episode)
        started = True
        while not timestep.last():
            if frames is not None:
                frames.append(env.render(env.task.main_camera, 256, 256))
            action = agent.act(timestep)
            if agent.gave_up is not None:
                reason = agent.gave_up
                break
            timestep = view.step(action)
            ret += float(timestep.reward)
            steps += 1
        if reason is None:
            agent.end_episode(timestep)
    except Exception as exc:  # an error must not lose the other episodes
        error = f"{type(exc).__name__}: {exc}"
        reason = f"error: {error}"
    # Counters of an episode whose agent never started are not the last episode's.
    stats = agent.episode_stats if started else OptionStats()
    row = {"episode": episode, "return": ret, "steps": steps,
           "wall_s": time.perf_counter() - start,
           "subgoals_issued": stats.issued, "subgoals_reached": stats.reached,
           "estimation_failures": stats.estimation_failures}
    if fam == "mujoban":
        # (after a failed reset the task still shows the last episode's end)
        row["solved"] = timestep is not None and bool(getattr(env.task, "solved", False))
        if not row["solved"]:
            row["failure_reason"] = reason or "time limit"
    else:
        outcome = env.task.outcome if timestep is not None else None
        row["outcome"] = outcome or "loss"  # a game still running counts as lost
        row["final_reward"] = float(timestep.reward or 0.0) if timestep is not None else 0.0
        if timestep is not None and getattr(env.task, "resigned", False):
            row["opponent_resigned"] = True
        if row["outcome"] != "win" and (reason or outcome is None):
            row["failure_reason"] = reason or "time limit"
    if error is not None:
        row["error"] = error
    return row, stats


def _run_policy(env_name, fam, episodes, seed, agent, levels, video, progress,
                stochastic) -> dict:
    from hier_agents.baselines.impala.evaluate import parse_agent, parse_random, play_checkpoint, play_random

    if levels is not None:
        raise ValueError(f"--levels is not supported with --agent {agent}")
    if agent.startswith("random"):
        hold = parse_random(agent)
        if video:
            raise ValueError(f"--video is not supported with --agent {agent}")
        rows, info = play_random(env_name, episodes, seed, hold=hold, progress=progress)
    else:
        rows, info = play_checkpoint(env_name, parse_agent(agent), episodes, seed,
                                     video=video, progress=progress, stochastic=stochastic)
    totals = OptionStats()
    for row in rows:  # auxiliary sub-episodes: reached, or not within T_abs
        totals.issued += row["subgoals_issued"]
        totals.reached += row["subgoals_reached"]
    totals.unfinished = totals.issued - totals.reached
    summary = _summary(env_name, fam, rows, totals, seed, "-", agent)
    summary["agent"] = agent
    summary.update(info)
    return summary


def _postfix(rows, fam) -> dict:
    if fam == "mujoban":
        return {"solved": f"{sum(r['solved'] for r in rows)}/{len(rows)}"}
    return {"wins": f"{sum(r['outcome'] == 'win' for r in rows)}/{len(rows)}"}


def _mean(values):
    return float(np.mean(values)) if len(values) else None


def _summary(env_name, fam, rows, totals: OptionStats, seed, planner, skill) -> dict:
    n = len(rows)
    out = {"env": env_name, "episodes": n, "seed": seed, "agent": "modular",
           "planner": planner or next(iter(PLANNERS[fam])),
           "skill": skill or next(iter(SKILLS[fam]))}
    if n == 0:  # e.g. interrupted before the first episode ended
        for key in (("success_rate",) if fam == "mujoban" else
                    ("win_rate", "draw_rate", "loss_rate", "success_rate")):
            out[key] = None
        out.update(mean_return=None, mean_steps=None, subgoal_success_rate=None,
                   subgoals={}, episode_failures={}, errors=0, wall_s=None,
                   control_steps_per_s=None, rows=[])
        return out
    if fam == "mujoban":
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
    out["mean_return"] = float(np.mean([r["return"] for r in rows]))
    out["mean_steps"] = float(np.mean([r["steps"] for r in rows]))
    rate = totals.success_rate
    out["subgoal_success_rate"] = None if rate != rate else rate  # NaN is not JSON
    out["subgoals"] = {"issued": totals.issued, "reached": totals.reached,
                       "failed": totals.failed, "cut_off": totals.cut_off,
                       "unfinished": totals.unfinished,
                       "failures": totals.failures,
                       "estimation_failures": totals.estimation_failures}
    reasons = {}
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
    return f"{100 * rate:5.1f}% [{100 * interval[0]:5.1f}, {100 * interval[1]:5.1f}]"


def format_table(summary: dict) -> str:
    if summary.get("agent", "modular") == "modular":
        who = (f"estimator {summary.get('estimator', '?')}"
               f"{' (PRIVILEGED: reads the simulator)' if summary.get('privileged') else ''}, "
               f"planner {summary['planner']}, skill {summary['skill']}")
        if summary.get("training_frames"):
            who += f" (learned parts trained on {summary['training_frames']:,} frames)"
    elif summary["agent"].startswith("random"):
        who = summary["condition"]
    else:
        who = (f"{summary['agent']} ({summary['condition']}, trained "
               f"{summary['training_frames']:,} frames on {summary['trained_env']})")
    lines = [f"{summary['env']}: {who}, {summary['episodes']} episodes, seed {summary['seed']}"]
    if summary.get("interrupted"):
        lines.append(f"  INTERRUPTED (Ctrl-C): {summary['episodes']} of "
                     f"{summary.get('episodes_requested', '?')} episodes played")
    if not summary["episodes"]:
        return "\n".join(lines)
    if "win_rate" in summary:
        lines.append(f"  win   {_pct(summary['win_rate'], summary['win_interval'])}")
        lines.append(f"  draw  {_pct(summary['draw_rate'], summary['draw_interval'])}")
        lines.append(f"  loss  {_pct(summary['loss_rate'], summary['loss_interval'])}")
    else:
        lines.append(f"  solved            {_pct(summary['success_rate'], summary['success_interval'])}")
    lines.append(f"  mean return       {summary['mean_return']:.2f}")
    lines.append(f"  mean steps        {summary['mean_steps']:.1f}")
    if summary["subgoal_success_rate"] is not None:
        lines.append(f"  subgoal success   {100 * summary['subgoal_success_rate']:.1f}% "
                     f"({summary['subgoals']['reached']}/{summary['subgoals']['issued']} issued)")
    else:
        lines.append("  subgoal success   - (no subgoals)")
    if summary.get("episode_failures"):
        lines.append("  unsolved because  " + ", ".join(
            f"{k} x{v}" for k, v in sorted(summary["episode_failures"].items())))
    if summary.get("errors"):
        first = next(r["error"] for r in summary["rows"] if "error" in r)
        lines.append(f"  errors            {summary['errors']} episode(s) ended by an error "
                     f"(first: {first[:120]})")
    lines.append(f"  wall s / episode  {summary['wall_s']:.2f}")
    if summary.get("control_steps_per_s"):
        lines.append(f"  control steps / s {summary['control_steps_per_s']:.0f} "
                     f"(environment and agent, one process)")
    return "\n".join(lines)


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(prog="python -m hier_agents.run",
                                     description=__doc__.split("\n\n")[0])
    parser.add_argument("env", nargs="?", default=None,
                        help=f"environment name (default: {DEFAULT_ENV}, {DEFAULT_EPISODES} episodes)")
    parser.add_argument("--episodes", type=int, default=None)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--agent", default="modular",
                        help="modular (default), checkpoint:PATH (a hier_agents.train run "
                             "directory or checkpoint file), random or random:HOLD (uniform random "
                             "actions, each held HOLD control steps)")
    parser.add_argument("--stochastic", action="store_true",
                        help="checkpoint agents: sample actions from the policy instead of "
                             "taking its mean")
    parser.add_argument("--planner", help="planner name (see --list)")
    parser.add_argument("--skill", help="skill name (see --list)")
    parser.add_argument("--estimator", help="estimator name (see --list)")
    parser.add_argument("--levels", help="MuJoBan: a Boxoban file to play in order")
    parser.add_argument("--env-option", action="append", default=[], metavar="KEY=VALUE",
                        help="an envs.load override for the modular agent's environment, e.g. "
                             "physics_timestep=0.005 or sleep=True (repeatable; VALUE is a "
                             "Python literal)")
    parser.add_argument("--video", help="write an MP4 of the first episode here")
    parser.add_argument("--json", help="write the summary here")
    parser.add_argument("--list", action="store_true", help="list planners and skills and exit")
    args = parser.parse_args(argv)
    if args.list:
        for fam in PLANNERS:
            names = [f"{name} (privileged)" if getattr(factory, "privileged", False) else name
                     for name, factory in ESTIMATORS[fam].items()]
            planners = list(PLANNERS[fam]) + (["learned:PATH"] if fam == "mujoban" else [])
            print(f"{fam}: planners {planners}, skills {list(SKILLS[fam])}, "
                  f"estimators {names}")
        return 0
    env_name = args.env or DEFAULT_ENV
    episodes = args.episodes if args.episodes is not None else (
        DEFAULT_EPISODES if args.env is None else 10)
    if env_name not in envs.names():
        parser.error(f"unknown environment {env_name!r}; known: {', '.join(envs.names())}")
    if episodes < 1:
        parser.error("--episodes must be >= 1")
    try:
        fam = family(env_name)
    except ValueError as exc:
        parser.error(str(exc))
    for kind, table, name in (("planner", PLANNERS, args.planner), ("skill", SKILLS, args.skill),
                              ("estimator", ESTIMATORS, args.estimator)):
        if name is not None and name not in table[fam]:
            extra = " or learned:PATH" if kind == "planner" and fam == "mujoban" else ""
            parser.error(f"unknown {kind} {name!r} for {fam}; valid: {sorted(table[fam])}{extra}")
    if args.planner and args.planner.startswith("learned:") and fam == "mujoban":
        from abstract_planners.learned_options import load_option_policy
        try:  # a missing or foreign checkpoint fails here, with a usage error
            load_option_policy(args.planner[len("learned:"):])
        except (FileNotFoundError, ValueError) as exc:
            parser.error(f"--planner {args.planner}: {exc}")
    if args.levels is not None and fam != "mujoban":
        parser.error("--levels only applies to mujoban environments")
    env_options = {}
    for item in args.env_option:
        key, sep, text = item.partition("=")
        if not sep or key not in envs.overrides(env_name) or key.endswith("_camera"):
            valid = [k for k in envs.overrides(env_name) if not k.endswith("_camera")]
            parser.error(f"--env-option must be KEY=VALUE with KEY one of {valid}, got {item!r}")
        try:
            env_options[key] = ast.literal_eval(text)
        except (ValueError, SyntaxError):
            env_options[key] = text
    if env_options:
        try:  # a bad value fails here, with the environment's own message
            envs.load(env_name, **envs.no_cameras(env_name), **env_options).close()
        except (TypeError, ValueError) as exc:
            parser.error(f"--env-option: {exc}")
    if args.stochastic and not args.agent.startswith("checkpoint:"):
        parser.error("--stochastic applies to checkpoint:PATH agents")
    if args.agent != "modular":
        if args.agent.startswith("random"):
            from hier_agents.baselines.impala.evaluate import parse_random
            try:
                parse_random(args.agent)
            except ValueError as exc:
                parser.error(str(exc))
        elif not args.agent.startswith("checkpoint:") or args.agent == "checkpoint:":
            parser.error(f"--agent must be modular, random[:HOLD] or checkpoint:PATH, "
                         f"got {args.agent!r}")
        for flag, value in (("--planner", args.planner), ("--skill", args.skill),
                            ("--estimator", args.estimator), ("--levels", args.levels),
                            ("--env-option", args.env_option or None)):
            if value is not None:
                parser.error(f"{flag} applies to the modular agent, not to {args.agent}")
    try:
        summary = run(env_name, episodes, args.seed, planner=args.planner, skill=args.skill,
                      estimator=args.estimator, levels=args.levels, video=args.video,
                      agent=args.agent, stochastic=args.stochastic, env_options=env_options)
    except (FileNotFoundError, ValueError) as exc:
        if args.agent == "modular":
            raise
        parser.error(str(exc))
    print(format_table(summary))
    if args.json:
        from hier_agents.provenance import provenance
        summary["provenance"] = provenance()
        with open(args.json, "w") as f:
            json.dump(summary, f, indent=2)
        print(f"wrote {args.json}")
    return 130 if summary.get("interrupted") else 0


if __name__ == "__main__":
    sys.exit(main())
