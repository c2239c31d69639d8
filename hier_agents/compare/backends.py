"""Running an experiment's jobs: a local pool of job processes, or a Ray cluster.

`run_jobs` is the scheduler both share: it skips evaluations whose record is
in the cache and trainings whose kept checkpoints at every budget are on disk
(or whose record is, when no evaluation to run needs their checkpoints),
starts a job once the jobs it needs are done (an evaluation of a trained
agent: or once its budget's checkpoint is on disk) and its CPUs are free
(evaluations that can run before trainings, so results arrive as the
experiment runs), stores each result as it arrives, retries a failed job
(``retries`` times), and prints a line per start and end with the count
done, and every ``progress_every`` seconds a line per running training with
the frames its run directory has reached. ``fresh`` names jobs to run
whatever the cache holds (``--retrain``: trainings, whose run directories are
removed first so they start from nothing, and their evaluations;
``--reevaluate``: evaluations). Every job runs in its own process (``python -m
hier_agents.compare.jobs``), which dies with its parent: jobs differ in the
CPUs they take and share nothing, so each gets a fresh process rather than a
kept `hier_agents.executor.Pool` worker. A job whose process dies (a signal,
a lost Ray worker or node) is run again under the executor's one retry policy
(`hier_agents.executor.Deaths`: the same stderr line, at most
`WORKER_RETRIES` times, then the job fails with `WorkerDied`'s message);
``retries`` is for jobs that fail (exit status 1: an error in the job).

* ``local``: up to ``cpus`` CPUs of this machine (default: all), a job taking
  its ``cpus`` (a train job its actors, an evaluation one).
* ``ray``: each job is a Ray task with ``num_cpus`` its CPUs, on the cluster
  at ``ray_address`` (``auto``: the one ``ray start`` made; an address with
  nothing behind it is a one-line `UsageError`). The cache folder
  must be one every node sees (a shared filesystem) when training jobs run
  on other machines than their evaluations.
"""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path
from typing import TYPE_CHECKING

from hier_agents.compare.jobs import (
    Job,
    artifacts_present,
    load_record,
    needed_checkpoint,
    store_record,
    train_dir,
)
from hier_agents.executor import Deaths, WorkerDied, die_with_parent, exit_status

if TYPE_CHECKING:
    from ray import ObjectRef

_ROOT = Path(__file__).resolve().parents[2]


class JobFailed(RuntimeError):
    """A job failed after its retries."""


def job_process(job: Job, cache: Path, log: Path) -> tuple[int, float]:
    """Runs ``job`` in a child process (output appended to ``log``); returns
    its exit status and the CPU seconds it and its children used."""
    cache = Path(cache)
    log.parent.mkdir(parents=True, exist_ok=True)
    with tempfile.NamedTemporaryFile("w", suffix=".json", delete=False, dir=log.parent) as f:
        json.dump(job.to_json(), f)
        spec_file = f.name
    env = dict(os.environ)
    env["PYTHONPATH"] = os.pathsep.join(p for p in (str(_ROOT), env.get("PYTHONPATH")) if p)
    env.setdefault("MUJOCO_GL", "egl")
    try:
        with open(log, "a") as out:
            proc = subprocess.Popen(
                [sys.executable, "-m", "hier_agents.compare.jobs", spec_file, str(cache)],
                stdout=out,
                stderr=out,
                env=env,
                preexec_fn=die_with_parent,
            )
            _, status, usage = os.wait4(proc.pid, 0)
            proc.returncode = os.waitstatus_to_exitcode(status)
    finally:
        os.unlink(spec_file)
    return proc.returncode, usage.ru_utime + usage.ru_stime


def _ray_task(job_json: dict, cache: str) -> dict:  # pragma: no cover - runs on Ray workers
    job = Job.from_json(job_json)
    log = Path(cache) / "logs" / f"{job.key}.log"
    status, _ = job_process(job, Path(cache), log)
    if status != 0:
        raise JobFailed(f"{job.describe()} exited with status {status}; see {log}")
    record = load_record(Path(cache), job.key)
    if record is None:
        raise JobFailed(f"{job.describe()} wrote no record")
    import ray

    record["ray_node"] = ray.get_runtime_context().get_node_id()
    return record


