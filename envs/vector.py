"""Batched environments for learners: N environments per call, their physics in parallel.

    import envs.vector
    vec = envs.vector.make("mujoban/level1", num_envs=16, obs="state", seed=0, threads=2)
    observations, infos = vec.reset()
    observations, rewards, terminated, truncated, infos = vec.step(vec.action_space.sample())
    vec.close()

After ``import envs``, ``gymnasium.make_vec(name, num_envs=16, obs="state")`` builds
the same (every name's ``vector_entry_point`` is `make`; ``vectorization_mode="sync"``
or ``"async"`` still gives gymnasium's own vector environments).

* `BatchedVectorEnv` (`make`): a ``gymnasium.vector.VectorEnv`` of N
  `envs.GymnasiumEnv` s of one name: their observation choice (``obs=``,
  `envs.gymnasium_env.OBSERVATIONS`), spaces (batched) and ``info`` keys.
* `envs.vector_sb3` (``make_sb3``): the same batch as a Stable-Baselines3
  ``VecEnv``, in its own module so that this one does not import SB3 and torch.

How a batch steps. `envs.core.Environment` runs a control step in three
parts, ``_begin_step`` (the action to the task), ``_advance`` (one
``mj_step(model, data, n_substeps)``, which releases the GIL) and
``_end_step`` (the task's hooks, reward, observation). A batch runs the first
part of every environment in the calling thread, then their ``_advance`` on
``threads`` threads (the calling one and ``threads - 1`` workers of a
persistent pool, each taking the next environment not yet taken), then the
last parts in the calling thread in environment order: the tasks' Python, the
board games' opponents (GNU Go) and camera frames stay serial. Every
environment has its own mjModel and mjData and runs its parts in the order
``step`` does, so it ends bit for bit where stepping it alone with the same
actions would; threads change only the wall time.

Why threads and not ``mujoco.rollout``: rollout (mujoco 3.17) steps many
models in C threads, but open loop from states copied in (``mj_getState``)
onto per-thread scratch mjData, returning the states to copy back
(``mj_setState``). An environment's own mjData would then lack what
``mj_step`` leaves there and the tasks read (the last substep's body poses,
sensors and contacts, and the warning counters that detect divergence);
recomputing them takes an ``mj_forward`` per environment and gives the values
of the step's end, not those sequential stepping gives. Without the solver's
warm start passed in, the states differ too (1e-14 after one MuJoBan step).

Seeds. ``seed=s`` (`make`, `BatchedVectorEnv.reset`) makes environment i's
next episode episode i of the run seeded ``s`` (`envs.Environment.seed` with
``episode=i``: the `envs.episode_seed` generator, a level file's i-th level),
which ``envs.load(name).seed(s, episode=i)`` reproduces alone; its later
episodes continue its own generator. ``reset(seed=[s0, s1, ...])`` seeds
environment i as ``GymnasiumEnv.reset(seed=si)`` does (None: left as it is).

Autoreset (``autoreset_mode``, in ``metadata["autoreset_mode"]``), as
gymnasium defines it: ``NEXT_STEP`` (default) the step after an episode's
last one resets that environment, ignores its action and returns its first
observation, reward 0, ``terminated`` and ``truncated`` False and the
reset's info; ``SAME_STEP`` the last step resets it at once, returns the first
observation and puts the last one in ``info["final_obs"]`` and its info in
``info["final_info"]``; ``DISABLED`` an ended environment must be reset with
``reset(options={"reset_mask": mask})`` before it steps again.

Action repeat: ``action_repeat=k`` holds each action for k control steps,
fewer when the episode ends first (`envs.gymnasium_env.ActionRepeat`'s rule,
`envs.gymnasium_env.HeldSteps`: summed reward, ``info["held"]``).

Errors: actions of the wrong shape, not numbers or not finite raise
ValueError or TypeError before any environment steps. A step or reset that
raises otherwise (``PhysicsError`` from a diverging simulation with
``raise_on_physics_error=True``, an environment's own error) leaves the batch
needing a full ``reset()``; the other environments finished their step
first, so no thread still runs.
"""

from __future__ import annotations

