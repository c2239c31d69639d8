"""An `envs` environment as a learning agent sees it, with the paper's auxiliary task.

    env = AgentEnv("mujoban/level3", "expert-planner", seed=1, cameras=False)
    obs = env.reset()
    while True:
        result = env.step(policy(obs))            # action in [-1, 1]^A
        obs = result.obs
        if result.last:
            print(result.info["episode_return"], result.info["subgoals_reached"])
            obs = env.reset()

Conditions (Mirza et al. 2020, "Experimental conditions"):

* ``"vanilla"``: cameras and proprioception only; no planner, no auxiliary
  reward (``reward_abs`` and ``discount_abs`` are always 0).
* ``"expert-planner"``: the family adapter's ``expert_planner`` (MuJoBan: the
  exact Sokoban solver ``"sokoban-solver"``, as in the paper), otherwise the
  family's default planner of `hier_agents.modular.components.PLANNERS` (minimax, GNU
  Go level 10), proposes targets for the auxiliary task.
* ``"random-planner"``: the family's ``"random"`` planner (a uniformly random
  legal next state).

Observations (``obs``, a dict of fresh numpy arrays):

* ``"proprio"`` float32, in this order: MuJoBan ``walker/joints_pos``,
  ``joints_vel``, ``joints_torque`` (2 each), ``walker/orientation`` (9),
  ``sensors_touch`` (1), ``sensors_accelerometer``, ``sensors_gyro``,
  ``sensors_velocimeter`` (3 each): 25 values; board games ``arm/joints_pos``,
  ``joints_vel``, ``joints_torque`` (9 each), ``arm/pinch_site_pos`` (3),
  ``arm/pinch_site_rmat`` (9): 39 values (the family adapter's ``proprio_keys``).
* one uint8 ``(3, H, W)`` image per enabled camera, under the environment's
  observation name: MuJoBan ``top_camera`` and ``walker/egocentric_camera``,
  board games ``front_camera`` (``cameras=True``: ``image_size`` squared, the
  paper's 96; ``cameras=False``: none, nothing is rendered).
* planner conditions: ``"planner"`` float32 ``(C, H, W)``, the current
  abstract state's planes stacked with the target's. MuJoBan: the entity
  planes wall, target, player, box (``full_entity_layer``) of each, C = 8,
  H x W the arena grid; board games: the empty, own, opponent planes of
  ``board_state`` of each, C = 6, N x N. MuJoBan also gets
  ``"planner_action"``, a float32 one-hot over the target move in the order
  of `PLANNER_ACTIONS` (``U, D, L, R`` = north, south, west, east; rows grow
  southwards); the board games infer the move from the planes (the paper).
  Without an active target the target planes repeat the current ones and the
  one-hot is all zeros.
* ``state=True`` (any condition): ``"state"`` float32 ``(C, H, W)``, the
  current abstract state at every step (MuJoBan: the entity planes of
  ``full_entity_layer``, C = 4, **privileged**: the simulator's rounded cells,
  as the entity-layer estimator reads them; board games: ``board_state``,
  C = 3). With ``cameras=False`` this is the comparison's "state" setting
  (``experiments/mujoban.toml``): the agent sees the grid (or board) and its
  proprioception, no images.

Actions: ``step`` clips the policy's action to [-1, 1] and maps it affinely
onto the environment's action bounds (MuJoBan [-1, 1]^2, the arm's joint
velocity limits).

Rewards and discounts (`StepResult`):

* ``reward_env``: the environment's reward. ``discount_env`` is ``gamma_env``
  times the timestep's discount on ordinary steps and **0 on the step that
  ends the episode, whatever ended it** (termination, time limit, diverged
  physics): the actors reset the environment then, so the next observation
  belongs to a new episode and there is nothing to bootstrap from.
* The auxiliary task runs in sub-episodes. At a sub-episode's start the
  ground-truth estimator (``entity-layer`` for MuJoBan, privileged as in the
  paper; ``board`` for the board games) estimates the abstract state and the
  planner proposes ONE transition
  (``planner.plan(state)``: one Sokoban move, one board move); the current
  state and the target stay fixed for the sub-episode (the paper's appendix).
  The sub-episode ends

  - when the target is reached: ``reward_abs = abs_reward``,
    ``discount_abs = 0``. MuJoBan: the estimated abstract state (the task's
    rounded cells, exactly what ``full_entity_layer`` shows) has the target's
    player cell and box cells. Board games: the agent's next registered move
    is the target's action (the estimated state after the step already holds
    the opponent's reply, so the task's move record is compared instead);
  - board games only: when the agent registers a *different* move (moves are
    irreversible, the target can no longer be reached): reward 0, discount 0;
  - after ``t_abs`` control steps: reward 0, ``discount_abs = 0``;

  otherwise ``reward_abs = 0`` and ``discount_abs = gamma_abs``. The next
  sub-episode starts with the observation returned by the step that ended
  the last one. ``discount_abs`` is also 0 on the episode's last step.
* No target: a solved or terminal abstract state, an estimate no Sokoban
  board can have (the walker rounded onto a box's cell, two boxes in one
  cell: physics allows it, the rules do not), or a planner that finds no
  plan (``NoPlanError``: a deadlocked Sokoban state, the solver's budget; or
  ``ValueError``), gives a sub-episode without a target (reward 0, target
  planes = current planes, zero one-hot) that ends after ``t_abs`` steps or
  as soon as the abstract state changes, when planning is tried again.

``info`` is empty except on the last step: ``episode_return`` (sum of
``reward_env``), ``episode_steps``, ``success`` (MuJoBan solved, board game
won), ``truncated`` (ended by the time limit, not by the task) and, for the
planner conditions, ``subgoals_issued``, ``subgoals_reached`` (targets
proposed and reached in the episode) and ``subgoals_unplanned`` (sub-episodes
the planner had no target for).

Reproducibility: the environment is built with ``envs.load(env_name,
seed=seed)``; the planner is reset at every episode with a seed derived from
``seed`` and the episode's index, so equal seeds and actions give equal
observations. ``raise_on_physics_error`` defaults to False here: a diverging
simulation ends the episode (reward 0) instead of killing an actor.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from envs.core import episode_seed
from hier_agents.baselines.impala.agent_env_spec import (
    CONDITIONS,
    PLANNER_ACTIONS,
    InputSpec,
    StepResult,
    _gamma,
    _load_env,
    main_camera_only,
)
from hier_agents.baselines.impala.inputs import ActionMap, AgentInputs, make_auxiliary
from hier_agents.modular.families import adapter, family
from hier_agents.modular.options import T_ABS

__all__ = [
    "AgentEnv",
    "CONDITIONS",
    "InputSpec",
    "PLANNER_ACTIONS",
    "StepResult",
    "main_camera_only",
]


class _Hold:
    """One agent step's action (mapped to the environment's) and what its
    control steps have added up so far."""

    __slots__ = ("action", "reward", "reward_abs", "discount_abs", "held", "timestep")

    def __init__(self, action):
        self.action = action
        self.timestep: Any = None  # the last control step's dm_env.TimeStep
        self.reward = self.reward_abs = 0.0
        self.discount_abs = 1.0
        self.held = 0


def step_all(agent_envs, actions, pool) -> list[StepResult]:
    """One agent step of every `AgentEnv` in ``agent_envs`` with its row of
    ``actions``: each one's `StepResult`, exactly what ``agent_envs[i].step(
    actions[i])`` gives, but each control step of all of them advanced at once
    by ``pool`` (an `envs.vector.PhysicsPool`: their physics in parallel
    threads). Every environment must have an episode running (RuntimeError)."""
    holds = [env._begin_hold(action) for env, action in zip(agent_envs, actions, strict=True)]
    running = list(range(len(holds)))
    while running:
        timesteps = pool.step(
            [agent_envs[i].env for i in running], [holds[i].action for i in running]
        )
        running = [
            i for i, timestep in zip(running, timesteps) if agent_envs[i]._add(holds[i], timestep)
        ]
    return [env._finish(hold) for env, hold in zip(agent_envs, holds)]


class AgentEnv:
    """An `envs` environment for an end-to-end agent (see the module docstring).

    The inputs and the auxiliary task's sub-episodes come from `AgentInputs`
    (`hier_agents.baselines.impala.inputs`), which the checkpoint agent
    shares; `InputSpec`, `StepResult` and the constants from `agent_env_spec`.

    Args:
      env_name: an `envs.names()` name of a game family (``mujoban/*``,
        ``mujoxo/*``, ``mujogo/*``, ``mujoboard/*``).
      condition: one of `CONDITIONS`.
      seed: seed of the environment and, per episode, of the planner.
      cameras: observe the paper's cameras (True) or render nothing (False).
        An explicit ``*_camera`` override in ``overrides`` wins either way.
      state: also observe the current abstract state at every step
        (``"state"``; privileged for MuJoBan, see the module docstring).
      image_size: side of the square camera images.
      t_abs: control steps of an auxiliary sub-episode (the paper's 50).
      abs_reward: auxiliary reward for reaching a target.
      gamma_env, gamma_abs: discounts; None takes the family adapter's
        ``discounts`` (the paper's).
      action_repeat: control steps each `step` holds its action for (the
        paper's 1). The repeat stops early when the episode ends, or when an
        auxiliary sub-episode ends (so the next action sees the new
        target); rewards add up over the held steps, ``discount_env`` and
        ``discount_abs`` are those of one agent step.
      **overrides: passed to ``envs.load`` (``envs.overrides(env_name)``).

    Attributes:
      env: the underlying ``envs`` environment. family: its family name.
      input_spec: `InputSpec`. inputs: the `AgentInputs`. gamma_env,
      gamma_abs. planner, estimator: the auxiliary task's parts (None for
      vanilla). subgoal: the current target (`Subgoal`) or None.
      abstract_state: the abstract state the current sub-episode started
      from. timestep: the environment's last ``dm_env.TimeStep``.
    """

    def __init__(
        self,
        env_name: str,
        condition: str = "vanilla",
        *,
        seed: int | None = 0,
        cameras: bool = True,
        image_size: int = 96,
        state: bool = False,
        t_abs: int = T_ABS,
        abs_reward: float = 1.0,
        gamma_env: float | None = None,
        gamma_abs: float | None = None,
        action_repeat: int = 1,
        **overrides,
    ):
        if condition not in CONDITIONS:
            raise ValueError(
                f"unknown condition {condition!r}; valid conditions: {', '.join(CONDITIONS)}"
            )
        self.family = family(env_name)
        if int(t_abs) < 1:
            raise ValueError(f"t_abs must be a positive number of control steps, got {t_abs!r}")
        if int(image_size) < 1:
            raise ValueError(f"image_size must be a positive number of pixels, got {image_size!r}")
        if int(action_repeat) < 1:
            raise ValueError(f"action_repeat must be >= 1, got {action_repeat!r}")
        self.action_repeat = int(action_repeat)
        self.env_name, self.condition = env_name, condition
        self.seed = None if seed is None else int(seed)
        discounts = adapter(env_name).discounts
        self.gamma_env = _gamma(gamma_env, discounts[0], "gamma_env")
        self.gamma_abs = _gamma(gamma_abs, discounts[1], "gamma_abs")
        self._closed = False
        self.env = _load_env(env_name, self.seed, image_size, cameras, overrides)
        planner = None
        try:
            description = self.env.description()
            planner, estimator = make_auxiliary(condition, description, self.seed, self.env)
            self.inputs = AgentInputs(
                description,
                self.env.observation_spec(),
                self.env.action_spec(),
                condition,
                state=state,
                task=self.env.task,
                planner=planner,
                estimator=estimator,
                t_abs=t_abs,
                abs_reward=abs_reward,
                gamma_abs=self.gamma_abs,
            )
            self._actions = ActionMap(self.env.action_spec())
        except BaseException:
            if planner is not None:
                planner.close()
            self.env.close()
            raise
        self.input_spec = self.inputs.spec
        self._episode = -1
        self._needs_reset = True
        self.timestep = None

    # The auxiliary task's parts and state, as `AgentInputs` holds them.
    planner = property(lambda self: self.inputs.planner)
    estimator = property(lambda self: self.inputs.estimator)
    subgoal = property(lambda self: self.inputs.subgoal)
    abstract_state = property(lambda self: self.inputs.abstract_state)

    def reset(self, episode: int | None = None) -> dict[str, np.ndarray]:
        """Starts a new episode; returns its first observation. With
        ``episode``, it is episode ``episode`` of the run's seed
        (`envs.Environment.seed`: the same draws whatever came before)."""
        if episode is not None:
            self.env.seed(self.seed, episode=episode)
            self._episode = int(episode) - 1
        timestep = self.timestep = self.env.reset()
        self._episode += 1
        self._return, self._steps = 0.0, 0
        self._needs_reset = False
        seed = None if self.seed is None else episode_seed(self.seed, self._episode)
        self.inputs.reset(timestep, seed)
        return self.inputs.observe(timestep.observation)

    def step(self, action) -> StepResult:
        """One agent step: ``action`` in [-1, 1]^A (clipped, then mapped) held
        for ``action_repeat`` control steps (fewer when the episode or an
        auxiliary sub-episode ends)."""
        hold = self._begin_hold(action)
        while self._add(hold, self.env.step(hold.action)):
            pass
        return self._finish(hold)

    def _begin_hold(self, action) -> _Hold:
        """The agent step's hold of ``action`` (`step`, `step_all`)."""
        if self._needs_reset:
            raise RuntimeError(
                "call reset() first: no episode is running "
                "(before the first reset, or after the last step)"
            )
        return _Hold(self._actions(action))

    def _add(self, hold: _Hold, timestep) -> bool:
        """Adds one control step's ``timestep`` to ``hold``; whether the hold
        goes on (not at the episode's end, an auxiliary sub-episode's end or
        the repeat's)."""
        self.timestep = hold.timestep = timestep
        hold.reward += float(timestep.reward)
        hold.held += 1
        self._steps += 1
        step_abs, hold.discount_abs = self.inputs.after_step(timestep)
        hold.reward_abs += step_abs
        if timestep.last() or (self.inputs.planning and hold.discount_abs == 0.0):
            return False
        return hold.held < self.action_repeat

    def _finish(self, hold: _Hold) -> StepResult:
        """The agent step's result once ``hold`` has ended."""
        timestep = hold.timestep
        self._return += hold.reward
        last = timestep.last()
        discount_env = 0.0 if last else self.gamma_env * float(timestep.discount)
        info = {}
        if last:
            self._needs_reset = True
            info = self._episode_info()
        return StepResult(
            self.inputs.observe(timestep.observation),
            hold.reward,
            discount_env,
            hold.reward_abs,
            hold.discount_abs,
            last,
            info,
        )

    def _episode_info(self) -> dict:
        task = self.env.task
        terminated = bool(task.should_terminate_episode(self.env.physics))
        info = {
            "episode_return": self._return,
            "episode_steps": self._steps,
            "success": self.inputs.adapter.success(task),
            "truncated": not terminated and self.env.step_count >= task.time_limit_steps,
        }
        info.update(self.inputs.episode_info())
        return info

    def close(self) -> None:
        """Frees the environment and the planner (GNU Go subprocesses). Idempotent."""
        if self._closed:
            return
        self._closed = True
        self.inputs.close()
        self.env.close()

    def __enter__(self):
        return self

    def __exit__(self, *exc_info) -> None:
        self.close()

    def __repr__(self) -> str:
        return (
            f"AgentEnv({self.env_name!r}, {self.condition!r}, seed={self.seed}, "
            f"images={[name for name, _ in self.input_spec.images]})"
        )
