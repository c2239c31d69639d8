"""The observation boundary: what an agent may hold of an environment.

`BoundaryEnv` wraps an environment and lets through only what a robot would
have: ``reset``, ``step``, the specs, ``control_timestep`` and the public
``description()`` (`envs.description`). Everything else (``physics``,
``task``, ``render``, ...) raises `BoundaryViolation` naming the attribute.
Timesteps lose the ground-truth observations the environment computes from
the simulator (`PRIVILEGED_OBSERVATIONS`: MuJoBan's ``full_entity_layer``
and ``pixel_layer``, as `envs.mujoban.task.Mujoban` declares them), so an
observation-only estimator that reads them fails loudly instead of quietly
cheating.

The board games declare their game record (``board_state``,
``move_history``, ``selected_point``) privileged too
(`envs.boards.task.BoardTask`). ``BoundaryEnv(env,
strip=env.privileged_observations)`` strips every key the environment
declares: ``hier_agents.run`` does so for every observation-only estimator
except the ``board`` one (`hier_agents.estimators.board`), which reads the
referee's record (`hier_agents.modular.components.reads_record`); the
camera board estimator reads cameras and proprioception only.

``python -m hier_agents.run`` puts every observation-only agent behind it;
``tests/test_boundary.py`` plays every listed estimator/planner/skill
combination through it.
"""

from __future__ import annotations

import dm_env

from envs.core import KeyedView
from envs.mujoban.task import Mujoban

__all__ = ["BoundaryEnv", "BoundaryViolation", "PRIVILEGED_OBSERVATIONS"]

#: Observations that are ground truth computed from the simulator (MuJoBan's
#: declaration, `envs.core.PhysicsTask.privileged_observations`).
PRIVILEGED_OBSERVATIONS = frozenset(Mujoban.privileged_observations)

_ALLOWED = frozenset(
    {
        "reset",
        "step",
        "action_spec",
        "observation_spec",
        "reward_spec",
        "discount_spec",
        "description",
        "control_timestep",
        "close",
    }
)


class BoundaryViolation(AttributeError):
    """An agent reached for something a robot does not have."""


class BoundaryEnv:
    """An environment seen from inside the observation boundary.

    Args:
      env: the environment (`envs.core.Environment` or any dm_env with a
        ``description()``).
      strip: observation keys removed from every timestep and from the
        observation spec (default `PRIVILEGED_OBSERVATIONS`).
    """

    def __init__(self, env, strip=PRIVILEGED_OBSERVATIONS):
        object.__setattr__(self, "_env", env)
        object.__setattr__(self, "_strip", frozenset(strip))

    def reset(self) -> dm_env.TimeStep:
        return self._filter(self._env.reset())

    def step(self, action) -> dm_env.TimeStep:
        return self._filter(self._env.step(action))

    def observation_spec(self):
        return {k: v for k, v in self._env.observation_spec().items() if k not in self._strip}

    def action_spec(self):
        return self._env.action_spec()

    def reward_spec(self):
        return self._env.reward_spec()

    def discount_spec(self):
        return self._env.discount_spec()

    def description(self):
        return self._env.description()

    @property
    def control_timestep(self) -> float:
        return self._env.control_timestep

    def close(self) -> None:
        self._env.close()

    def _filter(self, timestep: dm_env.TimeStep) -> dm_env.TimeStep:
        obs = timestep.observation
        if self._strip and any(k in obs for k in self._strip):
            timestep = timestep._replace(observation=_Without(obs, self._strip))
        return timestep

    def __getattr__(self, name):
        raise BoundaryViolation(
            f"an agent may not read env.{name}: behind the observation boundary it has "
            f"only {sorted(_ALLOWED)} (see hier_agents.boundary)"
        )

    def __setattr__(self, name, value):
        raise BoundaryViolation(f"an agent may not set env.{name}")


class _Without(KeyedView):
    """A view of an observation mapping without some keys; reads pass through
    (so lazily rendered camera frames stay lazy)."""

    __slots__ = ("_obs", "_keys")

    def __init__(self, obs, strip):
        self._obs = obs
        self._keys = tuple(k for k in obs if k not in strip)

    def __getitem__(self, key):
        if key not in self._keys:
            raise KeyError(key)
        return self._obs[key]
