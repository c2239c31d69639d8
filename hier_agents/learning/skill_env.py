"""Options as environments: one gymnasium episode is one option.

`BallOptionEnv` (``gymnasium.make("options/ball-push")`` after importing this
module) is MuJoBan's walk-then-push option: the Sokoban solver's
``next_push`` subgoal (walk to a box, push it; `abstract_planners.
sokoban_solver.SokobanSolverPlanner`), executed by the ball skill's
geometry (`skills.learned.LearnedBallSkill`: legs, carrot, speed profile,
status) with the low-level [roll, steer] action coming from the agent.

Scenes
======

Options start from realistic scenes: states along solver plans of
generated levels (``mujoban/level1`` ... ``level5``, with and without pegs)
and real Boxoban levels (``boxoban/<file>[-pegs]``: the shipped files in
MuJoBan's level-5 arena). A reset picks a source (uniformly from
``sources``), starts a fresh level and lets the *scripted* agent (the same
estimator, the solver, `skills.ball.BallSkill`, cut off after 50 control
steps as the option layer does) carry out a random number of subgoals
(uniform in 0..``max_skip``), so options start mid-level, sometimes with the
walker still rolling or a box left short by a cut-off push. With
probability ``p_continue`` a reset instead continues the level where the
last option (the agent's own) left it, if it succeeded or was cut off at
``t_abs`` (as the option layer re-plans from wherever the walker is). Levels whose
remaining time is shorter than ``t_abs`` steps, or that the solver finds
deadlocked, are replaced. Everything is seeded by ``reset(seed=...)``.

Observation, action
===================

* observation: the 12 path-relative features of `skills.learned.ball`
  (float32, in [-4, 4]): the skill's view of the scene estimate relative to
  the subgoal (carrot and speed target from the subgoal's legs) and the
  walker's proprioception (velocity, yaw rate) in its drive frame; exactly
  what `LearnedBallSkill`'s policy sees at run time.
* action: the raw MuJoBan action [roll, steer] in [-1, 1]^2 (clipped).

The scene estimate comes from an `Estimator`: ``estimator="oracle"``
(default; privileged: it reads the simulator, fast, for training) or
``"camera"`` (observation-only: top camera and proprioception; slower).
``env.privileged`` says which. The level generation and fast-forward are the
environment's business (they may read the simulator); the agent sees only
the observation above.

Reward, termination
===================

* ``+1`` on the step at which the subgoal is reached: the skill's own
  status turns to SUCCESS (the estimated abstract state equals the
  subgoal's and, when the trajectory ends with the subgoal, the pushed box
  is settled within 0.08 cells of its cell centre: the scripted skill's
  rule). When the push solves the level, MuJoBan ends the episode before the
  box can settle; as in `ModularAgent.end_episode`, the option is reached
  when the estimated boxes equal the subgoal's.
* ``-1`` when the option fails by disturbing the boxes: another box moved
  (``box disturbed``), the pushed box left its line (``box off line``) or
  the estimated boxes left the subgoal's path (``estimate deviates``).
* shaping: ``-0.002`` per control step (prefer fast options; at most -0.3
  over an option, below the success reward).
* ``terminated`` on success or any skill failure (``stuck``, ``not
  reached``, ... end the option with no reward besides the step cost);
  ``truncated`` after ``t_abs`` control steps or at MuJoBan's own time limit.

``t_abs`` defaults to 150 control steps (7.5 s), not the option layer's 50:
a walk-then-push subgoal on a 10x10 level-5 board takes the scripted skill
26 steps at the median and 94 at the 95th percentile (the option layer
cuts it at 50 and re-plans the same trajectory), so at 50 steps even the
scripted skill reaches only ~65% of them in one option.

``info``: ``status`` (``"running"``, ``"success"``, ``"failure"``),
``reason`` (a failure's reason), ``source``, ``steps``, ``is_success``
(bool, at the episode's end), ``expert_action`` (the scripted loops' raw
[roll, steer] for the current observation, for behaviour cloning and
comparison), ``reward_success``, ``reward_disturb``, ``reward_step``, ``sim_steps``
(control steps this environment simulated since its last seeded reset, the scripted
fast-forwards included: the honest frame count).
"""

from __future__ import annotations

import gymnasium
import numpy as np
from gymnasium import spaces

import envs
from abstract_planners.base import NoPlanError
from abstract_planners.sokoban_solver import SokobanSolverPlanner
from hier_agents.modular.components import env_overrides
from hier_agents.estimators.base import EstimationError
from hier_agents.modular.agent import run_option
from skills.ball import BallSkill
from skills.base import Status
from skills.learned.ball import OBS_DIM, SIGN, LearnedBallSkill, env_action

__all__ = ["BallOptionEnv", "TRAIN_SOURCES", "HELDOUT_SOURCES", "make_source_env"]

