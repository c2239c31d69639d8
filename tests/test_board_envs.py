"""MuJoXO and MuJoGo: touches register moves, opponents reply, rewards, GNU Go failures."""

from __future__ import annotations

import os
import signal
import sys

import gymnasium
import mujoco
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env

import envs
from fast_cover import cover, family_and_game
from abstract_planners.gtp import GTPError
from arm_driving import hold_action, place_hand, press_from_above, substep_touches, touch_point
from envs.boards import arena as arena_lib
from envs.boards import make_mujogo, make_mujoxo

NO_CAMERA = {"front_camera": None}
BOARD_NAMES = [
    "mujogo/7x7",
    "mujogo/7x7-eval",
    "mujogo/7x7-mixture",
    "mujogo/9x9",
    "mujoxo/mixture",
    "mujoxo/optimal",
    "mujoxo/random",
]


def piece_visible(env, point) -> bool:
    task = env.task
    return env.physics.model.geom_group[task._piece_ids[point]] != arena_lib.HIDDEN_GROUP


def assert_board_matches_openspiel(env, timestep):
    task = env.task
    np.testing.assert_array_equal(
        timestep.observation["board_state"], task.game.board_planes(task.state)
    )
    owners = task.game.owners(task.state)
    for point, owner in enumerate(owners):
        assert piece_visible(env, point) == (owner >= 0), f"point {point}"
    history = timestep.observation["move_history"]
    played = list(task.state.history())
    assert list(history[: len(played)]) == played and (history[len(played) :] == -1).all()


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
    assert timestep.observation["board_state"][point // task.game.size, point % task.game.size, 1]
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
    # White at 44, 46 and 38 surround the empty edge point 45 (on the row
    # nearest the arm): black playing there is suicide.
    env.task.play_moves([20, 44, 30, 46, 10, 38])
    assert 45 not in env.task.state.legal_actions()
    touch_point(env, env.task.point_position(45))
    assert env.task.moves == (20, 44, 30, 46, 10, 38) and env.task.moves_registered == 0
    assert not piece_visible(env, 45)
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
    env.task.play_moves([23, 24, 25, 10, 17, 12])  # white 24 between black 23, 25 and 17
    assert piece_visible(env, 24)
    timestep = touch_point(env, env.task.point_position(31))  # black 31 captures white 24
    assert env.task.moves[6] == 31
    white_replied_at_24 = env.task.moves[7] == 24
    assert white_replied_at_24 or not timestep.observation["board_state"][3, 3, 2]
    assert white_replied_at_24 or not piece_visible(env, 24)
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


@pytest.mark.parametrize("allow_double_pass", [False, True])
def test_holding_a_finger_on_the_pass_zone_passes_once_unless_double_passes_are_allowed(
    allow_double_pass,
):
    env = make_mujogo(seed=0, arm_reset=False, allow_double_pass=allow_double_pass, **NO_CAMERA)
    env.reset()
    task = env.task
    press_from_above(env, task.pass_position("left"))
    assert task.moves_registered == 1 and task.moves[0] == task.game.pass_action
    # Keep the finger on the pass zone: it stays pressed ...
    for _ in range(10):
        env.step(hold_action(env))
    readings, contacts = substep_touches(env, hold_action(env))
    assert (readings[:, -1] > arena_lib.TOUCH_THRESHOLD).all()
    assert any(geom.startswith("arm/hand/finger") for geom, zone in contacts[0] if zone == "pass")
    for _ in range(10):
        if env.step(hold_action(env)).last():  # GNU Go passed too: the game is over
            break
    agent_moves = task.moves[::2]
    if allow_double_pass:  # ... and passes again at once
        assert task.moves_registered >= 2 and agent_moves[:2] == (task.game.pass_action,) * 2
    else:  # ... but a second consecutive pass is ignored
        assert task.moves_registered == 1 and agent_moves == (task.game.pass_action,)
    env.close()


@pytest.mark.parametrize("allow_double_pass", [False, True])
def test_go_refuses_a_second_consecutive_pass_by_the_agent(allow_double_pass):
    env = make_mujogo(seed=0, allow_double_pass=allow_double_pass, **NO_CAMERA)
    env.reset()
    task = env.task
    press_from_above(env, task.pass_position("left"))
    assert task.moves_registered == 1 and len(task.moves) == 2  # the pass and GNU Go's reply
    assert task.moves[0] == task.game.pass_action and task.moves[1] != task.game.pass_action
    # The arm was reset away; press the pass zone again (a new press).
    press_from_above(env, task.pass_position("left"))
    if allow_double_pass:
        assert task.moves_registered == 2 and task.moves[2] == task.game.pass_action
    else:
        pressed = substep_touches(env, hold_action(env))[0][:, -1]
        assert pressed.max() > arena_lib.TOUCH_THRESHOLD  # the finger is on the pass zone
        for _ in range(5):
            env.step(hold_action(env))
        assert task.moves_registered == 1 and len(task.moves) == 2
    env.close()


def test_killed_gnugo_is_restarted_and_the_game_continues(gnugo):
    env = make_mujogo(seed=0, **NO_CAMERA)
    env.reset()
    touch_point(env, env.task.point_position(24))
    before = env.task.moves
    client = env.task.opponent.planner.client
    os.kill(client.pid, signal.SIGKILL)
    client._proc.wait()  # pylint: disable=protected-access
    free = 10 if 10 not in before else 12
    timestep = touch_point(env, env.task.point_position(free))
    assert env.task.moves[:3] == before + (free,) and len(env.task.moves) == 4
    assert_board_matches_openspiel(env, timestep)
    env.close()


def test_an_engine_that_never_answers_raises_gtp_error():
    hang = [sys.executable, "-c", "import time; time.sleep(1000)"]
    env = make_mujogo(seed=0, gnugo_command=hang, gnugo_timeout=0.5, **NO_CAMERA)
    env.reset()
    with pytest.raises(GTPError):
        touch_point(env, env.task.point_position(24))
    env.close()


@pytest.mark.parametrize(
    "kwargs, word",
    [
        ({"board_size": 4}, "board_size"),
        ({"board_size": 20}, "board_size"),
        ({"epsilon": -0.1}, "epsilon"),
        ({"epsilon": 1.5}, "epsilon"),
        ({"level": 0}, "level"),
        ({"level": 11}, "level"),
    ],
)
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


def test_the_originals_second_view_is_observed_only_when_asked_for():
    assert "front_camera_2" not in make_mujoxo(seed=0).observation_spec()
    env = make_mujogo(seed=0, front_camera_2=(60, 70))
    try:
        spec = env.observation_spec()["front_camera_2"]
        obs = env.reset().observation
        assert spec.shape == obs["front_camera_2"].shape == (60, 70, 3)
        # A different viewpoint: higher and steeper than front_camera.
        first = env.render("front_camera", 60, 70)
        assert np.abs(first.astype(int) - obs["front_camera_2"]).mean() > 10
    finally:
        env.close()
    with pytest.raises(ValueError, match="front_camera_2"):
        make_mujoxo(seed=0, front_camera_2=(0, 84))


@pytest.mark.parametrize("name", cover(BOARD_NAMES, family_and_game))
def test_every_board_name_passes_gymnasium_check_env(name):
    env = gymnasium.make(name, render_mode="rgb_array", front_camera=(32, 32), render_size=(32, 32))
    check_env(env.unwrapped, skip_render_check=False)
    env.close()


@pytest.mark.parametrize("make", [make_mujoxo, make_mujogo])
def test_default_physics_timestep_is_the_originals(make):
    env = make(seed=0, **NO_CAMERA)
    assert env.physics.model.opt.timestep == 0.002
    assert env.task.physics_steps_per_control_step == 25
    env.close()


def _arm_velocity_for(env, pinch_velocity):
    """Arm joint velocities moving the pinch site at ``pinch_velocity`` (m/s)."""
    task, model, data = env.task, env.physics.model.ptr, env.physics.data.ptr
    jacp, jacr = np.zeros((3, model.nv)), np.zeros((3, model.nv))
    mujoco.mj_jacSite(model, data, jacp, jacr, task._pinch_site)
    jac = np.vstack([jacp, jacr])[:, task._joint_dof[:6]]
    return np.linalg.pinv(jac) @ np.concatenate([pinch_velocity, np.zeros(3)])


def test_a_touch_lasting_a_single_substep_registers_the_move():
    env = make_mujoxo(epsilon=0.0, seed=0, arm_reset=False, **NO_CAMERA)
    env.reset()
    task = env.task
    # A fingertip pressed 3 mm into square 4 and flicked upwards at 0.12 m/s:
    # pressed in the first substep only (2 N), off the board for the other 24.
    place_hand(env, task.point_position(4) + (0, 0, 0.002))
    lift = _arm_velocity_for(env, [0.0, 0.0, 0.12])
    env.physics.data.qvel[task._joint_dof[:6]] = lift
    action = hold_action(env, lift)
    readings, contacts = substep_touches(env, action)
    pressed = np.flatnonzero(readings.max(axis=1) > arena_lib.TOUCH_THRESHOLD)
    assert pressed.tolist() == [0]  # exactly one substep of 25, not the last
    assert readings[0].argmax() == 4 and readings[-1].max() == 0.0
    timestep = env.step(action)
    assert task.moves_registered == 1 and task.moves[0] == 4
    assert timestep.observation["board_state"][1, 1, 1]
    assert timestep.observation["move_history"][0] == 4
    env.close()


@pytest.mark.parametrize("yaw", [1.57, 2.09])
def test_when_two_squares_are_pressed_in_one_substep_the_harder_press_wins(yaw):
    env = make_mujoxo(epsilon=0.0, seed=0, arm_reset=False, **NO_CAMERA)
    env.reset()
    task = env.task
    # The half-open hand straddles squares 3 and 4, its fingers pressing both.
    assert place_hand(env, (-0.05, 0.0, 0.06), yaw=yaw, fingers=np.full(3, 0.75))
    action = hold_action(env)
    action[6:] = 0.0
    readings, contacts = substep_touches(env, action)
    first = readings[0]
    assert first[3] > arena_lib.TOUCH_THRESHOLD and first[4] > arena_lib.TOUCH_THRESHOLD
    assert np.delete(first, [3, 4]).max() <= arena_lib.TOUCH_THRESHOLD
    assert all(geom.startswith("arm/hand/finger") for geom, _ in contacts[0])
    harder = 3 if first[3] > first[4] else 4
    env.step(action)
    assert task.moves_registered == 1 and task.moves[0] == harder
    env.close()


@pytest.mark.parametrize("make, noise", [(make_mujoxo, 1.0), (make_mujogo, 0.25)])
def test_physics_timestep_option_and_the_opponents_piece_jitter(make, noise):
    env = make(seed=0, physics_timestep=0.005, **NO_CAMERA)
    assert env.physics.model.opt.timestep == 0.005
    assert env.task.physics_steps_per_control_step == 10
    env.close()
    env = make(seed=0, **NO_CAMERA)
    task = env.task
    bound = noise * task.arena.pad_half
    offsets = []
    for _ in range(3):
        env.reset()
        free = [a for a in task.state.legal_actions() if a < task.game.num_points]
        point = 4 if task.game.size == 3 else 24
        press_from_above(env, task.point_position(point))
        assert task.moves_registered == 1 and task.moves[0] == point
        reply = task.moves[1]
        x, y, _ = env.physics.model.geom_pos[task._piece_ids[reply]]
        offsets.append(np.array([x, y]) - task.arena.point_xy[reply])
        assert free
    offsets = np.abs(offsets)
    assert offsets.max() <= bound + 1e-12
    assert offsets.max() > 0.2 * bound  # jittered, not at the centre
    env.close()


# The upper arm (its ring_3 geom) resting on a Go point in front of the base,
# the hand well above the board: found by scanning shoulder and elbow angles
# for a pose whose only robot-board contacts are non-finger arm geoms.
_UPPER_ARM_ON_BOARD = {1: 5.26, 2: 4.54}


@pytest.mark.parametrize("registering, registers", [(None, False), ("arm", True)])
def test_a_press_by_a_non_finger_arm_geom_registers_only_when_any_contact_counts(
    registering, registers
):
    # MuJoGo's default: a finger must touch the pressed point. registering="arm"
    # is MuJoXO's rule (any contact), offered as a MuJoGo deviation.
    overrides = {} if registering is None else {"registering": registering}
    env = envs.load("mujogo/7x7", seed=0, front_camera=None, arm_reset=False, **overrides)
    try:
        env.reset()
        task, data = env.task, env.physics.data
        for joint, angle in _UPPER_ARM_ON_BOARD.items():
            data.qpos[task._joint_qpos[joint]] = angle  # pylint: disable=protected-access
        data.qvel[:] = 0.0
        env.physics.forward()
        action = hold_action(env, arm_velocity=np.zeros(6))
        readings, contacts = substep_touches(env, action)
        touched = set().union(*contacts)
        # The board is pressed above the threshold, by arm geoms only.
        assert readings.max() > arena_lib.TOUCH_THRESHOLD
        assert touched and not any("finger" in robot for robot, _ in touched)
        timestep = env.step(action)
        assert (timestep.observation["move_history"][0] >= 0) == registers
    finally:
        env.close()
