"""The one episode runner: any agent kind on any environment, every row scored alike.

`Play` names what a run plays (an environment, an agent ``NAME[:ARG]`` with
its options, the seed, levels, environment options, video, profiling); it
is picklable, so a worker process or Ray task rebuilds the same `Player`
from it (`make_player`). A `Player` owns one environment and one agent,
built from the agent kind's `hier_agents.agents.base.AgentSetup`: the
environment with the settings the agent needs, the agent behind the
observation boundary unless it is privileged. `play_episode` is the loop
every agent's episodes go through; the row's verdict (solved, or the game's
outcome), the harness's judgement of a board estimate and the failure
reason come from the family adapter (`hier_agents.modular.families`).

Episode ``e`` of a run seeded ``s`` is seeded from ``(s, e)``
(`envs.Environment.seed`, `envs.episode_seed`): its level, opponent and
agent draws do not depend on the episodes before it, so any split of the
episodes over processes gives the same rows.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field

import envs
from envs.profile import PROFILE, SECTIONS
from hier_agents.agents.registry import resolve
from hier_agents.boundary import PRIVILEGED_OBSERVATIONS, BoundaryEnv
from hier_agents.modular.agent import OptionStats
from hier_agents.modular.families import adapter_for

__all__ = [
    "Play",
    "Player",
    "make_player",
    "play_episode",
    "play_each",
    "profile_summary",
    "counters",
]


@dataclass(frozen=True)
class Play:
    """What a run plays, everything but the episodes (picklable).

    Attributes:
      env_name: the environment.
      seed: the run's seed.
      agent: the agent, ``NAME[:ARG]`` (`hier_agents.agents.base.resolve`).
      options: the agent kind's options (modular: ``planner``, ``skill``,
        ``estimator``; checkpoint: ``stochastic``).
      levels: MuJoBan: a level file; episode ``e`` plays its ``e``-th level.
      env_options: `envs.load` overrides of the played environment.
      video: an MP4 path for episode ``video_episode``; profile: time the
        sections of every episode (`envs.profile`).
    """

    env_name: str
    seed: int = 0
    agent: str = "modular"
    options: dict = field(default_factory=dict)
    levels: str | None = None
    env_options: dict = field(default_factory=dict)
    video: str | None = None
    video_episode: int = 0
    profile: bool = False


class Player:
    """One environment and one agent of ``play``; ``play(episode, frames=None)``
    -> (row, subgoal counters); ``info`` describes the agent (the run
    summary's keys); ``close()`` frees both."""

    def __init__(self, play: Play):
        kind, arg = resolve(play.agent)
        setup = kind.setup(play.env_name, arg, dict(play.options))
        # A diverging simulation ends its episode (reward 0) instead of the run.
        overrides = {**setup.env_overrides, "raise_on_physics_error": False, **play.env_options}
        if play.levels is not None:
            overrides["levels"] = play.levels
        self.play_spec, self.env, self.agent = play, None, None
        try:
            self.env = envs.load(play.env_name, seed=play.seed, **overrides)
            # An observation-only agent sees the environment through the
            # boundary (no simulator, no ground-truth layers; a board game's
            # record only for the agents that read it); the harness keeps
            # `env` to judge.
            self.view: BoundaryEnv | envs.Environment = self.env
            if setup.access != "simulator":
                strip = (
                    PRIVILEGED_OBSERVATIONS
                    if setup.access == "record"
                    else self.env.privileged_observations
                )
                self.view = BoundaryEnv(self.env, strip=strip)
            self.description = self.view.description()
            self.agent = setup.build(
                self.view, play.seed, self.env if setup.access == "simulator" else None
            )
        except BaseException:
            self.close()
            raise
        self.info = {**setup.summary, "training_frames": int(self.agent.training_frames)}

    def play(self, episode: int, frames=None) -> tuple[dict, dict]:
        row, stats = play_episode(
            self.env, self.view, self.agent, self.description, episode, self.play_spec.seed, frames
        )
        return row, counters(stats)

    def close(self) -> None:
        try:
            if self.agent is not None:
                self.agent.close()
        finally:
            if self.env is not None:
                self.env.close()


def make_player(play: Play):
    """The `Player` of ``play`` (with ``play.profile``, its episodes' rows
    carry ``profile_s``)."""
    player = Player(play)
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
            row, stats = self.inner.play(episode, frames)
        finally:
            PROFILE.enabled = False
        row["profile_s"] = {name: round(t, 6) for name, t in PROFILE.take().items()}
        return row, stats

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
    return {
        "seconds": seconds,
        "wall_s": wall,
        "shares": {name: (t / wall if wall > 0 else None) for name, t in seconds.items()},
    }


def counters(stats: OptionStats) -> dict:
    """An episode's subgoal counters as a JSON-able dict (`OptionStats`'s fields)."""
    return {
        "issued": stats.issued,
        "reached": stats.reached,
        "failed": stats.failed,
        "cut_off": stats.cut_off,
        "unfinished": stats.unfinished,
        "estimation_failures": stats.estimation_failures,
        "failures": dict(stats.failures),
    }


def play_each(player, play: Play, indices, each) -> None:
    """``each((row, counters))`` for every episode of ``indices`` in order;
    the video episode's frames are written when it ends."""
    for episode in indices:
        frames: list | None = [] if play.video and episode == play.video_episode else None
        result = player.play(episode, frames)
        if frames:
            _write_video(play.video, frames, player.env.control_timestep)
        each(result)


def _write_video(path, frames, control_timestep: float) -> None:
    import imageio.v2 as imageio

    imageio.mimwrite(path, frames, fps=int(round(1 / control_timestep)), macro_block_size=1)


def play_episode(env, view, agent, description, episode: int, seed: int, frames=None):
    """Plays episode ``episode`` of ``seed`` with ``agent`` (seen through
    ``view``) in ``env``; returns (row, the agent's `OptionStats`).

    The row: ``episode``, ``return``, ``steps``, ``wall_s``,
    ``subgoals_issued``, ``subgoals_reached``, ``estimation_failures``; the
    family adapter's verdict (`FamilyAdapter.score`); for estimating agents
    where the family judges estimates, ``estimates`` and
    ``wrong_estimates`` (steps whose estimate was not the referee's). Any
    error inside the episode (reset, estimator, planner, skill, GTP engine)
    ends it with ``error`` ("Type: message") and ``failure_reason``; an
    agent that gives up ends it with its reason. ``frames``, if a list, gets
    the main camera's 256x256 frame before every action.
    """
    start = time.perf_counter()
    timestep, ret, steps, reason, error, started = None, 0.0, 0, None, None, False
    family = adapter_for(description)
    # The harness judges an estimating agent's board against the referee's, per step.
    judge = bool(getattr(agent, "estimates", False)) and family.games
    estimates = wrong = 0
    try:
        env.seed(seed, episode=episode)
        timestep = view.reset()
        agent.reset(description, timestep, seed=envs.episode_seed(seed, episode))
        started = True
        while not timestep.last():
            if frames is not None:
                frames.append(env.render(env.task.main_camera, 256, 256))
            action = agent.act(timestep)
            if judge:
                estimates += 1
                wrong += not family.estimate_right(env.task, agent.scene)
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
    row = {
        "episode": episode,
        "return": ret,
        "steps": steps,
        "wall_s": time.perf_counter() - start,
        "subgoals_issued": stats.issued,
        "subgoals_reached": stats.reached,
        "estimation_failures": stats.estimation_failures,
    }
    if judge:
        row["estimates"], row["wrong_estimates"] = estimates, wrong
    row.update(family.score(env.task, timestep, reason))
    if error is not None:
        row["error"] = error
    return row, stats
