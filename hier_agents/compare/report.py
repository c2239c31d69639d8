"""An experiment's results: points with statistics across seeds, the table,
the JSON and the plot.

A point is one agent in one environment at one training budget (end-to-end
agents: each budget; modular agents: the frames their learned parts were
trained on, 0 when scripted; random agents: 0). Per seed, its value is the
success rate over that seed's episodes (MuJoBan: solved; board games: won).
Across seeds: the mean with a 95% percentile-bootstrap interval over seeds
(`hier_agents.stats.bootstrap_interval`, 10,000 resamples, seeded), the
interquartile mean (`hier_agents.stats.iqm`) with its own bootstrap interval,
the per-seed values, and the pooled Wilson interval over all episodes for
reference. Series also report the CPU hours their jobs cost (training and
evaluation, from the job records: a training's own ``cpu_s`` counter, which
spans every resumed attempt; otherwise the record's ``cpu_s``, which covers
only the attempt that finished, counted in ``cpu_partial_jobs`` and marked
``>=`` in the table).
"""

from __future__ import annotations

from pathlib import Path

from hier_agents.stats import bootstrap_interval, iqm, wilson_interval


def _success(row: dict) -> bool:
    return bool(row["solved"]) if "solved" in row else row.get("outcome") == "win"


def _observations(agent, summary: dict) -> tuple[str, bool]:
    """What a point's agent observed, in words, and whether it was privileged,
    from the evaluation summary (`hier_agents.run.run`)."""
    if agent.kind == "random":
        return "none", False
    if agent.kind == "modular":
        name, privileged = summary.get("estimator", "?"), bool(summary.get("privileged"))
        if privileged:
            return f"simulator via the {name} estimator (PRIVILEGED) + proprioception", True
        return f"cameras + proprioception ({name} estimator)", False
    keys = summary.get("observations") or []
    privileged = bool(summary.get("privileged"))
    text = ", ".join(keys) if keys else "?"
    return text + (" (PRIVILEGED)" if privileged else ""), privileged


def points(spec, jobs, records) -> list[dict]:
    """The comparison's points, in the spec's agent order then environment
    and budget; points with missing jobs are left out."""
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
    by_label = {a.label: a for a in spec.agents}
    out = []
    for agent in spec.agents:
        for env in agent.envs:
            budgets = agent.budgets if agent.kind == "train" else (None,)
            for budget in budgets:
                where = (agent.label, env, budget)
                seeds = grouped.get(where, {})
                complete = {s: rows for s, rows in seeds.items() if len(rows) == agent.episodes}
                if not complete:
                    continue
                summary = summaries[where]
                per_seed = {
                    s: sum(map(_success, rows)) / len(rows) for s, rows in sorted(complete.items())
                }
                values = list(per_seed.values())
                wins = sum(sum(map(_success, rows)) for rows in complete.values())
                episodes = sum(len(rows) for rows in complete.values())
                observed, privileged = _observations(by_label[agent.label], summary)
                frames = (
                    int(summary.get("training_frames", budget or 0))
                    if budget
                    else int(summary.get("training_frames", 0) or 0)
                )
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
                    "iqm_interval": list(bootstrap_interval(values, iqm)),
                    "pooled_wilson_interval": list(wilson_interval(wins, episodes)),
                    "mean_steps": (
                        sum(r["steps"] for rows in complete.values() for r in rows) / episodes
                    ),
                    "observations": observed,
                    "privileged": privileged,
                }
                if agent.kind == "train":
                    point["condition"] = agent.train.get("condition", "vanilla")
                out.append(point)
    return out


def series_cost(spec, jobs, records) -> list[dict]:
    """Per agent and environment: CPU hours of training (all seeds, all
    budgets: one run per seed) and of evaluation, the jobs counted, and
    ``cpu_partial_jobs``: jobs retried whose CPU covers only their last
    attempt (a lower bound; see the module docstring), also split by kind
    (``cpu_partial_train_jobs``, ``cpu_partial_eval_jobs``)."""
    out: dict[tuple, dict] = {}
    for job in jobs:
        record = records.get(job.key)
        if record is None:
            continue
        key = (job.point["agent"], job.point["env"])
        entry = out.setdefault(
            key,
            {
                "agent": key[0],
                "env": key[1],
                "train_cpu_hours": 0.0,
                "eval_cpu_hours": 0.0,
                "train_jobs": 0,
                "eval_jobs": 0,
                "cpu_partial_jobs": 0,
                "cpu_partial_train_jobs": 0,
                "cpu_partial_eval_jobs": 0,
            },
        )
        counters = (record.get("result") or {}).get("counters") or {}
        if "cpu_s" in counters:  # the training's own count, every attempt
            seconds = float(counters["cpu_s"])
        else:
            seconds = float(record.get("cpu_s", 0.0))
            partial = int(record.get("attempts", 1)) > 1
            entry["cpu_partial_jobs"] += partial
            entry[f"cpu_partial_{job.kind}_jobs"] += partial
        entry[f"{job.kind}_cpu_hours"] += seconds / 3600
        entry[f"{job.kind}_jobs"] += 1
    return list(out.values())


