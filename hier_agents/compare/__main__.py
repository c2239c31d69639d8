"""``python -m hier_agents.compare SPEC``: see `hier_agents.compare`."""

from __future__ import annotations

import json
import sys
import time
from pathlib import Path

from physics_planning import cli

PROG = "python -m hier_agents.compare"


def build_parser() -> cli.Parser:
    import hier_agents.compare as package

    parser = cli.Parser(
        PROG,
        description=package.__doc__.split("\n\n")[0],
        epilog="examples:\n" + package.__doc__.split("\n\n")[1],
    )
    add = parser.add_argument
    add("spec", type=cli.existing_file, help="the experiment's TOML spec")
    add("--backend", default="local", help="local (a pool of processes here) or ray")
    add(
        "--ray-address",
        default=None,
        help="with --backend ray: the cluster to join (auto: the one `ray start` made; "
        "default: start a local one)",
    )
    add(
        "--cpus",
        type=cli.positive_int,
        default=None,
        help="CPUs the local pool may use (default: all of this machine's)",
    )
    add(
        "--retries",
        type=cli.non_negative_int,
        default=1,
        help="times a failed job is run again before it counts as failed",
    )
    add(
        "--cache",
        type=Path,
        default=None,
        help="the cache and output folder (default: the spec's cache, else runs/compare/NAME)",
    )
    add("--plan", action="store_true", help="print the jobs and which are cached; run nothing")
    add(
        "--report-only",
        action="store_true",
        help="write the outputs from the cached jobs; run nothing",
    )
    add(
        "--only",
        default=None,
        metavar="KIND",
        help="run only the train or only the eval jobs (eval jobs whose training is not "
        "cached then fail)",
    )
    add(
        "--agent",
        dest="agents",
        action="append",
        default=None,
        metavar="LABEL",
        help="run only the jobs of the agent with this label in the spec (repeatable); "
        "--plan, --retrain and --reevaluate then apply to it alone, and the outputs still "
        "report every agent the cache holds",
    )
    add(
        "--env",
        dest="envs",
        action="append",
        default=None,
        metavar="NAME",
        help="run only the jobs on this environment of the spec (repeatable; with --agent "
        "and --seed, narrowed by those too); --plan, --retrain, --reevaluate and --check "
        "then apply to it alone",
    )
    add(
        "--seed",
        dest="seeds",
        type=int,
        action="append",
        default=None,
        metavar="SEED",
        help="run only the jobs of this seed of the spec (repeatable; with --agent, of "
        "those agents); --plan, --retrain, --reevaluate and --check then apply to it alone",
    )
    add(
        "--retrain",
        action="store_true",
        help="train every series of the spec again from zero (its run directory is removed "
        "first) and evaluate it again, whatever the cache holds",
    )
    add(
        "--reevaluate",
        action="store_true",
        help="run every evaluation again, ignoring stored evaluation records (trainings "
        "whose kept checkpoints are on disk are not run: a cold run of shipped checkpoints)",
    )
    add(
        "--check",
        type=cli.positive_int,
        default=None,
        metavar="EPISODES",
        help="replay the first EPISODES episodes (at most its first shard's) of every point's "
        "stored evaluation (trained agents from their kept checkpoints) and compare them, "
        "field by field, with the record; trains nothing, writes CACHE/check.json, exit "
        "status 1 if any differs",
    )
    add(
        "--iqm",
        action="store_true",
        help="the plot's bands and the README table follow the interquartile mean (with its "
        "stratified bootstrap interval) instead of the mean",
    )
    add("--quiet", action="store_true", help="no line per job")
    return parser


