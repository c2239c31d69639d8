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

import math
import sys
import time
from dataclasses import dataclass, field
from typing import Callable

from tqdm import tqdm

import envs
from envs import cli
from envs.profile import PROFILE, SECTIONS
from hier_agents.boundary import BoundaryEnv
from hier_agents.modular.agent import OptionStats
from hier_agents.modular.components import (env_overrides, estimator_name, family,
                                            is_privileged, make_agent)
from hier_agents.modular.families import adapter
from hier_agents.run_cli import (DEFAULT_ENV, DEFAULT_EPISODES, PROG,  # noqa: F401 (re-exported)
                                 build_parser, check_args, print_components)
from hier_agents.run_report import format_table, postfix, summarize  # noqa: F401

Progress = Callable[[dict], None]


@dataclass(frozen=True)
class Play:
    """What a run plays (everything but the episodes): picklable, so worker
    processes and Ray tasks build the same player (`make_player`)."""

    env_name: str
    seed: int = 0
    agent: str = "modular"
    planner: str | None = None
    skill: str | None = None
    estimator: str | None = None
    levels: str | None = None
    stochastic: bool = False
    env_options: dict = field(default_factory=dict)
    video: str | None = None
    video_episode: int = 0
    profile: bool = False


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
        `envs.cli.UsageError` (a ValueError) for a checkpoint that does not
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

    def summary_now(finished: bool) -> dict:
        return _summary(play, fam, sorted(played, key=lambda p: p[0]["episode"]), meta,
                        len(indices), interrupted, finished)

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
            _play_here(play, indices, on_done, built)
        else:
            start_bar()
            _play_parallel(play, indices, workers, ray_address, on_done)
    except KeyboardInterrupt:
        # Ctrl-C: the episodes played so far make the table (those under way are dropped).
        interrupted = True
    finally:
        for bar in bars:
            bar.close()
    return summary_now(True)


def _summary(play: Play, fam, played, meta, requested, interrupted, finished) -> dict:
    rows = [row for row, _ in played]
    totals = OptionStats()
    for _, counters in played:
        totals.add(OptionStats(**counters))
    common = dict(env_options=play.env_options, levels=play.levels,
                  episodes_requested=requested, interrupted=interrupted, finished=finished)
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


# -- players: one environment and agent, any episode ------------------------------------------


class ModularPlayer:
    """The modular agent behind the observation boundary in its own
    environment; ``play(episode, frames=None)`` -> (row, subgoal counters)."""

    def __init__(self, play: Play):
        fam = family(play.env_name)
        self.play_spec, self.fam = play, fam
        # A diverging simulation ends its episode (reward 0) instead of the run.
        overrides = {**env_overrides(play.env_name, play.estimator),
                     "raise_on_physics_error": False, **play.env_options}
        if play.levels is not None:
            overrides["levels"] = play.levels
        self.env = self.agent = None
        try:
            self.env = envs.load(play.env_name, seed=play.seed, **overrides)
            privileged = is_privileged(fam, play.estimator)
            # An observation-only agent sees the environment through the boundary
            # (no simulator, no ground-truth layers); the harness keeps `env` to judge.
            self.view = self.env if privileged else BoundaryEnv(self.env)
            self.description = self.view.description()
            # The agent gets the public description and timesteps; only a privileged
            # estimator is handed the simulator, on purpose.
            self.agent = make_agent(play.env_name, self.description, planner=play.planner,
                                    skill=play.skill, estimator=play.estimator, seed=play.seed,
                                    simulator=self.env if privileged else None)
        except BaseException:
            self.close()
            raise
        self.info = {"training_frames": training_frames(self.agent)}

    def play(self, episode: int, frames=None) -> tuple[dict, dict]:
        row, stats = _play_episode(self.env, self.view, self.agent, self.description, self.fam,
                                   episode, self.play_spec.seed, frames)
        return row, _counters(stats)

    def close(self) -> None:
        try:
            if self.agent is not None:
                self.agent.close()
        finally:
            if self.env is not None:
                self.env.close()


class PolicyPlayer:
    """A checkpoint's or random actions' player (`hier_agents.baselines.impala.
    evaluate`) with the modular player's interface; the subgoal counters are
    the auxiliary sub-episodes (reached, or not within T_abs)."""

    def __init__(self, play: Play):
        from hier_agents.baselines.impala.evaluate import (CheckpointPlayer, RandomPlayer,
                                                           parse_agent, parse_random)
        if play.agent.startswith("random"):
            self.inner = RandomPlayer(play.env_name, play.seed, parse_random(play.agent))
        else:
            options = {**play.env_options,
                       **({"levels": play.levels} if play.levels is not None else {})}
            self.inner = CheckpointPlayer(play.env_name, parse_agent(play.agent), play.seed,
                                          stochastic=play.stochastic, env_options=options)
        self.info = self.inner.info

    def play(self, episode: int, frames=None) -> tuple[dict, dict]:
        row = self.inner.play(episode, frames)
        issued, reached = row["subgoals_issued"], row["subgoals_reached"]
        return row, {"issued": issued, "reached": reached, "unfinished": issued - reached}

    def close(self) -> None:
        self.inner.close()


def make_player(play: Play):
    """The player of ``play``: `ModularPlayer` or `PolicyPlayer` (with
    ``play.profile``, its episodes' rows carry ``profile_s``)."""
    player = ModularPlayer(play) if play.agent == "modular" else PolicyPlayer(play)
    return _Profiled(player) if play.profile else player


