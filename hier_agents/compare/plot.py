"""The plot of an experiment's points (`hier_agents.compare.report.points`):
one panel per environment (and one for the aggregate when there are
several): learning curves of every trained series (the metric against the
frames of its budgets: the mean with its interval shaded, the IQM dotted),
the modular agents as coloured horizontal lines and random actions as grey
dashed ones.
"""

from __future__ import annotations

from pathlib import Path

from hier_agents.modular.families import env_adapter


def plot(spec, pts: list[dict], path: Path, aggs=(), *, use_iqm: bool = False) -> None:
    """One panel per environment, and one for the aggregates (`aggregates`)
    when there are any: learning curves of the trained series (the
    environments' metric, `metrics`, against the frames of their budgets;
    the mean, or with ``use_iqm`` the IQM, as a solid line with its
    interval shaded, the other statistic dotted), the modular agents as
    coloured horizontal lines at their mean (IQM), random actions as grey
    dashed lines with their interval as a band; privileged series dashed;
    the legend below the panels."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    stat = "iqm" if use_iqm else "mean"
    panels = [(e, [p for p in pts if p["env"] == e]) for e in spec.envs]
    panels = [(e, here) for e, here in panels if here]
    if aggs:
        panels.append(("all environments (aggregate over runs)", list(aggs)))
    if not panels:
        return
    fig, axes = plt.subplots(
        1, len(panels), figsize=(5.2 * len(panels), 4.6), dpi=110, squeeze=False, sharey=True
    )
    colours = {
        a.label: plt.get_cmap("tab10")(i % 10)
        for i, a in enumerate(a for a in spec.agents if a.kind != "random")
    }
    handles: dict = {}
    xmax = max([p["training_frames"] for p in pts if p["kind"] == "train"] + [1])
    for ax, (title, here) in zip(axes[0], panels):
        _random_lines(ax, [p for p in here if p["kind"] == "random"], stat)
        for label, colour in colours.items():
            members = sorted(
                (p for p in here if p["agent"] == label), key=lambda p: p["training_frames"]
            )
            if members:
                handles[label] = _series(ax, members, colour, stat)
        ax.set_title(title, fontsize=10)
        ax.set_xlabel("training frames (control steps)")
        ax.set_xlim(-0.03 * xmax, 1.05 * xmax)
        ax.set_ylim(-2, 102)
        ax.grid(alpha=0.3)
    metric = " / ".join(dict.fromkeys(env_adapter(e).metric for e in spec.envs))
    axes[0][0].set_ylabel(f"{metric} % ({'IQM' if use_iqm else 'mean'} over seeds, 95% CI)")
    _legend(fig, handles, pts, stat)
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, metadata={"Software": None})
    plt.close(fig)


def _random_lines(ax, randoms: list[dict], stat: str) -> None:
    """Random agents' points as grey dashed lines at the statistic with
    their interval as a band, labelled at the panel's right edge."""
    for p in randoms:
        lo, hi = p[f"{stat}_interval"]
        ax.axhspan(100 * lo, 100 * hi, color="grey", alpha=0.15, lw=0)
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
    """One agent's points in a panel; returns the legend handle. A trained
    series: its learning curve (``stat`` solid with its interval shaded,
    the other statistic dotted, dashed when privileged); any other agent: a
    horizontal reference line at ``stat`` (dashed when privileged)."""
    other = "mean" if stat == "iqm" else "iqm"
    style = "--" if any(p["privileged"] for p in members) else "-"
    if members[0]["kind"] != "train":
        return ax.axhline(100 * members[0][stat], color=colour, lw=1.3, ls=style, alpha=0.9)
    x = [p["training_frames"] for p in members]
    lo = [100 * p[f"{stat}_interval"][0] for p in members]
    hi = [100 * p[f"{stat}_interval"][1] for p in members]
    (line,) = ax.plot(
        x, [100 * p[stat] for p in members], style, marker="o", ms=3.5, lw=1.4, color=colour
    )
    ax.fill_between(x, lo, hi, color=colour, alpha=0.18, lw=0)
    ax.plot(
        x,
        [100 * p[other] for p in members],
        ":",
        marker="o",
        mfc="white",
        ms=3.5,
        lw=1.1,
        color=colour,
    )
    return line


def _legend(fig, handles: dict, pts: list[dict], stat: str) -> None:
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
            bbox_to_anchor=(0.5, 0.05),
        )
    rows = (len(handles) + 2) // 3
    solid, dotted = ("IQM", "mean") if stat == "iqm" else ("mean", "IQM")
    fig.text(
        0.5,
        0.005,
        f"trained series: {solid} over seeds (solid, 95% interval shaded) and {dotted} "
        f"(dotted) at each budget; horizontal lines: modular agents ({solid}; their learned "
        f"parts' frames are in the table); grey dashed: random actions (band: 95% interval)."
        f"\n* privileged inputs (dashed). Intervals: mean, percentile bootstrap over seeds; "
        f"IQM, stratified bootstrap (episodes resampled within each seed); aggregate panel: "
        f"runs resampled within each environment",
        ha="center",
        va="bottom",
        fontsize=6.5,
        color="dimgrey",
    )
    fig.tight_layout(rect=(0, 0.09 + 0.05 * rows, 1, 1))
