"""Agents: estimators, the observation boundary, the option layer, modular and
end-to-end agents.

* `hier_agents.estimators`: observations -> scene estimates (``camera``,
  ``board``; the privileged ``oracle`` and ``entity-layer``);
* `hier_agents.boundary`: `BoundaryEnv`, what an agent may hold of an
  environment;
* `hier_agents.modular`: `ModularAgent`, the option runner, the parts by name (`components`);
* `hier_agents.learning`: option and skill environments, trainers; `hier_agents.run`: the CLI;
* `hier_agents.baselines.impala`, `hier_agents.train`: the end-to-end baselines.
"""
