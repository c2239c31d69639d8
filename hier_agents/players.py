"""Players of `hier_agents.run`: who plays an episode (the modular agent or
a trained policy), one episode's loop, and the drivers that split episodes
over processes (``--workers``) or Ray tasks (``--ray-address``).

`Play` names everything an episode needs, so a worker process rebuilds its
own player from it (`play_shard`, one player per process, closed at exit).
Episode ``e`` is seeded from ``(play.seed, e)``; the drivers only decide
where it runs, never what it does, so any split gives the same rows.
"""

from __future__ import annotations

import math
import sys
import time
from dataclasses import dataclass, field
from typing import Callable

import numpy as np

import envs
from envs.profile import PROFILE, SECTIONS
from hier_agents.boundary import PRIVILEGED_OBSERVATIONS, BoundaryEnv
from hier_agents.executor import WORKER_RETRIES, Pool, WorkerDied  # noqa: F401 - re-exported
from hier_agents.modular.agent import OptionStats
from hier_agents.modular.components import (env_overrides, family, is_privileged,
                                            make_agent, reads_record)
from hier_agents.modular.families import adapter


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
            # (no simulator, no ground-truth layers; the board games' record only
            # for the estimator that reads it); the harness keeps `env` to judge.
            strip = (PRIVILEGED_OBSERVATIONS if reads_record(fam, play.estimator)
                     else self.env.privileged_observations)
            self.view = self.env if privileged else BoundaryEnv(self.env, strip=strip)
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


def play_here(play: Play, indices, on_done, built=None) -> None:
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
    What a worker of `play_parallel` runs."""
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


class ShardWorker:
    """An `executor.Pool` worker of `play_parallel`: ``play(indices)`` is
    `play_shard` of its `Play`; ``close`` closes its player."""

    def __init__(self, play: Play, index: int = 0):
        self.spec = play

    def play(self, indices: list[int]) -> tuple[list, dict]:
        return play_shard(self.spec, indices)

    def close(self) -> None:
        _close_players()


#: The most episodes in one shard: progress and ``--json`` are updated per shard.
MAX_SHARD = 8


def shards(indices: list[int], workers: int) -> list[list[int]]:
    """``indices`` cut into contiguous shards, at least four per worker and
    at most `MAX_SHARD` episodes each (at least one), so that faster workers
    take more of them and progress is reported often."""
    size = max(1, min(MAX_SHARD, math.ceil(len(indices) / (4 * workers))))
    return [indices[i:i + size] for i in range(0, len(indices), size)]


def play_parallel(play: Play, indices, workers, ray_address, on_done) -> int:
    """Plays ``indices`` in `shards` over an `executor.Pool` of ``workers``
    (spawned processes, or Ray actors on the cluster at ``ray_address``; one
    player each, kept); each finished shard's results go to ``on_done`` as
    they arrive. Returns how many workers were replaced.

    A worker that dies has its shards played again by a new one (episodes
    are seeded by index, so their rows are the ones they would have been),
    the executor's one retry policy (`executor.Deaths`: a line on stderr, at
    most `WORKER_RETRIES` times per shard).

    Raises:
      WorkerDied: a shard's worker died more than `WORKER_RETRIES` times.
      UsageError: no Ray cluster answers at ``ray_address``.
    """
    from functools import partial

    pieces = shards(indices, workers)
    with Pool(partial(ShardWorker, play), min(workers, len(pieces)), address=ray_address,
              name="player") as pool:
        queue = list(enumerate(pieces))
        while queue or pool.pending:
            while queue and pool.pending < 2 * pool.size:  # one shard queued behind each
                number, piece = queue.pop(0)
                pool.submit("play", piece, label=f"shard {number + 1} of {len(pieces)} "
                            f"(episodes {piece[0]}-{piece[-1]} of {play.env_name})")
            on_done(*pool.next().result)
        return pool.restarts


def _write_video(path, frames, control_timestep: float) -> None:
    import imageio.v2 as imageio
    imageio.mimwrite(path, frames, fps=int(round(1 / control_timestep)), macro_block_size=1)


def training_frames(agent) -> int:
    """Environment frames spent training the learned parts of a modular agent.

    The sum of the parts' ``training_frames`` (a learned skill's, a learned
    planner's); 0 for scripted parts. Frames, not wall time: what
    `hier_agents.compare` puts beside the end-to-end agents' frames.
    """
    if agent is None:
        return 0
    parts = (getattr(agent, "planner", None), getattr(agent, "skill", None),
             getattr(agent, "estimator", None))
    return int(sum(int(getattr(part, "training_frames", 0) or 0) for part in parts))


def _estimate_right(task, scene) -> bool:
    """Board games: whether the agent's last scene has the referee's board
    (every point's owner) and player to move. The harness's judgement of an
    estimator; the agent never sees it."""
    if scene is None or getattr(scene, "state", None) is None:
        return False
    game, truth, state = task.game, task.state, scene.state
    return (state.current_player() == truth.current_player()
            and np.array_equal(game.players(state), game.players(truth)))


def _play_episode(env, view, agent, description, fam, episode, seed, frames):
    """One episode; any error inside it (reset, estimator, planner, skill, GTP
    engine) ends it with ``error`` and ``failure_reason`` in its row.
    Returns (row, the agent's subgoal counters for it)."""
    start = time.perf_counter()
    timestep, ret, steps, reason, error, started = None, 0.0, 0, None, None, False
    games = adapter(fam).games
    estimates = wrong_estimates = 0
    try:
        env.seed(seed, episode=episode)
        timestep = view.reset()
        agent.reset(description, timestep, seed=envs.episode_seed(seed, episode))
        started = True
        while not timestep.last():
            if frames is not None:
                frames.append(env.render(env.task.main_camera, 256, 256))
            action = agent.act(timestep)
            if games:
                estimates += 1
                wrong_estimates += not _estimate_right(env.task, agent.scene)
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
    if games:
        # The harness judges the agent's board against the referee's, per step.
        row["estimates"], row["wrong_estimates"] = estimates, wrong_estimates
    if not games:
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