import itertools
import numbers
import os
import threading
from concurrent.futures import ThreadPoolExecutor, wait
from typing import Any, Sequence

import gymnasium
import numpy as np
from gymnasium.vector import AutoresetMode
from gymnasium.vector.utils import batch_space, concatenate, create_empty_array, iterate

from envs.core import Environment
from envs.gymnasium_env import GymnasiumEnv, HeldSteps
from envs.profile import PROFILE

__all__ = ["BatchedVectorEnv", "PhysicsPool", "make"]


def _count(name: str, value: Any) -> int:
    """``value`` as an int >= 1; TypeError if it is not an integer, ValueError below 1."""
    if isinstance(value, bool) or not isinstance(value, numbers.Integral):
        raise TypeError(f"{name} must be an integer >= 1, got {value!r}")
    if value < 1:
        raise ValueError(f"{name} must be an integer >= 1, got {value!r}")
    return int(value)


def _autoreset_mode(value: Any) -> AutoresetMode:
    """``value`` (an `AutoresetMode` or its value) as an `AutoresetMode`; ValueError otherwise."""
    try:
        return AutoresetMode(value)
    except ValueError:
        valid = ", ".join(m.value for m in AutoresetMode)
        raise ValueError(f"unknown autoreset_mode {value!r}; valid: {valid}") from None


def _stack(space: gymnasium.Space, rows: Sequence) -> Any:
    """The batch (new arrays) of ``rows``, observations of ``space`` (`GymnasiumEnv`'s)."""
    out = create_empty_array(space, len(rows))
    assert out is not None  # None for no space a GymnasiumEnv has
    return concatenate(space, rows, out)


class PhysicsPool:
    """Steps `envs.core.Environment` s together, their physics on ``threads``
    threads: the caller's and ``threads - 1`` persistent workers (`step`).
    ``threads=1`` runs everything in the calling thread. `close` stops the
    workers."""

    def __init__(self, threads: int):
        self.threads = threads
        self._workers = None
        if threads > 1:
            self._workers = ThreadPoolExecutor(threads - 1, thread_name_prefix="envs-physics")
            # The executor starts threads lazily and reuses an idle one: tasks that
            # wait for each other make it start all of them now.
            started = threading.Barrier(threads - 1)
            wait([self._workers.submit(started.wait) for _ in range(threads - 1)])

    def advance(self, batch: Sequence[Environment]) -> list:
        """Each environment's ``_advance()`` result (bool) or the exception it
        raised, in ``batch``'s order. Returns when every one has finished."""
        outcomes: list = [None] * len(batch)
        order = itertools.count()  # next() of a count is atomic under the GIL

        def work() -> None:
            while (i := next(order)) < len(batch):
                try:
                    outcomes[i] = batch[i]._advance()
                except Exception as error:  # raised in the calling thread after the batch
                    outcomes[i] = error

        helpers = []
        if self._workers is not None:
            helpers = [self._workers.submit(work) for _ in range(min(self.threads, len(batch)) - 1)]
        try:
            work()
        finally:
            wait(helpers)
        return outcomes

    def step(self, batch: Sequence[Environment], actions: Sequence) -> list:
        """One control step of each environment of ``batch`` with its action
        (ValueError: a wrong shape or not finite; nothing steps then): each
        one's ``dm_env.TimeStep``, as ``batch[i].step(actions[i])`` would give.
        Every episode must be running (no environment after its LAST step).
        An error of one environment's step is raised once all have finished."""
        for env, action in zip(batch, actions, strict=True):
            env._check_action(action)
        for env, action in zip(batch, actions):
            env._begin_step(action)
        outcomes = self.advance(batch)
        timesteps = [
            env._end_step(outcome)
            for env, outcome in zip(batch, outcomes)
            if not isinstance(outcome, BaseException)
        ]
        error = next((o for o in outcomes if isinstance(o, BaseException)), None)
        if error is not None:
            raise error
        return timesteps

    def close(self) -> None:
        if self._workers is not None:
            self._workers.shutdown(wait=True)


