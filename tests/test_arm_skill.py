"""The Jaco arm-touch skill (`skills.arm.ArmTouchSkill`) in MuJoXO and MuJoGo."""

from __future__ import annotations

import shutil

import numpy as np
import pytest

import envs
from abstract_planners.base import Subgoal
from abstract_planners.tictactoe import MinimaxPlanner
from skills.arm import ArmTouchSkill
from skills.base import Status

NO_CAMERA = {"front_camera": None}
needs_gnugo = pytest.mark.skipif(shutil.which("gnugo") is None and
                                 shutil.which("/usr/games/gnugo") is None,
                                 reason="GNU Go is not installed")


@pytest.fixture(scope="module")
def mujoxo():
    env = envs.load("mujoxo/optimal", seed=0, **NO_CAMERA)
    yield env
    env.close()


@pytest.fixture(scope="module")
def mujogo():
    env = envs.load("mujogo/7x7", seed=0, **NO_CAMERA)
    yield env
    env.close()


def run_skill(env, skill, action, timestep, max_steps=80):
    """Resets ``skill`` on ``action`` from the current state and steps until it ends."""
    state = env.task.state.clone()
    skill.reset(env, Subgoal(action, state.child(action)), state)
    steps = 0
    while steps < max_steps:
        command = skill.act(timestep)
        if skill.status is not Status.RUNNING:
            break
        spec = env.action_spec()
        assert command.shape == spec.shape
        assert np.all(command >= spec.minimum) and np.all(command <= spec.maximum)
        timestep = env.step(command)
        steps += 1
        if timestep.last():
            skill.act(timestep)
            break
    return timestep, steps


@pytest.mark.parametrize("point", range(9))
def test_mujoxo_touch_registers_the_planned_point(mujoxo, point):
    env = mujoxo
    timestep = env.reset()
    skill = ArmTouchSkill()
    _, steps = run_skill(env, skill, point, timestep)
    assert skill.status is Status.SUCCESS, skill.failure_reason
    assert env.task.moves_registered == 1
    assert env.task.moves[0] == point
    assert steps <= skill.max_steps


@needs_gnugo
def test_mujogo_every_point_and_the_pass_register(mujogo):
    """Every point of the 7x7 board -- the far row, ~0.8 m from the arm's base,
    needs the hand leant -- and the pass, each from a fresh random arm pose."""
    env = mujogo
    game = env.task.game
    failures, leans = [], {}
    for action in list(range(game.num_points)) + [game.pass_action]:
        timestep = env.reset()
        skill = ArmTouchSkill()
        _, steps = run_skill(env, skill, action, timestep)
        if (skill.status is not Status.SUCCESS or env.task.moves[:1] != (action,)
                or steps > skill.max_steps):
            failures.append((action, skill.failure_reason, env.task.moves[:1], steps))
        leans[action] = skill.touch_tilt
    assert not failures
    # The far row (Go row 0, farthest from the arm) is touched with the hand
    # leant well away from vertical.
    assert min(leans[a] for a in range(game.size)) > 15


@needs_gnugo
def test_mujogo_several_touches_in_a_row(mujogo):
    """Touches from the random poses the arm is reset to after every move."""
    env = mujogo
    timestep = env.reset()
    skill = ArmTouchSkill()
    rng = np.random.default_rng(1)
    for touch in range(4):
        legal = [a for a in env.task.state.legal_actions() if a != env.task.game.pass_action]
        point = int(rng.choice(legal))
        timestep, _ = run_skill(env, skill, point, timestep)
        assert skill.status is Status.SUCCESS, (touch, point, skill.failure_reason)
        assert env.task.moves[2 * touch] == point
        assert env.task.moves_registered == touch + 1


@needs_gnugo
def test_mujogo_pass_on_the_pass_area(mujogo):
    env = mujogo
    timestep = env.reset()
    skill = ArmTouchSkill()
    pass_action = env.task.game.pass_action
    tool_x = env.task.pinch_site_position()[0]
    run_skill(env, skill, pass_action, timestep)
    assert skill.status is Status.SUCCESS, skill.failure_reason
    assert env.task.moves[0] == pass_action
    # The skill went for the pass area on the hand's side of the board, clear
    # of the board's squares.
    assert np.sign(skill.target[0]) == np.sign(tool_x) or abs(tool_x) < 1e-3
    arena = env.task.arena
    assert abs(skill.target[0] - arena.centre[0]) > arena.half_board + 0.05


