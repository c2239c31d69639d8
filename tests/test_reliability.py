"""Reliability: everything closes, GNU Go's resignation ends the game, runs survive
errors and Ctrl-C (issue 16).

Child processes are read from /proc (no psutil needed). GTP engines are
`tests/fake_gtp.py` (answers at once; passes or resigns) unless a test takes
the `gnugo` fixture. The finalisers of `GTPClient` and `GnuGoPlanner` are
switched off in these tests, so only an explicit ``close`` can end a process.
"""

from __future__ import annotations

import json
import os
import signal
import sys
from pathlib import Path

import gymnasium
import numpy as np
import pytest

import envs
from abstract_planners import go as go_lib
from abstract_planners import gtp as gtp_lib
from abstract_planners.go import GnuGoPlanner, go_game
from arm_driving import touch_point
from envs import core as core_lib
from envs.boards import make_mujogo
from envs.boards.task import BoardTask
from hier_agents import run as run_lib
from hier_agents.modular.agent import ModularAgent
from skills.arm import ArmTouchSkill

FAKE_GTP = Path(__file__).with_name("fake_gtp.py")


def fake_engine(mode: str = "pass") -> list[str]:
    return [sys.executable, str(FAKE_GTP), mode]


def children() -> set[int]:
    """Pids of this process's children (zombies included), from /proc."""
    me, found = os.getpid(), set()
    for entry in os.listdir("/proc"):
        if not entry.isdigit():
            continue
        try:
            with open(f"/proc/{entry}/stat") as f:
                stat = f.read()
        except OSError:
            continue
        # pid (comm) state ppid ...: comm may contain spaces, so split after ')'.
        fields = stat[stat.rindex(")") + 2 :].split()
        if int(fields[1]) == me:
            found.add(int(entry))
    return found


@pytest.fixture
def no_finalisers(monkeypatch):
    """Only explicit close() may end an engine; leftovers are killed afterwards."""
    monkeypatch.setattr(gtp_lib.GTPClient, "__del__", lambda self: None)
    monkeypatch.setattr(GnuGoPlanner, "__del__", lambda self: None)
    before = children()
    yield before
    for pid in children() - before:  # a failing test must not leak into the next
        try:
            os.kill(pid, signal.SIGKILL)
            os.waitpid(pid, 0)
        except (OSError, ChildProcessError):
            pass


@pytest.fixture
def fake_gnugo(monkeypatch):
    """Every GnuGoPlanner (the agent's and the environment's) runs the fake engine."""
    monkeypatch.setattr(go_lib, "default_gnugo_command", lambda: fake_engine("pass"))


def assert_no_new_children(before: set[int]) -> None:
    left = children() - before
    assert not left, f"child processes left behind: {sorted(left)}"


# -- context managers and close ------------------------------------------------


def test_environments_are_context_managers_and_close_their_engine(no_finalisers):
    with envs.load("mujogo/7x7", seed=0, front_camera=None, gnugo_command=fake_engine()) as env:
        env.reset()
        assert env.task.opponent.planner.client.alive
        assert children() - no_finalisers
    assert env.closed
    env.close()  # idempotent
    assert_no_new_children(no_finalisers)


def test_gymnasium_env_closes_its_engine_when_the_block_raises(no_finalisers):
    with pytest.raises(RuntimeError, match="inside the block"):
        with gymnasium.make("mujogo/7x7", front_camera=None, gnugo_command=fake_engine()) as env:
            env.reset(seed=0)
            env.unwrapped.dm_env.task.opponent.planner.client  # noqa: B018 - starts the engine
            assert children() - no_finalisers
            raise RuntimeError("inside the block")
    assert_no_new_children(no_finalisers)


def test_failed_construction_closes_the_task(no_finalisers, monkeypatch):
    original = core_lib.Environment._build

    def build_then_fail(self, task, *args):
        original(self, task, *args)
        task.opponent.planner.client  # noqa: B018 - an engine is running now
        raise RuntimeError("construction failed")

    monkeypatch.setattr(core_lib.Environment, "_build", build_then_fail)
    with pytest.raises(RuntimeError, match="construction failed"):
        make_mujogo(seed=0, front_camera=None, gnugo_command=fake_engine())
    assert_no_new_children(no_finalisers)