class _Batch:
    """N `GymnasiumEnv` s of one observation and action space, stepped
    together (the module's docstring: how), each action held ``repeat``
    control steps. Closes the environments when construction fails."""

    def __init__(self, envs: Sequence[GymnasiumEnv], threads: int | None, repeat: int):
        self.envs = tuple(envs)
        try:
            self._check(threads, repeat)
        except BaseException:
            for env in self.envs:
                if isinstance(env, GymnasiumEnv):
                    env.close()
            raise
        self._pool = PhysicsPool(self.threads)

    def _check(self, threads: int | None, repeat: int) -> None:
        if not self.envs or not all(isinstance(e, GymnasiumEnv) for e in self.envs):
            raise TypeError("a batch needs one or more envs.GymnasiumEnv instances")
        if len({id(e) for e in self.envs}) != len(self.envs):
            raise ValueError("a batch was given the same environment twice")
        first = self.envs[0]
        for env in self.envs[1:]:
            if (env.observation_space, env.action_space) != (
                first.observation_space,
                first.action_space,
            ):
                raise ValueError("the environments of a batch must have the same spaces")
        self.threads = _count("threads", (os.cpu_count() or 1) if threads is None else threads)
        self.repeat = _count("action_repeat", repeat)

    def check_actions(self, actions: Any) -> np.ndarray:
        """``actions`` as a float64 array of shape (N, *action shape).

        Raises:
          TypeError: not numbers.
          ValueError: another shape, or not finite.
        """
        shape = (len(self.envs), *(self.envs[0].action_space.shape or ()))
        try:
            array = np.asarray(actions, dtype=np.float64)
        except (TypeError, ValueError):
            raise TypeError(
                f"actions must be an array of numbers of shape {shape}, "
                f"got {type(actions).__name__}"
            ) from None
        if array.shape != shape:
            raise ValueError(f"actions must have shape {shape} (a row per env), got {array.shape}")
        if not np.isfinite(array).all():
            raise ValueError("actions must be finite, got NaN or inf")
        return array

    def reset(self, indices: Sequence[int], seed, options: dict | None) -> list[tuple]:
        """``(observation, info)`` of a new episode of each environment in
        ``indices``; ``seed``: None, an int (a run seed: environment i plays
        its episode i) or a list of N ints or None (each environment's own)."""
        out = []
        for i in indices:
            env = self.envs[i]
            if isinstance(seed, (list, tuple)):
                out.append(env.reset(seed=seed[i], options=options))
                continue
            if seed is not None:
                env.dm_env.seed(seed, episode=i)
            out.append(env.reset(options=options))
        return out

    def step(self, actions: np.ndarray, indices: Sequence[int]) -> list[tuple]:
        """Each environment in ``indices`` steps with ``actions[i]`` held
        `repeat` control steps; returns their ``step`` results in that order."""
        if self.repeat == 1:
            return self._control_step(actions, indices)
        holds = {i: HeldSteps() for i in indices}
        running = list(indices)
        for _ in range(self.repeat):
            if not running:
                break
            results = self._control_step(actions, running)
            running = [i for i, result in zip(running, results) if holds[i].add(result)]
        return [holds[i].result() for i in indices]

    def _control_step(self, actions: np.ndarray, indices: Sequence[int]) -> list[tuple]:
        """One control step of the environments ``indices``: their ``step`` results."""
        envs = [self.envs[i] for i in indices]
        for env in envs:
            env._check_running()
        with PROFILE.section("physics"):
            timesteps = self._pool.step([env.dm_env for env in envs], [actions[i] for i in indices])
        return [env._result(timestep) for env, timestep in zip(envs, timesteps)]

    def close(self) -> None:
        """Stops the workers and closes every environment (idempotent)."""
        try:
            self._pool.close()
        finally:
            for env in self.envs:
                env.close()


def _build(
    env_name: str, num_envs: int, obs: str, seed: int | None, render_mode, overrides: dict
) -> list[GymnasiumEnv]:
    """``num_envs`` `GymnasiumEnv` s of ``env_name``, environment i seeded for
    episode i of ``seed`` (when not None); all closed if one fails to build."""
    num_envs = _count("num_envs", num_envs)
    if seed is not None and (isinstance(seed, bool) or not isinstance(seed, numbers.Integral)):
        raise TypeError(f"seed must be an integer or None, got {seed!r}")
    built: list[GymnasiumEnv] = []
    try:
        for i in range(num_envs):
            built.append(GymnasiumEnv(env_name, obs=obs, render_mode=render_mode, **overrides))
            if seed is not None:
                built[-1].dm_env.seed(int(seed), episode=i)
    except BaseException:
        for env in built:
            env.close()
        raise
    return built


