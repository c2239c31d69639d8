"""Physically embedded planning environments (Mirza et al. 2020).

    import envs
    env = envs.load("mujoban/level5-pegs", seed=0)       # a dm_env.Environment
    gym_env = gymnasium.make("mujoban/level5-pegs")       # the same, as gymnasium
    gym_env = gymnasium.make("envs:mujoban/level5-pegs")  # the same, without `import envs`
    xo = envs.load("mujoxo/mixture")                     # tic-tac-toe with a Jaco arm
    go = envs.load("mujogo/7x7")                         # 7x7 Go against GNU Go

`envs.names()` lists every environment; `envs.overrides(name)` its settings;
`envs.check(name, **overrides)` checks a configuration without building it
(`envs.no_cameras(name)`: those that turn its cameras off;
`envs.original_options(name)`: those that give the original implementation's
settings where a default deviates from them, `envs.deviations(name, options)`:
which settings of a configuration differ from the original's).

Every name is a gymnasium id (`envs.gymnasium_env`): ``gymnasium.make(name,
obs=...)`` picks the observation (``"sensors"``, the default: cameras and
proprioception, what the paper's agents observe; ``"pixels"``; ``"state"``;
``"full"``), privileged keys (`Environment.privileged_observations`) only
when asked for; ``info["is_success"]`` ends every episode.
"""

from envs import _gl  # noqa: F401  (must run before mujoco picks a GL backend)
from envs import _malloc

_malloc.apply()  # fixed glibc mmap threshold: no growth over many rebuilds

from envs.core import Environment, PhysicsTask, episode_seed
from envs.registry import (
    UnknownEnvironmentError,
    check,
    describe,
    deviations,
    explicit_options,
    load,
    names,
    no_cameras,
    original_options,
    overrides,
    recorded_options,
)
from envs import mujoban  # noqa: F401  (registers the MuJoBan names)
from envs import boards  # noqa: F401  (registers the MuJoXO and MuJoGo names)
from envs.gymnasium_env import GymnasiumEnv, register_all as _register_gymnasium

_register_gymnasium()

__all__ = [
    "Environment",
    "GymnasiumEnv",
    "PhysicsTask",
    "UnknownEnvironmentError",
    "check",
    "describe",
    "deviations",
    "explicit_options",
    "episode_seed",
    "load",
    "names",
    "no_cameras",
    "original_options",
    "overrides",
    "recorded_options",
]
