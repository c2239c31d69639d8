"""The modular agent: option layer, `hier_agents.run` and its CLI."""

from __future__ import annotations

import json

import numpy as np
import pytest

import envs
from hier_agents import run as run_lib
from hier_agents.boundary import BoundaryEnv
from hier_agents.modular.components import env_overrides, make_agent
from hier_agents.modular.agent import ModularAgent

NO_CAMERAS = {"top_camera": None, "egocentric_camera": None}

# One box in an open room: the box starts at row 3, column 3, the pad is at
# row 3, column 6, the walker at row 6, column 4.
OPEN_ROOM = """; 0
##########
#        #
#        #
#  $  .  #
#        #
#        #
#   @    #
#        #
#        #
##########
"""


def test_a_short_run_solves_mujoban_level1_and_counts_every_subgoal():
    summary = run_lib.run("mujoban/level1", 3, seed=0, progress=False)
    assert summary["success_rate"] == 1.0
    assert summary["mean_return"] > 1.0
    subgoals = summary["subgoals"]
    # Every issued subgoal is accounted for, the last push of each episode too.
    assert subgoals["issued"] == (
        subgoals["reached"] + subgoals["failed"] + subgoals["cut_off"] + subgoals["unfinished"]
    )
    assert subgoals["issued"] >= 3


def test_the_option_layer_replans_after_a_box_is_moved_by_hand(tmp_path):
    levels = tmp_path / "open_room.txt"
    levels.write_text(OPEN_ROOM)
    # The default, observation-only agent (the camera estimator) sees the box
    # move: it is given only the description and the timesteps.
    env = envs.load("mujoban/level1", seed=0, levels=str(levels), **env_overrides("mujoban/level1"))
    view = BoundaryEnv(env)
    agent = make_agent("mujoban/level1", view.description())
    assert not agent.privileged
    timestep = view.reset()
    agent.reset(view.description(), timestep, seed=0)
    assert env.task.abstract_cells[0] == ((3, 3),)
    for _ in range(5):
        timestep = view.step(agent.act(timestep))
    assert agent.episode_stats.issued == 1 and agent.episode_stats.failed == 0
    # Move the box by hand two rows down, to row 5 (still solvable: open room).
    task, physics = env.task, env.physics
    x, y = task.arena.cell_centre(5, 3)
    physics.data.qpos[task._box_qpos[0]] = (x, y)
    physics.data.qvel[task._box_dof[0]] = 0.0
    pushes_before = agent.episode_stats.issued
    steps = 0
    while not timestep.last():
        timestep = view.step(agent.act(timestep))
        steps += 1
    assert env.task.solved, "the agent did not recover from the moved box"
    stats = agent.episode_stats
    assert stats.failed >= 1, stats  # the running subgoal was abandoned ...
    assert stats.issued > pushes_before  # ... and new ones were planned from the new state
    env.close()


def test_the_option_layer_rejects_a_bad_t_abs():
    env = envs.load("mujoban/level1", seed=0, **NO_CAMERAS)
    agent = make_agent("mujoban/level1", env.description(), estimator="oracle", simulator=env)
    with pytest.raises(ValueError, match="t_abs"):
        ModularAgent(agent.estimator, agent.planner, agent.skill, t_abs=0)
    env.close()


def test_mujoxo_against_the_optimal_opponent_never_loses():
    summary = run_lib.run("mujoxo/optimal", 2, seed=0, progress=False, estimator="board")
    assert summary["loss_rate"] == 0.0 and summary["draw_rate"] == 1.0
    assert summary["subgoal_success_rate"] == 1.0
    # The board estimator reads the referee's record: privileged, and said so.
    assert summary["privileged"] is True and summary["reads"] == "record"
    # The default reads the camera: observation-only.
    default = run_lib.run("mujoxo/optimal", 1, seed=0, progress=False)
    assert default["estimator"] == "camera"
    assert default["privileged"] is False and default["reads"] == "observations"


@pytest.mark.slow
def test_mujogo_with_the_gnugo_planner_wins_and_every_touch_registers_the_plan(gnugo):
    # The planner and the skill, not perception: the record estimator (the fastest).
    summary = run_lib.run("mujogo/7x7", 1, seed=0, progress=False, estimator="board")
    assert summary["win_rate"] == 1.0
    subgoals = summary["subgoals"]
    assert subgoals["failed"] == 0 and subgoals["reached"] == subgoals["issued"]


def test_cli_env_options_reach_the_environment_and_the_json(tmp_path):
    out = tmp_path / "out.json"
    assert (
        run_lib.main(
            [
                "mujoban/level1",
                "--episodes",
                "1",
                "--json",
                str(out),
                "--env-option",
                "physics_timestep=0.005",
                "--env-option",
                "pad_tolerance=0.3",
            ]
        )
        == 0
    )
    summary = json.loads(out.read_text())
    assert summary["env_options"] == {"physics_timestep": 0.005, "pad_tolerance": 0.3}
    # What differs from the original's settings: these two and the default's sleeping bodies.
    assert summary["deviations"] == {"pad_tolerance": 0.3, "physics_timestep": 0.005, "sleep": True}
    assert {"command", "commit", "date", "machine"} <= set(summary["provenance"])
    for bad in (
        ["--env-option", "bogus=1"],
        ["--env-option", "pad_tolerance=2.0"],
        ["--env-option", "sleep=maybe"],
    ):
        with pytest.raises(SystemExit) as exc:
            run_lib.main(["mujoban/level1", "--episodes", "1", *bad])
        assert exc.value.code == 2