def code_versions(records) -> dict:
    """How many of ``records`` ran at each commit (their provenance; a
    ``+dirty`` commit had uncommitted code changes), most first."""
    counts: dict = {}
    for record in records.values():
        commit = (record.get("provenance") or {}).get("commit") or "unknown"
        counts[commit] = counts.get(commit, 0) + 1
    return dict(sorted(counts.items(), key=lambda kv: (-kv[1], kv[0])))


def _cells(p: dict, cost: dict, stat: str) -> dict:
    """One point's table cells: success with its interval over seeds, per-seed
    values, and its series' training CPU hours (``>=`` where some attempts'
    CPU was not counted; ``-`` for agents without training)."""
    lo, hi = p[f"{stat}_interval"]
    c = cost.get((p["agent"], p["env"]), {})
    at_least = ">=" if c.get("cpu_partial_train_jobs") else ""
    return {
        "value": f"{100 * p[stat]:.1f}",
        "interval": f"[{100 * lo:.1f}, {100 * hi:.1f}]",
        "per_seed": " ".join(f"{100 * v:.0f}" for v in p["per_seed"]),
        "train_h": (
            f"{at_least}{c.get('train_cpu_hours', 0.0):.2f}" if p["kind"] == "train" else "-"
        ),
    }


def format_table(spec, pts: list[dict], costs: list[dict], *, use_iqm: bool = False) -> str:
    """The comparison as text: one block per environment, one row per point."""
    stat = "iqm" if use_iqm else "mean"
    lines = []
    width = max([len(p["agent"]) for p in pts] + [12])
    cost = {(c["agent"], c["env"]): c for c in costs}
    for env in spec.envs:
        rows = [p for p in pts if p["env"] == env]
        if not rows:
            continue
        lines.append(
            f"{env}: success % across seeds ({stat} [95% bootstrap interval over "
            f"seeds]; per-seed values)"
        )
        head = (
            f"  {'agent':<{width}} {'train frames':>13} {stat + ' %':>7} "
            f"{'[95% CI]':>14} {'seeds':>5}  {'per seed %':<22} {'train CPU-h':>11}  "
            f"observations"
        )
        lines.append(head)
        lines.append("  " + "-" * (len(head) - 2))
        for p in rows:
            c = _cells(p, cost, stat)
            lines.append(
                f"  {p['agent']:<{width}} {p['training_frames']:>13,} "
                f"{c['value']:>7} {c['interval']:>14} {len(p['seeds']):>5}  "
                f"{c['per_seed']:<22} {c['train_h']:>11}  {p['observations']}"
            )
        lines.append("")
    return "\n".join(lines).rstrip()


def format_markdown(
    envs, pts: list[dict], costs: list[dict], *, use_iqm: bool = False
) -> list[str]:
    """The comparison as Markdown lines (the README's table): one row per
    environment and point, in ``envs`` order, with `format_table`'s cells."""
    stat = "iqm" if use_iqm else "mean"
    cost = {(c["agent"], c["env"]): c for c in costs}
    lines = [
        f"| environment | agent | training frames | success, {stat} over seeds [95% CI] "
        f"| per seed | mean steps | training CPU-h (all seeds) | observes |",
        "| --- | --- | --- | --- | --- | --- | --- | --- |",
    ]
    for env in envs:
        for p in (p for p in pts if p["env"] == env):
            c = _cells(p, cost, stat)
            lines.append(
                f"| `{env}` | {p['agent']} | {p['training_frames']:,} "
                f"| {c['value']}% {c['interval']} | {c['per_seed']} "
                f"| {p['mean_steps']:.0f} | {c['train_h']} | {p['observations']} |"
            )
    return lines


