"""Gymnasium interface to every registered environment.

``gymnasium.make("mujoban/level1")`` (after ``import envs``; or
``gymnasium.make("envs:mujoban/level1")``, which imports it) builds a
`GymnasiumEnv`: a float32 Box action space, ``terminated`` for task ends
(discount 0) and ``truncated`` for the time limit, ``info["is_success"]`` on
every episode's last step, and ``render_mode="rgb_array"`` frames from the
task's main camera (MuJoBan's top-down camera, the board games' front camera)
whether or not that camera is observed.

The observation is chosen with ``obs=`` (`OBSERVATIONS`)::

    gymnasium.make("mujoban/level1")                # "sensors": Dict, SB3 MultiInputPolicy
    gymnasium.make("mujoban/level1", obs="pixels")  # (96, 96, 3) uint8 Box, SB3 CnnPolicy
    gymnasium.make("mujoban/level1", obs="state")   # float32 vector, SB3 MlpPolicy
    gymnasium.make("mujoban/level1", obs="full")    # Dict of everything

Privileged observations (ground truth the task declares in
`envs.core.PhysicsTask.privileged_observations`: MuJoBan's
``full_entity_layer`` and ``pixel_layer``, the board games' ``board_state``
and ``move_history``) are in ``"state"`` and ``"full"`` only; in ``"full"``
their keys start with ``privileged/``.

Action repeat: ``ActionRepeat(gymnasium.make(name, obs="state"), 4)`` holds
each action for 4 control steps and returns the summed reward, as the IMPALA
agent's ``--action-repeat 4`` does.

Vector environments: ``gymnasium.make_vec(name, num_envs=N, obs=...)`` builds
an `envs.vector.BatchedVectorEnv`, which steps the N environments' physics in
parallel threads (`envs.vector_sb3.make_sb3`: the same for Stable-Baselines3).
``gymnasium.vector.SyncVectorEnv`` and
``AsyncVectorEnv`` take ``lambda: gymnasium.make(name, ...)`` thunks. The
environments are built with lazy cameras, so no OpenGL context exists before
the first reset and ``AsyncVectorEnv``'s default (fork) context works when it
is made before the parent process renders anything; otherwise pass
``context="forkserver"`` (a forked child cannot use its parent's EGL state).
"""

from __future__ import annotations

from typing import Any, Mapping, Union

import gymnasium
import numpy as np
from dm_env import specs
from gymnasium import spaces

from envs.core import Environment
from envs.registry import (
    gymnasium_id,
    load,
    names,
    overrides as env_overrides,
    unknown_keywords_message,
)

#: The ``obs=`` choices of `GymnasiumEnv`, with what each holds.
OBSERVATIONS = {
    "sensors": "what the paper's agents observe: every enabled camera ((H, W, 3) uint8) and "
    "the proprioception (joint positions, velocities, torques, the walker's "
    "sensors, the arm's pinch site), as a Dict (SB3 MultiInputPolicy)",
    "pixels": "the task's main camera alone (MuJoBan's top_camera, the board games' "
    "front_camera) as an (H, W, 3) uint8 Box (SB3 CnnPolicy)",
    "state": "privileged: the proprioception and the task's abstract state (MuJoBan's "
    "full_entity_layer, the board games' board_state; booleans as 0/1) as one "
    "float32 vector (SB3 MlpPolicy); `GymnasiumEnv.state_layout` names its parts",
    "full": "every observation as a Dict, privileged keys prefixed 'privileged/' (research)",
}
#: Prefix of privileged keys in the ``obs="full"`` Dict.
PRIVILEGED_PREFIX = "privileged/"
#: `GymnasiumEnv`'s own keyword arguments (the rest go to `envs.load`).
_OWN_KEYWORDS = ("obs", "render_mode", "render_camera")