class BatchedVectorEnv(gymnasium.vector.VectorEnv):
    """A gymnasium vector environment of `GymnasiumEnv` s stepped as one batch
    (the module's docstring: threads, seeds, autoreset, action repeat, errors).

    Args:
      envs: the environments (built by `make`, or by hand: distinct, of one
        observation and action space); closed with this one.
      threads: threads that run the physics (default ``os.cpu_count()``; 1:
        all in the calling thread).
      action_repeat: control steps each action is held (>= 1).
      autoreset_mode: a ``gymnasium.vector.AutoresetMode`` or its value.

    Raises:
      TypeError: a non-integer ``threads``/``action_repeat``; ``envs`` not
        `GymnasiumEnv` s.
      ValueError: ``threads``/``action_repeat`` below 1, an unknown
        ``autoreset_mode``, environments of different spaces.

    Attributes:
      envs: the environments, in batch order.
    """

    def __init__(
        self,
        envs: Sequence[GymnasiumEnv],
        *,
        threads: int | None = None,
        action_repeat: int = 1,
        autoreset_mode: AutoresetMode | str = AutoresetMode.NEXT_STEP,
    ):
        self._batch = _Batch(envs, threads, action_repeat)
        try:
            mode = _autoreset_mode(autoreset_mode)
        except ValueError:
            self._batch.close()
            raise
        self.envs = self._batch.envs
        first = self.envs[0]
        self.num_envs = len(self.envs)
        self.threads = self._batch.threads
        self.action_repeat = self._batch.repeat
        self.autoreset_mode = mode
        self.metadata = {**first.metadata, "autoreset_mode": mode}
        self.render_mode = first.render_mode
        self.single_observation_space = first.observation_space
        self.single_action_space = first.action_space
        self.observation_space = batch_space(first.observation_space, self.num_envs)
        self.action_space = batch_space(first.action_space, self.num_envs)
        self._ended = np.zeros(self.num_envs, dtype=bool)  # the last step ended the episode
        self._broken = True  # a full reset is due: never reset, or a step raised
        empty = create_empty_array(self.single_observation_space, self.num_envs)
        self._rows = list(iterate(self.observation_space, empty))  # the last observations

    def reset(self, *, seed: int | list[int | None] | None = None, options: dict | None = None):
        """New episodes of all environments, or of those where
        ``options["reset_mask"]`` (bool array of shape (N,)) is True, the others
        left as they are. ``seed``: the module's docstring. Returns
        ``(observations, infos)``.

        Raises:
          ValueError: a seed list of another length; a bad reset mask.
        """
        options = dict(options or {})
        mask = self._reset_mask(options.pop("reset_mask", None))
        if isinstance(seed, (list, tuple)) and len(seed) != self.num_envs:
            raise ValueError(f"reset got {len(seed)} seeds for {self.num_envs} environments")
        if isinstance(seed, numbers.Integral):
            super().reset(seed=int(seed))
        indices = np.flatnonzero(mask).tolist()
        broken, self._broken = self._broken, True
        results = self._batch.reset(indices, seed, options or None)
        self._broken = broken and not mask.all()
        self._ended[indices] = False
        infos: dict = {}
        for i, (observation, info) in zip(indices, results):
            self._rows[i] = observation
            infos = self._add_info(infos, info, i)
        return self._stack(), infos

    def _reset_mask(self, mask) -> np.ndarray:
        if mask is None:
            return np.ones(self.num_envs, dtype=bool)
        mask = np.asarray(mask)
        if mask.dtype != np.bool_ or mask.shape != (self.num_envs,) or not mask.any():
            raise ValueError(
                f"options['reset_mask'] must be a bool array of shape ({self.num_envs},) "
                f"with a True, got {mask!r}"
            )
        return mask

    def step(self, actions: Any) -> tuple:
        """Steps every environment with its row of ``actions`` (shape
        ``action_space.shape``); returns ``(observations, rewards,
        terminations, truncations, infos)`` (infos: gymnasium's dict of arrays
        with ``_key`` masks; the keys of `GymnasiumEnv.step`).

        Raises:
          RuntimeError: before `reset`, after a step that raised, or (with
            ``DISABLED``) an ended environment not reset.
          TypeError, ValueError: ``actions`` not numbers, of another shape, or
            not finite (nothing is stepped).
        """
        if self._broken:
            raise RuntimeError("the batch needs reset(): never reset, or a step raised")
        mode = self.autoreset_mode
        if mode == AutoresetMode.DISABLED and self._ended.any():
            ended = np.flatnonzero(self._ended).tolist()
            raise RuntimeError(
                f"environments {ended} ended their episodes; with autoreset DISABLED "
                f"reset them (options={{'reset_mask': mask}}) before stepping"
            )
        actions = self._batch.check_actions(actions)
        resets = self._ended if mode == AutoresetMode.NEXT_STEP else np.zeros_like(self._ended)
        stepped = np.flatnonzero(~resets).tolist()
        self._broken = True
        results = self._batch.step(actions, stepped)
        rewards = np.zeros(self.num_envs)
        terminations = np.zeros(self.num_envs, dtype=bool)
        truncations = np.zeros(self.num_envs, dtype=bool)
        infos: dict = {}
        for i, (observation, reward, terminated, truncated, info) in zip(stepped, results):
            self._rows[i], rewards[i] = observation, reward
            terminations[i], truncations[i] = terminated, truncated
            if mode == AutoresetMode.SAME_STEP and (terminated or truncated):
                infos = self._add_info(infos, {"final_obs": observation, "final_info": info}, i)
                self._rows[i], info = self.envs[i].reset()
            infos = self._add_info(infos, info, i)
        for i in np.flatnonzero(resets).tolist():
            self._rows[i], info = self.envs[i].reset()
            infos = self._add_info(infos, info, i)
        self._ended = terminations | truncations
        self._broken = False
        return self._stack(), rewards, terminations, truncations, infos

    def _stack(self):
        """The batch of the environments' last observations (new arrays)."""
        return _stack(self.single_observation_space, self._rows)

    def render(self) -> tuple | None:
        """With ``render_mode="rgb_array"``: each environment's frame
        (`GymnasiumEnv.render`); else None."""
        if self.render_mode != "rgb_array":
            return None
        return tuple(env.render() for env in self.envs)

    def close_extras(self, **kwargs) -> None:
        """Stops the physics threads and closes every environment."""
        self._batch.close()


