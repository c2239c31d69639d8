"""What the end-to-end network observes of a timestep, and the paper's auxiliary task.

`AgentInputs` serves both places an end-to-end agent meets an environment:
`AgentEnv` (the actors' training environment) and the checkpoint agent
(`hier_agents.agents.checkpoint`, played by the episode runner). It turns a
timestep into the network's inputs (``observe``), runs the auxiliary task's
sub-episodes (``reset`` at an episode's first timestep, ``after_step`` after
every step) and counts them (``episode_info``); the semantics are in
`hier_agents.baselines.impala.agent_env`'s module docstring. Everything that
differs per game family (proprioceptive keys, state observation, planner
planes, when a target counts as reached) is read from the family adapter
(`hier_agents.modular.families`).

`ActionMap` maps the policy's actions in [-1, 1]^A onto the environment's
bounds.
"""

from __future__ import annotations

import numpy as np

from abstract_planners.base import NoPlanError, Subgoal
from hier_agents.baselines.impala.agent_env_spec import CONDITIONS, InputSpec
from hier_agents.estimators import EstimationError
from hier_agents.modular.families import adapter_for
from hier_agents.modular.options import T_ABS

__all__ = ["ActionMap", "AgentInputs", "camera_names"]


def camera_names(observation_spec) -> tuple[str, ...]:
    """The observation keys of the rendered cameras, in the observation
    spec's order (the task's): the ``*_camera`` keys (the environments'
    naming convention, as in `envs.no_cameras`) holding ``(H, W, 3)`` images."""
    return tuple(
        key
        for key, spec in observation_spec.items()
        if key.endswith("_camera") and len(spec.shape) == 3 and spec.shape[-1] == 3
    )


class ActionMap:
    """Maps an action in [-1, 1]^A (clipped) affinely onto ``action_spec``'s
    bounds. ``shape``: the action's shape; ``dim``: its size."""

    def __init__(self, action_spec):
        low = np.asarray(action_spec.minimum, np.float64) * np.ones(action_spec.shape)
        high = np.asarray(action_spec.maximum, np.float64) * np.ones(action_spec.shape)
        self._centre = ((high + low) / 2.0).ravel().tolist()
        self._half = ((high - low) / 2.0).ravel().tolist()
        self.shape = tuple(action_spec.shape)
        self.dim = int(np.prod(self.shape))

    def __call__(self, action) -> np.ndarray:
        """The environment's action for ``action`` (ValueError: wrong shape)."""
        a = np.asarray(action)
        if a.shape != self.shape:
            raise ValueError(f"action must have shape {self.shape}, got {a.shape}")
        # Plain Python on a few floats beats numpy's per-call overhead; NaN
        # passes through (the environment rejects non-finite actions).
        return np.array(
            [
                c + h * min(max(x, -1.0), 1.0)
                for x, c, h in zip(a.ravel().tolist(), self._centre, self._half)
            ]
        )


