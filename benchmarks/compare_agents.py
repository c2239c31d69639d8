"""Modular and end-to-end agents side by side on the same seeds, with their training frames.

    python benchmarks/compare_agents.py ENV [--episodes N] [--seed S]
        [--modular [SPEC ...]] [--checkpoint PATH ...] [--curve]
        [--max-frames N] [--budgets FRAMES ...]
        [--random HOLD ...] [--stochastic] [--json PATH] [--plot PNG]

Agents, each playing ``--episodes`` episodes in an environment built with the
same ``--seed`` (the same levels or opening sequence as long as the
environment's random draws do not depend on the agent's play):

* **modular agents**, one per ``--modular`` SPEC: ``default`` (the library's
  defaults) or comma-separated ``planner=NAME``, ``skill=NAME``,
  ``estimator=NAME`` (e.g. ``skill=learned-ball`` or
  ``planner=learned:PATH,skill=learned-ball``). Their training frames are
  those of their learned parts (`hier_agents.run.training_frames`: every
  control step simulated to train a learned skill or option policy); a
  scripted agent has 0. Without the flag: one default modular agent;
  ``--no-modular`` leaves them out.
* **end-to-end checkpoints** (``--checkpoint``: `hier_agents.train` run
  directories or checkpoint files), their policy's mean (``--stochastic``
  samples). With ``--curve`` a run directory stands for every checkpoint it
  kept (``--keep-checkpoints``: ``checkpoints/frames-N.pt``) and its last
  one, so each run becomes a curve of success against training frames;
  ``--max-frames`` drops checkpoints trained on more frames (an equal budget);
  ``--budgets F1 F2 ...`` keeps per run the last checkpoint within each budget.
* **random floors** (``--random HOLD ...``, default 1 and 10): uniformly
  random actions, a new draw every HOLD control steps.

One row per agent: success (MuJoBan: solved; board games: won) with its 95%
Wilson interval, draw and loss rates for board games, mean control steps,
mean return, wall seconds per episode, training frames and what the agent
observes (``observations``: cameras, state, privileged or not). Then, per
series (a modular agent, an end-to-end run), the smallest training budget at
which it **clears each random floor**: the lower end of its interval above
the upper end of the floor's. ``--json`` writes the rows and that summary
(with provenance); ``--plot`` draws success against training frames with the
intervals and the floors (matplotlib, a dev dependency).

``--reuse EARLIER.json`` takes the rows of an earlier run of this script for
the agents it already played (same environment, episodes and seed; a
modular spec, a checkpoint file or a random hold) instead of playing them
again: each reused row says so (``reused``) and the new JSON keeps the
earlier file's provenance under ``reused_from``. ``--keep-rows-of
EARLIER.json`` also keeps (marked ``reused``) every row of the earlier run
for agents this command does not name, in the earlier order: to re-measure
some rows of a comparison (say, the camera agents after a change of looks)
while the others, whose checkpoints may be gone, stay as measured.
"""

from __future__ import annotations

import json
import re
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from _common import cli, make_parser, prog, write_json  # noqa: E402

from hier_agents.modular.components import check, family  # noqa: E402
from hier_agents.run import run  # noqa: E402

PROG = prog(__file__)
_SPEC_KEYS = ("planner", "skill", "estimator")
_KEPT = re.compile(r"frames-(\d+)\.pt$")


def parse_modular(spec: str, fam: str | None = None) -> dict:
    """``"default"`` or ``"planner=X,skill=Y,estimator=Z"`` -> keyword arguments
    of `run`. With a family ``fam``, each name is checked
    (`hier_agents.modular.components.check`: ``NAME:ARG`` parsed, checkpoints
    loaded). Raises ValueError (`envs.cli.UsageError`) for a bad spec."""
    spec = spec.strip()
    if spec in ("", "default"):
        return {}
    out = {}
    for part in spec.split(","):
        key, sep, value = part.partition("=")
        key, value = key.strip(), value.strip()
        if not sep or key not in _SPEC_KEYS or not value:
            raise cli.UsageError(f"bad --modular part {part!r} in {spec!r}: expected "
                                 f"{'/'.join(_SPEC_KEYS)}=NAME[:ARG], comma-separated, or "
                                 f"'default'")
        if key in out:
            raise cli.UsageError(f"--modular {spec!r} gives {key} twice")
        if fam is not None:
            check(key, fam, value)
        out[key] = value
    return out