def run_jobs(
    jobs: list[Job],
    cache: Path,
    *,
    backend: str = "local",
    cpus: int | None = None,
    ray_address: str | None = None,
    retries: int = 1,
    progress=print,
    fresh=frozenset(),
    progress_every: float = 60.0,
    stats: dict | None = None,
) -> dict:
    """Runs every job not already done (module docstring); returns key ->
    record of the jobs whose record is stored. ``stats``, when given, gets
    ``ran`` (jobs run), ``wall_s`` (seconds this call took), ``cpus`` (the
    CPUs the jobs could use: the pool's, or the Ray cluster's) and
    ``backend``.

    Raises:
      JobFailed: some jobs failed after their retries (the message lists
        them; every other job's record is stored).
    """
    cache = Path(cache)
    start = time.perf_counter()
    (cache / "jobs").mkdir(parents=True, exist_ok=True)
    by_key = {job.key: job for job in jobs}
    records, done, evals, trains = _cached(jobs, cache, set(fresh))
    _remove_runs([j for j in trains if j.key in fresh], cache, progress)
    # Ready evaluations go first, so that each finished training is evaluated
    # before the next one starts and results arrive as the experiment runs.
    todo = evals + trains
    total, count = len(todo), 0
    cached = len(jobs) - total
    progress(
        f"{len(jobs)} jobs: {cached} in the cache ({cache}), {total} to run"
        + (f" on {backend}" if total else "")
    )
    slots = cpus or os.cpu_count() or 1
    if stats is not None:
        stats.update(ran=total, wall_s=0.0, cpus=slots, backend=backend)
    if not todo:
        return records
    failed: dict[str, str] = {}
    starts: dict[str, float] = {}

    def ready(job):
        if all(d in done for d in job.deps):
            return True
        path = needed_checkpoint(cache, job)
        return path is not None and path.is_file()

    def blocked(job):
        return any(d in failed for d in job.deps) and not ready(job)

    def finished(job, record, error=None):
        nonlocal count
        count += 1
        took = time.perf_counter() - starts.get(job.key, time.perf_counter())
        if error is None:
            records[job.key] = record
            done.add(job.key)
            progress(f"[{count}/{total}] done   {job.describe()} ({took:,.0f} s)")
        else:
            failed[job.key] = error
            progress(f"[{count}/{total}] FAILED {job.describe()}: {error}")

    watch = _Watch(cache, starts, progress, progress_every)
    if backend == "ray":
        slots = _run_ray(
            todo, cache, cpus, ray_address, retries, ready, blocked, finished, starts, watch
        )
    else:
        _run_local(todo, cache, slots, retries, ready, blocked, finished, starts, watch)
    if stats is not None:
        stats.update(wall_s=time.perf_counter() - start, cpus=slots)
    if failed:
        lines = "; ".join(f"{by_key[k].describe()}: {v}" for k, v in failed.items())
        raise JobFailed(f"{len(failed)} of {total} jobs failed: {lines}")
    return records


def _remove_runs(trains: list[Job], cache: Path, progress) -> None:
    """Removes the run directories of ``trains`` (they train again from zero)."""
    for job in trains:
        run = train_dir(cache, job.inputs["series"])
        if run.exists():
            progress(f"removing {run}: trained again from zero")
            shutil.rmtree(run)


class _Watch:
    """Every ``every`` seconds, a line per running training: the frames its
    run directory has reached (`Trainer.frames_done`) of its target, and
    how long it has run."""

    def __init__(self, cache: Path, starts: dict, progress, every: float) -> None:
        self.cache, self.starts, self.progress, self.every = cache, starts, progress, every
        self.last = time.perf_counter()

    def __call__(self, running) -> None:
        """``running``: the jobs running now; prints when a period has passed."""
        now = time.perf_counter()
        if now - self.last < self.every:
            return
        self.last = now
        for job in running:
            if job.kind == "train":
                self.progress(
                    "       " + train_progress(self.cache, job, now - self.starts[job.key])
                )


def train_progress(cache: Path, job: Job, elapsed: float) -> str:
    """One line on a running training: frames reached of its target, and
    the seconds it has run."""
    from hier_agents.compare import trainers

    i = job.inputs
    frames = trainers.get(i["trainer"]).frames_done(train_dir(cache, i["series"]))
    share = 100 * frames / max(1, i["frames"])
    return (
        f"{job.describe()}: {frames:,} of {i['frames']:,} frames ({share:.0f}%), "
        f"{elapsed / 60:,.0f} min"
    )


def _cached(jobs: list[Job], cache: Path, fresh: set) -> tuple[dict, set, list[Job], list[Job]]:
    """(records of the done jobs the cache holds, keys of the done jobs,
    evaluations to run, trainings to run). An evaluation is done with its
    record; a training with its kept checkpoints at every budget, or with
    its record when no evaluation to run needs its checkpoints. Jobs in
    ``fresh`` are run whatever the cache holds."""
    records, done, evals, trains = {}, set(), [], []
    needed_trains: set[str] = set()
    for job in jobs:
        if job.kind != "eval":
            continue
        record = None if job.key in fresh else load_record(cache, job.key)
        if record is not None:
            records[job.key] = record
            done.add(job.key)
        else:
            evals.append(job)
            needed_trains.update(job.deps)
    for job in jobs:
        if job.kind != "train":
            continue
        record = load_record(cache, job.key)
        if record is not None:
            records[job.key] = record
        if job.key in fresh:
            records.pop(job.key, None)
            trains.append(job)
        elif artifacts_present(cache, job) or (record is not None and job.key not in needed_trains):
            done.add(job.key)
        else:
            records.pop(job.key, None)
            trains.append(job)
    return records, done, evals, trains