def plot(spec, pts: list[dict], path: Path, *, use_iqm: bool = False) -> None:
    """One panel per environment: success against training frames, each
    series' across-seed interval shaded, modular agents as points, random
    agents as grey bands, the legend below the panels."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    stat = "iqm" if use_iqm else "mean"
    env_names = [e for e in spec.envs if any(p["env"] == e for p in pts)]
    if not env_names:
        return
    fig, axes = plt.subplots(
        1, len(env_names), figsize=(5.2 * len(env_names), 4.4), dpi=110, squeeze=False, sharey=True
    )
    labels = [a.label for a in spec.agents if a.kind != "random"]
    handles: dict = {}
    xmax = max([p["training_frames"] for p in pts] + [1])
    for ax, env in zip(axes[0], env_names):
        here = [p for p in pts if p["env"] == env]
        _random_bands(ax, [p for p in here if p["kind"] == "random"], stat)
        for i, label in enumerate(labels):
            members = sorted(
                (p for p in here if p["agent"] == label), key=lambda p: p["training_frames"]
            )
            if members:
                handles[label] = _series(ax, members, plt.get_cmap("tab10")(i % 10), stat)
        ax.set_title(env, fontsize=10)
        ax.set_xlabel("training frames (control steps)")
        ax.set_xlim(-0.03 * xmax, 1.05 * xmax)
        ax.set_ylim(-2, 102)
        ax.grid(alpha=0.3)
    axes[0][0].set_ylabel(f"success % ({stat} over seeds, 95% CI)")
    _legend(fig, handles, pts)
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, metadata={"Software": None})
    plt.close(fig)


def _random_bands(ax, randoms: list[dict], stat: str) -> None:
    """Random agents' points as grey bands (their interval) with a dashed
    line at the statistic, labelled at the panel's right edge."""
    for p in randoms:
        lo, hi = p[f"{stat}_interval"]
        ax.axhspan(100 * lo, 100 * hi, color="grey", alpha=0.18, lw=0)
        ax.axhline(100 * p[stat], color="grey", lw=0.8, ls="--")
        ax.annotate(
            p["agent"],
            (1.0, 100 * p[stat]),
            xycoords=("axes fraction", "data"),
            xytext=(-3, 2),
            textcoords="offset points",
            ha="right",
            va="bottom",
            fontsize=7,
            color="dimgrey",
        )


def _series(ax, members: list[dict], colour, stat: str):
    """One agent's points in a panel: a line with its shaded interval over
    budgets, or one point with error bars; dashed or hollow when privileged.
    Returns the legend handle."""
    x = [p["training_frames"] for p in members]
    y = [100 * p[stat] for p in members]
    lo = [100 * p[f"{stat}_interval"][0] for p in members]
    hi = [100 * p[f"{stat}_interval"][1] for p in members]
    style = "--" if any(p["privileged"] for p in members) else "-"
    if len(members) > 1:
        (line,) = ax.plot(x, y, style, marker="o", ms=3.5, lw=1.4, color=colour)
        ax.fill_between(x, lo, hi, color=colour, alpha=0.18, lw=0)
        return line
    return ax.errorbar(
        x,
        y,
        yerr=[[y[0] - lo[0]], [hi[0] - y[0]]],
        fmt="s",
        ms=5,
        capsize=3,
        color=colour,
        mfc="white" if style == "--" else colour,
    )


def _legend(fig, handles: dict, pts: list[dict]) -> None:
    """The legend below the panels (privileged series starred) and the note
    on what the marks mean; the panels leave room for it."""
    names = [
        n + (" *" if any(p["privileged"] for p in pts if p["agent"] == n) else "") for n in handles
    ]
    if handles:
        fig.legend(
            list(handles.values()),
            names,
            loc="lower center",
            ncol=min(3, len(handles)),
            fontsize=8,
            frameon=False,
            bbox_to_anchor=(0.5, 0.035),
        )
    rows = (len(handles) + 2) // 3
    fig.text(
        0.5,
        0.005,
        "* privileged inputs (dashed line or hollow marker); grey bands: "
        "random actions; shading: 95% bootstrap interval over seeds",
        ha="center",
        va="bottom",
        fontsize=7,
        color="dimgrey",
    )
    fig.tight_layout(rect=(0, 0.07 + 0.05 * rows, 1, 1))
