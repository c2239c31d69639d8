"""A fast dm_env runner for composer tasks.

``dm_control.composer.Environment`` calls Python hooks of the task and of every
entity, and updates observables, at *every physics substep*. That is why the
original MuJoBan ran at ~18% of its physics limit. Our tasks are still
composer tasks (entities, MJCF, the lifecycle hooks ``after_compile``,
``initialize_episode``, ``before_step``, ``after_step``, ``get_reward``,
``should_terminate_episode``, ``get_discount``), but this runner:

* compiles the MJCF model **once**; tasks change walls, boxes and colours in
  place at reset instead of recompiling;
* advances all substeps of a control step in **one C call**,
  ``mj_step(model, data, n)`` (``before_substep`` and ``after_substep`` are
  never called: a task that needs them must not use this runner);
* computes observations once per control step, from precomputed indices
  (``PhysicsTask.observe``), and renders only the cameras that are enabled,
  only when an observation is built -- or, with ``lazy_cameras=True``, only
  when an agent reads the frame (`LazyObservation`).

Every random draw comes from one ``np.random.Generator`` seeded by ``seed``.
"""

from __future__ import annotations

import abc
import math
from typing import Any, Mapping, Sequence

from envs import _gl  # noqa: F401

import dm_env
import mujoco
import numpy as np
from dm_control import composer, mjcf
from dm_control.rl import control
from dm_env import specs

from envs import _malloc
from envs.profile import PROFILE
from envs.rendering import CameraConfig, Cameras, Marker

_BADQACC = int(mujoco.mjtWarning.mjWARN_BADQACC)
_MID = dm_env.StepType.MID
_FLOAT64 = np.dtype(np.float64)


def episode_seed(seed: int, episode: int) -> int:
    """The seed of episode ``episode`` (>= 0) of a run seeded ``seed`` (>= 0):
    a 32-bit integer from ``np.random.SeedSequence([seed, episode])``, the one
    derivation used for environments, agents and planners, so that an
    episode's draws do not depend on the episodes played before it."""
    return int(np.random.SeedSequence([int(seed), int(episode)]).generate_state(1)[0])


class PhysicsTask(composer.Task, abc.ABC):
    """A composer task with the fast-path observation contract.

    Subclasses implement the composer hooks they need plus:

    * ``observation_spec()``: specs of the non-camera observations;
    * ``observe(physics)``: those observations, computed once per control step;
    * ``camera_configs``: the enabled camera observations by name.

    Hooks receive a ``np.random.Generator`` as ``random_state``.
    """

    #: Episode length in control steps (the time limit).
    time_limit_steps: int = 1000
    #: Camera that `render()` and gymnasium's rgb_array frames show by default.
    main_camera: str = "top_camera"
    #: (height, width) of `Environment.render` frames by default (a task keeps
    #: the size it was given; `envs.load` checks it is a pair).
    render_size: tuple[int, ...] = (256, 256)
    #: Observation keys that are ground truth from the simulator or the
    #: referee, not what a robot's cameras and joint sensors give (MuJoBan's
    #: entity and pixel layers, the board games' board and move record).
    #: The one place this fact lives: `envs.GymnasiumEnv` leaves these keys
    #: out of its default observation and prefixes them ``privileged/``.
    privileged_observations: frozenset[str] = frozenset()
    #: The privileged keys that hold the task's abstract state (the puzzle's
    #: cells, the board), in the order `envs.GymnasiumEnv`'s ``obs="state"``
    #: vector appends them.
    state_observations: tuple[str, ...] = ()

    @property
    def camera_configs(self) -> Mapping[str, CameraConfig]:
        return {}

    @abc.abstractmethod
    def observation_spec(self) -> dict[str, specs.Array]:
        """Specs of the observations returned by ``observe``."""

    @abc.abstractmethod
    def observe(self, physics: mjcf.Physics) -> dict[str, np.ndarray]:
        """Non-camera observations of the current state."""

    @property
    def observables(self):  # composer's per-substep observables are unused
        return {}

    @property
    @abc.abstractmethod
    def succeeded(self) -> bool:
        """Whether the current episode has reached the task's goal (MuJoBan:
        every pad covered; a board game: the agent won). Read at the episode's
        end it is the episode's success (gymnasium's ``info["is_success"]``)."""

    def render_markers(self) -> Sequence[Marker]:
        """Render-only shapes `Environment.render` draws over its frames
        (never in observed camera frames); none by default."""
        return ()

    def on_seed(self, episode: int = 0) -> None:
        """Called when the environment is reseeded: the next episode is
        ``episode`` of the seed's sequence (e.g. a level file restarts at
        its ``episode``-th level)."""

    def truncated_discount(self) -> float:
        """Discount on the last step of an episode cut by the time limit."""
        return 1.0

    def close(self) -> None:
        """Frees the task's external resources (e.g. an opponent's subprocess)."""


