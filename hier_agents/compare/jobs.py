"""Jobs of an experiment, their cache keys, and how one job is executed.

Two kinds:

* ``train``: ``python -m hier_agents.train`` on one environment and seed up
  to the agent's largest budget, keeping a checkpoint exactly at every budget
  (``--save-at``); its run directory is ``CACHE/train/KEY`` (a killed job
  resumes from its last checkpoint when run again);
* ``eval``: ``episodes`` episodes from ``first_episode`` of one agent (a
  modular agent, a random one, or a train job's checkpoint at one budget) in
  one environment at one seed (`hier_agents.run.run`, per-episode seeding:
  shards of a point played anywhere give the rows of one run).

A job's key is a hash of everything that decides its result: its kind, its
inputs (for a modular agent with learned parts, the content hash of their
checkpoint files) and the keys of the jobs it needs, and `CACHE_VERSION`.
Finished jobs are stored as ``CACHE/jobs/KEY.json`` (the inputs, the result,
CPU and wall seconds, attempts, provenance): a run of the same spec skips
them, so a killed or extended experiment continues where it stopped.
"""

from __future__ import annotations

import hashlib
import json
import os
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path

from physics_planning import cli

#: Bumped when a change of the code changes what a job with the same inputs returns.
CACHE_VERSION = 1


@dataclass(frozen=True)
class Job:
    """One unit of work: ``kind`` (train or eval), its ``inputs`` (JSON-able),
    the keys of the jobs it needs (``deps``), the CPUs it occupies, and where
    its result goes in the comparison (``point``: agent label, env, seed and,
    for end-to-end agents, the budget)."""

    kind: str
    inputs: dict
    deps: tuple = ()
    cpus: int = 1
    point: dict = field(default_factory=dict)

    @property
    def key(self) -> str:
        return job_key(self.kind, self.inputs, self.deps)

    def describe(self) -> str:
        i = self.inputs
        if self.kind == "train":
            return (
                f"train {self.point['agent']} on {i['env']}, seed {i['seed']}, "
                f"{i['frames']:,} frames"
            )
        last = i["first_episode"] + i["episodes"] - 1
        budget = f" at {self.point['budget']:,} frames" if self.point.get("budget") else ""
        return (
            f"eval {self.point['agent']}{budget} on {i['env']}, seed {i['seed']}, "
            f"episodes {i['first_episode']}-{last}"
        )

    def to_json(self) -> dict:
        return {
            "kind": self.kind,
            "inputs": self.inputs,
            "deps": list(self.deps),
            "cpus": self.cpus,
            "point": self.point,
            "key": self.key,
        }

    @classmethod
    def from_json(cls, data: dict) -> "Job":
        return cls(
            kind=data["kind"],
            inputs=data["inputs"],
            deps=tuple(data["deps"]),
            cpus=int(data["cpus"]),
            point=data["point"],
        )


def job_key(kind: str, inputs: dict, deps=()) -> str:
    """A stable hash (20 hex digits) of a job's kind, inputs, dependencies'
    keys and `CACHE_VERSION`; equal inputs give equal keys in any process or
    order of dict keys."""
    text = json.dumps(
        {"version": CACHE_VERSION, "kind": kind, "inputs": inputs, "deps": list(deps)},
        sort_keys=True,
        separators=(",", ":"),
    )
    return hashlib.sha256(text.encode()).hexdigest()[:20]


def plan(spec) -> list[Job]:
    """Every job of a spec (`hier_agents.compare.spec.Spec`), train jobs first."""
    from hier_agents.agents import resolve

    trains, evals = [], []
    targets: list[tuple[dict, tuple, dict]]
    cpus = os.cpu_count() or 1
    for agent in spec.agents:
        for env in agent.envs:
            for seed in agent.seeds:
                point = {"agent": agent.label, "env": env, "seed": seed}
                if agent.kind == "train":
                    inputs = {
                        "env": env,
                        "train": agent.train,
                        "seed": seed,
                        "frames": max(agent.budgets),
                        "save_at": list(agent.budgets),
                    }
                    actors = int(agent.train.get("actors", 2))
                    train = Job("train", inputs, cpus=min(cpus, actors), point=point)
                    trains.append(train)
                    targets = [
                        (
                            {"kind": "checkpoint", "budget": b, "stochastic": agent.stochastic},
                            (train.key,),
                            {**point, "budget": b},
                        )
                        for b in agent.budgets
                    ]
                else:
                    kind, arg = resolve(agent.agent)
                    targets = [(kind.job_inputs(env, arg, agent.options), (), point)]
                for target, deps, where in targets:
                    evals.extend(
                        _eval_jobs(
                            env, target, seed, agent.episodes, spec.shard_episodes, deps, where
                        )
                    )
    return trains + evals


def _eval_jobs(env, target, seed, episodes, shard, deps, point) -> list[Job]:
    """The evaluation jobs of one point: ``episodes`` in shards of ``shard``."""
    return [
        Job(
            "eval",
            {
                "env": env,
                "agent": target,
                "seed": seed,
                "first_episode": first,
                "episodes": min(shard, episodes - first),
            },
            deps=deps,
            point=point,
        )
        for first in range(0, episodes, shard)
    ]


# -- execution ---------------------------------------------------------------------------


def record_path(cache: Path, key: str) -> Path:
    return Path(cache) / "jobs" / f"{key}.json"


def train_dir(cache: Path, key: str) -> Path:
    return Path(cache) / "train" / key