def _skip_blocked(pending, blocked, finished) -> None:
    for job in [j for j in pending if blocked(j)]:
        pending.remove(job)
        finished(job, None, "a job it needs failed")


def _died(deaths: Deaths, job: Job, how: str, where: str, finished) -> bool:
    """The executor's retry policy for a job whose process died: True if it
    runs again, else the job is `finished` as failed (`WorkerDied`)."""
    try:
        deaths.died([job.key], [job.describe()], how, where)
        return True
    except WorkerDied as exc:
        finished(job, None, str(exc))
        return False


def _run_local(todo, cache, slots, retries, ready, blocked, finished, starts, watch) -> None:
    progress = watch.progress
    pending = list(todo)
    running: dict[str, threading.Thread] = {}
    results: dict[str, tuple[int, float]] = {}
    lock = threading.Condition()
    attempts: dict[str, int] = {}
    deaths = Deaths()
    used = 0

    def work(job):
        status = job_process(job, cache, cache / "logs" / f"{job.key}.log")
        with lock:
            results[job.key] = status
            lock.notify_all()

    while pending or running:
        with lock:
            for key in [k for k in running if k in results]:
                thread = running.pop(key)
                thread.join()
                job = next(j for j in todo if j.key == key)
                used -= min(job.cpus, slots)
                status, _ = results.pop(key)
                record = load_record(cache, key) if status == 0 else None
                if record is not None:
                    finished(job, record)
                elif status < 0:  # its process died: the executor's policy
                    if _died(deaths, job, exit_status(status), "process", finished):
                        attempts[key] -= 1
                        pending.insert(0, job)
                elif attempts[key] <= retries:
                    progress(
                        f"retrying {job.describe()} (exit status {status}; log "
                        f"{cache / 'logs' / (key + '.log')})"
                    )
                    pending.insert(0, job)
                else:
                    finished(job, None, f"exit status {status}; log {cache / 'logs' / key}.log")
            _skip_blocked(pending, blocked, finished)
            for job in list(pending):
                need = min(job.cpus, slots)
                if ready(job) and used + need <= slots:
                    pending.remove(job)
                    used += need
                    attempts[job.key] = attempts.get(job.key, 0) + 1
                    starts.setdefault(job.key, time.perf_counter())
                    progress(f"start  {job.describe()}")
                    thread = threading.Thread(target=work, args=(job,), daemon=True)
                    running[job.key] = thread
                    thread.start()
            if not running and pending and not any(ready(j) for j in pending):
                for job in pending:
                    finished(job, None, "its dependencies never finished")
                pending.clear()
            if running:
                lock.wait(timeout=5.0)
                watch([j for j in todo if j.key in running])


def _run_ray(todo, cache, cpus, address, retries, ready, blocked, finished, starts, watch) -> int:
    """Runs ``todo`` as Ray tasks; returns the cluster's CPUs."""
    from hier_agents.cluster import connect, remote

    progress = watch.progress
    ray = connect(address, num_cpus=cpus)
    cluster_cpus = int(ray.cluster_resources().get("CPU", 0))
    task = remote(_ray_task)
    pending = list(todo)
    running: dict[ObjectRef, Job] = {}  # task ref -> its job
    attempts: dict[str, int] = {}
    deaths = Deaths()
    lost = (
        ray.exceptions.RayActorError,
        ray.exceptions.WorkerCrashedError,
        ray.exceptions.NodeDiedError,
        ray.exceptions.ObjectLostError,
    )
    while pending or running:
        _skip_blocked(pending, blocked, finished)
        for job in [j for j in pending if ready(j)]:
            pending.remove(job)
            attempts[job.key] = attempts.get(job.key, 0) + 1
            starts.setdefault(job.key, time.perf_counter())
            progress(f"start  {job.describe()}")
            ref = task.options(num_cpus=job.cpus, max_retries=0, retry_exceptions=False).remote(
                job.to_json(), str(cache)
            )
            running[ref] = job
        if not running:
            for job in pending:
                finished(job, None, "its dependencies never finished")
            break
        done_refs, _ = ray.wait(list(running), num_returns=1, timeout=10.0)
        watch(list(running.values()))
        for ref in done_refs:
            job = running.pop(ref)
            try:
                record = ray.get(ref)
            except lost as exc:  # its worker or node died: the executor's policy
                how = f"{type(exc).__name__}: {str(exc).strip().splitlines()[0][:120]}"
                if _died(deaths, job, how, "Ray task", finished):
                    attempts[job.key] -= 1
                    pending.insert(0, job)
                continue
            except Exception as exc:  # noqa: BLE001 - a failed task, reported below
                if attempts[job.key] <= retries:
                    progress(f"retrying {job.describe()} ({type(exc).__name__})")
                    pending.insert(0, job)
                else:
                    finished(job, None, f"{type(exc).__name__}: {str(exc).splitlines()[0]}")
                continue
            store_record(cache, record)  # the driver's copy
            finished(job, record)
    return cluster_cpus