class AgentInputs:
    """One environment's inputs for the network and its auxiliary task.

    Args:
      description: the task's public description.
      observation_spec, action_spec: the environment's.
      condition: one of `CONDITIONS`.
      state: also observe the current abstract state (privileged for MuJoBan).
      task: the referee (``env.task``): the planner conditions' ground truth
        (its rounded cells or move record) and planner-plane shapes. Needed
        for the planner conditions and ``state``; None otherwise.
      planner, estimator: the auxiliary task's planner and ground-truth
        estimator (`make_auxiliary`); None for vanilla. The planner's seed is
        the episode's, given to `reset`.
      t_abs: control steps of a sub-episode.
      abs_reward: reward for reaching a target.
      gamma_abs: the auxiliary discount.

    Attributes:
      spec: the network's `InputSpec`.
      adapter: the family adapter.
      subgoal: the current target (None: none).
      abstract_state: the state the current sub-episode started from.
    """

    def __init__(
        self,
        description,
        observation_spec,
        action_spec,
        condition: str,
        *,
        state: bool = False,
        task=None,
        planner=None,
        estimator=None,
        t_abs: int = T_ABS,
        abs_reward: float = 1.0,
        gamma_abs: float = 0.9,
    ):
        if condition not in CONDITIONS:
            raise ValueError(
                f"unknown condition {condition!r}; valid conditions: {', '.join(CONDITIONS)}"
            )
        self.adapter = adapter_for(description)
        self.description, self.condition, self.task = description, condition, task
        self.planner, self.estimator = planner, estimator
        self.t_abs, self.abs_reward, self.gamma_abs = int(t_abs), float(abs_reward), gamma_abs
        self.planning = condition != "vanilla"
        self.cameras = camera_names(observation_spec)
        images = tuple(
            (name, (3, int(observation_spec[name].shape[0]), int(observation_spec[name].shape[1])))
            for name in self.cameras
        )
        proprio_dim = sum(
            int(np.prod(observation_spec[k].shape)) for k in self.adapter.proprio_keys
        )
        planner_shape, action_dim = None, 0
        if self.planning:
            planner_shape, action_dim = self.adapter.planner_inputs(task)
            self._planes = np.zeros(planner_shape, np.float32)
            self._onehot = np.zeros(action_dim, np.float32)
        self._state_key, state_shape = None, None
        if state:
            self._state_key = self.adapter.state_key
            h, w, c = (int(v) for v in observation_spec[self._state_key].shape)
            state_shape = (c, h, w)
        self.spec = InputSpec(
            images=images,
            proprio_dim=proprio_dim,
            planner_shape=planner_shape,
            planner_action_dim=action_dim,
            action_dim=int(np.prod(action_spec.shape)),
            state_shape=state_shape,
        )
        self.subgoal: Subgoal | None = None
        self.abstract_state = None
        self._issued = self._reached = self._unplanned = self._sub_steps = 0
        self._mark = None

    def observe(self, observation) -> dict[str, np.ndarray]:
        """The network's inputs (fresh arrays) from a timestep's observation."""
        obs = {
            "proprio": np.concatenate(
                [observation[k] for k in self.adapter.proprio_keys], dtype=np.float32
            )
        }
        for name in self.cameras:
            obs[name] = np.ascontiguousarray(observation[name].transpose(2, 0, 1))
        if self.planning:
            obs["planner"] = self._planes.copy()
            if self.spec.planner_action_dim:
                obs["planner_action"] = self._onehot.copy()
        if self._state_key is not None:
            obs["state"] = observation[self._state_key].transpose(2, 0, 1).astype(np.float32)
        return obs

    def reset(self, timestep, seed: int | None) -> None:
        """Starts an episode's auxiliary task at its first ``timestep``
        (``seed``: the episode's, for the planner)."""
        if not self.planning:
            return
        self._issued = self._reached = self._unplanned = 0
        self.planner.reset(seed)
        self.estimator.reset(self.description, timestep)
        self._start_subepisode(timestep)

    def after_step(self, timestep) -> tuple[float, float]:
        """(reward_abs, discount_abs) of the step that produced ``timestep``;
        starts the next sub-episode when this one ended (not on the
        episode's last step)."""
        if not self.planning:
            return 0.0, 0.0
        self._sub_steps += 1
        reached, over = self.adapter.subgoal_reached(self.task, self.subgoal, self._mark)
        self._reached += reached
        reward_abs = self.abs_reward if reached else 0.0
        if timestep.last():
            return reward_abs, 0.0  # reset() starts the next episode's sub-episode
        if reached or over or self._sub_steps >= self.t_abs:
            self._start_subepisode(timestep)  # with this step's observation
            return reward_abs, 0.0
        return reward_abs, self.gamma_abs

    def episode_info(self) -> dict:
        """The auxiliary task's counters of the episode so far (empty for vanilla)."""
        if not self.planning:
            return {}
        return {
            "subgoals_issued": self._issued,
            "subgoals_reached": self._reached,
            "subgoals_unplanned": self._unplanned,
        }

    def close(self) -> None:
        """Frees the planner (a GNU Go subprocess). Idempotent."""
        if self.planner is not None:
            self.planner.close()

    def _start_subepisode(self, timestep) -> None:
        """Estimates the abstract state, asks for a target, builds the planner inputs."""
        self._sub_steps = 0
        try:
            state = self.estimator.estimate(timestep).state
        except (EstimationError, ValueError):
            # Physics can put the rounded cells in a state no Sokoban board has
            # (two boxes in one cell, the walker on a box after a diagonal
            # shove): no target until the next sub-episode.
            state = None
        self.abstract_state = state
        subgoal = None
        if state is not None and not self.adapter.at_rest(state):
            try:
                subgoal = self.planner.plan(state)
            except (NoPlanError, ValueError):
                subgoal = None
        self.subgoal = subgoal
        if subgoal is None:
            self._unplanned += 1
        else:
            self._issued += 1
        self._mark = self.adapter.subepisode_mark(self.task)
        self.adapter.fill_planner_inputs(
            self._planes, self._onehot, timestep.observation, subgoal, self.task
        )


def make_auxiliary(condition: str, description, seed, simulator) -> tuple:
    """(planner, estimator) of the auxiliary task of ``condition`` (None, None
    for vanilla): the family's expert (`FamilyAdapter.expert_planner`, else
    its default planner) or ``"random"`` planner, and its ground-truth
    estimator (`FamilyAdapter.truth_estimator`, reading ``simulator``, the
    environment: privileged, as in the paper)."""
    if condition == "vanilla":
        return None, None
    from hier_agents.modular.components import resolve

    adapter = adapter_for(description)
    name = adapter.expert_planner if condition == "expert-planner" else "random"
    planner = resolve("planner", adapter.name, name).factory(description, seed)
    estimator = resolve("estimator", adapter.name, adapter.truth_estimator).factory(
        description, seed, simulator
    )
    return planner, estimator
