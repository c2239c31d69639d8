"""End-to-end baselines (`hier_agents.baselines.impala`)."""