def expand_checkpoints(paths, curve: bool, max_frames: int | None,
                       budgets=None) -> list[tuple[str, Path]]:
    """(series name, checkpoint file) pairs in the order given, each run's by frames.

    A run directory is its ``checkpoint.pt``, or with ``curve`` also every
    kept ``checkpoints/frames-N.pt``; ``max_frames`` drops checkpoints
    trained on more frames (read from the kept file's name or the checkpoint);
    ``budgets`` (frame counts) keeps, per run and budget, only the checkpoint
    trained on the most frames within it.
    """
    from hier_agents.baselines.impala.learner import load_checkpoint

    out = []
    for raw in paths:
        path = Path(raw)
        if not path.exists():
            raise FileNotFoundError(f"no checkpoint or run directory at {path}")
        if path.is_file():
            out.append((str(path), path))
            continue
        files = {}
        if curve:
            for kept in (path / "checkpoints").glob("frames-*.pt"):
                files[int(_KEPT.search(kept.name).group(1))] = kept
        last = path / "checkpoint.pt"
        if last.exists():
            files.setdefault(int(load_checkpoint(last)["counters"].get("frames", 0)), last)
        if not files:
            raise FileNotFoundError(f"{path} has no checkpoint.pt"
                                    + (" nor checkpoints/frames-*.pt" if curve else ""))
        frames = sorted(f for f in files if max_frames is None or f <= max_frames)
        if budgets:
            frames = sorted({max((f for f in frames if f <= b), default=None) for b in budgets}
                            - {None})
        out.extend((str(path), files[f]) for f in frames)
    return out


def observations(summary: dict) -> str:
    """What an agent's row saw, in words (privileged inputs say so)."""
    agent = summary["agent"]
    if agent == "modular":
        name = summary.get("estimator", "?")
        if summary.get("privileged"):
            return f"simulator via the {name} estimator (PRIVILEGED) + proprioception"
        return f"cameras + proprioception ({name} estimator)"
    if agent.startswith("random"):
        return "none"
    config = summary.get("checkpoint_config", {})
    parts = []
    if config.get("cameras"):
        parts.append("cameras")
    if config.get("state"):
        parts.append("abstract state (PRIVILEGED)")
    parts.append("proprioception")
    if config.get("condition", "vanilla") != "vanilla":
        parts.append("planner target (PRIVILEGED state)")
    return " + ".join(parts)


def clears(row: dict, floor: dict) -> bool:
    """The row's 95% interval lies wholly above the floor's."""
    return row["success_interval"][0] > floor["success_interval"][1]


def floor_summary(rows: list[dict]) -> dict:
    """Per series and random floor: the smallest budget whose row clears the floor."""
    floors = [r for r in rows if r["agent"].startswith("random")]
    series: dict[str, list[dict]] = {}
    for r in rows:
        if not r["agent"].startswith("random"):
            series.setdefault(r["series"], []).append(r)
    out = {}
    for name, members in series.items():
        members = sorted(members, key=lambda r: r["training_frames"])
        out[name] = {}
        for floor in floors:
            first = next((r for r in members if clears(r, floor)), None)
            out[name][floor["agent"]] = {
                "first_frames": None if first is None else first["training_frames"],
                "largest_frames_tried": members[-1]["training_frames"]}
    return out


def plot(rows: list[dict], path: Path, title: str) -> None:
    try:
        import matplotlib
    except ImportError as exc:  # pragma: no cover - a dev dependency
        raise SystemExit("--plot needs matplotlib (pip install -e '.[dev]')") from exc
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(8, 4.8), dpi=110)
    xmax = max([r["training_frames"] for r in rows] + [1])
    for r in rows:
        if r["agent"].startswith("random"):
            lo, hi = r["success_interval"]
            line = ax.axhline(100 * r["success_rate"], ls="--", lw=1, color="grey"
                              if r["agent"] == "random:1" else "black")
            ax.axhspan(100 * lo, 100 * hi, alpha=0.08, color=line.get_color())
            ax.text(xmax * 1.01, 100 * r["success_rate"], r["label"], va="center", fontsize=7)
    series: dict[str, list[dict]] = {}
    for r in rows:
        if not r["agent"].startswith("random"):
            series.setdefault(r["series"], []).append(r)
    for name, members in series.items():
        members = sorted(members, key=lambda r: r["training_frames"])
        x = [r["training_frames"] for r in members]
        y = [100 * r["success_rate"] for r in members]
        err = [[100 * (r["success_rate"] - r["success_interval"][0]) for r in members],
               [100 * (r["success_interval"][1] - r["success_rate"]) for r in members]]
        ax.errorbar(x, y, yerr=err, marker="o" if len(members) > 1 else "s", ms=4, capsize=3,
                    lw=1.2, label=members[0]["label"])
    ax.set_xlabel("training frames (control steps)")
    ax.set_ylabel("solved % (95% Wilson interval)" if "win_rate" not in rows[0]
                  else "won % (95% Wilson interval)")
    ax.set_ylim(-2, 102)
    ax.set_xlim(-0.02 * xmax, xmax * 1.15)
    ax.set_title(title, fontsize=9)
    ax.legend(fontsize=7, loc="lower right")
    ax.grid(alpha=0.3)
    fig.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path)
    plt.close(fig)


