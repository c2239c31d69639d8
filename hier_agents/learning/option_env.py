"""`OptionEnv`: the environment seen through options, a semi-MDP.

One gymnasium step is one *option*: the action picks an abstract transition
(MuJoBan: a move ``U``/``D``/``L``/``R``, which walks one cell or pushes a box
one cell; MuJoXO and MuJoGo: a board move, an OpenSpiel action), a skill
carries it out in the physical environment (the ball skill; the arm's touch
skill), and the step returns when the skill reports success or failure,
after ``t_abs`` control steps, or when the episode ends::

    env = OptionEnv("mujoban/level1", seed=0)
    obs, info = env.reset(seed=0)
    obs, reward, terminated, truncated, info = env.step(env.action_space.sample())
    info["duration"]    # control steps the option took
    info["status"]      # "success", "failure", "cut off" or "illegal"

* **Reward**: the option's discounted sum of the environment's rewards,
  ``sum_k gamma^k r_k`` over its ``duration`` control steps (``gamma`` the
  per-control-step discount, default 0.99); a learner over options discounts
  the next option's value by ``gamma ** info["duration"]``.
* **Observation**: the abstract state the estimator sees after the option
  (the scene estimate, never the simulator with the default observation-only
  estimators): MuJoBan: ``(4, H, W)`` float32 planes walls, pads, boxes,
  player; board games: OpenSpiel's observation tensor for the agent (player
  0). ``info["action_mask"]`` marks the legal options (int8);
  ``env.abstract_state`` is the state itself (a `SokobanState`, an OpenSpiel
  state).
* **Illegal actions** (a move into a wall or an unpushable box; an occupied
  point) are not executed: the agent holds still for one control step
  (``duration`` 1, ``status`` ``"illegal"``), and the reward of that step is
  the environment's plus ``illegal_penalty`` (default 0).
* **Termination** follows the environment: ``terminated`` when the episode
  ends with discount 0 (solved, game over), ``truncated`` at its time limit.
  ``info["steps"]`` counts the control steps of the episode so far; the
  durations add up to it.

Estimation failures (an estimate that cannot be made for a frame) make the
skill hold still for that step, as in the option layer
(`hier_agents.modular.agent`). The env and skill parts come from
`hier_agents.modular.components`: ``skill`` and ``estimator`` by name (defaults: the
family's), ``env_options`` passed to `envs.load`. A privileged estimator
(``"oracle"``) reads the simulator and says so in ``env.privileged``.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import gymnasium as gym
import numpy as np

import envs
from hier_agents.boundary import BoundaryEnv
from hier_agents.estimators.base import EstimationError
from hier_agents.modular.components import (
    ESTIMATORS,
    SKILLS,
    env_overrides,
    estimator_name,
    is_privileged,
)
from hier_agents.modular.families import adapter, encode_sokoban, family
from hier_agents.modular.options import T_ABS, Outcome, run_option

if TYPE_CHECKING:
    from dm_env import TimeStep

    from skills.scene import ArmScene, BallScene

__all__ = ["OptionEnv", "encode_sokoban"]


class OptionEnv(gym.Env):
    """A gymnasium environment whose steps are options (module docstring).

    Args:
      env_name: a registered environment (``envs.names()``).
      skill, estimator: names from `hier_agents.modular.components` (None: the
        family's default: the ball skill and camera estimator for MuJoBan).
      seed: seeds the environment (``reset(seed=...)`` reseeds it).
      gamma: per-control-step discount of the option's reward sum.
      t_abs: control steps an option may run before it is cut off.
      illegal_penalty: added to the reward of an illegal action.
      env_options: more `envs.load` keyword arguments (``levels=``, ...).
    """

    metadata = {"render_modes": []}
    #: One action per option (the family adapter's `spaces`).
    action_space: gym.spaces.Discrete

    def __init__(
        self,
        env_name: str,
        *,
        skill: str | None = None,
        estimator: str | None = None,
        seed: int | None = None,
        gamma: float = 0.99,
        t_abs: int = T_ABS,
        illegal_penalty: float = 0.0,
        env_options: dict | None = None,
    ):
        if not 0.0 < float(gamma) <= 1.0:
            raise ValueError(f"gamma must be in (0, 1], got {gamma!r}")
        if int(t_abs) < 1:
            raise ValueError(f"t_abs must be a positive number of control steps, got {t_abs!r}")
        self.env_name = env_name
        self.family = family(env_name)
        self.gamma = float(gamma)
        self.t_abs = int(t_abs)
        self.illegal_penalty = float(illegal_penalty)
        self.privileged = is_privileged(self.family, estimator)
        self.estimator_name = estimator_name(self.family, estimator)
        options = dict(env_overrides(env_name, estimator))
        options.update(env_options or {})
        self._env = envs.load(env_name, seed=seed, **options)
        try:
            self._view = self._env if self.privileged else BoundaryEnv(self._env)
            self._description = self._view.description()
            pick_skill = SKILLS[self.family]
            if skill is not None and skill not in pick_skill:
                raise ValueError(
                    f"unknown skill {skill!r} for {self.family}; valid: {sorted(pick_skill)}"
                )
            self.skill = (pick_skill[skill] if skill else next(iter(pick_skill.values())))(
                self._description, seed
            )
            self.estimator = ESTIMATORS[self.family][self.estimator_name](
                self._description, seed, self._env if self.privileged else None
            )
            self.adapter = adapter(self.family)
            self.action_space, self.observation_space = self.adapter.spaces(
                self._description, self._initial_state()
            )
        except Exception:
            self._env.close()
            raise
        self._timestep: TimeStep | None = None
        self._scene: BallScene | ArmScene | None = None
        self._steps = 0

    # -- gymnasium ---------------------------------------------------------------

    def reset(self, *, seed: int | None = None, options=None):
        super().reset(seed=seed)
        if seed is not None:
            self._env.seed(seed)
        self._timestep = self._view.reset()
        self.estimator.reset(self._description, self._timestep)
        self._scene = self._estimate_until_seen()
        self._steps = 0
        return self._observation(), self._info(status=None, duration=0)

    def step(self, action):
        if self._timestep is None:
            raise RuntimeError("call reset() before step()")
        if self._timestep.last():
            raise RuntimeError("the episode is over: call reset()")
        action = int(action)
        if not self.action_space.contains(action):
            raise ValueError(f"action must be in [0, {self.action_space.n}), got {action!r}")
        subgoal = self._subgoal(action)
        if subgoal is None:
            reward, duration = self._run_hold()
            reward += self.illegal_penalty
            status, reason = "illegal", None
        else:
            reward, duration, status, reason = self._run_option(subgoal)
        last = self._timestep.last()
        terminated = bool(last and float(self._timestep.discount or 0.0) == 0.0)
        truncated = bool(last and not terminated)
        info = self._info(status=status, duration=duration)
        if reason:
            info["failure_reason"] = reason
        return self._observation(), float(reward), terminated, truncated, info

    def close(self) -> None:
        for part in (self.skill, self.estimator):
            close = getattr(part, "close", None)
            if close is not None:
                close()
        self._env.close()

    # -- options -----------------------------------------------------------------

    @property
    def abstract_state(self):
        """The estimated abstract state after the last option (or reset)."""
        return None if self._scene is None else self._scene.state

    def legal_mask(self) -> np.ndarray:
        """int8 per action: 1 where the option is legal in the current estimate."""
        assert self._scene is not None  # estimated by reset()
        return self.adapter.legal_mask(self._scene.state, self.action_space.n)

    def _subgoal(self, action: int):
        assert self._scene is not None  # estimated by reset()
        return self.adapter.option_subgoal(self._scene.state, action)

    def _run_hold(self):
        self._timestep = self._view.step(self.skill.hold())
        self._steps += 1
        self._scene = self._estimate_or_keep()
        return float(self._timestep.reward or 0.0), 1

    def _run_option(self, subgoal):
        def keep(timestep, scene):  # the last frame that could be estimated
            self._scene = scene

        result = run_option(
            self._view,
            self.estimator,
            self.skill,
            subgoal,
            self._timestep,
            adapter=self.adapter,
            t_abs=self.t_abs,
            gamma=self.gamma,
            scene=self._scene,
            on_step=keep,
            description=self._description,
        )
        self._timestep = result.timestep
        self._steps += result.duration
        status = {Outcome.REACHED: "success", Outcome.FAILED: "failure"}.get(
            result.outcome, "cut off"
        )
        return result.reward, result.duration, status, result.reason

    # -- estimates and observations --------------------------------------------------

    def _estimate_or_keep(self):
        try:
            return self.estimator.estimate(self._timestep)
        except EstimationError:
            return self._scene

    def _estimate_until_seen(self, tries: int = 10):
        for _ in range(tries):
            try:
                return self.estimator.estimate(self._timestep)
            except EstimationError:
                assert self._timestep is not None  # reset() set it
                if self._timestep.last():
                    break
                self._timestep = self._view.step(self.skill.hold())
                self._steps += 1
        raise EstimationError(f"no estimate of the first frames of {self.env_name}")

    def _observation(self) -> np.ndarray:
        assert self._scene is not None  # estimated by reset()
        return self.adapter.observation(self._scene.state, self.observation_space)

    def _info(self, *, status, duration) -> dict:
        info = {
            "duration": int(duration),
            "steps": int(self._steps),
            "action_mask": self.legal_mask(),
        }
        if status is not None:
            info["status"] = status
        return info

    def _initial_state(self):
        timestep = self._view.reset()
        self.estimator.reset(self._description, timestep)
        return self.estimator.estimate(timestep).state

    def __repr__(self) -> str:
        return (
            f"OptionEnv({self.env_name!r}, skill={type(self.skill).__name__}, "
            f"estimator={self.estimator_name!r}{', PRIVILEGED' if self.privileged else ''})"
        )
