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
    python -m hier_agents.run mujoban/level5 --levels FILE --episodes 200 --workers 2
    python -m hier_agents.run --list                               # the parts by family

The modular agent sits behind the observation boundary: it is given the
task's public description (``env.description()``) and timesteps. The
default estimators are observation-only (MuJoBan: ``camera``, the top
camera and proprioception; board games: ``board``); ``--estimator oracle``
or ``entity-layer`` read the simulator and every table and JSON says
``privileged``.

Episode ``e`` of a run seeded ``s`` is seeded from ``(s, e)``: its level
(the ``e``-th of a ``--levels`` file), opponent and agent draws do not depend
on the episodes before it, so ``--workers N`` (processes on this machine) or
``--ray-address`` (tasks on a Ray cluster) split the episodes and give the
same rows and table as one process.

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
what is allowed, the closest name) and exit status 2 (`physics_planning.cli`). Output
folders are created up front; ``--json`` is rewritten after every episode
(``"finished": false`` until the run ends; checkpoint and random agents write
it at the end), the ``--video`` after the first.

MuJoBan rows report the solved fraction; board games win/draw/loss rates. All
rates carry 95% Wilson intervals. JSON keys: env, episodes, estimator,
privileged, success_rate, win_rate, draw_rate, loss_rate (board games),
mean_return, mean_steps, subgoal_success_rate, episode_failures (reason ->
count), wall_s, control_steps_per_s, plus planner, skill, seed, env_options,
levels, episodes_requested, interrupted, finished, worker_restarts (how many
times dead worker processes were replaced, `players.play_parallel`),
provenance and per-episode rows; checkpoint agents add their condition, training frames, ``observations``
(the input keys the policy reads) and ``privileged``.
"""

from __future__ import annotations

import sys

from tqdm import tqdm

from physics_planning import cli
from hier_agents.modular.components import estimator_name, family, is_privileged
from hier_agents.modular.families import adapter
from hier_agents.modular.agent import OptionStats
from hier_agents.players import Play, Progress, play_here, play_parallel, profile_summary
from hier_agents.run_cli import (DEFAULT_ENV, DEFAULT_EPISODES, PROG,  # noqa: F401 (re-exported)
                                 build_parser, check_args, print_components)
from hier_agents.run_report import format_table, postfix, summarize  # noqa: F401


def run(env_name: str, episodes: int, seed: int = 0, *, planner: str | None = None,
        skill: str | None = None, estimator: str | None = None, levels: str | None = None,
        video: str | None = None, progress: bool = True, agent: str = "modular",
        stochastic: bool = False, env_options: dict | None = None,
        on_progress: Progress | None = None, first_episode: int = 0, workers: int = 1,
        ray_address: str | None = None, profile: bool = False) -> dict:
    """Plays episodes ``first_episode`` .. ``first_episode + episodes - 1``;
    returns the JSON-able summary.

    Episode ``e`` is seeded from ``(seed, e)`` (`envs.Environment.seed`,
    `envs.episode_seed`): its level or opening, the opponent's and the agent's
    draws do not depend on the episodes played before, so any split of the
    episodes over processes gives the same rows.

    Args:
      agent: ``"modular"`` (estimator + planner + skill, named as
        `hier_agents.modular.components.resolve` reads them),
        ``"checkpoint:PATH"`` (a trained end-to-end agent, `hier_agents.train`;
        its policy's mean, or samples with ``stochastic``) or
        ``"random[:HOLD]"`` (uniformly random actions).
      levels: MuJoBan: a level file; episode ``e`` plays its ``e``-th level
        (modulo its length; modular and checkpoint agents).
      env_options: extra `envs.load` overrides of the played environment
        (e.g. ``{"physics_timestep": 0.005}``; modular and checkpoint agents);
        the summary records them.
      video: an MP4 of the first episode, written when it ends (not with
        ``ray_address``).
      on_progress: called with the summary so far (``"finished": False``)
        after every episode (in order of completion with workers; with one
        worker also once the agent is built).
      first_episode: index of the first episode (>= 0).
      workers: processes playing episodes at once (1: this process); each
        builds the environment and agent once and plays shards of episodes.
      ray_address: play the shards as tasks on this Ray cluster (``auto``:
        the one ``ray start`` made; ``"local"``: start one here) with
        ``workers`` tasks in flight; a task whose worker dies is retried.
      profile: time the sections of every episode (`envs.profile`: physics,
        render, estimator, planner, skill); each row gets ``profile_s`` and
        the summary ``profile`` (seconds and shares of the episodes' wall
        time, the rest as ``other``).

    Returns:
      The summary (`hier_agents.run_report.summarize` plus the keys in the
      module docstring), rows in episode order, ``"finished": True``.

    Raises:
      ValueError: an environment without a modular agent, a bad component
        name, ``levels``, ``env_options`` or ``video`` with the random agent,
        ``video`` with ``ray_address``, ``workers`` < 1, ``first_episode`` < 0;
        `physics_planning.cli.UsageError` (a ValueError) for a checkpoint that does not
        load or fit the environment (`play_checkpoint`).
      FileNotFoundError: a checkpoint that does not exist.
    """
    fam = family(env_name)
    if workers < 1 or first_episode < 0:
        raise ValueError(f"workers must be >= 1 and first_episode >= 0, got {workers} and "
                         f"{first_episode}")
    if agent != "modular" and not (agent == "checkpoint" or agent.startswith("checkpoint:")):
        from hier_agents.baselines.impala.evaluate import parse_random
        hold = parse_random(agent)
        if video or levels is not None or env_options:
            raise ValueError(f"--video, --levels and --env-option do not apply to "
                             f"--agent random:{hold}")
    elif agent != "modular":
        from hier_agents.baselines.impala.evaluate import parse_agent
        path = parse_agent(agent)
        if workers > 1 or ray_address is not None:  # refused here, not in every worker
            from hier_agents.baselines.impala.learner import load_checkpoint
            load_checkpoint(path)
    if levels is not None and not adapter(fam).level_files:
        raise ValueError("--levels only applies to mujoban environments")
    if video and ray_address:
        raise ValueError("--video is written by the process that plays the first episode: "
                         "not with --ray-address")
    play = Play(env_name, int(seed), agent, planner, skill, estimator, levels, bool(stochastic),
                dict(env_options or {}), video, first_episode, bool(profile))
    indices = list(range(first_episode, first_episode + episodes))
    played: list[tuple[dict, dict]] = []  # (row, subgoal counters)
    meta: dict = {}
    interrupted = False
    restarts = [0]

    def summary_now(finished: bool) -> dict:
        return _summary(play, fam, sorted(played, key=lambda p: p[0]["episode"]), meta,
                        len(indices), interrupted, finished, restarts[0])

    bars = []  # the progress bar, shown once the agent is built (a bad one: no bar)

    def start_bar():
        if not bars:
            bars.append(tqdm(total=len(indices), unit="episode", desc=env_name,
                             file=sys.stderr, disable=not progress))

    def on_done(results, info):
        start_bar()
        meta.update(info)
        played.extend(results)
        bars[0].update(len(results))
        bars[0].set_postfix(postfix([r for r, _ in played], fam))
        if on_progress is not None:
            on_progress(summary_now(False))

    def built(info):
        start_bar()
        meta.update(info)
        if on_progress is not None:
            on_progress(summary_now(False))

    try:
        if workers == 1 and ray_address is None:
            play_here(play, indices, on_done, built)
        else:
            start_bar()
            restarts[0] = play_parallel(play, indices, workers, ray_address, on_done)
    except KeyboardInterrupt:
        # Ctrl-C: the episodes played so far make the table (those under way are dropped).
        interrupted = True
    finally:
        for bar in bars:
            bar.close()
    return summary_now(True)


def _summary(play: Play, fam, played, meta, requested, interrupted, finished,
             worker_restarts: int = 0) -> dict:
    rows = [row for row, _ in played]
    totals = OptionStats()
    for _, counters in played:
        totals.add(OptionStats(**counters))
    common = dict(env_options=play.env_options, levels=play.levels,
                  episodes_requested=requested, interrupted=interrupted, finished=finished,
                  worker_restarts=worker_restarts)
    if play.profile:
        common["profile"] = profile_summary(rows)
    if play.agent == "modular":
        out = summarize(play.env_name, fam, rows, totals, play.seed, play.planner, play.skill)
        out.update(training_frames=int(meta.get("training_frames", 0)),
                   estimator=estimator_name(fam, play.estimator),
                   privileged=is_privileged(fam, play.estimator), **common)
        return out
    out = summarize(play.env_name, fam, rows, totals, play.seed, "-", play.agent)
    out.update(agent=play.agent, **common)
    out.update(meta)
    return out


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
                  env_options=checked.env_options, on_progress=save,
                  first_episode=args.first_episode, workers=args.workers,
                  ray_address=args.ray_address, profile=args.profile)
    print(format_table(summary))
    if save is not None:
        save(summary)
        print(f"wrote {checked.json}")
    return 130 if summary.get("interrupted") else 0


def main(argv=None) -> int:
    """``python -m hier_agents.run``: plays, prints the table, writes
    ``--json`` (after every episode) and ``--video``; returns the exit status
    (0; 130 when interrupted by Ctrl-C). Bad input: one line on stderr and
    `SystemExit` with status 2 before anything is played (`physics_planning.cli.run_main`)."""
    return cli.run_main(PROG, _main, argv)


if __name__ == "__main__":
    sys.exit(main())
