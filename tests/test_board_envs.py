"""MuJoXO and MuJoGo: touches register moves, opponents reply, rewards, GNU Go failures."""

from __future__ import annotations

import os
import signal
import sys

import gymnasium
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env

import envs
from abstract_planners.gtp import GTPError
from arm_driving import touch_point
from envs.boards import arena as arena_lib
from envs.boards import make_mujogo, make_mujoxo

NO_CAMERA = {"front_camera": None}
BOARD_NAMES = ["mujogo/7x7", "mujogo/7x7-eval", "mujogo/7x7-mixture", "mujogo/9x9",
               "mujoxo/mixture", "mujoxo/optimal", "mujoxo/random"]


def piece_visible(env, point) -> bool:
    task = env.task
    return env.physics.model.geom_group[task._piece_ids[point]] != arena_lib.HIDDEN_GROUP


def assert_board_matches_openspiel(env, timestep):
    task = env.task
    np.testing.assert_array_equal(timestep.observation["board_state"],
                                  task.game.board_planes(task.state))
    owners = task.game.owners(task.state)
    for point, owner in enumerate(owners):
        assert piece_visible(env, point) == (owner >= 0), f"point {point}"
    history = timestep.observation["move_history"]
    played = list(task.state.history())
    assert list(history[: len(played)]) == played and (history[len(played):] == -1).all()


def test_names_are_registered():
    assert [n for n in envs.names() if n.startswith(("mujoxo/", "mujogo/"))] == BOARD_NAMES


@pytest.mark.parametrize("name, point", [("mujoxo/optimal", 4), ("mujogo/7x7", 24)])
def test_touching_a_point_registers_that_move_and_the_opponent_replies(name, point):
    env = envs.load(name, seed=0, **NO_CAMERA)
    env.reset()
    timestep = touch_point(env, env.task.point_position(point))
    task = env.task
    assert task.moves_registered == 1
    assert task.moves[0] == point and len(task.moves) == 2  # the agent's, then the reply
    assert timestep.observation["board_state"][point // task.game.size,
                                               point % task.game.size, 1]
    # The agent's piece lies where it touched, inside the pad.
    x, y, _ = env.physics.model.geom_pos[task._piece_ids[point]]
    px, py, _ = task.point_position(point)
    assert abs(x - px) <= task.arena.pad_half + 1e-9 and abs(y - py) <= task.arena.pad_half + 1e-9
    assert_board_matches_openspiel(env, timestep)
    env.close()


def test_touching_an_occupied_point_changes_nothing():
    env = make_mujoxo(epsilon=0.0, seed=0, **NO_CAMERA)
    env.reset()
    env.task.play_moves([4, 0])
    touch_point(env, env.task.point_position(0))
    assert env.task.moves == (4, 0) and env.task.moves_registered == 0
    # A free point still registers afterwards.
    touch_point(env, env.task.point_position(8))
    assert env.task.moves[:3] == (4, 0, 8)


def test_an_illegal_go_point_changes_nothing():
    env = make_mujogo(seed=0, **NO_CAMERA)
    env.reset()
    # White at 1 and 7 surround the empty corner 0: black playing there is suicide.
    env.task.play_moves([20, 1, 30, 7])
    assert 0 not in env.task.state.legal_actions()
    touch_point(env, env.task.point_position(0))
    assert env.task.moves == (20, 1, 30, 7) and env.task.moves_registered == 0
    assert not piece_visible(env, 0)
    env.close()


def test_retaking_a_ko_at_once_changes_nothing():
    env = make_mujogo(seed=0, **NO_CAMERA)
    env.reset()
    # Black 17, 31, 25 and white 22, 16, 30 frame a ko; black 23 fills it and
    # white 24 captures it. Black may not retake at 23 at once.
    env.task.play_moves([17, 22, 31, 16, 25, 30, 23, 24])
    assert not piece_visible(env, 23) and piece_visible(env, 24)
    assert 23 not in env.task.state.legal_actions()
    touch_point(env, env.task.point_position(23))
    assert env.task.moves == (17, 22, 31, 16, 25, 30, 23, 24)
    assert env.task.moves_registered == 0 and not piece_visible(env, 23)
    env.close()


def test_a_captured_stone_disappears_from_the_board():
    env = make_mujogo(seed=0, **NO_CAMERA)
    env.reset()
    env.task.play_moves([1, 0, 20, 40])  # white 0 in the corner, black 1 beside it
    assert piece_visible(env, 0)
    timestep = touch_point(env, env.task.point_position(7))  # black 7 captures white 0
    assert env.task.moves[4] == 7
    white_replied_at_0 = env.task.moves[5] == 0
    assert white_replied_at_0 or not timestep.observation["board_state"][0, 0, 2]
    assert white_replied_at_0 or not piece_visible(env, 0)
    assert_board_matches_openspiel(env, timestep)
    env.close()


def test_a_win_gives_one_and_ends_the_game():
    env = make_mujoxo(epsilon=0.0, seed=0, **NO_CAMERA)
    env.reset()
    env.task.play_moves([0, 3, 1, 4])
    timestep = touch_point(env, env.task.point_position(2))
    assert timestep.last() and timestep.reward == 1.0 and timestep.discount == 0.0