def make(
    env_name: str,
    num_envs: int = 1,
    *,
    obs: str = "sensors",
    seed: int | None = None,
    threads: int | None = None,
    action_repeat: int = 1,
    autoreset_mode: AutoresetMode | str = AutoresetMode.NEXT_STEP,
    render_mode: str | None = None,
    **overrides,
) -> BatchedVectorEnv:
    """A `BatchedVectorEnv` of ``num_envs`` environments ``env_name``.

    Args:
      env_name: a name from `envs.names()`.
      num_envs: environments (>= 1).
      obs, render_mode, **overrides: as `GymnasiumEnv` (``obs="state"``: no
        camera is rendered; overrides such as ``time_limit=5.0`` go to `envs.load`).
      seed: None (fresh entropy), or environment i plays episode i of the run
        seeded ``seed`` first (the module's docstring).
      threads, action_repeat, autoreset_mode: as `BatchedVectorEnv`.

    Raises:
      TypeError: a non-integer ``num_envs``/``threads``/``action_repeat``/
        ``seed``, or an unknown keyword (`GymnasiumEnv`'s message).
      ValueError: a count below 1, a bad ``obs``/override/``autoreset_mode``.
      KeyError: an unknown environment name.
    """
    _count("threads", 1 if threads is None else threads)
    _count("action_repeat", action_repeat)
    _autoreset_mode(autoreset_mode)
    built = _build(env_name, num_envs, obs, seed, render_mode, overrides)
    return BatchedVectorEnv(
        built, threads=threads, action_repeat=action_repeat, autoreset_mode=autoreset_mode
    )
