"""Options as environments: one gymnasium episode is one option of a learned skill.

`SkillEnv(spec)` turns any `hier_agents.learning.skill_spec.SkillSpec` into a
gymnasium environment for training and evaluating the skill's policy::

    env = SkillEnv("ball", seed=0)            # or SkillEnv(spec(...)); "arm"
    obs, info = env.reset(seed=0)
    obs, reward, terminated, truncated, info = env.step(env.action_space.sample())

* **Scenes**: every reset asks the spec's `SceneSource` for an option start
  (a level or game mid-way, a subgoal from a planner; sources seeded by
  ``reset(seed=...)``); ``heldout=True`` uses the spec's held-out scenes.
* **Observation**: the skill's ``features`` (float32, ``len(FEATURES)``,
  clipped to ``[-spec.feature_bound, spec.feature_bound]``), computed from the
  scene estimate, the subgoal and the public description: exactly what the
  skill's policy sees at run time.
* **Action**: the policy's action (``[-1, 1]^ACTION_DIM``); the skill maps
  it to the environment's (`LearnedSkill.env_action`). While no estimate can
  be made the skill holds still instead, as the option runner does.
* **Termination**: the option runner's (`hier_agents.modular.options`):
  ``terminated`` when the option is reached or failed; ``truncated`` when it
  is cut off at ``t_abs`` or interrupted by the episode's end.
* **Reward**: the spec's rule (``spec.reward``: success reward, penalties by
  failure reason, a cost per control step).

``info``: ``status`` (``"running"``, ``"reached"``, ``"failed"``, ``"cut
off"``, ``"interrupted"``), ``reason``, ``source``, ``steps`` (this
option's control steps), ``is_success`` (at the end), ``expert_action``
(the teacher's policy-space action for the current observation, for
cloning and comparison), ``sim_steps`` (every control step simulated since
the last seeded reset, scene set-up included: the honest frame count).
``env.privileged`` is True when the estimator reads the simulator.

Registered with gymnasium by `hier_agents.learning` (importing this module
imports it): ``gymnasium.make("options/ball-push")`` (the ball skill) and
``"options/arm-touch"`` (the arm's touch skill) after ``import
hier_agents.learning``, or ``gymnasium.make("hier_agents.learning:options/ball-push")``
without it; keyword arguments go to `SkillEnv`.
"""

from __future__ import annotations

import gymnasium
import numpy as np
from gymnasium import spaces

from hier_agents.estimators.base import EstimationError
from hier_agents.learning.skill_spec import OptionStart, SceneSource, SkillSpec, spec as spec_named
from hier_agents.modular.families import adapter_for
from hier_agents.modular.options import Outcome, OptionRunner

__all__ = ["SkillEnv"]