def test_cli_writes_the_table_json_and_video(tmp_path, capsys):
    out, video = tmp_path / "out.json", tmp_path / "first.mp4"
    assert (
        run_lib.main(
            [
                "mujoban/level1",
                "--episodes",
                "2",
                "--seed",
                "3",
                "--json",
                str(out),
                "--video",
                str(video),
            ]
        )
        == 0
    )
    printed = capsys.readouterr().out
    assert "solved" in printed and "wall s / episode" in printed
    summary = json.loads(out.read_text())
    for key in (
        "env",
        "episodes",
        "success_rate",
        "mean_return",
        "mean_steps",
        "subgoal_success_rate",
        "wall_s",
    ):
        assert key in summary, key
    assert summary["env"] == "mujoban/level1" and summary["episodes"] == 2
    assert video.stat().st_size > 1000
    import imageio.v2 as imageio

    frames = imageio.mimread(str(video), memtest=False)
    assert len(frames) == summary["rows"][0]["steps"] and np.asarray(frames[0]).ndim == 3


def test_board_game_json_has_win_draw_loss_rates(tmp_path):
    out = tmp_path / "xo.json"
    assert run_lib.main(["mujoxo/optimal", "--episodes", "1", "--json", str(out)]) == 0
    summary = json.loads(out.read_text())
    for key in ("win_rate", "draw_rate", "loss_rate", "success_rate"):
        assert key in summary, key
    assert summary["success_rate"] == summary["win_rate"]
    assert summary["win_rate"] + summary["draw_rate"] + summary["loss_rate"] == pytest.approx(1)


@pytest.mark.parametrize(
    "argv, listed",
    [
        (["mujoban/nope"], "mujoban/level1"),
        (["mujoban/level1", "--planner", "nope"], "sokoban-solver"),
        (["mujoxo/mixture", "--skill", "nope"], "arm-touch"),
        (["mujogo/7x7", "--estimator", "nope"], "board"),
        (["mujoxo/mixture", "--levels", "x.txt"], "mujoban"),
    ],
)
def test_cli_rejects_unknown_names_listing_the_valid_ones(argv, listed, capsys):
    with pytest.raises(SystemExit) as exc:
        run_lib.main(argv)
    assert exc.value.code == 2
    assert listed in capsys.readouterr().err


def test_make_agent_rejects_unknown_names():
    env = envs.load("mujoban/level1", seed=0, **NO_CAMERAS)
    with pytest.raises(ValueError, match="random"):
        make_agent("mujoban/level1", env.description(), planner="minimax")
    with pytest.raises(ValueError, match="mujoban"):
        make_agent("cartpole/swingup", env.description())
    with pytest.raises(ValueError, match="privileged"):
        make_agent("mujoban/level1", env.description(), estimator="oracle")
    env.close()


# Level 0: the box starts in a corner that is not a pad (a deadlock the
# solver proves); level 1 is solvable.
DEADLOCK_THEN_OPEN = """; 0
##########
#$       #
#        #
#     .  #
#        #
#   @    #
##########

; 1
##########
#        #
#  $  .  #
#        #
#   @    #
#        #
##########
"""


def test_a_deadlocked_episode_ends_as_a_failure_with_its_reason_and_the_run_goes_on(tmp_path):
    levels = tmp_path / "deadlock.txt"
    levels.write_text(DEADLOCK_THEN_OPEN)
    summary = run_lib.run(
        "mujoban/level1", 2, seed=0, levels=str(levels), progress=False, estimator="oracle"
    )
    first, second = summary["rows"]
    assert not first["solved"] and first["failure_reason"].startswith("no plan (unsolvable)")
    assert first["steps"] < 5  # given up at once, not run into the time limit
    assert second["solved"] and "failure_reason" not in second
    assert summary["episode_failures"] == {"no plan (unsolvable)": 1}
    assert summary["privileged"] is True and summary["estimator"] == "oracle"


def test_an_agent_error_costs_its_episode_not_the_run(monkeypatch):
    from skills.ball import BallSkill

    calls = {"n": 0}
    original = BallSkill.act

    def flaky(self, timestep, scene):
        calls["n"] += 1
        if calls["n"] == 3:
            raise RuntimeError("a bug in the skill")
        return original(self, timestep, scene)

    monkeypatch.setattr(BallSkill, "act", flaky)
    summary = run_lib.run("mujoban/level1", 2, seed=0, progress=False, estimator="oracle")
    first, second = summary["rows"]
    assert first["failure_reason"] == "error: RuntimeError: a bug in the skill"
    assert second["solved"]