#: The default training mixture: generated L1-L5 with and without pegs and
#: the shipped Boxoban files (with and without pegs).
TRAIN_SOURCES = tuple(f"mujoban/level{d}{p}" for d in range(1, 6) for p in ("", "-pegs")) + (
    "boxoban/unfiltered-valid-000", "boxoban/unfiltered-valid-000-pegs",
    "boxoban/medium-valid-000-pegs")
#: Held-out evaluation: level-5 with pegs (other seeds than training).
HELDOUT_SOURCES = ("mujoban/level5-pegs",)

SUCCESS_REWARD = 1.0
DISTURB_PENALTY = -1.0
STEP_COST = -0.002
_DISTURB_KINDS = ("box disturbed", "box off line", "estimate deviates")


def make_source_env(source: str, seed: int, estimator: str = "oracle"):
    """The MuJoBan environment of a scene source (``mujoban/<name>`` or
    ``boxoban/<file>[-pegs]``) with the cameras the estimator reads."""
    from envs.mujoban.levels import BOXOBAN_DIR
    cameras = env_overrides("mujoban/level1", estimator)
    if source.startswith("boxoban/"):
        stem = source[len("boxoban/"):]
        pegs = stem.endswith("-pegs")
        stem = stem[: -len("-pegs")] if pegs else stem
        path = BOXOBAN_DIR / f"{stem}.txt"
        if not path.exists():
            raise ValueError(f"{source}: no level file {path}")
        base = "mujoban/level5-pegs" if pegs else "mujoban/level5"
        return envs.load(base, seed=seed, levels=str(path), **cameras)
    return envs.load(source, seed=seed, **cameras)


def _make_estimator(name: str, env):
    if name == "oracle":
        from hier_agents.estimators import OracleEstimator
        return OracleEstimator(env)
    if name == "camera":
        from hier_agents.estimators.camera import CameraEstimator
        return CameraEstimator()
    raise ValueError(f"estimator must be 'oracle' or 'camera', got {name!r}")


class _Source:
    """One scene source: its MuJoBan environment, estimator, solver."""

    def __init__(self, name: str, seed: int, estimator: str) -> None:
        self.name = name
        self.env = make_source_env(name, seed, estimator)
        self.estimator = _make_estimator(estimator, self.env)
        self.planner = SokobanSolverPlanner(time_limit=5.0)
        self.description = self.env.description()
        self.timestep = None
        self.scene = None


