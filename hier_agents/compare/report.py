"""An experiment's results: points with statistics across seeds, aggregates
across environments, the costs and the table.

A point is one agent in one environment at one training budget (trained
agents: each budget; modular agents: the frames their learned parts were
trained on, 0 when scripted; random agents: 0). Per seed, its value is the
mean over that seed's episodes of the environment family's per-episode
metric (`hier_agents.modular.families.FamilyAdapter.episode_score`, the one
place that chooses it): MuJoBan's **success** (1 solved, 0 not: the share
solved), the board games' **game score** (1 for a win, 1/2 for a draw, 0
for a loss; against MuJoXO's optimal opponent nobody wins, so a win rate
would be 0 for every agent). Board-game points add the shares of games
won, drawn and lost, and of the lost those still running at the time limit
(``outcomes``). Across seeds (`hier_agents.stats`,
10,000 resamples, seeded):

* the **mean** over seeds with a 95% percentile-bootstrap interval over the
  per-seed rates (`hier_agents.stats.bootstrap_interval`);
* the **IQM** (interquartile mean, `hier_agents.stats.iqm`) over seeds with
  a 95% **stratified bootstrap** interval
  (`hier_agents.stats.stratified_interval`): the strata are the seeds; each
  resample draws every seed's episodes with replacement within that seed,
  recomputes each seed's mean score, and takes the IQM over the seeds;
* the per-seed values and a pooled interval over all episodes: Wilson's
  (``pooled_wilson_interval``) for a 0/1 metric, else a percentile
  bootstrap of the mean over every episode's score
  (``pooled_bootstrap_interval``).

An **aggregate** per agent (and budget) over the spec's environments where
it has a point, rliable-style (`aggregates`): the mean and the IQM over
every run (one per environment and seed), with 95% intervals from a
stratified bootstrap whose strata are the environments (each resample draws
every environment's runs with replacement within it:
`hier_agents.stats.aggregate_interval`); environments whose metrics differ
are never aggregated together.

Series also report the CPU hours their jobs cost (`series_cost`): training,
summed over seeds, each seed's run counted over every resumed part (the
train job's ``series_cpu_s``, or its trainer's ``cpu_s`` counter; else the
record's ``cpu_s``, which covers only the attempt that finished, counted in
``cpu_partial_jobs`` and marked ``>=`` in the table), and evaluation.

The plot of the points is `hier_agents.compare.plot`.
"""

from __future__ import annotations


from hier_agents.agents.base import SOURCE
from hier_agents.modular.families import env_adapter
from hier_agents.stats import (
    aggregate_interval,
    bootstrap_interval,
    iqm,
    stratified_interval,
    wilson_interval,
)

#: The table's, the JSON's and the plot's words for the statistics.
STATISTICS = (
    "mean over seeds [95% percentile bootstrap over the per-seed rates]; IQM over seeds "
    "[95% stratified bootstrap: each seed's episodes resampled within that seed, the "
    "per-seed rates recomputed, the IQM over seeds]; 10,000 resamples, seeded"
)
AGGREGATE = (
    "over environments, rliable-style: mean and IQM over all runs (one per environment and "
    "seed) [95% stratified bootstrap: runs resampled within each environment]"
)


def metrics(envs) -> dict:
    """Environment -> its metric, ``"NAME: DEFINITION"`` (the JSON's
    ``metric``; `hier_agents.modular.families.FamilyAdapter.metric`)."""
    return {e: f"{env_adapter(e).metric}: {env_adapter(e).metric_definition}" for e in envs}


def _headings(envs) -> list[str]:
    """The distinct metric headings of ``envs``, in order."""
    return list(dict.fromkeys(env_adapter(e).metric_heading for e in envs))