class SkillEnv(gymnasium.Env):
    """One option of a learned skill per episode (module docstring).

    Args:
      skill_spec: a `SkillSpec` or its name (``"ball"``, ``"arm"``).
      estimator: one of ``skill_spec.estimators`` (None: the first).
      t_abs: control steps before the option is cut off (None: the spec's).
      heldout: draw scenes from the spec's held-out source.
      seed: seeds the scene source (also ``reset(seed=...)``).
    """

    metadata = {"render_modes": []}

    def __init__(
        self,
        skill_spec: SkillSpec | str,
        *,
        estimator: str | None = None,
        t_abs: int | None = None,
        heldout: bool = False,
        seed: int | None = None,
    ):
        super().__init__()
        self.spec_ = spec_named(skill_spec) if isinstance(skill_spec, str) else skill_spec
        spec = self.spec_
        self.estimator_name = estimator or spec.estimators[0]
        if self.estimator_name not in spec.estimators:
            raise ValueError(
                f"estimator must be one of {list(spec.estimators)} for the "
                f"{spec.name} skill, got {estimator!r}"
            )
        #: True when the scene estimate reads the simulator.
        self.privileged = spec.is_privileged(self.estimator_name)
        self.t_abs = int(t_abs if t_abs is not None else spec.t_abs)
        self.heldout = bool(heldout)
        self.skill = spec.make_skill(None)
        bound = spec.feature_bound
        self.observation_space = spaces.Box(-bound, bound, (len(self.skill.FEATURES),), np.float32)
        self.action_space = spaces.Box(-1.0, 1.0, (self.skill.ACTION_DIM,), np.float32)
        self._runner = OptionRunner(self.skill, t_abs=self.t_abs)
        self._seed = seed
        self._rng = np.random.default_rng(seed)
        self._source: SceneSource | None = None
        self._start: OptionStart | None = None
        self._scene = None
        self._obs = np.zeros(self.observation_space.shape, np.float32)

    @property
    def sim_steps(self) -> int:
        """Control steps simulated since the last seeded reset (set-up included)."""
        return 0 if self._source is None else int(self._source.sim_steps)

    @property
    def source(self):
        """The scene source (built at the first reset)."""
        return self._source

    def reset(self, *, seed=None, options=None):
        super().reset(seed=seed)
        if seed is not None or self._source is None:
            if seed is not None:
                self._seed = seed
            self._rng = np.random.default_rng(self._seed)
            if self._source is not None:
                self._source.close()
            make = self.spec_.heldout if self.heldout else self.spec_.scenes
            self._source = make(int(self._rng.integers(2**31)), self.estimator_name)
        for _ in range(100):
            if self._start_option():
                break
        else:
            raise RuntimeError(f"{self.spec_.name}: no option could be started in 100 tries")
        return self._obs.copy(), self._info(None)

    def _start_option(self) -> bool:
        assert self._source is not None  # reset() made it before starting an option
        start = self._source.start(self._rng)
        if start is None:
            return False
        self._start, self._scene = start, start.scene
        self._runner.adapter = adapter_for(start.description)
        if start.fresh:
            self.skill.forget_history()
        self._runner.start(start.description, start.subgoal, start.scene)
        if self._runner.act(start.timestep, start.scene) is None:
            return False  # ended at once (an unreachable or already-done subgoal)
        self._obs = self._features()
        return True

    def step(self, action):
        if self._start is None:
            raise RuntimeError("call reset() before step()")
        if not self._runner.running:
            raise RuntimeError("the option is over: call reset()")
        start = self._start
        if self._scene is None:
            command = self.skill.hold()
        else:
            policy_action = np.clip(np.asarray(action, np.float64).reshape(-1), -1.0, 1.0)
            command = self.skill.env_action(policy_action)
        timestep = start.env.step(command)
        start.timestep = timestep
        try:
            self._scene = start.estimator.estimate(timestep)
        except EstimationError:
            self._scene = None
        running = self._runner.act(timestep, self._scene) is not None
        if self._scene is not None:
            self._obs = self._features()
        result = None if running else self._runner.result
        reward = self.spec_.reward(result)
        terminated = result is not None and result.outcome in (Outcome.REACHED, Outcome.FAILED)
        truncated = result is not None and not terminated
        if result is not None:
            self._source.end(
                result.outcome in (Outcome.REACHED, Outcome.CUT_OFF) and not timestep.last()
            )
        return self._obs.copy(), float(reward), terminated, truncated, self._info(result)

    def _features(self) -> np.ndarray:
        bound = self.spec_.feature_bound
        return np.clip(self.skill.features, -bound, bound).astype(np.float32)

    def _info(self, result) -> dict:
        assert self._start is not None  # only called once an option has started
        teacher = self.skill.teacher_action
        info = {
            "status": "running" if result is None else result.outcome.value,
            "reason": None if result is None else result.reason,
            "source": self._start.source,
            "steps": self._runner.duration,
            "is_success": bool(result is not None and result.reached),
            "sim_steps": self.sim_steps,
        }
        if teacher is not None:
            info["expert_action"] = np.asarray(teacher, np.float32)
        return info

    def close(self) -> None:
        if self._source is not None:
            self._source.close()
            self._source = None