class _Part:
    def __init__(self, log, name, fail=False):
        self.log, self.name, self.fail = log, name, fail

    def close(self):
        self.log.append(self.name)
        if self.fail:
            raise OSError(f"{self.name} close failed")


def test_modular_agent_closes_planner_skill_and_estimator_even_if_one_raises():
    log = []
    agent = ModularAgent.__new__(ModularAgent)  # the parts are stand-ins
    agent.planner, agent.skill, agent.estimator = (
        _Part(log, "planner", fail=True),
        _Part(log, "skill"),
        _Part(log, "estimator"),
    )
    with pytest.raises(OSError, match="planner close failed"):
        with agent:
            pass
    assert log == ["planner", "skill", "estimator"]


def test_base_roles_have_a_harmless_close():
    from abstract_planners.base import Planner
    from hier_agents.estimators.base import Estimator
    from skills.base import Skill

    for cls in (Planner, Estimator, Skill):
        assert callable(cls.close)
    GnuGoPlanner(command=fake_engine()).close()


# -- runs that raise at every stage leave no process ---------------------------

#: Failures of the planner, the skill and the engine, not of perception: the
#: record estimator (the fastest).
GO_RUN = dict(
    episodes=2, seed=0, progress=False, env_options={"time_limit": 2.0}, estimator="board"
)


def _raise(exc_type, text):
    raise exc_type(f"injected {text}")


@pytest.mark.parametrize("exc_type", [RuntimeError, KeyboardInterrupt])
@pytest.mark.parametrize("stage", ["construction", "reset", "planner", "skill"])
def test_a_run_that_raises_at_any_stage_leaves_no_child_process(
    stage, exc_type, no_finalisers, fake_gnugo, monkeypatch
):
    calls = {"n": 0}
    if stage == "construction":
        original = core_lib.Environment._build

        def patched(self, task, *args):
            original(self, task, *args)
            task.opponent.planner.client  # noqa: B018 - the property starts the engine
            _raise(exc_type, stage)

        monkeypatch.setattr(core_lib.Environment, "_build", patched)
    elif stage == "reset":
        original = BoardTask.initialize_episode

        def patched(self, physics, random_state):
            original(self, physics, random_state)
            self.opponent.planner.client  # noqa: B018 - the property starts the engine
            calls["n"] += 1
            if calls["n"] == 2:
                _raise(exc_type, stage)

        monkeypatch.setattr(BoardTask, "initialize_episode", patched)
    elif stage == "planner":
        original = GnuGoPlanner.plan

        def patched(self, state):
            self.client  # noqa: B018 - the property starts the engine
            calls["n"] += 1
            if calls["n"] == 2:
                _raise(exc_type, stage)
            return original(self, state)

        monkeypatch.setattr(GnuGoPlanner, "plan", patched)
    else:
        original = ArmTouchSkill.act

        def patched(self, timestep, scene):
            calls["n"] += 1
            if calls["n"] == 5:
                _raise(exc_type, stage)
            return original(self, timestep, scene)

        monkeypatch.setattr(ArmTouchSkill, "act", patched)

    if stage == "construction" and exc_type is RuntimeError:
        with pytest.raises(RuntimeError, match="injected"):
            run_lib.run("mujogo/7x7", **GO_RUN)
    else:
        summary = run_lib.run("mujogo/7x7", **GO_RUN)
        if exc_type is KeyboardInterrupt:
            assert summary["interrupted"] and summary["episodes"] < 2
        else:
            assert summary["episodes"] == 2 and not summary["interrupted"]
            errors = [row for row in summary["rows"] if "error" in row]
            assert len(errors) == 1 and errors[0]["error"] == f"RuntimeError: injected {stage}"
            assert errors[0]["failure_reason"].startswith("error: RuntimeError")
            assert summary["errors"] == 1 and summary["episode_failures"]["error"] == 1
            assert "errors            1" in run_lib.format_table(summary)
    assert_no_new_children(no_finalisers)