def spec_to_space(spec: specs.Array) -> spaces.Box:
    """A gymnasium Box equivalent to a dm_env array spec."""
    dtype = np.dtype(spec.dtype)
    if dtype == np.bool_:
        return spaces.Box(0, 1, spec.shape, dtype=np.bool_)  # type: ignore[arg-type]  # bool Boxes work; the stubs omit them
    if isinstance(spec, specs.BoundedArray):
        low = np.broadcast_to(spec.minimum, spec.shape).astype(dtype)
        high = np.broadcast_to(spec.maximum, spec.shape).astype(dtype)
        return spaces.Box(low, high, spec.shape, dtype=dtype)
    if np.issubdtype(dtype, np.integer):
        info = np.iinfo(dtype)
        return spaces.Box(info.min, info.max, spec.shape, dtype=dtype)
    return spaces.Box(-np.inf, np.inf, spec.shape, dtype=dtype)


#: What `observation_keys` returns: a Dict's ``{name: key}``, one key, or the
#: keys concatenated into one float32 vector.
ObservationKeys = Union[dict[str, str], str, tuple[str, ...]]


def observation_keys(env: Environment, obs: str) -> ObservationKeys:
    """Which of ``env``'s observations the ``obs`` choice (`OBSERVATIONS`) holds.

    Returns:
      ``"sensors"``, ``"full"``: ``{name: key}`` (a Dict observation; in
      ``"full"`` privileged keys named with `PRIVILEGED_PREFIX`);
      ``"pixels"``: the main camera's key; ``"state"``: the proprioception's
      keys then the task's ``state_observations``, in the vector's order.

    Raises:
      ValueError: ``obs="pixels"`` with the main camera switched off; an
        unknown ``obs``.
    """
    spec = env.observation_spec()
    privileged = env.privileged_observations
    cameras = [k for k in env.task.camera_configs if k in spec]
    if obs == "sensors":
        return {k: k for k in spec if k not in privileged}
    if obs == "full":
        return {(PRIVILEGED_PREFIX + k if k in privileged else k): k for k in spec}
    if obs == "pixels":
        main = env.task.main_camera
        if main not in cameras:
            raise ValueError(
                f"obs='pixels' is the main camera {main!r}, which is switched "
                f"off; build the environment with {main}=(height, width)"
            )
        return main
    if obs == "state":
        proprio = [k for k in spec if k not in privileged and k not in cameras]
        return tuple(proprio + [k for k in env.task.state_observations if k in spec])
    raise ValueError(f"unknown obs {obs!r}; valid: {', '.join(OBSERVATIONS)}")


def flat_keys(keys: ObservationKeys) -> list[str]:
    """The environment's observation keys that ``keys`` (`observation_keys`) reads, in order."""
    if isinstance(keys, str):
        return [keys]
    return list(keys.values()) if isinstance(keys, dict) else list(keys)


def convert_observation(keys: ObservationKeys, observation: Mapping[str, np.ndarray]):
    """The gymnasium observation of a dm_env ``observation`` (a timestep's)
    for ``keys`` (`observation_keys`): a dict of arrays, one array, or the
    arrays flattened, as float32 (booleans 0/1), and concatenated."""
    if isinstance(keys, str):
        return observation[keys]
    if isinstance(keys, dict):
        return {name: observation[key] for name, key in keys.items()}
    return np.concatenate([np.asarray(observation[k], np.float32).ravel() for k in keys])


