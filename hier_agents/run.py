"""Run the modular agent (estimator + planner + skill) and print a results table.

    python -m hier_agents.run                                  # small default: mujoban/level3
    python -m hier_agents.run mujoban/level5-pegs --episodes 100 --json out.json
    python -m hier_agents.run mujoxo/mixture --episodes 50
    python -m hier_agents.run mujogo/7x7 --episodes 20 --video go.mp4
    python -m hier_agents.run mujoban/level5 --planner random      # swap a part
    python -m hier_agents.run mujoxo/mixture --planner mcts:3000   # a part with a parameter
    python -m hier_agents.run mujoban/level5 --skill learned-ball:runs/ball/ball_policy.pt
    python -m hier_agents.run mujoban/level5 --estimator oracle    # privileged upper bound
    python -m hier_agents.run mujoban/level1 --agent checkpoint:runs/impala   # a trained agent
    python -m hier_agents.run mujoban/level1 --agent random        # uniform random actions
    python -m hier_agents.run mujoban/level1 --agent random:10     # ... each held 10 steps
    python -m hier_agents.run --list                               # the parts by family

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

Bad input (an unknown name, a negative seed, a missing or malformed
``--levels`` file, an output path that cannot be written, ...) ends the
command before anything is played with one line on stderr (what was wrong,
what is allowed, the closest name) and exit status 2 (`envs.cli`). Output
folders are created up front; ``--json`` is rewritten after every episode
(``"finished": false`` until the run ends; checkpoint and random agents write
it at the end), the ``--video`` after the first.

MuJoBan rows report the solved fraction; board games win/draw/loss rates. All
rates carry 95% Wilson intervals. JSON keys: env, episodes, estimator,
privileged, success_rate, win_rate, draw_rate, loss_rate (board games),
mean_return, mean_steps, subgoal_success_rate, episode_failures (reason ->
count), wall_s, control_steps_per_s, plus planner, skill, seed, env_options,
levels, episodes_requested, interrupted, finished, provenance and per-episode
rows; checkpoint agents add their condition, training frames, ``observations``
(the input keys the policy reads) and ``privileged``.
"""

from __future__ import annotations

import sys
import time
from typing import Callable

from tqdm import tqdm

import envs
from envs import cli
from hier_agents.boundary import BoundaryEnv
from hier_agents.modular.agent import OptionStats
from hier_agents.modular.components import (env_overrides, estimator_name, family,
                                            is_privileged, make_agent)
from hier_agents.modular.families import adapter
from hier_agents.run_cli import (DEFAULT_ENV, DEFAULT_EPISODES, PROG,  # noqa: F401 (re-exported)
                                 build_parser, check_args, print_components)
from hier_agents.run_report import format_table, postfix, summarize  # noqa: F401

Progress = Callable[[dict], None]


def run(env_name: str, episodes: int, seed: int = 0, *, planner: str | None = None,
        skill: str | None = None, estimator: str | None = None, levels: str | None = None,
        video: str | None = None, progress: bool = True, agent: str = "modular",
        stochastic: bool = False, env_options: dict | None = None,
        on_progress: Progress | None = None) -> dict:
    """Plays ``episodes`` episodes; returns the JSON-able summary.

    Args:
      agent: ``"modular"`` (estimator + planner + skill, named as
        `hier_agents.modular.components.resolve` reads them),
        ``"checkpoint:PATH"`` (a trained end-to-end agent, `hier_agents.train`;
        its policy's mean, or samples with ``stochastic``) or
        ``"random[:HOLD]"`` (uniformly random actions).
      levels: MuJoBan: a level file played in order (modular and checkpoint agents).
      env_options: extra `envs.load` overrides of the played environment
        (e.g. ``{"physics_timestep": 0.005}``; modular and checkpoint agents);
        the summary records them.
      video: an MP4 of the first episode, written when it ends.
      on_progress: called with the summary so far (``"finished": False``)
        after every episode (the modular agent: also once it is built).

    Returns:
      The summary (`hier_agents.run_report.summarize` plus the keys in the
      module docstring), ``"finished": True``.

    Raises:
      ValueError: an environment without a modular agent, a bad component
        name, ``levels``, ``env_options`` or ``video`` with the random agent;
        `envs.cli.UsageError` (a ValueError) for a checkpoint that does not
        load or fit the environment (`play_checkpoint`).
      FileNotFoundError: a checkpoint that does not exist.
    """
    fam = family(env_name)
    env_options = dict(env_options or {})
    if agent != "modular":
        return _run_policy(env_name, fam, episodes, seed, agent, levels, video, progress,
                           stochastic, env_options, on_progress)
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

    def summary_now(finished: bool) -> dict:
        out = summarize(env_name, fam, rows, totals, seed, planner, skill)
        out.update(training_frames=training_frames(made),
                   estimator=estimator_name(fam, estimator),
                   privileged=is_privileged(fam, estimator), env_options=env_options,
                   levels=levels, episodes_requested=episodes, interrupted=interrupted,
                   finished=finished)
        return out

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
        if on_progress is not None:
            on_progress(summary_now(False))
        for episode in range(episodes):
            row, stats = _play_episode(env, view, made, description, fam, episode, seed,
                                       frames if video and episode == 0 else None)
            rows.append(row)
            totals.add(stats)
            if video and episode == 0 and frames:
                _write_video(video, frames, env.control_timestep)
                frames = []
            bar.update(1)
            bar.set_postfix(postfix(rows, fam))
            if on_progress is not None:
                on_progress(summary_now(False))
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
    return summary_now(True)