@pytest.mark.parametrize("seed", [0, 1])
def test_a_whole_mujoxo_game_against_the_optimal_opponent_is_a_draw(seed):
    env = envs.load("mujoxo/optimal", seed=seed, **NO_CAMERA)
    planner = MinimaxPlanner(seed=seed)
    skill = ArmTouchSkill()
    timestep = env.reset()
    touches = 0
    while not timestep.last():
        state = env.task.state.clone()
        subgoal = planner.plan(state)
        skill.reset(env, subgoal, state)
        for _ in range(50):
            command = skill.act(timestep)
            if skill.status is not Status.RUNNING:
                break
            timestep = env.step(command)
            if timestep.last():
                skill.act(timestep)
                break
        assert skill.status is Status.SUCCESS, skill.failure_reason
        touches += 1
        assert touches <= 5
    state = env.task.state
    assert state.is_terminal()
    assert state.returns()[0] == 0  # a draw: never a loss
    assert timestep.reward == pytest.approx(0.5)
    env.close()


@needs_gnugo
def test_a_new_subgoal_mid_flight_is_followed(mujogo):
    """Reset on another point while the arm moves (as after a cut-off): the new
    point registers."""
    env = mujogo
    timestep = env.reset()
    skill = ArmTouchSkill()
    state = env.task.state.clone()
    skill.reset(env, Subgoal(0, state.child(0)), state)
    for _ in range(8):
        timestep = env.step(skill.act(timestep))
    assert env.task.moves_registered == 0
    run_skill(env, skill, 48, timestep)
    assert skill.status is Status.SUCCESS, skill.failure_reason
    assert env.task.moves[0] == 48


def test_unreachable_target_fails_at_once(mujoxo, monkeypatch):
    env = mujoxo
    timestep = env.reset()
    monkeypatch.setattr(env.task, "point_position",
                        lambda action: np.array([1.5, 1.5, 0.024]))
    skill = ArmTouchSkill()
    state = env.task.state.clone()
    skill.reset(env, Subgoal(4, state.child(4)), state)
    assert skill.status is Status.FAILURE
    assert skill.failure_reason.startswith("unreachable")
    command = skill.act(timestep)  # holds still, does not raise
    assert np.all(command[:6] == 0)


def test_illegal_or_off_board_actions_fail(mujoxo):
    env = mujoxo
    env.reset()
    env.task.play_moves([4, 0])  # the centre is taken
    skill = ArmTouchSkill()
    state = env.task.state.clone()
    skill.reset(env, Subgoal(4, None), state)
    assert skill.status is Status.FAILURE and skill.failure_reason.startswith("illegal")
    skill.reset(env, Subgoal(9, None), state)
    assert skill.status is Status.FAILURE and skill.failure_reason.startswith("illegal")


def test_another_registered_move_is_a_failure(mujoxo, monkeypatch):
    """The skill is fooled into touching point 2's pad while asked for point 0."""
    env = mujoxo
    timestep = env.reset()
    real = env.task.point_position
    monkeypatch.setattr(env.task, "point_position", lambda action: real(2))
    skill = ArmTouchSkill()
    run_skill(env, skill, 0, timestep)
    assert skill.status is Status.FAILURE
    assert skill.failure_reason.startswith("wrong move")
    assert env.task.moves[0] == 2


def test_a_target_that_never_registers_fails_within_the_step_limit(mujoxo, monkeypatch):
    """A target off the pads (beside the board) cannot register: the skill gives up."""
    env = mujoxo
    timestep = env.reset()
    real = env.task.point_position
    monkeypatch.setattr(env.task, "point_position",
                        lambda action: real(action) + np.array([0.3, 0.0, 0.0]))
    skill = ArmTouchSkill()
    _, steps = run_skill(env, skill, 5, timestep, max_steps=200)
    assert skill.status is Status.FAILURE
    assert env.task.moves_registered == 0
    assert steps <= skill.max_steps


def test_the_skill_does_not_change_the_simulation(mujoxo):
    env = mujoxo
    timestep = env.reset()
    data = env.physics.data
    qpos, qvel = data.qpos.copy(), data.qvel.copy()
    skill = ArmTouchSkill()
    state = env.task.state.clone()
    skill.reset(env, Subgoal(4, state.child(4)), state)
    skill.act(timestep)
    np.testing.assert_array_equal(data.qpos, qpos)
    np.testing.assert_array_equal(data.qvel, qvel)
    assert skill.name == "arm-touch"