class GymnasiumEnv(gymnasium.Env):
    """A gymnasium ``Env`` around an `envs.core.Environment`.

    Args:
      env_name: a name from `envs.names()` (ignored when `env` is given).
      env: an already built environment to wrap (it is closed with this one).
      obs: the observation, one of `OBSERVATIONS`: ``"sensors"`` (default),
        ``"pixels"``, ``"state"`` or ``"full"``.
      render_mode: None or ``"rgb_array"``.
      render_camera: camera for `render()`; defaults to the task's main camera
        (MuJoBan's top-down camera, the board games' front camera).
      **overrides: passed to `envs.load` (`envs.overrides(env_name)` lists
        them), e.g. ``render_size=(512, 512)`` for the size of `render()`
        frames (default 256x256), ``top_camera=(64, 64)``, ``time_limit=5.0``.
        Cameras the chosen observation does not hold are not rendered (the
        environment is built with ``lazy_cameras=True`` unless told otherwise).

    Raises:
      TypeError: a keyword that is neither this class's nor an override of
        the environment (the message names the closest and lists the valid ones).
      ValueError: a bad ``obs`` or ``render_mode`` (the message lists the
        valid values), ``obs="pixels"`` with the main camera switched off, or
        a bad override value (`envs.load`).
      KeyError: an unknown environment name (`envs.UnknownEnvironmentError`).

    Attributes:
      state_layout: for ``obs="state"``, ``{key: slice}`` of each observation
        in the vector (empty otherwise).
    """

    metadata = {"render_modes": ["rgb_array"], "render_fps": 20}

    def __init__(
        self,
        env_name: str | None = None,
        *,
        env: Environment | None = None,
        obs: str = "sensors",
        render_mode: str | None = None,
        render_camera: str | None = None,
        **overrides,
    ):
        from physics_planning.cli import choice

        choice("obs", obs, OBSERVATIONS)
        if render_mode not in (None, *self.metadata["render_modes"]):
            raise ValueError(
                f"render_mode must be one of {self.metadata['render_modes']} or None, "
                f"got {render_mode!r}"
            )
        if env is None:
            if env_name is None:
                raise ValueError(f"give env_name (one of {names()}) or env")
            valid = env_overrides(env_name)
            unknown = sorted(set(overrides) - set(valid))
            if unknown:
                raise TypeError(
                    unknown_keywords_message(
                        env_name, unknown, sorted([*_OWN_KEYWORDS, *valid]), "keyword"
                    )
                )
            if "lazy_cameras" in valid:
                overrides.setdefault("lazy_cameras", True)
            env = load(env_name, **overrides)
        elif overrides:
            raise TypeError(f"overrides {sorted(overrides)} apply to env_name, not to a built env")
        self._env = env
        try:
            self.render_mode = render_mode
            self._render_camera = render_camera or env.task.main_camera
            self._obs = obs
            self._build_spaces()
        except BaseException:
            env.close()
            raise
        self._needs_reset = True

    def _build_spaces(self) -> None:
        env = self._env
        spec = env.observation_spec()
        # What `_observation` returns (`observation_keys`).
        self._keys = observation_keys(env, self._obs)
        self.state_layout: dict[str, slice] = {}
        if isinstance(self._keys, str):
            self.observation_space = spec_to_space(spec[self._keys])
        elif isinstance(self._keys, dict):
            self.observation_space = spaces.Dict(
                {name: spec_to_space(spec[key]) for name, key in self._keys.items()}
            )
        else:  # "state"
            lows, highs, start = [], [], 0
            for key in self._keys:
                box = spec_to_space(spec[key])
                lows.append(box.low.astype(np.float32).ravel())
                highs.append(box.high.astype(np.float32).ravel())
                self.state_layout[key] = slice(start, start + box.low.size)
                start += box.low.size
            self.observation_space = spaces.Box(
                np.concatenate(lows), np.concatenate(highs), dtype=np.float32
            )
        aspec = env.action_spec()
        self.action_space = spaces.Box(
            np.broadcast_to(aspec.minimum, aspec.shape).astype(np.float32),
            np.broadcast_to(aspec.maximum, aspec.shape).astype(np.float32),
            aspec.shape,
            dtype=np.float32,
        )

    @property
    def dm_env(self) -> Environment:
        """The wrapped dm_env environment (physics, task, specs)."""
        return self._env

    @property
    def obs(self) -> str:
        """The observation choice (a key of `OBSERVATIONS`)."""
        return self._obs

    def _observation(self, observation: Mapping[str, np.ndarray]):
        return convert_observation(self._keys, observation)

    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None):
        super().reset(seed=seed)
        if seed is not None:
            self._env.seed(seed)
        timestep = self._env.reset()
        self._needs_reset = False
        return self._observation(timestep.observation), {}

    def step(self, action):
        """One control step. ``info``: ``discount``, ``steps`` (control steps
        this episode) and, on the episode's last step, ``is_success`` (bool:
        MuJoBan solved, the board game won; `PhysicsTask.succeeded`)."""
        self._check_running()
        return self._result(self._env.step(action))

    def _check_running(self) -> None:
        """Raises RuntimeError unless an episode is running (after `reset`,
        before its last step)."""
        if self._needs_reset:
            raise RuntimeError("the episode has ended (or never began): call reset() first")

    def _result(self, timestep):
        """`step`'s return value for the wrapped environment's ``timestep``
        (``(observation, reward, terminated, truncated, info)``); after the
        episode's last step the next `step` needs a `reset`."""
        terminated = truncated = False
        info = {"discount": float(timestep.discount), "steps": self._env.step_count}
        if timestep.last():
            self._needs_reset = True
            terminated = timestep.discount == 0.0
            truncated = not terminated
            info["is_success"] = bool(self._env.task.succeeded)
        return (
            self._observation(timestep.observation),
            float(timestep.reward),
            terminated,
            truncated,
            info,
        )

    def render(self):
        """With ``render_mode="rgb_array"``: a (height, width, 3) uint8 frame
        of `render_camera` at the environment's ``render_size`` (default
        256x256), MuJoBan's pegs marked (`envs.core.Environment.render`);
        else None."""
        if self.render_mode != "rgb_array":
            return None
        return self._env.render(self._render_camera)

    def close(self):
        """Closes the wrapped environment (idempotent); gymnasium envs are
        context managers: ``with gymnasium.make(name) as env:``."""
        self._env.close()


