"""Jobs of an experiment, their cache keys, and how one job is executed.

Two kinds:

* ``train``: one trainer (`hier_agents.compare.trainers`: ``impala``,
  ``sb3``) on one environment and seed up to the agent's largest budget,
  keeping a checkpoint exactly at every budget (``save_at``). A training
  series (trainer, environment, the trainer's table, seed) has one run
  directory, ``CACHE/train/SERIES`` (`series_key`), whatever its budgets: a
  killed job resumes from the run's last checkpoint, and a spec whose
  largest budget grows (1M -> 5M frames) resumes the same run where it
  stopped instead of training again from zero;
* ``eval``: ``episodes`` episodes from ``first_episode`` of one agent (a
  modular agent, a random one, or a series' kept checkpoint at one budget)
  in one environment at one seed (`hier_agents.run.run`, per-episode
  seeding: shards of a point played anywhere give the rows of one run).

A job names its environment by name and, as ``env_options``, by the settings
that differ from the original implementation's (`envs.deviations`; absent
when there are none), and plays it with ``envs.original_options(env)``
updated by them (`env_overrides`): a default that changes gives new keys to
the specs that leave it as it is, while a spec pinned to the original's
settings keeps its keys and its meaning.

A job's key is a hash of its kind, its inputs and `CACHE_VERSION`: for an
evaluation of a trained agent, the series key and the budget (not the
largest budget: growing a series keeps its evaluations); for a modular
agent with learned parts, the content hash of their checkpoint files; for a
training, the series and the budgets it must reach. Finished jobs are
stored as ``CACHE/jobs/KEY.json`` (the inputs, the result, CPU and wall
seconds, attempts, provenance): a run of the same spec skips them, so a
killed or extended experiment continues where it stopped. A training whose
kept checkpoints at every budget are on disk counts as done without its
record (a clone with shipped checkpoints).

Version 2 (this one): keys no longer hash the keys of the jobs a job needs,
train jobs carry their trainer's name and series key, and an evaluation of
a trained agent names its series and budget; run directories are
``train/SERIES``. `hier_agents.compare.migrate` re-keys a version 1 cache.
"""

from __future__ import annotations

import hashlib
import json
import os
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path

from hier_agents.compare import trainers
from physics_planning import cli

#: Bumped when keys change, or when a change of the code changes what a job with
#: the same inputs returns. 2: series keys (module docstring).
CACHE_VERSION = 2