def _main(argv=None) -> int:
    from hier_agents.compare import jobs as jobs_mod
    from hier_agents.compare import report
    from hier_agents.compare.spec import load

    args = build_parser().parse_args(argv)
    cli.choice("--backend", args.backend, ("local", "ray"))
    if args.ray_address and args.backend != "ray":
        raise cli.UsageError("--ray-address needs --backend ray")
    spec = load(args.spec)
    cache = args.cache or spec.cache
    planned = jobs_mod.plan(spec)
    selected = _selected(spec, planned, args.agents, args.seeds, args.envs)
    if args.only is not None:
        cli.choice("--only", args.only, ("train", "eval"))
    if args.report_only and (args.retrain or args.reevaluate):
        raise cli.UsageError("--report-only runs nothing: drop --retrain and --reevaluate")
    if args.retrain and args.only == "eval":
        raise cli.UsageError("--retrain trains: it does not go with --only eval")
    if args.check is not None:
        given = [f for f in ("retrain", "reevaluate", "report_only", "only") if getattr(args, f)]
        if given:
            flag = "--" + given[0].replace("_", "-")
            raise cli.UsageError(f"--check replays stored evaluations: drop {flag}")
        return _check(selected, Path(cache), args)
    fresh = _fresh(selected, args)
    if args.plan:
        _print_plan(selected, cache, fresh)
        return 0
    failure = None if args.report_only else _run(selected, cache, args, fresh)
    records = {j.key: r for j in planned if (r := jobs_mod.load_record(cache, j.key)) is not None}
    pts = report.points(spec, planned, records)
    costs = report.series_cost(spec, planned, records, jobs_mod.series_records(cache))
    aggs = report.aggregates(spec, pts)
    table = report.format_table(spec, pts, costs, aggs, use_iqm=args.iqm)
    print(table)
    missing = sum(
        1
        for j in planned
        if j.key not in records and not (j.kind == "train" and jobs_mod.artifacts_present(cache, j))
    )
    code_versions = report.code_versions(records)
    content = _content(spec, args, planned, (pts, aggs, costs), missing, code_versions)
    if len(code_versions) > 1:
        _warn_code_versions(code_versions)
    _write_outputs(Path(cache), content, table, spec, (pts, aggs), args)
    if failure:
        print(f"{PROG}: {failure}", file=sys.stderr)
        return 1
    if missing:
        print(f"{PROG}: {cli.plural(missing, 'job')} missing from the cache", file=sys.stderr)
    return 0


def _selected(
    spec,
    planned,
    labels: list[str] | None,
    seeds: list[int] | None = None,
    env_names: list[str] | None = None,
) -> list:
    """The jobs of the agents ``labels`` (``--agent``), of the ``seeds``
    (``--seed``) and on the environments ``env_names`` (``--env``); None:
    every agent, seed, environment.

    Raises:
      UsageError: a label, seed or environment the spec does not have (with
        the closest label or environment, or its seeds).
    """
    for label in labels or ():
        cli.choice("--agent", label, [agent.label for agent in spec.agents])
    for name in env_names or ():
        cli.choice("--env", name, sorted({job.inputs["env"] for job in planned}))
    spec_seeds = sorted({job.inputs["seed"] for job in planned})
    for seed in seeds or ():
        if seed not in spec_seeds:
            raise cli.UsageError(
                f"--seed {seed}: the spec runs seeds {', '.join(map(str, spec_seeds))}"
            )
    return [
        job
        for job in planned
        if (not labels or job.point["agent"] in labels)
        and (not seeds or job.inputs["seed"] in seeds)
        and (not env_names or job.inputs["env"] in env_names)
    ]


def _fresh(planned, args) -> set[str]:
    """Keys of the jobs to run whatever the cache holds: with ``--retrain``
    every training and the evaluations of trained agents, with
    ``--reevaluate`` every evaluation."""
    fresh: set[str] = set()
    for job in planned:
        if args.reevaluate and job.kind == "eval":
            fresh.add(job.key)
        if args.retrain and (job.kind == "train" or job.deps):
            fresh.add(job.key)
    return fresh


def _print_plan(planned, cache, fresh) -> None:
    """``--plan``: a line per job, done (its record, or a training's kept
    checkpoints) or to run."""
    from hier_agents.compare import jobs as jobs_mod

    for job in planned:
        done = job.key not in fresh and (
            jobs_mod.load_record(cache, job.key) is not None
            if job.kind == "eval"
            else jobs_mod.artifacts_present(cache, job)
            or jobs_mod.load_record(cache, job.key) is not None
        )
        print(f"{job.key}  {'cached' if done else 'to run':<7} {job.describe()}")