def test_a_real_gnugo_run_with_a_failing_skill_leaves_no_gnugo(gnugo, no_finalisers, monkeypatch):
    original = ArmTouchSkill.act
    calls = {"n": 0}

    def patched(self, timestep, scene):
        calls["n"] += 1
        if calls["n"] == 60:  # mid-game: both GNU Go engines are running
            raise RuntimeError("injected skill")
        return original(self, timestep, scene)

    monkeypatch.setattr(ArmTouchSkill, "act", patched)
    summary = run_lib.run(
        "mujogo/7x7",
        episodes=1,
        seed=0,
        progress=False,
        estimator="board",  # failures of the engine and the skill, not of perception
        env_options={"time_limit": 6.0},
    )
    assert summary["rows"][0]["error"] == "RuntimeError: injected skill"
    assert_no_new_children(no_finalisers)


# -- GNU Go resigning ----------------------------------------------------------


def test_the_planner_reports_a_resignation():
    with GnuGoPlanner(board_size=7, command=fake_engine("resign")) as planner:
        subgoal = planner.plan(go_game(7, 5.5).new_initial_state())
    assert subgoal.info["resigned"] is True


def test_an_opponent_resignation_ends_the_game_as_the_agents_win(no_finalisers):
    with make_mujogo(seed=0, front_camera=None, gnugo_command=fake_engine("resign")) as env:
        env.reset()
        timestep = touch_point(env, env.task.point_position(24))
        assert timestep.last() and timestep.discount == 0.0
        assert timestep.reward == 1.0
        assert env.task.resigned and env.task.outcome == "win"
        assert env.task.moves == (24,)  # nothing is played for the resignation
        assert env.reset().first() and not env.task.resigned
    assert_no_new_children(no_finalisers)


def test_a_run_counts_an_opponent_resignation_as_a_win(no_finalisers):
    summary = run_lib.run(
        "mujogo/7x7",
        episodes=1,
        seed=0,
        progress=False,
        planner="random",
        estimator="board",  # the engine's faults, not perception: the fastest estimator
        env_options={"gnugo_command": fake_engine("resign")},
    )
    row = summary["rows"][0]
    assert row["outcome"] == "win" and row["opponent_resigned"] and "failure_reason" not in row
    assert summary["win_rate"] == 1.0
    assert_no_new_children(no_finalisers)


# -- run.py: errors and Ctrl-C -------------------------------------------------


def test_ctrl_c_ends_the_run_with_the_table_and_json_of_the_episodes_played(
    tmp_path, monkeypatch, capsys
):
    original = ModularAgent.reset
    calls = {"n": 0}

    def patched(self, *args, **kwargs):
        calls["n"] += 1
        if calls["n"] == 3:
            raise KeyboardInterrupt
        return original(self, *args, **kwargs)

    monkeypatch.setattr(ModularAgent, "reset", patched)
    out = tmp_path / "run.json"
    code = run_lib.main(["mujoban/level1", "--episodes", "5", "--json", str(out)])
    assert code == 130
    text = capsys.readouterr().out
    assert "INTERRUPTED (Ctrl-C): 2 of 5 episodes played" in text and "solved" in text
    summary = json.loads(out.read_text())
    assert summary["interrupted"] and summary["episodes"] == 2 and len(summary["rows"]) == 2
    assert summary["episodes_requested"] == 5


def test_ctrl_c_before_any_episode_ends_gives_an_empty_table(monkeypatch):
    monkeypatch.setattr(ModularAgent, "reset", lambda self, *a, **k: _raise(KeyboardInterrupt, ""))
    summary = run_lib.run("mujoban/level1", episodes=3, progress=False)
    assert summary["interrupted"] and summary["episodes"] == 0 and summary["rows"] == []
    assert "0 of 3 episodes played" in run_lib.format_table(summary)


def test_an_error_in_reset_ends_only_that_episode(monkeypatch):
    from hier_agents.boundary import BoundaryEnv

    original = BoundaryEnv.reset
    calls = {"n": 0}

    def patched(self):
        calls["n"] += 1
        if calls["n"] == 2:
            raise ValueError("injected reset")
        return original(self)

    monkeypatch.setattr(BoundaryEnv, "reset", patched)
    summary = run_lib.run("mujoban/level1", episodes=3, progress=False)
    rows = summary["rows"]
    assert [("error" in r) for r in rows] == [False, True, False]
    assert rows[1]["error"] == "ValueError: injected reset" and rows[1]["subgoals_issued"] == 0
    assert rows[0]["solved"] and rows[2]["solved"] and not rows[1]["solved"]
    assert summary["errors"] == 1 and summary["episode_failures"] == {"error": 1}
    assert np.isclose(summary["success_rate"], 2 / 3)