def _observations(agent, env: str, summary: dict) -> tuple[str, bool]:
    """What a point's agent observed on ``env``, in words (with "; policy
    sampled" for an agent evaluated with ``stochastic``), and whether it was
    privileged, from the evaluation summary (`hier_agents.run.run`); a
    modular agent's from its estimator (`components.access`)."""
    if agent.kind == "random":
        return "none", False
    if agent.kind == "modular":
        from hier_agents.modular.components import access, family

        name = summary.get("estimator", "?")
        # The registry's word, also for records made before summaries said it.
        reads = access(family(env), name) if name != "?" else summary.get("reads")
        if reads not in SOURCE and summary.get("privileged"):
            reads = "simulator"  # a record made before summaries said what it read
        if reads in SOURCE:
            return f"{SOURCE[reads]} via the {name} estimator (PRIVILEGED) + proprioception", True
        return f"cameras + proprioception ({name} estimator)", False
    keys = summary.get("observations") or []
    privileged = bool(summary.get("privileged"))
    text = (", ".join(keys) if keys else "?") + (" (PRIVILEGED)" if privileged else "")
    if agent.stochastic:  # evaluated with its policy sampled, not its mean
        text += "; policy sampled"
    return text, privileged


def points(spec, jobs, records) -> list[dict]:
    """The comparison's points, in the spec's agent order then environment
    and budget; a seed with a missing shard is left out of its point (and
    named in ``missing_seeds``), a point without any complete seed is left out."""
    grouped: dict[tuple, dict[int, list]] = {}
    summaries: dict[tuple, dict] = {}
    for job in jobs:
        record = records.get(job.key)
        p = job.point
        if record is None or job.kind == "train":
            continue
        where = (p["agent"], p["env"], p.get("budget"))
        grouped.setdefault(where, {}).setdefault(p["seed"], []).extend(record["result"]["rows"])
        summaries.setdefault(where, record["result"]["summary"])
    out = []
    for agent in spec.agents:
        for env in agent.envs:
            for budget in agent.budgets_for(env):
                where = (agent.label, env, budget)
                seeds = grouped.get(where, {})
                complete = {s: rows for s, rows in seeds.items() if len(rows) == agent.episodes}
                if complete:
                    out.append(_point(agent, env, budget, complete, summaries[where]))
    return out


def _point(agent, env: str, budget, complete: dict, summary: dict) -> dict:
    """One point from its complete seeds' rows (seed -> rows) and an
    evaluation summary (`hier_agents.run.run`): per seed the mean of its
    episodes' scores (``env``'s family's `episode_score`), the statistics
    over seeds (module docstring) and, for games, ``outcomes``: the shares
    of all episodes won, drawn and lost, and lost unfinished at the time
    limit (`outcome_shares`)."""
    family = env_adapter(env)
    scores = [[family.episode_score(r) for r in rows] for _, rows in sorted(complete.items())]
    per_seed = {s: sum(x) / len(x) for s, x in zip(sorted(complete), scores)}
    values = list(per_seed.values())
    pooled = [x for seed in scores for x in seed]
    episodes = len(pooled)
    observed, privileged = _observations(agent, env, summary)
    frames = int(summary.get("training_frames", budget or 0) or 0)
    point = {
        "agent": agent.label,
        "kind": agent.kind,
        "env": env,
        "budget": budget,
        "training_frames": frames,
        "seeds": list(per_seed),
        "per_seed": [round(v, 6) for v in values],
        "missing_seeds": sorted(set(agent.seeds) - set(per_seed)),
        "episodes_per_seed": agent.episodes,
        "mean": sum(values) / len(values),
        "mean_interval": list(bootstrap_interval(values)),
        "iqm": iqm(values),
        "iqm_interval": list(stratified_interval(scores, "iqm")),
        **_pooled_interval(family, pooled),
        "mean_steps": sum(r["steps"] for rows in complete.values() for r in rows) / episodes,
        "observations": observed,
        "privileged": privileged,
    }
    shares = family.outcome_shares(r for rows in complete.values() for r in rows)
    if shares is not None:
        point["outcomes"] = shares
    if agent.kind == "train":
        point["trainer"] = agent.trainer
        key = "condition" if agent.trainer == "impala" else "algo"
        point["condition"] = agent.train.get(key, "vanilla" if key == "condition" else "?")
    return point