@dataclass(frozen=True)
class Job:
    """One unit of work: ``kind`` (train or eval), its ``inputs`` (JSON-able),
    the keys of the jobs it waits for (``deps``: scheduling only, not part
    of its key), the CPUs it occupies, and where its result goes in the
    comparison (``point``: agent label, env, seed and, for trained agents,
    the budget)."""

    kind: str
    inputs: dict
    deps: tuple = ()
    cpus: int = 1
    point: dict = field(default_factory=dict)

    @property
    def key(self) -> str:
        return job_key(self.kind, self.inputs)

    def describe(self) -> str:
        i = self.inputs
        if self.kind == "train":
            return (
                f"train {self.point['agent']} ({i['trainer']}) on {i['env']}, seed {i['seed']}, "
                f"to {i['frames']:,} frames"
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


def job_key(kind: str, inputs: dict) -> str:
    """A stable hash (20 hex digits) of a job's kind, inputs and
    `CACHE_VERSION`; equal inputs give equal keys in any process or order
    of dict keys."""
    text = json.dumps(
        {"version": CACHE_VERSION, "kind": kind, "inputs": inputs},
        sort_keys=True,
        separators=(",", ":"),
    )
    return hashlib.sha256(text.encode()).hexdigest()[:20]


def series_key(trainer: str, env: str, table: dict, seed: int, env_options=None) -> str:
    """The key of a training series: its trainer's name, environment (with
    ``env_options``, the settings that differ from the original's,
    `envs.deviations`, when there are any), the trainer's table and seed, not
    its budgets (the run directory ``CACHE/train/KEY`` and every evaluation
    of the series name it).

    The key holds the table as the spec gives it, not the trainer's
    defaults: a change of a default that changes what a table trains must
    bump `CACHE_VERSION` (or come as a new option or preset, as
    ``--preset small-batches`` did), else old runs would stand for new ones.
    An environment's default needs neither: ``env_options`` name every
    setting that deviates from the original's, defaults included."""
    inputs = {"trainer": trainer, "env": env, "table": table, "seed": seed}
    return job_key("series", {**inputs, **_with_env_options(env_options)})


def _with_env_options(deviations) -> dict:
    """``{"env_options": deviations}``, or nothing when there are none (the
    keys of jobs on the original's settings stay what they were before
    job inputs named settings)."""
    return {"env_options": dict(deviations)} if deviations else {}


def env_overrides(inputs: dict) -> dict:
    """The `envs.load` overrides a job's ``inputs`` play their environment
    with: the original implementation's settings updated by the job's
    ``env_options`` (the deviations from them; `envs.recorded_options`)."""
    import envs

    return envs.recorded_options(inputs["env"], inputs.get("env_options", {}))


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
                    train = train_job(agent, env, seed, point, cpus)
                    trains.append(train)
                    targets = [
                        (
                            {
                                "kind": "series",
                                "trainer": agent.trainer,
                                "series": train.inputs["series"],
                                "budget": b,
                                "stochastic": agent.stochastic,
                            },
                            (train.key,),
                            {**point, "budget": b},
                        )
                        for b in agent.budgets_for(env)
                    ]
                else:
                    kind, arg = resolve(agent.agent)
                    targets = [(kind.job_inputs(env, arg, agent.options), (), point)]
                deviations = agent.deviations(env)
                for target, deps, where in targets:
                    evals.extend(
                        _eval_jobs(
                            env,
                            deviations,
                            target,
                            seed,
                            agent.episodes,
                            spec.shard_episodes,
                            deps,
                            where,
                        )
                    )
    return trains + evals


def train_job(agent, env: str, seed: int, point: dict, cpus: int) -> Job:
    """The train job of a trained agent's series on ``env`` at ``seed``: up
    to its largest budget, keeping every budget."""
    trainer = trainers.get(agent.trainer)
    deviations = agent.deviations(env)
    inputs = {
        "trainer": agent.trainer,
        "env": env,
        **_with_env_options(deviations),
        "train": agent.train,
        "seed": seed,
        "series": series_key(agent.trainer, env, agent.train, seed, deviations),
        "frames": max(agent.budgets_for(env)),
        "save_at": list(agent.budgets_for(env)),
    }
    return Job("train", inputs, cpus=trainer.cpus(agent.train, cpus), point=point)


def _eval_jobs(env, deviations, target, seed, episodes, shard, deps, point) -> list[Job]:
    """The evaluation jobs of one point: ``episodes`` in shards of ``shard``
    on ``env`` with the settings ``deviations`` (`envs.deviations`)."""
    return [
        Job(
            "eval",
            {
                "env": env,
                **_with_env_options(deviations),
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


# -- the cache -----------------------------------------------------------------------------


def record_path(cache: Path, key: str) -> Path:
    return Path(cache) / "jobs" / f"{key}.json"


def train_dir(cache: Path, series: str) -> Path:
    """A series' run directory."""
    return Path(cache) / "train" / series


def checkpoint_of(cache: Path, trainer: str, series: str, budget: int) -> Path:
    """A series' kept checkpoint at ``budget`` frames."""
    return trainers.get(trainer).checkpoint(train_dir(cache, series), budget)


def needed_checkpoint(cache: Path, job: Job) -> Path | None:
    """The kept checkpoint an evaluation of a trained agent plays (None for
    other jobs): once it is on disk the evaluation may run, whatever its
    training job's state."""
    agent = job.inputs.get("agent") or {}
    if job.kind != "eval" or agent.get("kind") != "series":
        return None
    return checkpoint_of(cache, agent["trainer"], agent["series"], agent["budget"])


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
    """Whether a train job's kept checkpoints at every budget are on disk
    (True for other jobs)."""
    if job.kind != "train":
        return True
    i = job.inputs
    return all(checkpoint_of(cache, i["trainer"], i["series"], b).is_file() for b in i["save_at"])


def series_records(cache: Path) -> dict[str, dict]:
    """Per series key, the stored train record that reached the most frames
    (any spec's, any budgets: the series' cost so far)."""
    out: dict[str, dict] = {}
    for path in sorted((Path(cache) / "jobs").glob("*.json")):
        try:
            record = json.loads(path.read_text())
        except (OSError, ValueError):
            continue
        series = (record.get("inputs") or {}).get("series")
        if record.get("kind") != "train" or not series:
            continue
        best = out.get(series)
        if best is None or record["inputs"]["frames"] > best["inputs"]["frames"]:
            out[series] = record
    return out


def unreachable_budgets(cache: Path, job: Job) -> list[int]:
    """Budgets of a train job its run can no longer keep a checkpoint at:
    missing, and below what the run has already trained (a budget added
    under a finished part), or every missing one when the run's resumable
    checkpoint is gone but kept ones are there (a clone with shipped
    checkpoints: training again from zero would overwrite them). Empty
    when the job can run."""
    i = job.inputs
    trainer = trainers.get(i["trainer"])
    run = train_dir(cache, i["series"])
    kept = trainer.kept_budgets(run)
    missing = [b for b in i["save_at"] if not trainer.checkpoint(run, b).is_file()]
    if kept and not (run / trainer.latest).is_file():
        return missing
    done = trainer.frames_done(run)
    return [b for b in missing if b < done]


# -- execution ---------------------------------------------------------------------------


def execute(job: Job, cache: Path) -> dict:
    """Runs one job in this process; returns its result (JSON-able).

    Raises whatever the job raised (a failed training, a missing checkpoint).
    """
    if job.kind == "train":
        return _train(job, Path(cache))
    return _evaluate(job, Path(cache))


def _train(job: Job, cache: Path) -> dict:
    """A train job: trains (or resumes) the series' run to the job's frames.

    Result: the trainer's ``counters``, ``series_cpu_s`` (CPU seconds of the
    series so far, over every resumed part: the trainer's own ``cpu_s`` when
    it spans resumes, else the series' earlier parts' plus this one's; None
    when unknown), the frames it resumed from (0: a fresh run), and the
    command that trains the same run (None for trainers without one).

    Raises:
      RuntimeError: budgets the run can no longer keep (`unreachable_budgets`)
        or a training that ended without a checkpoint at every budget.
    """
    i = job.inputs
    trainer = trainers.get(i["trainer"])
    logdir = train_dir(cache, i["series"])
    unreachable = unreachable_budgets(cache, job)
    if unreachable:
        raise RuntimeError(
            f"{logdir} cannot keep checkpoints at {unreachable} any more (its run is past "
            f"them, or its resumable {trainer.latest} is not here); run with --retrain"
        )
    resumed_from = trainer.frames_done(logdir) if (logdir / trainer.latest).is_file() else 0
    before = series_records(cache).get(i["series"])
    planned = dict(frames=i["frames"], seed=i["seed"], save_at=i["save_at"], logdir=logdir)
    config = trainer.make_config(i["env"], i["train"], env_options=env_overrides(i), **planned)
    counters = trainer.train(config)
    counters.pop("last_stats", None)
    missing = [b for b in i["save_at"] if not trainer.checkpoint(logdir, b).is_file()]
    if missing:
        raise RuntimeError(
            f"training ended at {counters.get('frames')} frames without checkpoints at {missing}"
        )
    cpu = counters.get("cpu_s")
    if cpu is not None and not trainer.cpu_spans_resumes and resumed_from:
        earlier = ((before or {}).get("result") or {}).get("series_cpu_s")
        cpu = None if earlier is None else float(earlier) + float(cpu)
    return {
        "counters": counters,
        "series_cpu_s": cpu,
        "resumed_from": resumed_from,
        "argv": trainer.argv(
            i["env"], i["train"], **{**planned, "logdir": str(logdir)}, env_options=env_overrides(i)
        ),
    }


def _evaluate(job: Job, cache: Path) -> dict:
    """An eval job: its episodes played (`hier_agents.run.run`); the rows
    and the summary."""
    from hier_agents.agents import kind_of
    from hier_agents.run import run

    inputs = job.inputs
    agent = inputs["agent"]
    path = needed_checkpoint(cache, job)
    if path is not None:  # a series' kept checkpoint at a budget
        if not path.is_file():
            raise FileNotFoundError(f"the series' checkpoint {path} is missing")
        name = trainers.get(agent["trainer"]).agent(path)
        options = {"stochastic": agent.get("stochastic", False)}
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
        env_options=env_overrides(inputs),
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
