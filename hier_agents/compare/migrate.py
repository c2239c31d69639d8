"""``python -m hier_agents.compare.migrate SPEC [--cache DIR]``: re-keys a
version 1 cache (`hier_agents.compare.jobs.CACHE_VERSION` 1) to this version.

Version 1 keyed a train job by its inputs without a trainer or series, its
run directory by that key (which held the largest budget), and an evaluation
of a trained agent by ``{"kind": "checkpoint", "budget", "stochastic"}`` and
its train job's key. For every job of the spec's plan this recomputes the
version 1 key; a record stored under it is rewritten under the job's key
now, with the job's inputs, dependencies and key, its result unchanged, and
``migrated: {"from_version": 1, "from_key": OLD}``; the old record is
removed. A version 1 run directory ``train/OLD`` becomes
``train/SERIES``. Records of jobs the spec does not plan are left alone.
Exit status 0, 2 with one line for bad input.
"""

from __future__ import annotations

import hashlib
import json
import sys
from pathlib import Path

from physics_planning import cli

PROG = "python -m hier_agents.compare.migrate"


def v1_key(kind: str, inputs: dict, deps=()) -> str:
    """A job's key under version 1 (its kind, inputs and dependencies' keys)."""
    text = json.dumps(
        {"version": 1, "kind": kind, "inputs": inputs, "deps": list(deps)},
        sort_keys=True,
        separators=(",", ":"),
    )
    return hashlib.sha256(text.encode()).hexdigest()[:20]


def v1_keys(planned) -> dict[str, str]:
    """Key now -> its version 1 key, for every job of a plan whose trainer
    version 1 knew (IMPALA's ``train`` tables)."""
    trains = {}  # series -> the version 1 key of its train job
    out = {}
    for job in planned:
        if job.kind == "train" and job.inputs["trainer"] == "impala":
            i = job.inputs
            old = {k: i[k] for k in ("env", "train", "seed", "frames", "save_at")}
            trains[i["series"]] = out[job.key] = v1_key("train", old)
    for job in planned:
        if job.kind != "eval":
            continue
        agent = job.inputs["agent"]
        if agent.get("kind") != "series":
            out[job.key] = v1_key("eval", job.inputs)
        elif agent["series"] in trains:
            target = {"kind": "checkpoint", "budget": agent["budget"]}
            target["stochastic"] = agent["stochastic"]
            inputs = {**job.inputs, "agent": target}
            out[job.key] = v1_key("eval", inputs, (trains[agent["series"]],))
    return out


def migrate(planned, cache: Path) -> dict:
    """Re-keys ``cache``'s version 1 records and run directories of the
    ``planned`` jobs (module docstring); returns the counts ``records``,
    ``run_dirs`` and ``already`` (jobs whose record is already keyed now)."""
    from hier_agents.compare import jobs as jobs_mod

    cache = Path(cache)
    counts = {"records": 0, "run_dirs": 0, "already": 0}
    by_key = {job.key: job for job in planned}
    for key, old in v1_keys(planned).items():
        job = by_key[key]
        if jobs_mod.load_record(cache, key) is not None:
            counts["already"] += 1
        elif (record := jobs_mod.load_record(cache, old)) is not None:
            migrated = {"from_version": 1, "from_key": old}
            jobs_mod.store_record(cache, {**record, **job.to_json(), "migrated": migrated})
            jobs_mod.record_path(cache, old).unlink()
            counts["records"] += 1
        if job.kind == "train":
            before, after = cache / "train" / old, jobs_mod.train_dir(cache, job.inputs["series"])
            if before.is_dir() and not after.exists():
                before.rename(after)
                counts["run_dirs"] += 1
    return counts


def _main(argv=None) -> int:
    from hier_agents.compare import jobs as jobs_mod
    from hier_agents.compare.spec import load

    parser = cli.Parser(PROG, description=__doc__.split("\n\n")[0])
    parser.add_argument("spec", type=cli.existing_file, help="the experiment's TOML spec")
    parser.add_argument(
        "--cache",
        type=Path,
        default=None,
        help="the cache folder (default: the spec's cache, else runs/compare/NAME)",
    )
    args = parser.parse_args(argv)
    spec = load(args.spec)
    counts = migrate(jobs_mod.plan(spec), args.cache or spec.cache)
    print(
        f"{cli.plural(counts['records'], 'record')} and "
        f"{cli.plural(counts['run_dirs'], 'run directory', 'run directories')} re-keyed to "
        f"version {jobs_mod.CACHE_VERSION}; {counts['already']} already were"
    )
    return 0


def main(argv=None) -> int:
    """The command (module docstring)."""
    return cli.run_main(PROG, _main, argv)


if __name__ == "__main__":
    sys.exit(main())