# -- determinism: the same seed, two processes, the same rows ------------------

DETERMINISM_RUNS = {
    "mujoban": ["mujoban/level2", "--episodes", "2"],
    "mujoxo": ["mujoxo/mixture", "--episodes", "2", "--env-option", "time_limit=4.0"],
    "mujogo": ["mujogo/7x7", "--episodes", "1", "--env-option", "time_limit=6.0"],
}
WALL_CLOCK = {"wall_s"}


@pytest.mark.slow
@pytest.mark.parametrize("family", DETERMINISM_RUNS)
def test_the_same_seed_gives_the_same_rows_in_two_processes(family, tmp_path, request):
    import subprocess

    if family == "mujogo":
        request.getfixturevalue("gnugo")
    root = Path(__file__).resolve().parents[1]
    procs, paths = [], []
    for i in range(2):
        path = tmp_path / f"run{i}.json"
        paths.append(path)
        procs.append(
            subprocess.Popen(
                [
                    sys.executable,
                    "-m",
                    "hier_agents.run",
                    *DETERMINISM_RUNS[family],
                    "--seed",
                    "7",
                    "--json",
                    str(path),
                ],
                cwd=root,
                stdout=subprocess.PIPE,
                stderr=subprocess.STDOUT,
                env={**os.environ, "PYTHONHASHSEED": str(i)},
            )
        )  # hash order may differ
    for proc in procs:
        out, _ = proc.communicate(timeout=300)
        assert proc.returncode == 0, out.decode()[-2000:]
    rows = [
        [
            {k: v for k, v in row.items() if k not in WALL_CLOCK}
            for row in json.loads(path.read_text())["rows"]
        ]
        for path in paths
    ]
    assert rows[0] == rows[1]
    assert all("error" not in row for row in rows[0])


# -- faults injected in full runs -----------------------------------------------


def test_an_engine_that_dies_once_mid_game_is_replayed_and_the_run_goes_on(tmp_path, no_finalisers):
    marker = tmp_path / "died"
    summary = run_lib.run(
        "mujogo/7x7",
        episodes=2,
        seed=0,
        progress=False,
        planner="random",
        estimator="board",  # the engine's faults, not perception: the fastest estimator
        env_options={"gnugo_command": fake_engine(f"die-once:{marker}"), "time_limit": 4.0},
    )
    assert marker.exists()  # the engine did die
    assert summary["episodes"] == 2 and summary["errors"] == 0
    assert "errors  " not in run_lib.format_table(summary)
    assert_no_new_children(no_finalisers)


def test_an_engine_that_hangs_fails_that_episode_and_the_next_gets_a_new_engine(
    tmp_path, no_finalisers
):
    marker = tmp_path / "hung"
    summary = run_lib.run(
        "mujogo/7x7",
        episodes=2,
        seed=0,
        progress=False,
        planner="random",
        estimator="board",  # the engine's faults, not perception: the fastest estimator
        env_options={
            "gnugo_command": fake_engine(f"hang-once:{marker}"),
            "gnugo_timeout": 1.0,
            "time_limit": 4.0,
        },
    )
    first, second = summary["rows"]
    assert first["error"].startswith("GTPError: ") and "timeout" in first["error"]
    assert "error" not in second and second["subgoals_issued"] >= 1
    assert summary["errors"] == 1 and summary["episode_failures"]["error"] == 1
    assert_no_new_children(no_finalisers)


@pytest.mark.slow
def test_the_soak_benchmark_samples_and_closes_everything(tmp_path, gnugo):
    sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "benchmarks"))
    import soak

    before = children()
    result = soak.soak(
        len(soak.CONFIGS), sample_every=4, rebuild_every=1, steps=3, moves=2, progress=False
    )
    assert not result["errors"]
    assert [s["episode"] for s in result["samples"]] == [0, 4, 8]
    assert {"rss_mb", "open_fds", "children", "threads", "gl_objects"} <= set(result["samples"][1])
    assert result["samples"][-1]["children"] >= 1  # the MuJoGo environment's GNU Go
    assert result["after_close"]["children"] == len(before)
    assert_no_new_children(before)