def _key(row: dict) -> tuple:
    """What identifies an agent's row for ``--reuse``."""
    agent = row["agent"]
    if agent == "modular":
        return ("modular", row["series"])
    if agent.startswith("random"):
        return ("random", agent)
    return ("checkpoint", row["checkpoint"], "(sampled)" in row.get("condition", ""))


def _label(row: dict) -> str:
    agent = row["agent"]
    if agent == "modular":
        parts = [f"planner {row['planner']}", f"skill {row['skill']}",
                 f"estimator {row.get('estimator', '?')}"]
        return "modular: " + ", ".join(parts)
    if agent.startswith("random"):
        return row["condition"]
    return f"end-to-end {row['condition']} ({row['series']})"


def _main(argv=None) -> int:
    parser = make_parser(__file__, __doc__)
    parser.add_argument("env", help="environment name (see python -m envs --list)")
    parser.add_argument("--episodes", type=cli.positive_int, default=20,
                        help="episodes per agent")
    parser.add_argument("--seed", type=cli.non_negative_int, default=0)
    parser.add_argument("--modular", nargs="*", default=None, metavar="SPEC",
                        help="modular agents: 'default' or planner=..,skill=..,estimator=.. "
                             "(NAME or NAME:ARG; default: one default agent)")
    parser.add_argument("--no-modular", action="store_true", help="leave the modular agents out")
    parser.add_argument("--checkpoint", nargs="*", default=[], metavar="PATH",
                        help="hier_agents.train run directories or checkpoint files")
    parser.add_argument("--curve", action="store_true",
                        help="a run directory stands for all its kept checkpoints")
    parser.add_argument("--max-frames", type=cli.positive_int, default=None,
                        help="leave out checkpoints trained on more frames")
    parser.add_argument("--budgets", type=cli.positive_int, nargs="*", default=None,
                        metavar="FRAMES",
                        help="with --curve: per run, only the last checkpoint within each "
                             "of these frame budgets")
    parser.add_argument("--random", type=cli.positive_int, nargs="*", default=[1, 10],
                        metavar="HOLD",
                        help="random-action rows, one per hold (control steps per draw); "
                             "give the flag alone for none")
    parser.add_argument("--stochastic", action="store_true",
                        help="checkpoints sample from their policy instead of taking its mean")
    parser.add_argument("--json", type=Path, help="write the rows here")
    parser.add_argument("--plot", type=Path, help="PNG of success against training frames")
    parser.add_argument("--reuse", type=Path, metavar="EARLIER_JSON",
                        help="reuse the rows of an earlier run for the agents it played")
    parser.add_argument("--keep-rows-of", type=Path, metavar="EARLIER_JSON",
                        help="also keep the earlier run's rows of agents not named here")
    parser.add_argument("--no-progress", action="store_true")
    args = parser.parse_args(argv)
    cli.environment(args.env)
    fam = family(args.env)
    specs = [] if args.no_modular else (args.modular if args.modular else ["default"])
    modular = [(spec, parse_modular(spec, fam)) for spec in specs]
    checkpoints = expand_checkpoints(args.checkpoint, args.curve, args.max_frames,
                                     args.budgets)
    if not modular and not checkpoints and not args.keep_rows_of:
        raise cli.UsageError("nothing to compare: give --checkpoint PATH or drop --no-modular")
    if args.reuse and args.keep_rows_of and args.reuse != args.keep_rows_of:
        raise cli.UsageError("--reuse and --keep-rows-of must name the same earlier run")
    cli.output_file(args.json, "--json")
    cli.output_file(args.plot, "--plot")

    from hier_agents.baselines.impala.learner import load_checkpoint

    earlier, reused_from, old = {}, None, None
    source = args.reuse or args.keep_rows_of
    if source:
        flag = "--reuse" if args.reuse else "--keep-rows-of"
        try:
            old = json.loads(source.read_text())
        except (OSError, ValueError) as exc:
            raise cli.UsageError(f"{flag} {source}: {exc}") from None
        if not isinstance(old, dict) or not isinstance(old.get("rows"), list):
            raise cli.UsageError(f"{flag} {source} is not a compare_agents.py --json file")
        if (old.get("env"), old.get("episodes"), old.get("seed")) != (
                args.env, args.episodes, args.seed):
            raise cli.UsageError(f"{flag} {source} played {old.get('env')}, {old.get('episodes')} "
                         f"episodes, seed {old.get('seed')}: not this comparison")
        reused_from = {"path": str(source), "provenance": old.get("provenance")}
        if old.get("reused_from"):  # the earlier run's own reused rows keep their origin
            reused_from["reused_from"] = old["reused_from"]
        if args.reuse:
            earlier = {_key(r): r for r in old["rows"]}

    def play(key, **kwargs):
        if key in earlier:
            print(f"reusing the row of {key[1]} from {args.reuse}", file=sys.stderr)
            return {**earlier[key], "reused": True}
        return run(args.env, args.episodes, args.seed, progress=progress, **kwargs)

    rows = []
    progress = not args.no_progress
    for spec, kwargs in modular:
        summary = play(("modular", f"modular {spec}"), **kwargs)
        summary["series"] = f"modular {spec}"
        summary["spec"] = spec
        rows.append(summary)
    for series, path in checkpoints:
        summary = play(("checkpoint", str(path), bool(args.stochastic)),
                       agent=f"checkpoint:{path}", stochastic=args.stochastic)
        config = load_checkpoint(path)["config"]
        summary["checkpoint"] = str(path)
        summary["checkpoint_config"] = {k: config.get(k) for k in
                                        ("env", "condition", "cameras", "state", "seed",
                                         "actors", "envs_per_actor", "batch_size",
                                         "learning_rate", "abs_reward")}
        summary["series"] = series
        rows.append(summary)
    for hold in args.random:
        agent = f"random:{hold}"
        summary = play(("random", agent), agent=agent)
        summary["series"] = agent
        rows.append(summary)
    if args.keep_rows_of:
        played = {_key(r): r for r in rows}
        kept = [played.pop(_key(r), None) or {**r, "reused": True} for r in old["rows"]]
        rows = kept + list(played.values())
    for r in rows:
        r.pop("rows", None)
        r.setdefault("training_frames", 0)
        r["observations"] = observations(r)
        r["label"] = _label(r)
    floors = floor_summary(rows)

    board = "win_rate" in rows[0]
    width = max(20, *(len(r["label"]) for r in rows))
    head = (f"{'agent':<{width}} {'success % [95% CI]':>22} "
            + (f"{'draw %':>7} {'loss %':>7} " if board else "")
            + f"{'steps':>7} {'return':>7} {'s/ep':>6} {'train frames':>13}  observations")
    print(head)
    print("-" * len(head))
    for r in rows:
        lo, hi = r.get("success_interval") or r.get("win_interval")
        line = (f"{r['label']:<{width}} {100 * r['success_rate']:>6.1f} "
                f"[{100 * lo:5.1f},{100 * hi:5.1f}]{'':>4} ")
        if board:
            line += f"{100 * r['draw_rate']:>7.1f} {100 * r['loss_rate']:>7.1f} "
        line += (f"{r['mean_steps']:>7.1f} {r['mean_return']:>7.2f} {r['wall_s']:>6.2f} "
                 f"{r['training_frames']:>13,}  {r['observations']}")
        print(line)
    if floors and any(floors.values()):
        print("\nfirst training budget clearing each random floor (interval above the floor's):")
        for name, by_floor in floors.items():
            for floor, found in by_floor.items():
                first = found["first_frames"]
                print(f"  {name}: {floor}: "
                      + (f"{first:,} frames" if first is not None else
                         f"not within {found['largest_frames_tried']:,} frames"))
    if args.json:
        write_json(args.json, {"env": args.env, "episodes": args.episodes, "seed": args.seed,
                               "rows": rows, "clears_random_floor": floors,
                               **({"reused_from": reused_from} if reused_from else {})})
    if args.plot:
        plot(rows, args.plot, f"{args.env}: {args.episodes} episodes per point, seed {args.seed}")
    return 0


def main(argv=None) -> int:
    """Plays every agent, prints the table, writes ``--json`` and ``--plot``;
    bad input: one line on stderr, exit status 2, before anything is played."""
    return cli.run_main(PROG, _main, argv)


if __name__ == "__main__":
    sys.exit(main())