class BallOptionEnv(gymnasium.Env):
    """MuJoBan's walk-then-push option as a gymnasium environment (module docstring).

    Args:
      sources: scene sources (default `TRAIN_SOURCES`).
      estimator: ``"oracle"`` (privileged, fast) or ``"camera"`` (observation-only).
      t_abs: control steps before the option is cut off (truncated).
      max_skip: at most this many scripted subgoals before the option.
      p_continue: probability that a reset continues the current level.
      seed: seeds the environments' level generators (also ``reset(seed=)``).
    """

    metadata = {"render_modes": []}

    def __init__(self, sources=None, *, estimator: str = "oracle", t_abs: int = 150,
                 max_skip: int = 6, p_continue: float = 0.7, seed: int | None = None):
        super().__init__()
        self.sources = tuple(sources or TRAIN_SOURCES)
        self.estimator_name = estimator
        if estimator not in ("oracle", "camera"):
            raise ValueError(f"estimator must be 'oracle' or 'camera', got {estimator!r}")
        #: True when the scene estimate reads the simulator (``oracle``).
        self.privileged = estimator == "oracle"
        self.t_abs = int(t_abs)
        self.max_skip = int(max_skip)
        self.p_continue = float(p_continue)
        self.observation_space = spaces.Box(-4.0, 4.0, (OBS_DIM,), np.float32)
        self.action_space = spaces.Box(-1.0, 1.0, (2,), np.float32)
        self._base_seed = seed
        self._rng = np.random.default_rng(seed)
        self._envs: dict[str, _Source] = {}
        self._src: _Source | None = None
        self._alive = False
        self.skill = LearnedBallSkill(record_only=True)
        self._scripted = BallSkill()
        self.subgoal = None
        self._steps = 0
        self._hold_next = False
        self._obs = np.zeros(OBS_DIM, np.float32)
        #: Control steps simulated since the last seeded reset, the scripted
        #: fast-forwards included.
        self.sim_steps = 0

    # -- scenes -------------------------------------------------------------------

    def _source(self, name: str) -> _Source:
        src = self._envs.get(name)
        if src is None:
            seed = int(self._rng.integers(2 ** 31))
            src = self._envs[name] = _Source(name, seed, self.estimator_name)
        return src

    def _new_level(self, src: _Source) -> None:
        src.timestep = src.env.reset()
        src.estimator.reset(src.description, src.timestep)
        src.planner.reset(int(self._rng.integers(2 ** 31)))
        src.scene = None

    def _estimate(self, src: _Source):
        try:
            src.scene = src.estimator.estimate(src.timestep)
        except EstimationError:
            src.scene = None
        return src.scene

    def _time_left(self, src: _Source) -> int:
        return src.description.time_limit_steps - src.env.step_count

    def _skip(self, src: _Source, n: int) -> bool:
        """Runs the scripted agent for ``n`` subgoals; False if the level ended."""
        for _ in range(n):
            scene = self._estimate(src)
            if scene is None or src.timestep.last() or scene.state.is_solved():
                return scene is not None and not src.timestep.last()
            subgoal = src.planner.next_push(scene.state)
            result = run_option(src.env, src.estimator, self._scripted, subgoal, src.timestep,
                                t_abs=50, scene=scene)
            src.timestep = result.timestep
            self.sim_steps += result.steps
            if src.timestep.last():
                return False
        return True

    def _start_option(self) -> bool:
        """Picks a scene and starts an option there; False to try again."""
        if not (self._alive and self._rng.random() < self.p_continue):
            self._src = self._source(self.sources[int(self._rng.integers(len(self.sources)))])
            self._new_level(self._src)
            skip = int(self._rng.integers(self.max_skip + 1))
            fresh = True
        else:
            skip = int(self._rng.random() < 0.3)
            fresh = skip > 0
        src = self._src
        self._alive = False
        try:
            if not self._skip(src, skip):
                return False
            scene = self._estimate(src)
            if scene is None or src.timestep.last() or scene.state.is_solved() \
                    or self._time_left(src) < self.t_abs:
                return False
            self.subgoal = src.planner.next_push(scene.state)
        except NoPlanError:
            return False
        self.skill.reset(src.description, self.subgoal, scene)
        if fresh:
            # The skill did not see the fast-forward: no yaw rate on its first step.
            self.skill._drive.prev_heading = None
        if self.skill.status is not Status.RUNNING:
            return False
        self.skill.act(src.timestep, scene)
        if self.skill.status is not Status.RUNNING:
            return False
        return True

    # -- gymnasium ----------------------------------------------------------------

    def reset(self, *, seed=None, options=None):
        super().reset(seed=seed)
        if seed is not None:
            self._rng = np.random.default_rng(seed)
            for src in self._envs.values():
                src.env.close()
            self._envs = {}
            self._alive = False
            self.sim_steps = 0
        for _ in range(100):
            if self._start_option():
                break
        else:
            raise RuntimeError("no option could be started in 100 tries")
        self._steps = 0
        self._hold_next = False
        self._obs = self._features()
        return self._obs.copy(), self._info(Status.RUNNING, None, 0.0, 0.0, 0.0, False)

    def step(self, action):
        src = self._src
        action = np.clip(np.asarray(action, np.float64).reshape(2), -1.0, 1.0)
        if self._hold_next:  # the last estimate failed: the option layer holds still
            action = self.skill.hold()
        src.timestep = src.env.step(action)
        self._steps += 1
        self.sim_steps += 1
        timestep = src.timestep
        scene = self._estimate(src)
        self._hold_next = scene is None
        if scene is not None:
            self.skill.act(timestep, scene)
            self._obs = self._features()
        status = self.skill.status
        reason = self.skill.failure_reason
        if status is Status.RUNNING and timestep.last() and scene is not None \
                and timestep.discount == 0.0 and scene.state.boxes == self.subgoal.state.boxes:
            status = Status.SUCCESS  # the push solved the level (module docstring)
        r_success = SUCCESS_REWARD if status is Status.SUCCESS else 0.0
        disturbed = status is Status.FAILURE and str(reason).startswith(_DISTURB_KINDS)
        r_disturb = DISTURB_PENALTY if disturbed else 0.0
        reward = r_success + r_disturb + STEP_COST
        terminated = status is not Status.RUNNING
        truncated = not terminated and (self._steps >= self.t_abs or timestep.last())
        # The next reset may continue from here after a success or a cut-off
        # at t_abs (the option layer re-plans from wherever the walker is).
        self._alive = (status is Status.SUCCESS or truncated) and not timestep.last()
        info = self._info(status, reason, r_success, r_disturb, STEP_COST,
                          terminated or truncated)
        return self._obs.copy(), float(reward), bool(terminated), bool(truncated), info

    def _features(self) -> np.ndarray:
        return np.clip(self.skill.features, -4.0, 4.0).astype(np.float32)

    def _info(self, status, reason, r_success, r_disturb, r_step, done) -> dict:
        return {"status": status.value, "reason": reason, "source": self._src.name,
                "steps": self._steps, "is_success": bool(done and status is Status.SUCCESS),
                "expert_action": env_action(self.skill.teacher_action,
                                            float(self._obs[SIGN])).astype(np.float32),
                "reward_success": r_success, "reward_disturb": r_disturb,
                "reward_step": r_step, "sim_steps": self.sim_steps}

    def close(self) -> None:
        for src in self._envs.values():
            src.estimator.close()
            src.env.close()
        self._envs = {}


gymnasium.register("options/ball-push", entry_point="hier_agents.learning.skill_env:BallOptionEnv")
