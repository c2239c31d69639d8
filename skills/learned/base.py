"""`LearnedSkill`: the contract every learned skill keeps.

A learned skill is a `skills.base.Skill` whose motor command comes from a
policy ``features -> policy action``. It keeps the same `Skill` API (``reset``,
``act``, ``hold``, ``status``, ``failure_reason``), so the option runner,
the agent and the benchmarks run it like a scripted skill, and adds:

* ``features`` (float32 array, ``len(FEATURES)``): the policy's observation
  computed at the last ``act`` from the subgoal, the scene estimate and the
  public description (never the simulator);
* ``teacher_action`` (float32, policy space) or None: what the skill's
  teacher (a scripted skill) would do at the last ``act``, for behaviour
  cloning, DAgger and comparison;
* ``env_action(policy_action) -> action``: the fixed map from the policy's
  output to the environment's action (clipped to its bounds);
* ``policy``: a callable ``features -> policy action``, ``"teacher"`` (act
  as the teacher), or None (*record only*: ``act`` computes ``features``,
  ``teacher_action`` and ``status`` and returns ``hold()``; whoever drives
  the skill supplies the action: the skill-training environment);
* ``training_frames``: control steps simulated to train the policy (0 when
  not learned);

``FEATURES`` (a class attribute: the names of the feature entries) is what a
checkpoint is checked against (`skills.learned.policy.load_policy`).
"""

from __future__ import annotations

import numpy as np

from skills.base import Skill

__all__ = ["LearnedSkill"]


class LearnedSkill(Skill):
    """Base class of learned skills (module docstring)."""

    FEATURES: tuple[str, ...] = ()
    #: Size of the policy's action.
    ACTION_DIM: int = 0

    def __init__(self, policy=None) -> None:
        super().__init__()
        self.policy = policy

    @property
    def record_only(self) -> bool:
        return self.policy is None

    @property
    def features(self) -> np.ndarray:
        raise NotImplementedError

    @property
    def teacher_action(self) -> np.ndarray | None:
        return None

    def env_action(self, policy_action) -> np.ndarray:
        raise NotImplementedError

    @property
    def training_frames(self) -> int:
        """Control steps simulated to train the policy: the checkpoint's
        ``sim_steps`` (scene set-up included), else its ``frames``; 0 when the
        policy is not a trained checkpoint."""
        meta = getattr(self.policy, "meta", None) or {}
        return int(meta.get("sim_steps", meta.get("frames", 0)))
