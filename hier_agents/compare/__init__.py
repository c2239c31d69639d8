"""Modular and end-to-end agents compared over seeds, from one spec file.

    python -m hier_agents.compare experiments/mujoban.toml            # local pool
    python -m hier_agents.compare experiments/mujoban.toml --plan     # the jobs, nothing run
    python -m hier_agents.compare experiments/mujoban.toml --backend ray --ray-address auto

The spec (`hier_agents.compare.spec`) names environments, agents (modular
variants by component names, end-to-end training conditions with their
observations, random actions), frame budgets, seeds and evaluation episodes.
The command plans the training and evaluation jobs
(`hier_agents.compare.jobs`), runs those not in the cache on a local pool of
processes or a Ray cluster (`hier_agents.compare.backends`), and writes
``comparison.json`` (points with statistics across seeds, per-seed values,
CPU hours, provenance), ``comparison.txt`` (the table) and
``comparison.png`` (one panel per environment) into the cache folder
(`hier_agents.compare.report`). Finished jobs are cached by a key of their
inputs: a killed experiment continues where it stopped, an extended one runs
only its new jobs, and a re-run with a warm cache rewrites nothing. The key
leaves out the code: every record keeps the commit it ran at, and
``comparison.json`` counts them (``code_versions``; the command warns when
there is more than one). To run jobs again after a change that matters,
delete their records, ``CACHE/jobs/KEY.json`` (``--plan`` lists the keys).
"""

__all__ = ["jobs", "spec", "backends", "report"]