class _Profiled:
    """A player whose ``play`` adds the episode's section seconds
    (`envs.profile.PROFILE`) to its row as ``profile_s``."""

    def __init__(self, player):
        self.inner, self.info = player, player.info

    def play(self, episode: int, frames=None):
        PROFILE.enabled = True
        PROFILE.take()
        try:
            row, counters = self.inner.play(episode, frames)
        finally:
            PROFILE.enabled = False
        row["profile_s"] = {name: round(t, 6) for name, t in PROFILE.take().items()}
        return row, counters

    def close(self) -> None:
        self.inner.close()

    def __getattr__(self, name):
        return getattr(self.inner, name)


def profile_summary(rows: list[dict]) -> dict:
    """Seconds per section summed over ``rows`` (their ``profile_s``), the
    episodes' wall seconds, and each section's share of it; ``other`` is the
    wall time no section claimed (the agent's loop, the boundary, Python)."""
    seconds = {name: 0.0 for name in SECTIONS}
    for row in rows:
        for name, value in row.get("profile_s", {}).items():
            seconds[name] = seconds.get(name, 0.0) + value
    wall = sum(row["wall_s"] for row in rows)
    seconds["other"] = max(0.0, wall - sum(seconds.values()))
    return {"seconds": seconds, "wall_s": wall,
            "shares": {name: (t / wall if wall > 0 else None) for name, t in seconds.items()}}


def _counters(stats: OptionStats) -> dict:
    return {"issued": stats.issued, "reached": stats.reached, "failed": stats.failed,
            "cut_off": stats.cut_off, "unfinished": stats.unfinished,
            "estimation_failures": stats.estimation_failures,
            "failures": dict(stats.failures)}


def _play_here(play: Play, indices, on_done, built=None) -> None:
    """Plays ``indices`` in this process, reporting each episode to ``on_done``."""
    player = make_player(play)
    try:
        if built is not None:
            built(player.info)
        _play_each(player, play, indices, lambda result: on_done([result], player.info))
    finally:
        player.close()


def _play_each(player, play: Play, indices, each) -> None:
    """``each((row, counters))`` for every episode of ``indices`` in order;
    the video episode's frames are written when it ends."""
    for episode in indices:
        frames = [] if play.video and episode == play.video_episode else None
        result = player.play(episode, frames)
        if frames:
            _write_video(play.video, frames, _control_timestep(player))
        each(result)


def _control_timestep(player) -> float:
    env = getattr(player, "env", None) or player.inner.env
    env = getattr(env, "env", env)  # an AgentEnv wraps the environment
    return env.control_timestep


#: Per worker process: its player, by the ``repr`` of its `Play`.
_PLAYERS: dict = {}


def play_shard(play: Play, indices: list[int]) -> tuple[list, dict]:
    """Plays ``indices`` with this process's player of ``play`` (built on
    first use and kept for later shards); returns ([(row, counters)], info).
    The function worker processes and Ray tasks run."""
    player = _PLAYERS.get(repr(play))
    if player is None:
        _close_players()  # one environment per process at a time
        player = _PLAYERS[repr(play)] = make_player(play)
    out = []
    _play_each(player, play, indices, out.append)
    return out, player.info


def _close_players() -> None:
    for player in _PLAYERS.values():
        player.close()
    _PLAYERS.clear()


#: The most episodes in one shard: progress and ``--json`` are updated per shard.
MAX_SHARD = 8


def shards(indices: list[int], workers: int) -> list[list[int]]:
    """``indices`` cut into contiguous shards, at least four per worker and
    at most `MAX_SHARD` episodes each (at least one), so that faster workers
    take more of them and progress is reported often."""
    size = max(1, min(MAX_SHARD, math.ceil(len(indices) / (4 * workers))))
    return [indices[i:i + size] for i in range(0, len(indices), size)]


def _play_parallel(play: Play, indices, workers, ray_address, on_done) -> None:
    pieces = shards(indices, workers)
    if ray_address is not None:
        _play_ray(play, pieces, workers, ray_address, on_done)
        return
    import multiprocessing
    from concurrent.futures import FIRST_COMPLETED, ProcessPoolExecutor, wait

    context = multiprocessing.get_context("spawn")  # no GL or torch state inherited
    pool = ProcessPoolExecutor(max_workers=min(workers, len(pieces)), mp_context=context,
                               initializer=_worker_init)
    try:
        pending = {pool.submit(play_shard, play, piece) for piece in pieces}
        while pending:
            done, pending = wait(pending, return_when=FIRST_COMPLETED)
            for future in done:
                on_done(*future.result())
    except BaseException:
        # Ctrl-C or a failed shard: the shards under way are dropped, their
        # workers stopped now rather than when their shard ends.
        workers_alive = list(getattr(pool, "_processes", {}).values())
        pool.shutdown(wait=False, cancel_futures=True)
        for process in workers_alive:
            process.terminate()
        raise
    pool.shutdown(wait=True)


def _worker_init() -> None:
    import atexit
    import signal
    signal.signal(signal.SIGINT, signal.SIG_IGN)  # Ctrl-C is the parent's to handle
    atexit.register(_close_players)


def _play_ray(play: Play, pieces, workers, address, on_done) -> None:
    from hier_agents.cluster import connect, remote

    ray = connect(address)
    task = remote(play_shard, num_cpus=1, max_retries=3)
    queue = list(pieces)
    running = []
    while queue or running:
        while queue and len(running) < workers:
            running.append(task.remote(play, queue.pop(0)))
        done, running = ray.wait(running, num_returns=1)
        for ref in done:
            on_done(*ray.get(ref))


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
        env.seed(seed, episode=episode)
        timestep = view.reset()
        agent.reset(description, timestep, seed=envs.episode_seed(seed, episode))
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
    `SystemExit` with status 2 before anything is played (`envs.cli.run_main`)."""
    return cli.run_main(PROG, _main, argv)


if __name__ == "__main__":
    sys.exit(main())
