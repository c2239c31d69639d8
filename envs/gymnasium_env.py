"""Gymnasium interface to every registered environment.

``gymnasium.make("mujoban/level1")`` (after ``import envs``) builds a
`GymnasiumEnv`: Dict observation space from the dm_env specs, a float32 Box
action space, ``terminated`` for task ends (discount 0) and ``truncated`` for
the time limit, and ``render_mode="rgb_array"`` frames from the task's main
camera (MuJoBan's top-down camera, the board games' front camera) whether or
not that camera is observed.
"""

from __future__ import annotations

from typing import Any

import gymnasium
import numpy as np
from dm_env import specs
from gymnasium import spaces

from envs.core import Environment
from envs.registry import load, names


def spec_to_space(spec: specs.Array) -> spaces.Space:
    """A gymnasium Box equivalent to a dm_env array spec."""
    dtype = np.dtype(spec.dtype)
    if dtype == np.bool_:
        return spaces.Box(0, 1, spec.shape, dtype=np.bool_)
    if isinstance(spec, specs.BoundedArray):
        low = np.broadcast_to(spec.minimum, spec.shape).astype(dtype)
        high = np.broadcast_to(spec.maximum, spec.shape).astype(dtype)
        return spaces.Box(low, high, spec.shape, dtype=dtype)
    if np.issubdtype(dtype, np.integer):
        info = np.iinfo(dtype)
        return spaces.Box(info.min, info.max, spec.shape, dtype=dtype)
    return spaces.Box(-np.inf, np.inf, spec.shape, dtype=dtype)


class GymnasiumEnv(gymnasium.Env):
    """A gymnasium ``Env`` around an `envs.core.Environment`.

    Args:
      env_name: a name from `envs.names()` (ignored when `env` is given).
      env: an already built environment to wrap.
      render_mode: None or ``"rgb_array"``.
      render_camera: camera for `render()`; defaults to the task's main camera
        (MuJoBan's top-down camera, the board games' front camera).
      render_size: (height, width) of rendered frames.
      **overrides: passed to `envs.load`.
    """

    metadata = {"render_modes": ["rgb_array"], "render_fps": 20}

    def __init__(self, env_name: str | None = None, *, env: Environment | None = None,
                 render_mode: str | None = None, render_camera: str | None = None,
                 render_size: tuple[int, int] = (256, 256), **overrides):
        if render_mode not in (None, *self.metadata["render_modes"]):
            raise ValueError(f"render_mode must be one of {self.metadata['render_modes']} or None, "
                             f"got {render_mode!r}")
        if env is None:
            if env_name is None:
                raise ValueError(f"give env_name (one of {names()}) or env")
            env = load(env_name, **overrides)
        self._env = env
        try:
            self.render_mode = render_mode
            self._render_camera = render_camera or env.task.main_camera
            self._render_size = tuple(render_size)
            self.observation_space = spaces.Dict(
                {k: spec_to_space(s) for k, s in env.observation_spec().items()})
            aspec = env.action_spec()
            self.action_space = spaces.Box(
                np.broadcast_to(aspec.minimum, aspec.shape).astype(np.float32),
                np.broadcast_to(aspec.maximum, aspec.shape).astype(np.float32),
                aspec.shape, dtype=np.float32)
        except BaseException:
            env.close()
            raise
        self._needs_reset = True

    @property
    def dm_env(self) -> Environment:
        """The wrapped dm_env environment (physics, task, specs)."""
        return self._env

    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None):
        super().reset(seed=seed)
        if seed is not None:
            self._env.seed(seed)
        timestep = self._env.reset()
        self._needs_reset = False
        return timestep.observation, {}

    def step(self, action):
        if self._needs_reset:
            raise RuntimeError("the episode has ended (or never began): call reset() first")
        timestep = self._env.step(action)
        terminated = truncated = False
        if timestep.last():
            self._needs_reset = True
            terminated = timestep.discount == 0.0
            truncated = not terminated
        info = {"discount": float(timestep.discount), "steps": self._env.step_count}
        return timestep.observation, float(timestep.reward), terminated, truncated, info

    def render(self):
        if self.render_mode != "rgb_array":
            return None
        return self._env.render(self._render_camera, *self._render_size)

    def close(self):
        """Closes the wrapped environment (idempotent); gymnasium envs are
        context managers: ``with gymnasium.make(name) as env:``."""
        self._env.close()


def register_all() -> None:
    """Registers every `envs` name with gymnasium (idempotent)."""
    registry = gymnasium.envs.registration.registry
    for name in names():
        if name not in registry:
            gymnasium.register(id=name, entry_point="envs.gymnasium_env:GymnasiumEnv",
                               kwargs={"env_name": name})