def _check_trainable(planned, cache, fresh) -> None:
    """Refuses, before anything runs, a training that can no longer keep a
    checkpoint at one of its budgets (`hier_agents.compare.jobs.unreachable_budgets`).

    Raises:
      UsageError: one line naming the agent, environment, seed and budgets.
    """
    from hier_agents.compare import jobs as jobs_mod

    for job in planned:
        if job.kind != "train" or job.key in fresh or jobs_mod.artifacts_present(cache, job):
            continue
        unreachable = jobs_mod.unreachable_budgets(cache, job)
        if unreachable:
            p = job.point
            raise cli.UsageError(
                f"agent {p['agent']!r} on {p['env']}, seed {p['seed']}: its run "
                f"{jobs_mod.train_dir(cache, job.inputs['series'])} cannot keep checkpoints at "
                f"{', '.join(f'{b:,}' for b in unreachable)} frames (it is past them, or its "
                f"resumable checkpoint is not here, as in a clone of shipped checkpoints); "
                f"--retrain trains its series again from zero"
            )


def _run(planned, cache, args, fresh) -> str | None:
    """Runs the jobs ``--only`` selects that are not done (``fresh`` ones
    whatever the cache holds), then prints the wall time and the CPUs it
    had; the failure's message when jobs failed (the others' records are
    kept), else None."""
    from hier_agents.compare.backends import JobFailed, run_jobs

    runnable = [j for j in planned if args.only in (None, j.kind)]
    _check_trainable(runnable, cache, fresh)
    say = _progress(args.quiet)
    stats: dict = {}
    failure = None
    try:
        run_jobs(
            runnable,
            cache,
            backend=args.backend,
            cpus=args.cpus,
            ray_address=args.ray_address,
            retries=args.retries,
            progress=say,
            fresh=fresh,
            stats=stats,
        )
    except JobFailed as exc:
        failure = str(exc)
    if stats.get("ran"):
        why = " (--reevaluate: every evaluation)" if args.reevaluate else ""
        print(
            f"{PROG}: {cli.plural(stats['ran'], 'job')} run{why} in "
            f"{_clock(stats['wall_s'])} wall on {stats['cpus']} CPUs ({stats['backend']})",
            file=sys.stderr,
        )
    return failure


def _check(selected, cache: Path, args) -> int:
    """``--check``: plans the replays (`hier_agents.compare.check`), prints
    them with ``--plan``, else runs them, prints the verdict per agent and
    writes ``CACHE/check.json``. 0 when no replay failed or differs from a
    record made on this kind of CPU, else 1."""
    from hier_agents.compare import check
    from hier_agents.compare.backends import JobFailed, run_jobs
    from hier_agents.provenance import provenance

    checks, skipped = check.plan(selected, cache, args.check)
    for point, why in skipped:
        budget = f" at {point['budget']:,} frames" if point.get("budget") else ""
        print(
            f"{PROG}: not replayed: {point['agent']}{budget} on {point['env']}, "
            f"seed {point['seed']}: {why}",
            file=sys.stderr,
        )
    if args.plan:
        for job, _ in checks:
            print(f"{job.key}  replay  {job.describe()}")
        return 0
    if not checks:
        raise cli.UsageError("--check: no stored evaluation to replay")
    folder = check.scratch(cache)
    stats: dict = {}
    failure = None
    try:
        run_jobs(
            [job for job, _ in checks],
            folder,
            backend=args.backend,
            cpus=args.cpus,
            ray_address=args.ray_address,
            retries=args.retries,
            progress=_progress(args.quiet),
            fresh={job.key for job, _ in checks},
            stats=stats,
        )
    except JobFailed as exc:
        failure = str(exc)
    results = check.verdicts(checks, folder)
    print(check.summary_table(results))
    for entry in results:
        for line in entry.get("differences", [])[:5]:
            p = entry["point"]
            print(f"{p['agent']} on {p['env']}, seed {p['seed']}: {line}")
    bad = sum(1 for e in results if check.failed(e))
    other = sum(1 for e in results if e.get("differences") and not check.failed(e))
    episodes = sum(e["episodes"] for e in results)
    took = f"{_clock(stats.get('wall_s', 0.0))} wall on {stats.get('cpus')} CPUs"
    print(
        f"{PROG}: {cli.plural(len(results), 'point')} replayed ({episodes} episodes) in {took}: "
        + (f"{bad} differ or failed" if bad else "none differs from a record of this CPU kind")
        + (f"; {other} differ from records made on another kind of CPU" if other else ""),
        file=sys.stderr,
    )
    cli.write_json(
        cache / "check.json",
        {
            "episodes_per_point": args.check,
            "agents": args.agents,
            "seeds": args.seeds,
            "envs": args.envs,
            "points": results,
            "not_replayed": [{"point": p, "why": why} for p, why in skipped],
            "wall_s": stats.get("wall_s"),
            "cpus": stats.get("cpus"),
            "backend": args.backend,
            "provenance": provenance(),
        },
    )
    if failure:
        print(f"{PROG}: {failure}", file=sys.stderr)
    return 1 if bad or failure else 0