class Environment(dm_env.Environment):
    """dm_env interface to a ``PhysicsTask``, stepping physics in one C call.

    Args:
      task: the task to run.
      seed: seed of the environment's random generator (levels, colours,
        initial poses, opponents). ``None`` draws fresh entropy.
      raise_on_physics_error: if False, a diverging simulation ends the
        episode (reward 0, discount 0) instead of raising ``PhysicsError``.
      lazy_cameras: camera frames are rendered when first read from the
        timestep's observation (a `LazyObservation`), not when it is built;
        a frame left unread costs nothing. It must be read before the next
        ``step``/``reset`` (then it raises `StaleObservationError`): agents
        that look at every k-th frame save the rendering of the others. The
        OpenGL context is made for the first frame, not at construction (so
        a process may build the environment and then fork, as gymnasium's
        ``AsyncVectorEnv`` does); without lazy cameras it is made here.
    """

    def __init__(
        self,
        task: PhysicsTask,
        seed: int | None = None,
        *,
        raise_on_physics_error: bool = True,
        lazy_cameras: bool = False,
    ):
        if not isinstance(task, PhysicsTask):
            raise TypeError(f"task must be a PhysicsTask, got {type(task).__name__}")
        self._task = task
        self._closed = False
        # Set by `_build`; None only while building (the constructor raises if that fails).
        self._cameras: Cameras | None = None
        try:
            self._build(task, seed, raise_on_physics_error, lazy_cameras)
        except BaseException:
            # Whatever failed, the task's external resources (a GNU Go
            # subprocess) and any GL context made so far are freed.
            self.close()
            raise

    def _build(self, task, seed, raise_on_physics_error, lazy_cameras) -> None:
        self._rng = np.random.default_rng(seed)
        self._raise_on_physics_error = raise_on_physics_error
        self._physics = mjcf.Physics.from_mjcf_model(task.root_entity.mjcf_model)
        self._physics.legacy_step = False  # for users who call physics.step()
        self._n_sub_steps = task.physics_steps_per_control_step
        self._model, self._data = self._physics.model.ptr, self._physics.data.ptr
        self._warning_counts = self._data.warning.number  # a live view
        task.after_compile(self._physics, self._rng)
        cameras = self._cameras = Cameras(self._physics.model.ptr)
        self._camera_ids = {
            name: (cameras.camera_id(cfg.camera), cfg.height, cfg.width)
            for name, cfg in task.camera_configs.items()
        }
        if not isinstance(lazy_cameras, bool):
            raise TypeError(f"lazy_cameras must be True or False, got {lazy_cameras!r}")
        self._lazy = lazy_cameras and bool(self._camera_ids)
        if not self._lazy:
            for _, height, width in self._camera_ids.values():
                cameras.prepare(height, width)  # GL context now, not in reset
        self._step_count = 0
        self._reset_next_step = True
        self._action_spec = task.action_spec(self._physics)
        self._stamp = 0  # counts observations built; a lazy frame is valid for one

    # -- dm_env API ---------------------------------------------------------

    def reset(self) -> dm_env.TimeStep:
        with PROFILE.section("physics"):
            return self._reset()

    def _reset(self) -> dm_env.TimeStep:
        with self._physics.reset_context():
            self._task.initialize_episode(self._physics, self._rng)
        self._step_count = 0
        self._reset_next_step = False
        return dm_env.restart(self._observation())

    def step(self, action) -> dm_env.TimeStep:
        with PROFILE.section("physics"):
            return self._step(action)

    def _step(self, action) -> dm_env.TimeStep:
        if self._reset_next_step:
            return self._reset()
        self._begin_step(action)
        return self._end_step(self._advance())

    # A control step in three parts, which `_step` runs in this order and
    # `envs.vector` runs for many environments at once (the `_advance` calls
    # of all of them in worker threads, the other parts in the calling one).

    def _begin_step(self, action) -> None:
        """The part of a step before the physics: checks ``action`` (ValueError:
        wrong shape, not finite) and hands it to the task's ``before_step``.
        The episode must be running (not after a LAST step)."""
        self._task.before_step(self._physics, self._check_action(action), self._rng)

    def _end_step(self, advanced: bool) -> dm_env.TimeStep:
        """The part of a step after the physics: the step's timestep, given
        whether `_advance` went through (False: it diverged, the episode ends
        with reward 0 and discount 0). Runs the task's ``after_step`` and
        builds the observation."""
        task, physics = self._task, self._physics
        if not advanced:
            self._reset_next_step = True
            return dm_env.termination(0.0, self._observation())
        task.after_step(physics, self._rng)
        self._step_count += 1
        reward = task.get_reward(physics)
        observation = self._observation()
        if task.should_terminate_episode(physics):
            self._reset_next_step = True
            return dm_env.TimeStep(
                dm_env.StepType.LAST, reward, task.get_discount(physics), observation
            )
        if self._step_count >= task.time_limit_steps:
            self._reset_next_step = True
            return dm_env.truncation(reward, observation, task.truncated_discount())
        return dm_env.TimeStep(_MID, reward, task.get_discount(physics), observation)

    def observation_spec(self) -> dict[str, specs.Array]:
        spec = dict(self._task.observation_spec())
        for name, (_, height, width) in self._camera_ids.items():
            spec[name] = specs.BoundedArray((height, width, 3), np.uint8, 0, 255, name=name)
        return spec

    def action_spec(self) -> specs.BoundedArray:
        return self._action_spec

    def reward_spec(self) -> specs.Array:
        return specs.Array((), np.float64, name="reward")

    def discount_spec(self) -> specs.BoundedArray:
        return specs.BoundedArray((), np.float64, 0.0, 1.0, name="discount")

    def close(self) -> None:
        """Frees the GL contexts and the task's external resources (a GNU Go
        subprocess). Idempotent; also called by ``with envs.load(...) as env:``
        (dm_env environments are context managers) and when construction fails."""
        if getattr(self, "_closed", True):
            return
        self._closed = True
        try:
            if self._cameras is not None:
                self._cameras.close()
        finally:
            try:
                self._task.close()
            finally:
                _malloc.trim()  # hand the freed GL buffers back

    @property
    def closed(self) -> bool:
        """Whether `close` has been called."""
        return self._closed

    # -- extras -------------------------------------------------------------

    def seed(self, seed: int | None, episode: int | None = None) -> None:
        """Reseeds the random generator; the next ``reset`` starts from it.

        With ``episode``, the next episode is episode ``episode`` of a run
        seeded ``seed``, whatever was played before: the generator is seeded
        with `episode_seed` and a level file moves to its ``episode``-th
        level (modulo its length). Episodes seeded this way can be played in
        any order, in any process, and give the same result.
        """
        if episode is None:
            self._rng = np.random.default_rng(seed)
            self._task.on_seed(0)
        else:
            if seed is None:
                raise ValueError("seeding an episode needs a run seed, got None")
            self._rng = np.random.default_rng(episode_seed(seed, episode))
            self._task.on_seed(int(episode))
        self._reset_next_step = True

    @property
    def physics(self) -> mjcf.Physics:
        return self._physics

    @property
    def task(self) -> PhysicsTask:
        return self._task

    @property
    def control_timestep(self) -> float:
        return self._task.control_timestep

    @property
    def step_count(self) -> int:
        """Control steps taken in the current episode."""
        return self._step_count

    @property
    def random_generator(self) -> np.random.Generator:
        return self._rng

    def description(self):
        """The task's public description (`envs.description`): what an agent
        may know besides its observations. Raises `NotImplementedError` for
        tasks that have none."""
        describe = getattr(self._task, "description", None)
        if describe is None:
            raise NotImplementedError(f"{type(self._task).__name__} has no public description")
        return describe()

    @property
    def privileged_observations(self) -> frozenset[str]:
        """Observation keys that are ground truth, not sensor readings
        (`PhysicsTask.privileged_observations`)."""
        return frozenset(self._task.privileged_observations)

    def render(
        self,
        camera: str | None = None,
        height: int | None = None,
        width: int | None = None,
        *,
        markers: bool = True,
    ) -> np.ndarray:
        """An RGB image (height, width, 3) uint8 of the current state from any
        camera of the model, for people to look at.

        Args:
          camera: a camera name (default: the task's ``main_camera``).
          height, width: pixels (default: the task's ``render_size``, the
            ``render_size`` setting of `envs.load`; larger frames raise
            ValueError).
          markers: draw the task's `PhysicsTask.render_markers` (MuJoBan's
            pegs as discs visible at 256 pixels); observed camera frames
            never show them.
        """
        default_h, default_w = self._task.render_size
        assert self._cameras is not None  # set by the constructor
        return self._cameras.render(
            self._physics.data.ptr,
            camera or self._task.main_camera,
            default_h if height is None else height,
            default_w if width is None else width,
            markers=self._task.render_markers() if markers else (),
        )

    # -- internals ----------------------------------------------------------

    def _advance(self) -> bool:
        """Runs one control step of physics; False if the simulation diverged.

        One ``mj_step(model, data, n_substeps)`` call: exactly the work of the
        physics limit. As in every mj_step-based environment, quantities that
        MuJoCo computes before integrating (body poses ``xpos``/``xmat``,
        sensors) describe the start of the last substep (5 ms old); ``qpos``
        and ``qvel`` are current. Divergence is MuJoCo's bad-acceleration
        warning, after which MuJoCo has reset the state.

        Touches only this environment's ``mjData`` (and reads its own
        ``mjModel``), so environments may advance in parallel threads:
        ``mj_step`` releases the GIL.
        """
        warnings = self._warning_counts
        before = warnings[_BADQACC]
        mujoco.mj_step(self._model, self._data, self._n_sub_steps)
        if warnings[_BADQACC] > before:
            message = (
                f"physics diverged at t={self._data.time:.3f}s (MuJoCo warning "
                f"{mujoco.mjtWarning.mjWARN_BADQACC.name})"
            )
            self._reset_next_step = True
            if self._raise_on_physics_error:
                raise control.PhysicsError(message)
            return False
        return True

    def _check_action(self, action: Any) -> np.ndarray:
        if type(action) is not np.ndarray or action.dtype is not _FLOAT64:
            action = np.asarray(action, dtype=np.float64)
        if action.shape != self._action_spec.shape:
            raise ValueError(
                f"action must have shape {self._action_spec.shape}, got {action.shape}"
            )
        # A Python sum of a few floats is several times cheaper than a numpy
        # reduction; NaN and inf propagate through it.
        if not math.isfinite(sum(action.tolist())):
            raise ValueError(f"action must be finite, got {action}")
        return action

    def _observation(self) -> Mapping[str, np.ndarray]:
        obs = self._task.observe(self._physics)
        self._stamp += 1
        if self._lazy:
            return LazyObservation(obs, self, self._stamp)
        if self._camera_ids:
            data, cameras = self._data, self._cameras
            assert cameras is not None  # set by the constructor
            for name, (cam_id, height, width) in self._camera_ids.items():
                obs[name] = cameras.render(data, cam_id, height, width)
        return obs

    def _render_camera(self, name: str, stamp: int) -> np.ndarray:
        if stamp != self._stamp:
            raise StaleObservationError(
                f"the {name!r} frame of an earlier timestep was read after the environment "
                f"stepped on; with lazy_cameras=True read camera frames before the next "
                f"step (or build the environment with lazy_cameras=False)"
            )
        cam_id, height, width = self._camera_ids[name]
        assert self._cameras is not None  # set by the constructor
        return self._cameras.render(self._data, cam_id, height, width)


