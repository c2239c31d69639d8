"""Batched environments for Stable-Baselines3: `envs.vector`'s batch as an SB3 ``VecEnv``.

    from stable_baselines3 import PPO
    from envs.vector_sb3 import make_sb3
    venv = make_sb3("mujoban/level1", num_envs=16, obs="state", seed=0, threads=2)
    model = PPO("MlpPolicy", venv).learn(100_000)

The environments step as in `envs.vector` (its docstring: the physics of all
on ``threads`` threads, each bit for bit as stepped alone, action repeat,
errors), in SB3's conventions: an ended episode resets in the same step, its
last observation in ``info["terminal_observation"]``; ``dones`` is terminated
or truncated, ``info["TimeLimit.truncated"]`` truncated and not terminated;
rewards float32; ``seed(s)`` (SB3 calls it with the model's seed) reseeds
environment i with ``s + i`` at the next ``reset``, as SB3's ``DummyVecEnv``
does. Importing this module imports Stable-Baselines3 and torch.
"""

from __future__ import annotations

from typing import Any, Sequence

import gymnasium
import numpy as np
from stable_baselines3.common.vec_env import VecEnv

from envs.gymnasium_env import GymnasiumEnv
from envs.vector import _Batch, _build, _count, _stack

__all__ = ["Sb3VecEnv", "make_sb3"]


class Sb3VecEnv(VecEnv):
    """Stable-Baselines3's ``VecEnv`` over a batch of `GymnasiumEnv` s (the
    module's docstring: its conventions).

    Args:
      envs, threads, action_repeat: as `envs.vector.BatchedVectorEnv`.
    """

    def __init__(
        self, envs: Sequence[GymnasiumEnv], *, threads: int | None = None, action_repeat: int = 1
    ):
        self._batch = _Batch(envs, threads, action_repeat)
        self.envs = self._batch.envs
        first = self.envs[0]
        super().__init__(len(self.envs), first.observation_space, first.action_space)
        self._actions: np.ndarray | None = None

    def reset(self) -> Any:
        """First observations of new episodes (seeds and options of
        ``seed``/``set_options`` apply once)."""
        results = []
        for i, env in enumerate(self.envs):
            options = self._options[i] or None
            results.append(env.reset(seed=self._seeds[i], options=options))
        self._reset_seeds()
        self._reset_options()
        self.reset_infos = [info for _, info in results]
        return self._stack([observation for observation, _ in results])

    def step_async(self, actions: np.ndarray) -> None:
        self._actions = self._batch.check_actions(actions)

    def step_wait(self) -> tuple:
        if self._actions is None:
            raise RuntimeError("step_wait() without step_async()")
        actions, self._actions = self._actions, None
        results = self._batch.step(actions, range(self.num_envs))
        observations, infos = [], []
        dones = np.zeros(self.num_envs, dtype=bool)
        rewards = np.zeros(self.num_envs, dtype=np.float32)
        for i, (observation, reward, terminated, truncated, info) in enumerate(results):
            info = {**info, "TimeLimit.truncated": bool(truncated and not terminated)}
            rewards[i], dones[i] = reward, terminated or truncated
            if dones[i]:
                info["terminal_observation"] = observation
                observation, self.reset_infos[i] = self.envs[i].reset()
            observations.append(observation)
            infos.append(info)
        return self._stack(observations), rewards, dones, infos

    def _stack(self, observations: list):
        return _stack(self.envs[0].observation_space, observations)

    def close(self) -> None:
        self._batch.close()

    def get_images(self) -> Sequence[np.ndarray | None]:
        return [env.render() for env in self.envs]

    def get_attr(self, attr_name: str, indices=None) -> list[Any]:
        return [self.envs[i].get_wrapper_attr(attr_name) for i in self._get_indices(indices)]

    def set_attr(self, attr_name: str, value: Any, indices=None) -> None:
        for i in self._get_indices(indices):
            setattr(self.envs[i], attr_name, value)

    def env_method(self, method_name: str, *method_args, indices=None, **method_kwargs):
        return [
            self.envs[i].get_wrapper_attr(method_name)(*method_args, **method_kwargs)
            for i in self._get_indices(indices)
        ]

    def env_is_wrapped(self, wrapper_class: type[gymnasium.Wrapper], indices=None) -> list[bool]:
        from stable_baselines3.common.env_util import is_wrapped

        return [is_wrapped(self.envs[i], wrapper_class) for i in self._get_indices(indices)]


def make_sb3(
    env_name: str,
    num_envs: int = 1,
    *,
    obs: str = "sensors",
    seed: int | None = None,
    threads: int | None = None,
    action_repeat: int = 1,
    render_mode: str | None = None,
    **overrides,
) -> Sb3VecEnv:
    """An `Sb3VecEnv` of ``num_envs`` environments ``env_name``; the arguments
    and errors of `envs.vector.make` (``seed``: environment i's first episode,
    unless SB3's ``VecEnv.seed`` reseeds before the first reset)."""
    _count("threads", 1 if threads is None else threads)
    _count("action_repeat", action_repeat)
    built = _build(env_name, num_envs, obs, seed, render_mode, overrides)
    return Sb3VecEnv(built, threads=threads, action_repeat=action_repeat)
