"""`SkillSpec`: everything the skill trainer needs to know about one learned skill.

One spec per learned skill; the trainer (``python -m
hier_agents.learning.train_skill SPEC``), the skill environment
(`hier_agents.learning.skill_env.SkillEnv`) and the evaluation take any spec.
A spec names:

* ``make_skill(policy)``: the `skills.learned.base.LearnedSkill` (its
  ``FEATURES`` and ``ACTION_DIM`` are the observation and action of the
  policy; ``policy=None`` gives the record-only skill the environment drives);
* ``scenes(seed, estimator)`` / ``heldout(seed, estimator)``: a `SceneSource`
  for training and one for evaluation (other seeds, other levels);
* the success rule: ``+success_reward`` when the option is reached (the
  option runner's rules: the skill's status, the family adapter);
  ``penalties`` maps failure-reason prefixes to a reward (other failures end
  the option with the step cost only); ``step_cost`` per control step;
* ``t_abs``: control steps before the option is cut off (truncated);
* ``family``: the game family whose estimator table
  (`hier_agents.modular.components.ESTIMATORS`) names ``estimators``, the
  scene estimators the scenes can use (the first the default); whether one
  reads the simulator is decided there (`components.is_privileged`); a spec
  outside the families (``family=""``) has no privileged estimator;
* ``checkpoint``: the shipped policy's path (used when ``--skill`` names the
  skill without a path).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any, Callable, Protocol

import numpy as np

if TYPE_CHECKING:
    from abstract_planners.base import Subgoal
    from hier_agents.estimators.base import Estimator
    from skills.learned.base import LearnedSkill

__all__ = ["SkillSpec", "SceneSource", "OptionStart", "SPECS", "spec", "register"]


class OptionEnvironment(Protocol):
    """The environment an option runs in: ``step(action) -> timestep``."""

    def step(self, action: np.ndarray) -> Any: ...


@dataclass
class OptionStart:
    """Where an option starts: the environment (``step(action) -> timestep``),
    the estimator (reset for this episode), the public ``description``, the
    current ``timestep`` and ``scene`` (its estimate), and the ``subgoal``."""

    env: OptionEnvironment
    estimator: Estimator
    description: Any  # the family's public description
    timestep: Any  # a dm_env.TimeStep
    scene: Any  # the estimator's estimate
    subgoal: Subgoal
    #: A name for logs and tables (``"mujoban/level3-pegs"``, ``"mujoxo/optimal"``).
    source: str = ""
    #: True when the skill did not see the frames before this start (a new
    #: level or a scripted fast-forward): no history (rates) on its first step.
    fresh: bool = True


class SceneSource(Protocol):
    """Makes option starts: ``start(rng)`` returns an `OptionStart` or None
    (nothing usable this try; the caller tries again); ``end(result)`` is told
    how the option ended (a source may continue from there); ``close()``
    frees the environments. ``sim_steps`` counts every control step it
    simulated (scene set-up included)."""

    sim_steps: int

    def start(self, rng: np.random.Generator) -> OptionStart | None: ...

    def end(self, succeeded_or_cut_off: bool) -> None: ...

    def close(self) -> None: ...


@dataclass(frozen=True)
class SkillSpec:
    """One learned skill (module docstring)."""

    name: str
    make_skill: Callable[[Any], LearnedSkill]
    scenes: Callable[[int, str], SceneSource]
    heldout: Callable[[int, str], SceneSource]
    checkpoint: Path
    t_abs: int
    estimators: tuple[str, ...]
    family: str = ""
    success_reward: float = 1.0
    penalties: dict = field(default_factory=dict)
    step_cost: float = -0.002
    #: The registry name of the learned skill (``--skill``).
    skill_name: str = ""
    #: Features are clipped to [-feature_bound, feature_bound].
    feature_bound: float = 4.0

    def is_privileged(self, estimator: str) -> bool:
        """Whether the named estimator reads the simulator."""
        if not self.family:
            return False
        from hier_agents.modular.components import is_privileged

        return is_privileged(self.family, estimator)

    def reward(self, result) -> float:
        """The reward of one control step: the step cost, plus, when the
        step ended the option (``result``: its
        `hier_agents.modular.options.OptionResult`; None while running), the
        success reward if reached or the penalty of the failure's reason."""
        from hier_agents.modular.options import Outcome

        reward = self.step_cost
        if result is None:
            return reward
        if result.outcome is Outcome.REACHED:
            reward += self.success_reward
        elif result.outcome is Outcome.FAILED:
            for prefix, penalty in self.penalties.items():
                if str(result.reason).startswith(prefix):
                    reward += penalty
                    break
        return reward


#: name -> spec: the shipped ones (`hier_agents.learning.skills`, loaded on
#: first use) and any added with `register`.
SPECS: dict[str, SkillSpec] = {}
_shipped_loaded = False


def _load_shipped() -> None:
    global _shipped_loaded
    if not _shipped_loaded:
        from hier_agents.learning.skills import register_all

        shipped: dict[str, SkillSpec] = {}
        register_all(shipped)
        for name, value in shipped.items():
            SPECS.setdefault(name, value)
        _shipped_loaded = True


def register(skill_spec: SkillSpec) -> SkillSpec:
    """Adds ``skill_spec`` under its name (replacing one of the same name) so
    that the trainer and `SkillEnv` find it by name; returns it."""
    _load_shipped()
    SPECS[skill_spec.name] = skill_spec
    return skill_spec


def spec(name: str) -> SkillSpec:
    """The skill spec named ``name`` (``"ball"``, ``"arm"``, or one added with
    `register`); ValueError if unknown."""
    _load_shipped()
    if name not in SPECS:
        raise ValueError(f"unknown skill spec {name!r}; valid: {sorted(SPECS)}")
    return SPECS[name]