def test_a_draw_gives_one_half():
    env = make_mujoxo(epsilon=0.0, seed=0, **NO_CAMERA)
    env.reset()
    env.task.play_moves([0, 1, 2, 4, 3, 5, 7, 6])
    timestep = touch_point(env, env.task.point_position(8))
    assert timestep.last() and timestep.reward == 0.5 and timestep.discount == 0.0


def test_a_loss_gives_zero():
    env = make_mujoxo(epsilon=0.0, seed=0, **NO_CAMERA)
    env.reset()
    env.task.play_moves([0, 3, 1, 4])  # the agent ignores its own win at 2 ...
    rewards = []
    timestep = touch_point(env, env.task.point_position(8))  # ... and O wins
    rewards.append(timestep.reward)
    while not timestep.last():
        free = env.task.state.legal_actions()
        timestep = touch_point(env, env.task.point_position(free[0]))
        rewards.append(timestep.reward)
    assert env.task.state.returns()[0] == -1.0
    assert sum(rewards) == 0.0 and timestep.discount == 0.0


def test_holding_a_pass_pad_passes_once():
    env = make_mujogo(seed=0, arm_reset=False, **NO_CAMERA)
    env.reset()
    touch_point(env, env.task.pass_position("left"), steps=60)
    # Keep pressing: the pad stays touched but must not register again.
    task = env.task
    for _ in range(20):
        env.step(np.zeros(env.action_spec().shape))
    passes = [m for i, m in enumerate(task.moves) if i % 2 == 0]
    assert task.moves_registered == 1 and passes == [task.game.pass_action]
    env.close()


def test_killed_gnugo_is_restarted_and_the_game_continues():
    env = make_mujogo(seed=0, **NO_CAMERA)
    env.reset()
    touch_point(env, env.task.point_position(24))
    before = env.task.moves
    client = env.task.opponent.planner.client
    os.kill(client.pid, signal.SIGKILL)
    client._proc.wait()  # pylint: disable=protected-access
    timestep = touch_point(env, env.task.point_position(0))
    assert env.task.moves[:3] == before + (0,) and len(env.task.moves) == 4
    assert_board_matches_openspiel(env, timestep)
    env.close()


def test_an_engine_that_never_answers_raises_gtp_error():
    hang = [sys.executable, "-c", "import time; time.sleep(1000)"]
    env = make_mujogo(seed=0, gnugo_command=hang, gnugo_timeout=0.5, **NO_CAMERA)
    env.reset()
    with pytest.raises(GTPError):
        touch_point(env, env.task.point_position(24))
    env.close()


@pytest.mark.parametrize("kwargs, word", [
    ({"board_size": 4}, "board_size"), ({"board_size": 20}, "board_size"),
    ({"epsilon": -0.1}, "epsilon"), ({"epsilon": 1.5}, "epsilon"),
    ({"level": 0}, "level"), ({"level": 11}, "level"),
])
def test_bad_go_configurations_raise_value_errors(kwargs, word):
    with pytest.raises(ValueError, match=word):
        make_mujogo(**kwargs, **NO_CAMERA)


def test_bad_tictactoe_epsilon_raises():
    with pytest.raises(ValueError, match=r"epsilon.*\[0, 1\]"):
        make_mujoxo(epsilon=2.0, **NO_CAMERA)


def test_go_time_limit_is_a_loss_and_tictactoe_time_limit_truncates():
    go = make_mujogo(seed=0, time_limit=0.5, **NO_CAMERA)
    xo = make_mujoxo(seed=0, time_limit=0.5, **NO_CAMERA)
    for env, discount in ((go, 0.0), (xo, 1.0)):
        env.reset()
        for _ in range(10):
            timestep = env.step(np.zeros(env.action_spec().shape))
        assert timestep.last() and timestep.reward == 0.0 and timestep.discount == discount
        env.close()


def test_arm_starts_above_the_board_at_random_and_seeds_reproduce():
    positions = []
    for seed in (0, 0, 1):
        env = make_mujoxo(seed=seed, **NO_CAMERA)
        positions.append(env.reset().observation["arm/pinch_site_pos"])
    np.testing.assert_array_equal(positions[0], positions[1])
    assert not np.allclose(positions[0], positions[2])
    for pos in positions:
        assert pos[2] > arena_lib.BOARD_TOP + 0.1


def test_camera_is_observed_at_its_size():
    env = make_mujoxo(seed=0, front_camera=(48, 64))
    frame = env.reset().observation["front_camera"]
    assert frame.shape == (48, 64, 3) and frame.dtype == np.uint8 and frame.std() > 5


@pytest.mark.parametrize("name", BOARD_NAMES)
def test_every_board_name_passes_gymnasium_check_env(name):
    env = gymnasium.make(name, render_mode="rgb_array", front_camera=(32, 32))
    check_env(env.unwrapped, skip_render_check=False)
    env.close()