def _pooled_interval(family, pooled: list[float]) -> dict:
    """The pooled 95% interval over every episode's score: Wilson's for a
    0/1 metric, else the percentile bootstrap of the mean (seeded)."""
    if family.binary_metric:
        return {"pooled_wilson_interval": list(wilson_interval(round(sum(pooled)), len(pooled)))}
    return {"pooled_bootstrap_interval": list(bootstrap_interval(pooled))}


def aggregates(spec, pts: list[dict]) -> list[dict]:
    """Per agent, budget and metric (`metrics`) with points in two or more of
    the spec's environments of that metric: the mean and IQM over all its
    runs (per-seed values of every such environment), with 95%
    stratified-bootstrap intervals (strata: the environments; `AGGREGATE`),
    the environments and the runs counted."""
    out = []
    for agent in spec.agents:
        budgets = agent.budgets if agent.kind == "train" else (None,)
        for budget in budgets:
            mine = [p for p in pts if p["agent"] == agent.label and p["budget"] == budget]
            groups: dict[str, list[dict]] = {}
            for p in mine:
                groups.setdefault(env_adapter(p["env"]).metric, []).append(p)
            out += [_aggregate(agent, budget, here) for here in groups.values() if len(here) > 1]
    return out


def _aggregate(agent, budget, here: list[dict]) -> dict:
    """One aggregate (`aggregates`) of ``agent`` at ``budget`` over the points ``here``."""
    runs = [p["per_seed"] for p in here]
    flat = [v for r in runs for v in r]
    return {
        "agent": agent.label,
        "kind": agent.kind,
        "budget": budget,
        "training_frames": max(p["training_frames"] for p in here),
        "envs": [p["env"] for p in here],
        "runs": len(flat),
        "mean": sum(flat) / len(flat),
        "mean_interval": list(aggregate_interval(runs, "mean")),
        "iqm": iqm(flat),
        "iqm_interval": list(aggregate_interval(runs, "iqm")),
        "privileged": any(p["privileged"] for p in here),
    }


def series_cost(spec, jobs, records, series_records=None) -> list[dict]:
    """Per agent and environment: CPU hours of training (summed over seeds,
    each seed's run over every resumed part; `_train_seconds`) and of
    evaluation, the jobs counted, and ``cpu_partial_jobs``: jobs retried
    whose CPU covers only their last attempt (a lower bound; module
    docstring), also split by kind (``cpu_partial_train_jobs``,
    ``cpu_partial_eval_jobs``), and ``cpu_unknown_train_jobs``: trainings
    done (their kept checkpoints on disk) without any record of their cost.
    ``series_records``: series key -> its most advanced train record
    (`hier_agents.compare.jobs.series_records`), for trainings without a
    record of their own."""
    out: dict[tuple, dict] = {}
    for job in jobs:
        record = records.get(job.key)
        if record is None and job.kind == "train":
            record = (series_records or {}).get(job.inputs.get("series"))
        key = (job.point["agent"], job.point["env"])
        entry = out.setdefault(key, _cost_entry(*key))
        if record is None:
            entry["cpu_unknown_train_jobs"] += job.kind == "train"
            continue
        seconds, partial = _train_seconds(record) if job.kind == "train" else (0.0, False)
        if job.kind != "train" or seconds is None:
            seconds = float(record.get("cpu_s", 0.0))
            partial = int(record.get("attempts", 1)) > 1
        entry["cpu_partial_jobs"] += partial
        entry[f"cpu_partial_{job.kind}_jobs"] += partial
        entry[f"{job.kind}_cpu_hours"] += seconds / 3600
        entry[f"{job.kind}_jobs"] += 1
    return [e for e in out.values() if e["train_jobs"] or e["eval_jobs"]]


def _cost_entry(agent: str, env: str) -> dict:
    return {
        "agent": agent,
        "env": env,
        "train_cpu_hours": 0.0,
        "eval_cpu_hours": 0.0,
        "train_jobs": 0,
        "eval_jobs": 0,
        "cpu_partial_jobs": 0,
        "cpu_partial_train_jobs": 0,
        "cpu_partial_eval_jobs": 0,
        "cpu_unknown_train_jobs": 0,
    }