class ActionRepeat(gymnasium.Wrapper):
    """Each ``step`` holds its action for ``repeat`` control steps of the
    wrapped environment (fewer when the episode ends first), as the IMPALA
    agent's ``--action-repeat`` does: the reward is the sum over the held
    steps, ``terminated``, ``truncated`` and ``info`` are those of the last
    one, and ``info["held"]`` says how many steps the action was held.

    A learner counting this environment's steps counts agent decisions;
    ``repeat`` times that is the control steps (the frames) it saw, short by
    the steps a hold lost at each episode's end.

    Raises:
      ValueError: ``repeat`` below 1.
    """

    def __init__(self, env: gymnasium.Env, repeat: int):
        if isinstance(repeat, bool) or not isinstance(repeat, int) or repeat < 1:
            raise ValueError(f"repeat must be an integer >= 1 control steps, got {repeat!r}")
        super().__init__(env)
        self.repeat = repeat

    def step(self, action):
        hold = HeldSteps()
        while hold.add(self.env.step(action)) and hold.held < self.repeat:
            pass
        return hold.result()


class HeldSteps:
    """`ActionRepeat`'s rule for one action held over control steps: `add`
    each step's ``(observation, reward, terminated, truncated, info)`` while
    it returns True (the episode goes on) and the hold lasts; `result` is the
    hold's: the summed reward, the last step's observation, ``terminated``,
    ``truncated`` and ``info``, plus ``info["held"]`` (the steps added)."""

    __slots__ = ("total", "held", "_last")

    def __init__(self) -> None:
        self.total, self.held = 0.0, 0
        self._last: tuple | None = None

    def add(self, result: tuple) -> bool:
        """Adds one control step's result; whether its episode goes on."""
        self.total += float(result[1])
        self.held += 1
        self._last = result
        return not (result[2] or result[3])

    def result(self) -> tuple:
        """The hold's ``(observation, reward, terminated, truncated, info)``
        (RuntimeError before any `add`)."""
        if self._last is None:
            raise RuntimeError("no control step was added to the hold")
        observation, _, terminated, truncated, info = self._last
        return observation, self.total, terminated, truncated, {**info, "held": self.held}


def register_all() -> None:
    """Registers every `envs` name with gymnasium (idempotent), so that
    ``gymnasium.make(name)`` works after ``import envs`` and
    ``gymnasium.make("envs:" + name)`` works without it."""
    for name in names():
        gymnasium_id(name)