class StaleObservationError(RuntimeError):
    """A lazy camera frame was read after its environment stepped on."""


class KeyedView(Mapping):
    """A read-only mapping over the keys in ``self._keys`` (subclasses set it
    and define ``__getitem__``)."""

    _keys: tuple

    def __iter__(self):
        return iter(self._keys)

    def __len__(self) -> int:
        return len(self._keys)

    def __contains__(self, key) -> bool:
        return key in self._keys


class LazyObservation(KeyedView):
    """A timestep's observations whose camera frames render on first read.

    Behaves as a read-only mapping (``obs["top_camera"]``, iteration, ``len``,
    ``dict(obs)``, which reads, and so renders, every frame). Non-camera
    observations are computed when it is built, as without lazy cameras.
    """

    __slots__ = ("_values", "_env", "_stamp", "_keys")

    def __init__(self, values: dict, env: Environment, stamp: int):
        self._values, self._env, self._stamp = values, env, stamp
        self._keys = tuple(values) + tuple(env._camera_ids)  # pylint: disable=protected-access

    def __getitem__(self, key):
        try:
            return self._values[key]
        except KeyError:
            if key not in self._env._camera_ids:  # pylint: disable=protected-access
                raise
        frame = self._env._render_camera(key, self._stamp)  # pylint: disable=protected-access
        self._values[key] = frame
        return frame

    def rendered(self, key) -> bool:
        """Whether frame ``key`` has been rendered (read) already."""
        return key in self._values

    def __repr__(self) -> str:
        shown = {
            k: ("<rendered>" if k in self._values else "<not rendered>")
            if k in self._env._camera_ids
            else self._values[k]  # pylint: disable=protected-access
            for k in self._keys
        }
        return f"LazyObservation({shown})"
