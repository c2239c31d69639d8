"""Learning over the modular stack.

* `hier_agents.learning.option_env`: `OptionEnv`, the whole task as a
  semi-MDP (one step = one option), for learned policies over options;
* `hier_agents.learning.skill_env`: one option as an episode, for learned
  skills (``options/ball-push``);
* `hier_agents.learning.train_skill`, `hier_agents.learning.train_options`:
  the trainers.
"""
