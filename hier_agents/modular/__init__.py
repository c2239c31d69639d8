"""The modular agent: estimator -> planner -> option runner -> skill.

* `hier_agents.modular.agent`: `ModularAgent`, the policy over options;
* `hier_agents.modular.components`: planners, skills and estimators by name
  (`make_agent`).
"""
