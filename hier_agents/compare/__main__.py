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
        "--iqm",
        action="store_true",
        help="table and plot show the interquartile mean over seeds instead of the mean",
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
    if args.only is not None:
        cli.choice("--only", args.only, ("train", "eval"))
    if args.plan:
        _print_plan(planned, cache)
        return 0
    failure = None if args.report_only else _run(planned, cache, args)
    records = {j.key: r for j in planned if (r := jobs_mod.load_record(cache, j.key)) is not None}
    pts = report.points(spec, planned, records)
    costs = report.series_cost(spec, planned, records)
    table = report.format_table(spec, pts, costs, use_iqm=args.iqm)
    print(table)
    missing = sum(1 for j in planned if j.key not in records)
    code_versions = report.code_versions(records)
    content = _content(spec, args, planned, pts, costs, missing, code_versions)
    if len(code_versions) > 1:
        _warn_code_versions(code_versions)
    _write_outputs(Path(cache), content, table, spec, pts, args)
    if failure:
        print(f"{PROG}: {failure}", file=sys.stderr)
        return 1
    if missing:
        print(f"{PROG}: {cli.plural(missing, 'job')} missing from the cache", file=sys.stderr)
    return 0


def _print_plan(planned, cache) -> None:
    """``--plan``: a line per job, cached or to run."""
    from hier_agents.compare import jobs as jobs_mod

    for job in planned:
        record = jobs_mod.load_record(cache, job.key)
        state = "cached" if record is not None else "to run"
        print(f"{job.key}  {state:<7} {job.describe()}")


def _run(planned, cache, args) -> str | None:
    """Runs the jobs ``--only`` selects that are not cached; the failure's
    message when jobs failed (the others' records are kept), else None."""
    from hier_agents.compare.backends import JobFailed, run_jobs

    runnable = [j for j in planned if args.only in (None, j.kind)]
    say = (
        (lambda text: None)
        if args.quiet
        else (
            lambda text: print(f"{time.strftime('%H:%M:%S')} {text}", file=sys.stderr, flush=True)
        )
    )
    try:
        run_jobs(
            runnable,
            cache,
            backend=args.backend,
            cpus=args.cpus,
            ray_address=args.ray_address,
            retries=args.retries,
            progress=say,
        )
    except JobFailed as exc:
        return str(exc)
    return None


def _content(spec, args, planned, pts, costs, missing, code_versions) -> dict:
    """comparison.json's content, its provenance aside."""
    return {
        "name": spec.name,
        "description": spec.description,
        "spec": spec.raw,
        "spec_file": str(spec.path),
        "statistic": "iqm" if args.iqm else "mean",
        "points": pts,
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


def _write_outputs(cache: Path, content, table, spec, pts, args) -> None:
    """Writes comparison.txt, comparison.png and comparison.json into
    ``cache`` (the JSON last: it marks them done), unless they already hold
    ``content``."""
    from hier_agents.compare import report
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
        report.plot(spec, pts, outputs[1], use_iqm=args.iqm)
        cli.write_json(out, {**content, "provenance": provenance()})  # last: marks them done
        print(f"wrote {out}, comparison.txt and comparison.png", file=sys.stderr)


def main(argv=None) -> int:
    """Runs the experiment and writes its outputs; exit status 0, 1 when jobs
    failed (the others' results are kept and reported), 2 with one line on
    stderr for bad input (`physics_planning.cli.run_main`)."""
    return cli.run_main(PROG, _main, argv)


if __name__ == "__main__":
    sys.exit(main())
