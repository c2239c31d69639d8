"""Modular and end-to-end agents compared over seeds, from one spec file.

    python -m hier_agents.compare experiments/mujoban.toml            # local pool
    python -m hier_agents.compare experiments/mujoban.toml --plan     # the jobs, nothing run
    python -m hier_agents.compare experiments/mujoban.toml --reevaluate   # every evaluation again
    python -m hier_agents.compare experiments/mujoban.toml --agent "random, held 10" --reevaluate
    python -m hier_agents.compare experiments/mujoban.toml --check 2  # replay 2 episodes a point
    python -m hier_agents.compare SPEC --agent LABEL --seed 0 --env mujoban/level1 --retrain
    python -m hier_agents.compare experiments/mujoban.toml --backend ray --ray-address auto

The spec (`hier_agents.compare.spec`) names environments, agents (modular
variants by component names, end-to-end agents by their trainer's table,
``train`` for IMPALA or ``sb3`` for Stable-Baselines3
(`hier_agents.compare.trainers`), random actions), frame budgets, seeds and
evaluation episodes. The command plans the training and evaluation jobs
(`hier_agents.compare.jobs`), runs those not done on a local pool of
processes or a Ray cluster (`hier_agents.compare.backends`), and writes
``comparison.json`` (points with the mean and the IQM across seeds of the
environment family's metric, MuJoBan's success or the board games' game
score, and their intervals, aggregates across environments, per-seed values, CPU
hours, provenance), ``comparison.txt`` (the table) and ``comparison.png``
(learning curves, one panel per environment and one for the aggregate)
into the cache folder (`hier_agents.compare.report`, `hier_agents.compare.plot`,
`hier_agents.stats`).

Finished jobs are cached by a key of their inputs: a killed experiment
continues where it stopped, an extended one runs only its new jobs, and a
re-run with a warm cache rewrites nothing. A training series (trainer,
environment, table, seed) has one run directory keyed by the series, not
its budgets: a larger budget resumes the run from its last checkpoint, and
the evaluations of the budgets already done keep their keys. A training
whose kept budget checkpoints are on disk counts as done (a clone of a
cache whose checkpoints were committed); ``--reevaluate`` runs every
evaluation again and ``--retrain`` trains every series again from zero;
``--check EPISODES`` replays the first episodes of every point from the
shipped checkpoints and compares them with the records
(`hier_agents.compare.check`). The
key leaves out the code: every record keeps the commit it ran at, and
``comparison.json`` counts them (``code_versions``; the command warns when
there is more than one). To run jobs again after a change that matters,
delete their records, ``CACHE/jobs/KEY.json`` (``--plan`` lists the keys).
"""

__all__ = ["jobs", "spec", "backends", "report", "trainers", "migrate", "check", "plot"]
