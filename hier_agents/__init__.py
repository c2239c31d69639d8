"""Agents: estimators, the observation boundary, the option layer, modular and
end-to-end agents.

* `hier_agents.estimators`: observations -> scene estimates (``camera``,
  ``board``; the privileged ``oracle`` and ``entity-layer``);
* `hier_agents.boundary`: `BoundaryEnv`, what an agent may hold of an
  environment;
* `hier_agents.option_layer`: `ModularAgent` and `run_option`;
* `hier_agents.components`: the parts by name; `hier_agents.run`: the CLI;
* `hier_agents.impala`, `hier_agents.train`: the end-to-end baselines.
"""
