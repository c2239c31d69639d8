"""The one executor (`hier_agents.executor`): stateful workers kept across
calls, a dead worker replaced and its calls run again under one retry policy
(one stderr line format, `WORKER_RETRIES`, then `WorkerDied`) for every
caller, an unreachable Ray address refused in one line, and one `TrainConfig`
from argv or a spec's train table."""

from __future__ import annotations

import os
import signal
import tomllib
from functools import partial

import pytest

from physics_planning.cli import UsageError
from hier_agents.executor import WORKER_RETRIES, CallFailed, Pool, WorkerDied

LINE = (
    "hier_agents: a worker process died ({how}); running {what} again in a new {where} "
    "(retry {n} of " + str(WORKER_RETRIES) + ")"
)


class Counter:
    """A worker with state: ``add`` returns its running total and its pid."""

    def __init__(self, start: int, index: int):
        self.total = start + 100 * index

    def add(self, n: int) -> tuple[int, int]:
        self.total += n
        return self.total, os.getpid()

    def die(self) -> None:
        os.kill(os.getpid(), signal.SIGKILL)

    def fail(self) -> None:
        raise ValueError("a bad call")


def test_a_worker_keeps_its_state_between_calls():
    with Pool(partial(Counter, 1), 2) as pool:
        pool.submit("add", 1, worker=0)
        pool.submit("add", 2, worker=0)
        pool.submit("add", 5, worker=1)
        results = sorted(pool.next(timeout=120).result[0] for _ in range(3))
    assert results == [2, 4, 106]


def test_a_killed_worker_is_replaced_and_its_call_runs_again(capfd):
    with Pool(partial(Counter, 0), 1) as pool:
        first_pid = pool.submit("add", 1) and pool.next(timeout=120).result[1]
        os.kill(first_pid, signal.SIGKILL)
        call = pool.submit("add", 2, label="the second add")
        total, pid = pool.next(timeout=120).result
    assert call.result == (total, pid) and pid != first_pid and pool.restarts == 1
    assert total == 2  # the new worker was built afresh by the factory
    assert (
        LINE.format(how="killed by SIGKILL", what="the second add", where="process", n=1)
        in capfd.readouterr().err
    )


def test_a_call_that_keeps_killing_its_worker_raises_worker_died(capfd):
    with Pool(partial(Counter, 0), 1) as pool:
        pool.submit("die", label="a deadly call")
        with pytest.raises(WorkerDied, match="a deadly call"):
            pool.next(timeout=300)
        assert pool.restarts == WORKER_RETRIES
    lines = [line for line in capfd.readouterr().err.splitlines() if "worker process" in line]
    assert lines == [
        LINE.format(how="killed by SIGKILL", what="a deadly call", where="process", n=n)
        for n in range(1, WORKER_RETRIES + 1)
    ]


def test_a_call_that_raises_is_not_retried_and_names_the_error():
    with Pool(partial(Counter, 0), 1) as pool:
        pool.submit("fail", label="a bad call")
        with pytest.raises(CallFailed, match="(?s)a bad call failed.*ValueError"):
            pool.next(timeout=120)
        assert pool.restarts == 0
        pool.submit("add", 1)
        assert pool.next(timeout=120).result[0] == 1  # the worker goes on


def test_compare_runs_a_job_whose_process_died_again_with_the_same_line(
    tmp_path, monkeypatch, capfd
):
    from test_compare import SPEC, _fake_records, write_spec

    from hier_agents.compare import jobs as jobs_mod
    from hier_agents.compare.backends import run_jobs
    from hier_agents.compare.spec import load

    spec = load(write_spec(tmp_path, SPEC))
    planned = jobs_mod.plan(spec)
    deaths = []

    def fake(job, cache, log):
        if not deaths:
            deaths.append(job.key)
            return -signal.SIGKILL, 0.0
        _fake_records(cache, planned, [job])
        return 0, 0.0

    monkeypatch.setattr("hier_agents.compare.backends.job_process", fake)
    records = run_jobs(planned, spec.cache, cpus=2, progress=lambda line: None)
    assert len(records) == len(planned)
    job = next(j for j in planned if j.key == deaths[0])
    assert (
        LINE.format(how="killed by SIGKILL", what=job.describe(), where="process", n=1)
        in capfd.readouterr().err
    )


