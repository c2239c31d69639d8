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

import json
import sys
import time

from tqdm import tqdm

import envs
from hier_agents.boundary import BoundaryEnv
from hier_agents.modular.agent import OptionStats
from hier_agents.modular.components import (env_overrides, estimator_name, family,
                                            is_privileged, make_agent)
from hier_agents.modular.families import adapter
from hier_agents.run_cli import (DEFAULT_ENV, DEFAULT_EPISODES,  # noqa: F401 (re-exported)
                                 build_parser, check_args, print_components)
from hier_agents.run_report import format_table, postfix, summarize  # noqa: F401


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
        if not adapter(fam).level_files:
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
            bar.set_postfix(postfix(rows, fam))
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
    summary = summarize(env_name, fam, rows, totals, seed, planner, skill)
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
    if not adapter(fam).games:
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
    summary = summarize(env_name, fam, rows, totals, seed, "-", agent)
    summary["agent"] = agent
    summary.update(info)
    return summary


def main(argv=None) -> int:
    """``python -m hier_agents.run``: plays, prints the table, writes
    ``--json``; returns the exit status (130 when interrupted by Ctrl-C).
    Usage errors exit with status 2 (`hier_agents.run_cli`)."""
    parser = build_parser(__doc__.split("\n\n")[0])
    args = parser.parse_args(argv)
    if args.list:
        print_components()
        return 0
    env_name, episodes, env_options = check_args(parser, args)
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