def _train_seconds(record: dict) -> tuple[float | None, bool]:
    """A train record's CPU seconds over every resumed part of its series,
    and False (not a lower bound); (None, False) when the record has no
    such count (the caller falls back to the record's own ``cpu_s``)."""
    result = record.get("result") or {}
    if result.get("series_cpu_s") is not None:
        return float(result["series_cpu_s"]), False
    counters = result.get("counters") or {}
    if "cpu_s" in counters:  # the IMPALA learner's own count, every attempt
        return float(counters["cpu_s"]), False
    return None, False


def code_versions(records) -> dict:
    """How many of ``records`` ran at each commit (their provenance; a
    ``+dirty`` commit had uncommitted code changes), most first."""
    counts: dict = {}
    for record in records.values():
        commit = (record.get("provenance") or {}).get("commit") or "unknown"
        counts[commit] = counts.get(commit, 0) + 1
    return dict(sorted(counts.items(), key=lambda kv: (-kv[1], kv[0])))


def _train_hours(c: dict) -> str:
    """A series' training CPU hours cell: ``>=`` where some attempts' or
    some seeds' CPU was not counted, ``?`` when none was."""
    if not c.get("train_jobs"):
        return "?" if c.get("cpu_unknown_train_jobs") else "-"
    lower = c.get("cpu_partial_train_jobs") or c.get("cpu_unknown_train_jobs")
    return f"{'>=' if lower else ''}{c['train_cpu_hours']:.2f}"


def _pct(value: float) -> str:
    return f"{100 * value:.1f}"


def _ci(interval) -> str:
    lo, hi = interval
    return f"[{100 * lo:.1f}, {100 * hi:.1f}]"


def _cells(p: dict, cost: dict, stat: str) -> dict:
    """One point's table cells: ``stat`` (the mean or the IQM) with its
    interval, both statistics with theirs, per-seed values, and its
    series' training CPU hours (`_train_hours`; ``-`` for agents without
    training)."""
    c = cost.get((p["agent"], p["env"]), {})
    return {
        "value": _pct(p[stat]),
        "interval": _ci(p[f"{stat}_interval"]),
        "mean": _pct(p["mean"]),
        "mean_ci": _ci(p["mean_interval"]),
        "iqm": _pct(p["iqm"]),
        "iqm_ci": _ci(p["iqm_interval"]),
        "per_seed": " ".join(f"{100 * v:.0f}" for v in p["per_seed"]),
        "train_h": _train_hours(c) if p["kind"] == "train" else "-",
        "wdl": _wdl(p),
    }


#: The text table's width of the ``W/D/L %`` column (`_wdl`).
WDL_WIDTH = len("99.7/0/0.3 (0.3 unfinished)")


def _wdl(p: dict) -> str:
    """A game point's shares won, drawn and lost in percent, ``W/D/L``, and
    of the lost those unfinished at the time limit, ``(U unfinished)`` when
    any (``-`` for a point without ``outcomes``)."""
    shares = p.get("outcomes")
    if not shares:
        return "-"
    wdl = "/".join(_share(shares[k]) for k in ("win", "draw", "loss"))
    unfinished = shares.get("unfinished", 0.0)
    return f"{wdl} ({_share(unfinished)} unfinished)" if unfinished else wdl


def _share(share: float) -> str:
    """A share in whole percent, with one decimal where rounding would
    show 0 or 100 for a share that is neither (one game of 300 shows)."""
    text = f"{100 * share:.0f}"
    if text in ("0", "100") and 0.0 < share < 1.0:
        text = f"{100 * share:.1f}"
    return text