def test_compare_fails_a_job_whose_process_keeps_dying(tmp_path, monkeypatch, capfd):
    from test_compare import SPEC, write_spec

    from hier_agents.compare import jobs as jobs_mod
    from hier_agents.compare.backends import JobFailed, run_jobs
    from hier_agents.compare.spec import load

    spec = load(write_spec(tmp_path, SPEC))
    planned = jobs_mod.plan(spec)[:1]
    calls = []

    def dies(job, cache, log):
        calls.append(job.key)
        return -signal.SIGABRT, 0.0

    monkeypatch.setattr("hier_agents.compare.backends.job_process", dies)
    with pytest.raises(JobFailed, match="died 4 times"):
        run_jobs(planned, spec.cache, cpus=1, retries=0, progress=lambda line: None)
    assert len(calls) == WORKER_RETRIES + 1
    assert f"(retry {WORKER_RETRIES} of {WORKER_RETRIES})" in capfd.readouterr().err


@pytest.mark.parametrize("address", ["127.0.0.1:1", "nonsense"])
def test_an_unreachable_ray_address_is_one_line(address):
    from hier_agents.cluster import connect

    with pytest.raises(UsageError) as info:
        connect(address)
    assert "\n" not in str(info.value) and address in str(info.value)


def test_run_refuses_an_unreachable_ray_address_in_one_line(capsys):
    from hier_agents.run import main

    with pytest.raises(SystemExit) as exc:
        main(
            [
                "mujoban/level1",
                "--agent",
                "random:10",
                "--episodes",
                "2",
                "--ray-address",
                "127.0.0.1:1",
            ]
        )
    errors = [line for line in capsys.readouterr().err.splitlines() if "error:" in line]
    assert exc.value.code == 2 and len(errors) == 1 and "127.0.0.1:1" in errors[0], errors


TABLE = """
condition = "expert-planner"
observations = "main-camera"
preset = "cpu"
actors = 1
envs_per_actor = 4
batch_size = 16
learning_rate = 0.001
state = true
"""


def test_a_train_table_and_its_argv_give_the_same_config(tmp_path):
    from hier_agents import train as train_cli
    from hier_agents.baselines.impala.config import TrainConfig
    from hier_agents.compare.spec import train_argv

    table = tomllib.loads(TABLE)
    planned = {"frames": 2000, "seed": 3, "logdir": str(tmp_path), "save_at": [1000, 2000]}
    from_table = TrainConfig.from_options("mujoban/level1", {**table, **planned})
    argv = train_argv(
        "mujoban/level1", table, frames=2000, seed=3, logdir=str(tmp_path), save_at=(1000, 2000)
    )
    from_argv = train_cli.config_from_args(train_cli.parse_args(argv))
    assert from_table == from_argv
    assert (from_table.image_size, from_table.envs_per_actor, from_table.cameras) == (48, 4, True)
    assert from_table.env_overrides == {"egocentric_camera": None}
    assert from_table.save_at == (1000, 2000) and from_table.state
    assert from_table.actor_config(7).seed == 3007 and from_table.seed == 3


def test_a_train_table_of_the_wrong_type_is_one_line():
    from hier_agents.baselines.impala.config import TrainConfig

    with pytest.raises(UsageError, match="actors must be an integer"):
        TrainConfig.from_options("mujoban/level1", {"actors": "two"})
    with pytest.raises(UsageError, match="did you mean 'envs_per_actor'"):
        TrainConfig.from_options("mujoban/level1", {"envs_per_actors": 2})
