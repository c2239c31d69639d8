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
    python -m hier_agents.run --list                               # agent kinds, parts by family

The modular agent sits behind the observation boundary: it is given the
task's public description (``env.description()``) and timesteps. The
default estimators are observation-only (``camera``: MuJoBan's top camera,
the board games' high front camera, and proprioception); ``--estimator
oracle`` or ``entity-layer`` read the simulator, and a board game's
``--estimator board`` reads the referee's record: every table and JSON says
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
(``"finished": false`` until the run ends), the ``--video`` after the first.

Every agent kind (``--agent NAME[:ARG]``: ``modular``, ``checkpoint:PATH``,
``random[:HOLD]`` and any kind registered with `hier_agents.agents.register`)
is played by the one episode runner (`hier_agents.agents.runner`) and scored
by its family adapter.

MuJoBan rows report the solved fraction; board games win/draw/loss rates. All
rates carry 95% Wilson intervals. JSON keys: env, episodes, estimator,
privileged and reads (modular agents: what the estimator reads, "simulator",
"record" -- a board game's referee's record -- or "observations"; the first
two are privileged), success_rate, win_rate, draw_rate, loss_rate (board games),
mean_return, mean_steps, subgoal_success_rate, episode_failures (reason ->
count), wall_s, control_steps_per_s, plus planner, skill, seed, env_options,
deviations (the settings of ``env_options`` that differ from the original
implementation's, `envs.deviations`: ``{"sleep": true}`` for MuJoBan by
default; a summary written before this key existed played the original's
settings), levels, episodes_requested, interrupted, finished, worker_restarts (how many
times dead worker processes were replaced, `players.play_parallel`),
provenance and per-episode rows; checkpoint agents add their condition,
training frames, ``observations`` (the input keys the policy reads) and
``privileged``.
"""

from __future__ import annotations

import sys

from tqdm import tqdm

import envs
from envs.cli import checked_options
from hier_agents.agents import resolve
from hier_agents.agents.runner import Play, profile_summary
from hier_agents.modular.agent import OptionStats
from hier_agents.modular.families import adapter, family
from hier_agents.players import Progress, play_here, play_parallel
from hier_agents.run_cli import (
    DEFAULT_ENV,  # noqa: F401
    DEFAULT_EPISODES,  # noqa: F401
    PROG,  # noqa: F401 (re-exported)
    build_parser,
    check_args,
    print_components,
)
from hier_agents.run_report import format_table, postfix, summarize  # noqa: F401
from physics_planning import cli


def run(
    env_name: str,
    episodes: int,
    seed: int = 0,
    *,
    planner: str | None = None,
    skill: str | None = None,
    estimator: str | None = None,
    levels: str | None = None,
    video: str | None = None,
    progress: bool = True,
    agent: str = "modular",
    stochastic: bool = False,
    env_options: dict | None = None,
    on_progress: Progress | None = None,
    first_episode: int = 0,
    workers: int = 1,
    ray_address: str | None = None,
    profile: bool = False,
    options: dict | None = None,
) -> dict:
    """Plays episodes ``first_episode`` .. ``first_episode + episodes - 1``;
    returns the JSON-able summary.

    Episode ``e`` is seeded from ``(seed, e)`` (`envs.Environment.seed`,
    `envs.episode_seed`): its level or opening, the opponent's and the agent's
    draws do not depend on the episodes played before, so any split of the
    episodes over processes gives the same rows.

    Args:
      agent: ``NAME[:ARG]`` of an agent kind (`hier_agents.agents.resolve`):
        ``"modular"`` (estimator + planner + skill, named as
        `hier_agents.modular.components.resolve` reads them),
        ``"checkpoint:PATH"`` (a trained end-to-end agent, `hier_agents.train`;
        its policy's mean, or samples with ``stochastic``), ``"sb3:PATH"`` (a
        Stable-Baselines3 model, `hier_agents.baselines.sb3`), ``"random[:HOLD]"``
        (uniformly random actions), or a registered kind.
      planner, skill, estimator, stochastic: the options of the kinds that
        take them (modular; checkpoint); ``options``: any kind's options.
      levels: MuJoBan: a level file; episode ``e`` plays its ``e``-th level
        (modulo its length).
      env_options: extra `envs.load` overrides of the played environment
        (e.g. ``{"physics_timestep": 0.005}``); the summary records them.
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
      ValueError: an environment without a modular agent, a bad agent or
        component name (`physics_planning.cli.UsageError`), an option the
        agent kind does not take, ``levels``, ``env_options`` or ``video``
        for a kind they do not apply to, ``video`` with ``ray_address``,
        ``workers`` < 1, ``first_episode`` < 0, a checkpoint that does not
        load or fit the environment.
      FileNotFoundError: a checkpoint that does not exist.
    """
    given = dict(planner=planner, skill=skill, estimator=estimator, stochastic=stochastic or None)
    chosen = {k: v for k, v in {**given, **(options or {})}.items() if v is not None}
    settings = dict(levels=levels, env_options=env_options, video=video, profile=profile)
    play = _play(env_name, seed, agent, chosen, first_episode, workers, ray_address, **settings)
    indices = list(range(first_episode, first_episode + episodes))
    return _Run(play, indices, progress, on_progress).go(workers, ray_address)


def _play(
    env_name,
    seed,
    agent,
    options,
    first_episode,
    workers,
    ray_address,
    *,
    levels,
    env_options,
    video,
    profile,
) -> Play:
    """The checked `Play` of `run`'s arguments (its ValueErrors)."""
    fam = family(env_name)
    if workers < 1 or first_episode < 0:
        raise ValueError(
            f"workers must be >= 1 and first_episode >= 0, got {workers} and {first_episode}"
        )
    kind, arg = resolve(agent)
    unknown = sorted(set(options) - set(kind.options))
    if unknown:
        raise ValueError(
            f"--agent {agent} takes no option {', '.join(unknown)} (it takes: "
            f"{', '.join(kind.options) or 'none'})"
        )
    if not kind.env_flags and (video or levels is not None or env_options):
        raise ValueError(f"--video, --levels and --env-option do not apply to --agent {agent}")
    if workers > 1 or ray_address is not None:  # refused here, not in every worker
        kind.check(env_name, arg, options)
    if levels is not None and not adapter(fam).level_files:
        raise ValueError("--levels only applies to mujoban environments")
    if video and ray_address:
        raise ValueError(
            "--video is written by the process that plays the first episode: not with --ray-address"
        )
    checked_options(
        env_name,
        {
            "seed": seed,
            **(env_options or {}),
            **({"levels": levels} if levels is not None else {}),
        },
        env_name,
    )
    return Play(
        env_name,
        int(seed),
        agent,
        dict(options),
        levels,
        dict(env_options or {}),
        video,
        first_episode,
        bool(profile),
    )


class _Run:
    """One `run`: the episodes played so far, the progress bar, the summary."""

    def __init__(self, play: Play, indices: list[int], progress: bool, on_progress):
        self.play, self.indices = play, indices
        self.progress, self.on_progress = progress, on_progress
        self.played: list[tuple[dict, dict]] = []  # (row, subgoal counters)
        self.meta: dict = {}
        self.interrupted, self.restarts = False, 0
        self.bar: tqdm | None = None  # shown once the agent is built (a bad one: no bar)

    def go(self, workers: int, ray_address) -> dict:
        try:
            if workers == 1 and ray_address is None:
                play_here(self.play, self.indices, self.on_done, self.built)
            else:
                self._start_bar()
                self.restarts = play_parallel(
                    self.play, self.indices, workers, ray_address, self.on_done
                )
        except KeyboardInterrupt:
            # Ctrl-C: the episodes played so far make the table (those under way are dropped).
            self.interrupted = True
        finally:
            if self.bar is not None:
                self.bar.close()
        return self.summary(True)

    def _start_bar(self) -> tqdm:
        if self.bar is None:
            self.bar = tqdm(
                total=len(self.indices),
                unit="episode",
                desc=self.play.env_name,
                file=sys.stderr,
                disable=not self.progress,
            )
        return self.bar

    def built(self, info: dict) -> None:
        self._start_bar()
        self.meta.update(info)
        if self.on_progress is not None:
            self.on_progress(self.summary(False))

    def on_done(self, results, info: dict) -> None:
        bar = self._start_bar()
        self.meta.update(info)
        self.played.extend(results)
        bar.update(len(results))
        bar.set_postfix(postfix([r for r, _ in self.played], family(self.play.env_name)))
        if self.on_progress is not None:
            self.on_progress(self.summary(False))

    def summary(self, finished: bool) -> dict:
        play = self.play
        played = sorted(self.played, key=lambda p: p[0]["episode"])
        rows = [row for row, _ in played]
        totals = OptionStats()
        for _, counters in played:
            totals.add(OptionStats(**counters))
        out = summarize(play.env_name, family(play.env_name), rows, totals, play.seed)
        # Who played: "-" until the kind's description arrives (a worker reports it).
        out.update(agent=play.agent, planner="-", skill="-")
        out.update(self.meta)
        out.update(
            env_options=play.env_options,
            deviations=envs.deviations(play.env_name, play.env_options),
            levels=play.levels,
            episodes_requested=len(self.indices),
            interrupted=self.interrupted,
            finished=finished,
            worker_restarts=self.restarts,
        )
        if play.profile:
            out["profile"] = profile_summary(rows)
        return out


def _main(argv=None) -> int:
    parser = build_parser(__doc__.split("\n\n")[0], epilog="examples:\n" + __doc__.split("\n\n")[1])
    args = parser.parse_args(argv)
    if args.list:
        print_components()
        return 0
    checked = check_args(args)
    save = None
    if checked.json is not None:
        from hier_agents.provenance import provenance

        record, out = provenance(), checked.json

        def save(summary: dict) -> None:
            cli.write_json(out, {**summary, "provenance": record})

    summary = run(
        checked.env,
        checked.episodes,
        args.seed,
        levels=checked.levels,
        video=None if checked.video is None else str(checked.video),
        agent=args.agent,
        options=checked.options,
        env_options=checked.env_options,
        on_progress=save,
        first_episode=args.first_episode,
        workers=args.workers,
        ray_address=args.ray_address,
        profile=args.profile,
    )
    print(format_table(summary))
    if save is not None:
        save(summary)
        print(f"wrote {checked.json}")
    return 130 if summary.get("interrupted") else 0


def main(argv=None) -> int:
    """``python -m hier_agents.run``: plays, prints the table, writes
    ``--json`` (after every episode) and ``--video``; returns the exit status
    (0; 130 when interrupted by Ctrl-C). Bad input: one line on stderr and
    `SystemExit` with status 2 before anything is played
    (`physics_planning.cli.run_main`)."""
    return cli.run_main(PROG, _main, argv)


if __name__ == "__main__":
    sys.exit(main())
