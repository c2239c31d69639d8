"""Learned skills, beside the scripted ones.

* `LearnedBallSkill` (``--skill learned-ball``): MuJoBan's ball skill with
  the scripted geometry (legs, pursuit carrot, speed profile, box contact,
  status) and a learned low-level controller (carrot and speed target ->
  [roll, steer]), trained on the ``ball`` skill spec
  (`hier_agents.learning.skills.ball`) by ``python -m
  hier_agents.learning.train_skill ball``. The trained checkpoint ships as
  ``skills/learned/ball_policy.pt``. See `skills.learned.ball`.
"""

from skills.learned.ball import (
    FEATURES,
    POLICY_PATH,
    LearnedBallSkill,
    LearnedDrive,
    NumpyPolicy,
    env_action,
    load_policy,
    policy_action,
)

__all__ = [
    "LearnedBallSkill",
    "LearnedDrive",
    "NumpyPolicy",
    "FEATURES",
    "POLICY_PATH",
    "load_policy",
    "env_action",
    "policy_action",
]