def _progress(quiet: bool):
    """The per-job progress printer: timestamped lines on stderr, or none."""
    if quiet:
        return lambda text: None
    return lambda text: print(f"{time.strftime('%H:%M:%S')} {text}", file=sys.stderr, flush=True)


def _clock(seconds: float) -> str:
    """``H:MM:SS``."""
    s = int(round(seconds))
    return f"{s // 3600}:{s // 60 % 60:02d}:{s % 60:02d}"


def _content(spec, args, planned, results, missing, code_versions) -> dict:
    """comparison.json's content, its provenance aside; ``results``: the
    points, the aggregates and the series' costs (`hier_agents.compare.report`)."""
    from hier_agents.compare import report

    pts, aggs, costs = results
    return {
        "name": spec.name,
        "description": spec.description,
        "spec": spec.raw,
        "spec_file": str(spec.path),
        "metric": report.metrics(spec.envs),
        "statistic": "iqm" if args.iqm else "mean",
        "statistics": report.STATISTICS,
        "aggregate_statistics": report.AGGREGATE,
        "points": pts,
        "aggregates": aggs,
        "series_cost": costs,
        "jobs": len(planned),
        "jobs_missing": missing,
        "code_versions": code_versions,
        "job_keys": [j.key for j in planned if j.kind == "eval"],
    }


def _warn_code_versions(code_versions) -> None:
    """Warns that the job records come from more than one code version."""
    versions = ", ".join(f"{c} ({n})" for c, n in code_versions.items())
    print(
        f"{PROG}: warning: the job records come from "
        f"{len(code_versions)} code versions: {versions}; records are "
        f"cached by their inputs, not the code: delete CACHE/jobs/KEY.json to run a "
        f"job again",
        file=sys.stderr,
    )


def _write_outputs(cache: Path, content, table, spec, results, args) -> None:
    """Writes comparison.txt, comparison.png and comparison.json into
    ``cache`` (the JSON last: it marks them done), unless they already hold
    ``content``; ``results``: the points and the aggregates."""
    from hier_agents.compare import plot
    from hier_agents.provenance import provenance

    out = cache / "comparison.json"
    try:
        old = json.loads(out.read_text())
    except (OSError, ValueError):
        old = None
    outputs = [cache / name for name in ("comparison.txt", "comparison.png")]
    if (
        old is not None
        and all(p.is_file() for p in outputs)
        and {k: v for k, v in old.items() if k != "provenance"} == content
    ):
        print(f"{out} is unchanged", file=sys.stderr)
    else:
        outputs[0].parent.mkdir(parents=True, exist_ok=True)
        outputs[0].write_text(table + "\n")
        plot.plot(spec, results[0], outputs[1], results[1], use_iqm=args.iqm)
        cli.write_json(out, {**content, "provenance": provenance()})  # last: marks them done
        print(f"wrote {out}, comparison.txt and comparison.png", file=sys.stderr)


def main(argv=None) -> int:
    """Runs the experiment and writes its outputs; exit status 0, 1 when jobs
    failed (the others' results are kept and reported), 2 with one line on
    stderr for bad input (`physics_planning.cli.run_main`)."""
    return cli.run_main(PROG, _main, argv)


if __name__ == "__main__":
    sys.exit(main())
