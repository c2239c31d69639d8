"""Learning over the modular stack.

* `hier_agents.learning.option_env`: `OptionEnv`, the whole task as a
  semi-MDP (one step = one option), for learned policies over options;
* `hier_agents.learning.skill_env`: one option as an episode, for learned
  skills (``options/ball-push``, ``options/arm-touch``);
* `hier_agents.learning.train_skill`, `hier_agents.learning.train_options`:
  the trainers.

Importing this package registers the option environments with gymnasium
(``OPTION_IDS``): ``gymnasium.make("options/ball-push")`` after ``import
hier_agents.learning``, or ``gymnasium.make("hier_agents.learning:options/ball-push")``
in gymnasium's ``module:id`` form without it. Nothing heavy is imported
until an environment is made.
"""

import gymnasium as _gymnasium

#: Gymnasium ids of the option environments -> `SkillEnv` keyword arguments.
OPTION_IDS = {
    "options/ball-push": {"skill_spec": "ball"},
    "options/arm-touch": {"skill_spec": "arm"},
}

for _id, _kwargs in OPTION_IDS.items():
    if _id not in _gymnasium.envs.registration.registry:
        _gymnasium.register(
            _id, entry_point="hier_agents.learning.skill_env:SkillEnv", kwargs=_kwargs
        )