def checkpoint_of(cache: Path, train_key: str, budget: int) -> Path:
    """A train job's kept checkpoint at ``budget`` frames."""
    return train_dir(cache, train_key) / "checkpoints" / f"frames-{int(budget)}.pt"


def store_record(cache: Path, record: dict) -> Path:
    """Writes a finished job's record (``record["key"]``) atomically."""
    path = record_path(cache, record["key"])
    path.parent.mkdir(parents=True, exist_ok=True)
    return cli.write_json(path, record)


def load_record(cache: Path, key: str) -> dict | None:
    """The stored record of a finished job, or None (absent or unreadable)."""
    try:
        return json.loads(record_path(cache, key).read_text())
    except (OSError, ValueError):
        return None


def artifacts_present(cache: Path, job: Job) -> bool:
    """Whether a finished train job's checkpoints are still on disk (they are
    not shipped; a record without them is re-run when an evaluation needs them)."""
    if job.kind != "train":
        return True
    return all(checkpoint_of(cache, job.key, b).is_file() for b in job.inputs["save_at"])


def execute(job: Job, cache: Path) -> dict:
    """Runs one job in this process; returns its result (JSON-able).

    Raises whatever the job raised (a failed training, a missing checkpoint).
    """
    cache = Path(cache)
    inputs = job.inputs
    if job.kind == "train":
        from hier_agents.baselines.impala.config import TrainConfig
        from hier_agents.baselines.impala.learner import train
        from hier_agents.compare.spec import train_argv

        logdir = train_dir(cache, job.key)
        planned = {
            "frames": inputs["frames"],
            "seed": inputs["seed"],
            "logdir": str(logdir),
            "save_at": list(inputs["save_at"]),
            "no_progress": True,
            "log_every": 30.0,
            "checkpoint_every": 120.0,
        }
        config = TrainConfig.from_options(inputs["env"], {**inputs["train"], **planned})
        counters = train(config)
        counters.pop("last_stats", None)
        missing = [b for b in inputs["save_at"] if not checkpoint_of(cache, job.key, b).is_file()]
        if missing:
            raise RuntimeError(
                f"training ended at {counters.get('frames')} frames without "
                f"checkpoints at {missing}"
            )
        # The command that trains the same run, for a reader of the record.
        argv = train_argv(
            inputs["env"],
            inputs["train"],
            frames=inputs["frames"],
            seed=inputs["seed"],
            logdir=str(logdir),
            save_at=inputs["save_at"],
        ) + ["--no-progress", "--log-every", "30", "--checkpoint-every", "120"]
        return {"counters": counters, "argv": argv}
    from hier_agents.agents import kind_of
    from hier_agents.run import run

    agent = inputs["agent"]
    if agent["kind"] == "checkpoint" and job.deps:  # a train job's checkpoint at a budget
        path = checkpoint_of(cache, job.deps[0], agent["budget"])
        if not path.is_file():
            raise FileNotFoundError(f"the train job's checkpoint {path} is missing")
        name, options = f"checkpoint:{path}", {"stochastic": agent.get("stochastic", False)}
    else:
        kind = kind_of(agent["kind"])
        arg, options = kind.from_job_inputs(agent)
        name = kind.form(arg)
    summary = run(
        inputs["env"],
        inputs["episodes"],
        inputs["seed"],
        progress=False,
        first_episode=inputs["first_episode"],
        agent=name,
        options={k: v for k, v in options.items() if v not in (None, False)},
    )
    rows = summary.pop("rows")
    summary.pop("provenance", None)
    return {"rows": rows, "summary": summary}


def _cpu_seconds() -> float:
    import resource

    usage = [resource.getrusage(w) for w in (resource.RUSAGE_SELF, resource.RUSAGE_CHILDREN)]
    return sum(u.ru_utime + u.ru_stime for u in usage)


def run_job_file(path: str | Path, cache: str | Path) -> int:
    """The job process: reads a job (`Job.to_json`) from ``path``, executes it,
    and stores its record in ``cache`` (atomically). Returns 0, or 1 after
    printing the error (the record is not written)."""
    from hier_agents.provenance import provenance

    cache = Path(cache)
    job = Job.from_json(json.loads(Path(path).read_text()))
    attempts = _note_attempt(cache, job.key)
    start, cpu0 = time.perf_counter(), _cpu_seconds()
    try:
        result = execute(job, cache)
    except BaseException as exc:  # reported to the scheduler by the exit status
        import traceback

        traceback.print_exc()
        print(f"job {job.key} failed: {type(exc).__name__}: {exc}", file=sys.stderr)
        return 1
    record = {
        **job.to_json(),
        "result": result,
        "wall_s": time.perf_counter() - start,
        "cpu_s": _cpu_seconds() - cpu0,
        "attempts": attempts,
        "provenance": provenance(),
    }
    store_record(cache, record)
    return 0


def _note_attempt(cache: Path, key: str) -> int:
    """Appends this process to the job's attempt log (``CACHE/attempts/KEY``:
    one line per start, with the pid and the parent's); returns the count."""
    folder = cache / "attempts"
    folder.mkdir(parents=True, exist_ok=True)
    log = folder / key
    with open(log, "a") as f:
        f.write(f"{time.time():.3f} pid={os.getpid()} parent={os.getppid()}\n")
    return sum(1 for _ in open(log))


if __name__ == "__main__":
    sys.exit(run_job_file(sys.argv[1], sys.argv[2]))
