"""``--check EPISODES``: a cache's evaluation records replayed and compared.

For every point of the spec (agent, environment, seed and, for trained
agents, budget) whose first evaluation shard has a stored record, a check
job plays that shard's first ``EPISODES`` episodes again, with the same
agent, seeds and environment settings: a trained agent from its series' kept
checkpoint (the shipped ``frames-B`` file), a modular or random agent as the
spec builds it. Evaluation seeds each episode (`hier_agents.run.run`), so a
replay gives the stored rows again, field for field, when the code,
checkpoints and libraries are those the records came from. Nothing is
trained.

The check jobs run through `hier_agents.compare.backends.run_jobs` (local
pool or Ray) in the scratch folder ``CACHE/checks`` (not committed), whose
``train`` links to ``CACHE/train``; the cache's own records are only read.
The verdict is written to ``CACHE/check.json``: per point the episodes
replayed, the fields that differ and whether the record was made on another
kind of CPU (floating point then differs in the last bits and long episodes
may diverge: such differences are reported, not counted as failures), the
points that cannot be replayed (no stored record, or a kept checkpoint that
is not on disk: not shipped) and the wall time it took.
"""

from __future__ import annotations

import json
import math
from pathlib import Path

from hier_agents.compare.jobs import Job, load_record, needed_checkpoint

#: Row fields a replay does not reproduce (timing).
TIMING_FIELDS = frozenset({"wall_s"})

#: The folder of ``CACHE`` that holds the check jobs' records.
SCRATCH = "checks"


def plan(planned: list[Job], cache: Path, episodes: int) -> tuple[list[tuple[Job, dict]], list]:
    """The check jobs of ``planned`` (a spec's jobs), each with the stored
    record it replays, and the points that cannot be checked.

    Returns:
      ``(checks, skipped)``: ``checks`` pairs a check job (the point's first
      shard with its first ``episodes`` episodes) with that shard's record;
      ``skipped`` lists ``(point, why)``.
    """
    first: dict[str, Job] = {}
    for job in planned:
        if job.kind != "eval":
            continue
        point = json.dumps(job.point, sort_keys=True)
        if point not in first or job.inputs["first_episode"] < first[point].inputs["first_episode"]:
            first[point] = job
    checks, skipped = [], []
    for job in first.values():
        record = load_record(cache, job.key)
        checkpoint = needed_checkpoint(cache, job)
        if record is None:
            skipped.append((job.point, "no stored record"))
        elif checkpoint is not None and not checkpoint.is_file():
            skipped.append((job.point, f"its checkpoint {checkpoint} is not on disk"))
        else:
            count = min(episodes, job.inputs["episodes"])
            replay = Job(
                "eval",
                {**job.inputs, "episodes": count},
                cpus=job.cpus,
                point=job.point,
            )
            checks.append((replay, record))
    return checks, skipped


def scratch(cache: Path) -> Path:
    """``CACHE/checks``, made if absent, with ``train`` linked to the cache's
    run directories (the kept checkpoints the replays load)."""
    folder = Path(cache) / SCRATCH
    folder.mkdir(parents=True, exist_ok=True)
    link = folder / "train"
    if not link.is_symlink() and not link.exists():
        link.symlink_to((Path(cache) / "train").resolve(), target_is_directory=True)
    return folder


def differences(stored: list[dict], replayed: list[dict]) -> list[str]:
    """The fields in which ``replayed`` rows differ from the first
    ``len(replayed)`` of ``stored``, one line each; empty when they agree.
    The fields compared are the stored row's, timing aside (a field the
    replay adds is a newer diagnostic the record predates; one it lacks
    differs); floats agree to 1e-9 relative."""
    out = []
    if len(replayed) > len(stored):
        return [f"{len(replayed)} rows replayed, {len(stored)} stored"]
    for old, new in zip(stored, replayed):
        episode = old.get("episode")
        for name in sorted(set(old) - TIMING_FIELDS):
            a, b = old[name], new.get(name, "(absent)")
            if not _same(a, b):
                out.append(f"episode {episode}: {name} {a!r} stored, {b!r} replayed")
    return out


def _same(a, b) -> bool:
    if isinstance(a, float) or isinstance(b, float):
        if a is None or b is None:
            return a is b
        return math.isclose(a, b, rel_tol=1e-9, abs_tol=1e-12)
    if isinstance(a, list) and isinstance(b, list):
        return len(a) == len(b) and all(_same(x, y) for x, y in zip(a, b))
    if isinstance(a, dict) and isinstance(b, dict):
        return a.keys() == b.keys() and all(_same(a[k], b[k]) for k in a)
    return a == b


def verdicts(checks: list[tuple[Job, dict]], folder: Path) -> list[dict]:
    """Per check: its point, the episodes replayed, the differences
    (`differences`) or ``error`` when its replay wrote no record, and
    ``other_cpu``: whether the record was made on another kind of CPU than
    this one (MuJoCo's and torch's vectorised floating point then differs in
    the last bits, and a long episode may diverge)."""
    from hier_agents.provenance import cpu_model

    here = cpu_model()
    out = []
    for job, record in checks:
        replayed = load_record(folder, job.key)
        made_on = ((record.get("provenance") or {}).get("machine") or {}).get("cpu")
        entry = {
            "point": job.point,
            "episodes": job.inputs["episodes"],
            "recorded_on": made_on,
            "replayed_on": here,
            "other_cpu": made_on is not None and made_on != here,
        }
        if replayed is None:
            entry["error"] = "the replay wrote no record (it failed)"
        else:
            entry["differences"] = differences(record["result"]["rows"], replayed["result"]["rows"])
        out.append(entry)
    return out


def failed(entry: dict) -> bool:
    """Whether a verdict counts against the check: a replay that failed, or
    one that differs from a record made on this kind of CPU."""
    return "error" in entry or bool(entry.get("differences")) and not entry["other_cpu"]


def summary_table(results: list[dict]) -> str:
    """A line per agent: points replayed, episodes, points that agree, that
    differ (from records of this kind of CPU / of another) and that failed."""
    by_agent: dict[str, list[dict]] = {}
    for entry in results:
        by_agent.setdefault(entry["point"]["agent"], []).append(entry)
    width = max([len("agent"), *map(len, by_agent)])
    lines = [f"{'agent':<{width}}  points  episodes  agree  differ  differ, other CPU  failed"]
    for agent, entries in by_agent.items():
        differ = sum(1 for e in entries if e.get("differences") and not e["other_cpu"])
        other = sum(1 for e in entries if e.get("differences") and e["other_cpu"])
        errors = sum(1 for e in entries if "error" in e)
        episodes = sum(e["episodes"] for e in entries)
        agree = len(entries) - differ - other - errors
        lines.append(
            f"{agent:<{width}}  {len(entries):>6}  {episodes:>8}  {agree:>5}  {differ:>6}  "
            f"{other:>17}  {errors:>6}"
        )
    return "\n".join(lines)