def _write_video(path, frames, control_timestep: float) -> None:
    import imageio.v2 as imageio
    imageio.mimwrite(path, frames, fps=int(round(1 / control_timestep)), macro_block_size=1)


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
                stochastic, env_options, on_progress=None) -> dict:
    """`run` for ``checkpoint:PATH`` and ``random[:HOLD]`` agents
    (`hier_agents.baselines.impala.evaluate`)."""
    from hier_agents.baselines.impala.evaluate import (parse_agent, parse_random,
                                                       play_checkpoint, play_random)

    def summary_of(rows, info, finished):
        totals = OptionStats()
        for row in rows:  # auxiliary sub-episodes: reached, or not within T_abs
            totals.issued += row["subgoals_issued"]
            totals.reached += row["subgoals_reached"]
        totals.unfinished = totals.issued - totals.reached
        summary = summarize(env_name, fam, rows, totals, seed, "-", agent)
        summary.update(agent=agent, env_options=env_options, levels=levels,
                       episodes_requested=episodes, interrupted=False, finished=finished)
        summary.update(info)
        return summary

    on_rows = None if on_progress is None else (
        lambda rows: on_progress(summary_of(rows, {}, False)))
    if agent == "random" or agent.startswith("random:"):
        hold = parse_random(agent)
        if video or levels is not None or env_options:
            raise ValueError(f"--video, --levels and --env-option do not apply to "
                             f"--agent {agent}")
        rows, info = play_random(env_name, episodes, seed, hold=hold, progress=progress,
                                 on_rows=on_rows)
    else:
        options = {**env_options, **({"levels": levels} if levels is not None else {})}
        rows, info = play_checkpoint(env_name, parse_agent(agent), episodes, seed, video=video,
                                     progress=progress, stochastic=stochastic,
                                     env_options=options, on_rows=on_rows)
    return summary_of(rows, info, True)


def _main(argv=None) -> int:
    parser = build_parser(__doc__.split("\n\n")[0],
                          epilog="examples:\n" + __doc__.split("\n\n")[1])
    args = parser.parse_args(argv)
    if args.list:
        print_components()
        return 0
    checked = check_args(args)
    save = None
    if checked.json is not None:
        from hier_agents.provenance import provenance
        record = provenance()

        def save(summary: dict) -> None:
            cli.write_json(checked.json, {**summary, "provenance": record})
    summary = run(checked.env, checked.episodes, args.seed, planner=args.planner,
                  skill=args.skill, estimator=args.estimator, levels=checked.levels,
                  video=None if checked.video is None else str(checked.video),
                  agent=args.agent, stochastic=args.stochastic,
                  env_options=checked.env_options, on_progress=save)
    print(format_table(summary))
    if save is not None:
        save(summary)
        print(f"wrote {checked.json}")
    return 130 if summary.get("interrupted") else 0


def main(argv=None) -> int:
    """``python -m hier_agents.run``: plays, prints the table, writes
    ``--json`` (after every episode) and ``--video``; returns the exit status
    (0; 130 when interrupted by Ctrl-C). Bad input: one line on stderr and
    `SystemExit` with status 2 before anything is played (`envs.cli.run_main`)."""
    return cli.run_main(PROG, _main, argv)


if __name__ == "__main__":
    sys.exit(main())
