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

import gymnasium as gym
import numpy as np

import envs
from abstract_planners.base import Subgoal
from abstract_planners.sokoban import MOVES
from hier_agents.boundary import BoundaryEnv
from hier_agents.modular.components import (ESTIMATORS, SKILLS, env_overrides, estimator_name, family,
                                    is_privileged)
from hier_agents.estimators.base import EstimationError
from skills.base import Status

__all__ = ["OptionEnv", "encode_sokoban"]


def encode_sokoban(state, shape) -> np.ndarray:
    """A Sokoban state as ``(4, H, W)`` float32 planes: walls, pads, boxes, player."""
    height, width = shape
    planes = np.zeros((4, height, width), np.float32)
    for k, cells in enumerate((state.walls, state.targets, state.boxes, (state.player,))):
        for r, c in cells:
            if 0 <= r < height and 0 <= c < width:
                planes[k, r, c] = 1.0
    return planes


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

    def __init__(self, env_name: str, *, skill: str | None = None,
                 estimator: str | None = None, seed: int | None = None, gamma: float = 0.99,
                 t_abs: int = 50, illegal_penalty: float = 0.0, env_options: dict | None = None):
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
                raise ValueError(f"unknown skill {skill!r} for {self.family}; "
                                 f"valid: {sorted(pick_skill)}")
            self.skill = (pick_skill[skill] if skill else next(iter(pick_skill.values())))(
                self._description, seed)
            self.estimator = ESTIMATORS[self.family][self.estimator_name](
                self._description, seed, self._env if self.privileged else None)
            if self.family == "mujoban":
                shape = tuple(int(v) for v in self._description.grid_shape)
                self._shape = shape
                self._moves = tuple(MOVES)
                self.action_space = gym.spaces.Discrete(len(self._moves))
                self.observation_space = gym.spaces.Box(0.0, 1.0, (4, *shape), np.float32)
            else:
                game = self._board_game()
                self._num_actions = int(game.num_distinct_actions())
                self.action_space = gym.spaces.Discrete(self._num_actions)
                obs_shape = tuple(int(v) for v in game.observation_tensor_shape())
                # OpenSpiel's tic-tac-toe and Go tensors are 0/1 planes.
                self.observation_space = gym.spaces.Box(0.0, 1.0, obs_shape, np.float32)
        except Exception:
            self._env.close()
            raise
        self._timestep = None
        self._scene = None
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
        state = self._scene.state
        if self.family == "mujoban":
            return np.array([state.is_legal(m) for m in self._moves], np.int8)
        mask = np.zeros(self._num_actions, np.int8)
        if not state.is_terminal() and state.current_player() == 0:
            mask[list(state.legal_actions())] = 1
        return mask

    def _subgoal(self, action: int) -> Subgoal | None:
        state = self._scene.state
        if self.family == "mujoban":
            move = self._moves[action]
            if not state.is_legal(move):
                return None
            return Subgoal(action=(move,), state=state.apply(move), plan=())
        if state.is_terminal() or state.current_player() != 0 \
                or action not in state.legal_actions():
            return None
        return Subgoal(action, state.child(action))

    def _step_env(self, action, discount_power: int) -> float:
        self._timestep = self._view.step(action)
        self._steps += 1
        return (self.gamma ** discount_power) * float(self._timestep.reward or 0.0)

    def _run_hold(self):
        reward = self._step_env(self.skill.hold(), 0)
        self._scene = self._estimate_or_keep()
        return reward, 1

    def _run_option(self, subgoal):
        skill = self.skill
        skill.reset(self._description, subgoal, self._scene)
        reward, duration, seen = 0.0, 0, True
        while duration < self.t_abs and not self._timestep.last():
            action = skill.act(self._timestep, self._scene) if seen else skill.hold()
            if skill.status is not Status.RUNNING:
                break
            reward += self._step_env(action, duration)
            duration += 1
            try:
                self._scene, seen = self.estimator.estimate(self._timestep), True
            except EstimationError:
                seen = False
        if self._timestep.last() and seen and skill.status is Status.RUNNING:
            skill.act(self._timestep, self._scene)  # let the skill see the outcome
        if not seen:
            self._scene = self._estimate_or_keep()
        status = {Status.SUCCESS: "success", Status.FAILURE: "failure"}.get(skill.status,
                                                                             "cut off")
        return reward, duration, status, skill.failure_reason

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
                if self._timestep.last():
                    break
                self._timestep = self._view.step(self.skill.hold())
                self._steps += 1
        raise EstimationError(f"no estimate of the first frames of {self.env_name}")

    def _observation(self) -> np.ndarray:
        state = self._scene.state
        if self.family == "mujoban":
            return encode_sokoban(state, self._shape)
        return np.asarray(state.observation_tensor(0), np.float32).reshape(
            self.observation_space.shape)

    def _info(self, *, status, duration) -> dict:
        info = {"duration": int(duration), "steps": int(self._steps),
                "action_mask": self.legal_mask()}
        if status is not None:
            info["status"] = status
        return info

    def _board_game(self):
        state = self._initial_board_state()
        return state.get_game()

    def _initial_board_state(self):
        timestep = self._view.reset()
        self.estimator.reset(self._description, timestep)
        scene = self.estimator.estimate(timestep)
        return scene.state

    def __repr__(self) -> str:
        return (f"OptionEnv({self.env_name!r}, skill={type(self.skill).__name__}, "
                f"estimator={self.estimator_name!r}{', PRIVILEGED' if self.privileged else ''})")