def format_table(
    spec, pts: list[dict], costs: list[dict], aggs=(), *, use_iqm: bool = False
) -> str:
    """The comparison as text: a header line per metric (the environments'
    `metrics`: MuJoBan's success, the board games' game score) with the
    statistics, one block per environment with one row per point (mean and
    IQM with their intervals, per-seed values, for games the shares won,
    drawn and lost, training CPU hours, observations), then the aggregates
    over environments (`aggregates`). ``use_iqm``: accepted for the
    command's ``--iqm``; the table shows both statistics either way."""
    lines = [f"{heading}: {STATISTICS}" for heading in _headings(spec.envs)] + [""]
    width = max([len(p["agent"]) for p in pts] + [12])
    cost = {(c["agent"], c["env"]): c for c in costs}
    for env in spec.envs:
        rows = [p for p in pts if p["env"] == env]
        if not rows:
            continue
        games = env_adapter(env).games
        wdl = f" {'W/D/L %':>{WDL_WIDTH}}" if games else ""
        head = (
            f"  {'agent':<{width}} {'train frames':>13} {'mean %':>7} {'[95% CI]':>14} "
            f"{'IQM %':>6} {'[95% CI]':>14} {'seeds':>5}  {'per seed %':<16}{wdl} "
            f"{'train CPU-h':>11}  observations"
        )
        lines += [f"{env}:", head, "  " + "-" * (len(head) - 2)]
        for p in rows:
            c = _cells(p, cost, "mean")
            outcomes = f" {c['wdl']:>{WDL_WIDTH}}" if games else ""
            lines.append(
                f"  {p['agent']:<{width}} {p['training_frames']:>13,} {c['mean']:>7} "
                f"{c['mean_ci']:>14} {c['iqm']:>6} {c['iqm_ci']:>14} {len(p['seeds']):>5}  "
                f"{c['per_seed']:<16}{outcomes} {c['train_h']:>11}  {p['observations']}"
            )
        lines.append("")
    if aggs:
        lines += [f"all environments ({AGGREGATE}):"]
        lines.append(
            f"  {'agent':<{width}} {'train frames':>13} {'mean %':>7} {'[95% CI]':>14} "
            f"{'IQM %':>6} {'[95% CI]':>14} {'runs':>5}  environments"
        )
        for a in aggs:
            lines.append(
                f"  {a['agent']:<{width}} {a['training_frames']:>13,} {_pct(a['mean']):>7} "
                f"{_ci(a['mean_interval']):>14} {_pct(a['iqm']):>6} {_ci(a['iqm_interval']):>14} "
                f"{a['runs']:>5}  {', '.join(a['envs'])}"
            )
    return "\n".join(lines).rstrip()


def format_markdown(
    envs, pts: list[dict], costs: list[dict], *, use_iqm: bool = False
) -> list[str]:
    """The comparison as Markdown lines (the README's table): one row per
    environment and point, in ``envs`` order, with `format_table`'s cells:
    the metric's (``envs``' `metrics` names, e.g. success) mean (``use_iqm``:
    the IQM) with its interval, the IQM (the mean) with its, per-seed
    values, when a game is among ``envs`` the shares won, drawn and lost
    and of the lost those unfinished at the time limit (``-`` for other
    environments), mean steps, training CPU hours,
    observations."""
    first, second = ("iqm", "mean") if use_iqm else ("mean", "iqm")
    names = {"mean": "mean over seeds", "iqm": "IQM over seeds"}
    metric = " / ".join(dict.fromkeys(env_adapter(e).metric for e in envs))
    games = any(env_adapter(e).games for e in envs)
    cost = {(c["agent"], c["env"]): c for c in costs}
    lines = [
        f"| environment | agent | training frames | {metric}, {names[first]} [95% CI] "
        f"| {names[second]} [95% CI] | per seed |{' W/D/L % |' if games else ''} mean steps "
        f"| training CPU-h (all seeds) | observes |",
        "| --- " * (10 if games else 9) + "|",
    ]
    for env in envs:
        for p in (p for p in pts if p["env"] == env):
            c = _cells(p, cost, first)
            outcomes = f" {c['wdl']} |" if games else ""
            lines.append(
                f"| `{env}` | {p['agent']} | {p['training_frames']:,} "
                f"| {c[first]}% {c[first + '_ci']} | {c[second]}% {c[second + '_ci']} "
                f"| {c['per_seed']} |{outcomes} {p['mean_steps']:.0f} "
                f"| {c['train_h']} | {p['observations']} |"
            )
    return lines
