"""The Jaco arm-touch skill (`skills.arm.ArmTouchSkill`) in MuJoXO and MuJoGo.

The skill runs through the option layer (`run_option`, `ModularAgent`) with
the observation-only `BoardEstimator`, on an environment wrapper that offers
only what a robot's interface would (`PublicEnv`). The tests themselves read
the simulator to *check* outcomes (they are outside the observation
boundary); the skill does not.
"""

from __future__ import annotations

import ast
import dataclasses
from pathlib import Path

import dm_env
import numpy as np
import pytest

import envs
from abstract_planners.base import Subgoal
from abstract_planners.tictactoe import MinimaxPlanner
from hier_agents.estimators import BoardEstimator
from hier_agents.modular.agent import ModularAgent
from hier_agents.modular.options import Outcome, run_option
from skills.arm import ArmModel, ArmTouchConfig, ArmTouchSkill
from skills.base import Status

NO_CAMERA = {"front_camera": None}
ARM_PACKAGE = Path(__file__).resolve().parents[1] / "skills" / "arm"
needs_gnugo = pytest.mark.usefixtures("gnugo")  # conftest decides whether GNU Go is there


class PublicEnv:
    """An environment seen through its public interface only: ``reset``,
    ``step``, ``action_spec``, ``observation_spec`` and ``description``
    (optionally a doctored one). Every action must lie within the spec."""

    def __init__(self, env, description=None):
        self._env = env
        self._description = description

    def reset(self):
        return self._env.reset()

    def step(self, action):
        spec = self._env.action_spec()
        action = np.asarray(action)
        assert action.shape == spec.shape
        assert np.all(action >= spec.minimum) and np.all(action <= spec.maximum)
        return self._env.step(action)

    def action_spec(self):
        return self._env.action_spec()

    def observation_spec(self):
        return self._env.observation_spec()

    def description(self):
        return self._description if self._description is not None else self._env.description()


def moved(description, shift=None, positions=None):
    """``description`` with its board points moved by ``shift`` (x, y, z) or
    put at ``positions(action)`` (the skill is fooled; the board is not)."""
    points = [description.point_position(a) for a in range(description.num_points)]
    if positions is not None:
        points = [positions(a) for a in range(description.num_points)]
    if shift is not None:
        points = [p + np.asarray(shift, float) for p in points]
    return dataclasses.replace(
        description, point_positions=tuple(tuple(map(float, p)) for p in points)
    )


def run_touch(env, skill, action, timestep, *, description=None, t_abs=80):
    """Runs ``skill`` on ``action`` from ``timestep`` through the option layer."""
    public = PublicEnv(env, description)
    estimator = BoardEstimator()
    estimator.reset(public.description(), timestep)
    scene = estimator.estimate(timestep)
    subgoal = Subgoal(
        action, scene.state.child(action) if action in scene.state.legal_actions() else None
    )
    return run_option(public, estimator, skill, subgoal, timestep, t_abs=t_abs, scene=scene)


def scene_of(env, timestep):
    estimator = BoardEstimator()
    estimator.reset(env.description(), timestep)
    return estimator.estimate(timestep)


@pytest.fixture
def mujoxo():
    """A fresh environment per test (as `mujogo`)."""
    env = envs.load("mujoxo/optimal", seed=0, **NO_CAMERA)
    yield env
    env.close()


@pytest.fixture
def mujogo():
    """A fresh environment per test: the arm's random reset poses then do not
    depend on which tests ran before (the order differs between workers)."""
    env = envs.load("mujogo/7x7", seed=0, **NO_CAMERA)
    yield env
    env.close()


# -- the observation boundary -------------------------------------------------------


def test_the_skill_package_never_names_the_simulator():
    """No module of `skills.arm` reads ``physics``, the ``task``, an ``env`` or
    raw MuJoCo pointers (``.ptr``)."""
    forbidden = {"physics", "task", "ptr", "env", "_env"}
    for path in sorted(ARM_PACKAGE.glob("*.py")):
        tree = ast.parse(path.read_text())
        names = {node.attr for node in ast.walk(tree) if isinstance(node, ast.Attribute)}
        names |= {node.id for node in ast.walk(tree) if isinstance(node, ast.Name)}
        names |= {
            arg.arg
            for node in ast.walk(tree)
            if isinstance(node, ast.arguments)
            for arg in node.args + node.kwonlyargs
        }
        assert not names & forbidden, (path.name, names & forbidden)


def test_a_touch_registers_through_the_public_interface_only(mujoxo):
    """A MuJoXO touch through a wrapper that has no ``physics`` or ``task``."""
    env = PublicEnv(mujoxo)
    assert not hasattr(env, "physics") and not hasattr(env, "task")
    timestep = env.reset()
    estimator = BoardEstimator()
    estimator.reset(env.description(), timestep)
    scene = estimator.estimate(timestep)
    skill = ArmTouchSkill()
    result = run_option(env, estimator, skill, Subgoal(4, scene.state.child(4)), timestep, t_abs=80)
    assert result.outcome is Outcome.REACHED, result.reason
    assert estimator.estimate(result.timestep).moves[0] == 4
    assert mujoxo.task.moves[0] == 4  # (the check reads the simulator; the skill did not)


def test_the_arm_model_matches_the_simulated_arm(mujogo):
    """The skill's own arm model, set to the observed joints, puts the pinch
    site where the simulation has it."""
    env = mujogo
    timestep = env.reset()
    arm = ArmModel(env.description().arm, band=0.006)
    arm.set_posture(timestep.observation["arm/joints_pos"])
    np.testing.assert_allclose(
        arm.current.data.site_xpos[arm.site], env.task.pinch_site_position(), atol=1e-9
    )
    assert np.all(arm.fingers_closed > 1.0)
    np.testing.assert_allclose(arm.base_xy(), env.description().arm.base_position[:2], atol=1e-9)


def test_config_and_keyword_overrides():
    config = ArmTouchConfig(pre_height=0.03)
    assert ArmTouchSkill(config).config.pre_height == 0.03
    skill = ArmTouchSkill(config, max_tilt=40, orientations=[[0, 0]])
    assert skill.config.pre_height == 0.03 and skill.config.max_tilt == 40.0
    assert skill.config.orientations == ((0.0, 0.0),)
    assert ArmTouchSkill(pre_height=0.02).config.pre_height == 0.02
    assert ArmTouchSkill().config == ArmTouchConfig()
    with pytest.raises(TypeError):
        ArmTouchSkill(no_such_parameter=1)
    with pytest.raises(dataclasses.FrozenInstanceError):
        config.pre_height = 0.1
    assert ArmTouchSkill().hold().shape == (9,)  # before any reset


# -- touches --------------------------------------------------------------------


@pytest.mark.parametrize("point", range(9))
def test_mujoxo_touch_registers_the_planned_point(mujoxo, point):
    env = mujoxo
    timestep = env.reset()
    skill = ArmTouchSkill()
    result = run_touch(env, skill, point, timestep)
    assert result.outcome is Outcome.REACHED, result.reason
    assert env.task.moves_registered == 1
    assert env.task.moves[0] == point
    # (run_option takes one more step, the one on which the skill sees the move)
    assert result.duration <= skill.config.max_steps + 1


@pytest.mark.slow
@needs_gnugo
def test_mujogo_every_point_and_the_pass_register(mujogo):
    """Every point of the 7x7 board -- the far row, ~0.8 m from the arm's base,
    needs the hand leant -- and the pass, each from a fresh random arm pose."""
    env = mujogo
    description = env.description()
    failures, leans = [], {}
    for action in list(range(description.num_points)) + [description.pass_action]:
        timestep = env.reset()
        skill = ArmTouchSkill()
        result = run_touch(env, skill, action, timestep)
        if (
            result.outcome is not Outcome.REACHED
            or env.task.moves[:1] != (action,)
            or result.duration > skill.config.max_steps + 1
        ):
            failures.append((action, result.reason, env.task.moves[:1], result.duration))
        leans[action] = skill.touch_tilt
    assert not failures
    # The far row (Go row 0, farthest from the arm) is touched with the hand
    # leant well away from vertical.
    assert min(leans[a] for a in range(description.board_size)) > 15


@needs_gnugo
def test_mujogo_several_touches_in_a_row(mujogo):
    """Touches from the random poses the arm is reset to after every move."""
    env = mujogo
    timestep = env.reset()
    skill = ArmTouchSkill()
    rng = np.random.default_rng(1)
    pass_action = env.description().pass_action
    for touch in range(4):
        state = scene_of(env, timestep).state
        legal = [a for a in state.legal_actions() if a != pass_action]
        point = int(rng.choice(legal))
        result = run_touch(env, skill, point, timestep)
        timestep = result.timestep
        assert result.outcome is Outcome.REACHED, (touch, point, result.reason)
        assert env.task.moves[2 * touch] == point
        assert env.task.moves_registered == touch + 1


@needs_gnugo
def test_mujogo_pass_on_the_pass_area(mujogo):
    env = mujogo
    timestep = env.reset()
    skill = ArmTouchSkill()
    description = env.description()
    tool_x = env.task.pinch_site_position()[0]
    result = run_touch(env, skill, description.pass_action, timestep)
    assert result.outcome is Outcome.REACHED, result.reason
    assert env.task.moves[0] == description.pass_action
    # The skill went for the pass area on the hand's side of the board, clear
    # of the board's squares.
    cx = description.board_centre[0]
    assert np.sign(skill.target[0] - cx) == np.sign(tool_x - cx) or abs(tool_x - cx) < 1e-3
    assert abs(skill.target[0] - cx) > description.board_half + 0.05


@pytest.mark.parametrize("seed", [0, 1])
def test_a_whole_mujoxo_game_against_the_optimal_opponent_is_a_draw(seed):
    """The modular agent (board estimator, minimax, the arm skill) plays a
    whole game on the public interface: every touch registers, and the game
    is a draw."""
    raw = envs.load("mujoxo/optimal", seed=seed, **NO_CAMERA)
    env = PublicEnv(raw)
    agent = ModularAgent(BoardEstimator(), MinimaxPlanner(seed=seed), ArmTouchSkill())
    timestep = env.reset()
    agent.reset(env.description(), timestep, seed=seed)
    while not timestep.last():
        timestep = env.step(agent.act(timestep))
    agent.end_episode(timestep)
    stats = agent.episode_stats
    assert stats.failed == 0 and stats.cut_off == 0, stats.failures
    assert stats.reached == stats.issued <= 5
    state = agent.estimator.estimate(timestep).state
    assert state.is_terminal()
    assert state.returns()[0] == 0  # a draw: never a loss
    assert timestep.reward == pytest.approx(0.5)
    raw.close()


@needs_gnugo
def test_a_new_subgoal_mid_flight_is_followed(mujogo):
    """Reset on another point while the arm moves (as after a cut-off): the new
    point registers."""
    env = mujogo
    timestep = env.reset()
    skill = ArmTouchSkill()
    result = run_touch(env, skill, 0, timestep, t_abs=8)
    assert result.outcome is Outcome.CUT_OFF and result.duration == 8
    assert env.task.moves_registered == 0
    assert np.abs(result.timestep.observation["arm/joints_vel"][:6]).max() > 0.05  # moving
    result = run_touch(env, skill, 48, result.timestep)
    assert result.outcome is Outcome.REACHED, result.reason
    assert env.task.moves[0] == 48


# -- failures -------------------------------------------------------------------


def test_unreachable_target_fails_at_once(mujoxo):
    env = mujoxo
    timestep = env.reset()
    description = moved(env.description(), positions=lambda a: np.array([1.5, 1.5, 0.024]))
    scene = scene_of(env, timestep)
    skill = ArmTouchSkill()
    skill.reset(description, Subgoal(4, scene.state.child(4)), scene)
    assert skill.status is Status.FAILURE
    assert skill.failure_reason.startswith("unreachable")
    command = skill.act(timestep, scene)  # holds still, does not raise
    assert np.all(command[:6] == 0)


def test_illegal_or_off_board_actions_fail(mujoxo):
    env = mujoxo
    env.reset()
    env.task.play_moves([4, 0])  # the centre is taken
    timestep = env.step(ArmTouchSkill().hold())
    scene = scene_of(env, timestep)
    assert scene.moves == (4, 0)
    skill = ArmTouchSkill()
    skill.reset(env.description(), Subgoal(4, None), scene)
    assert skill.status is Status.FAILURE and skill.failure_reason.startswith("illegal")
    skill.reset(env.description(), Subgoal(9, None), scene)
    assert skill.status is Status.FAILURE and skill.failure_reason.startswith("illegal")


def test_another_registered_move_is_a_failure(mujoxo):
    """The skill is fooled into touching point 2's pad while asked for point 0."""
    env = mujoxo
    timestep = env.reset()
    real = env.description()
    description = moved(real, positions=lambda a: real.point_position(2))
    result = run_touch(env, ArmTouchSkill(), 0, timestep, description=description)
    assert result.outcome is Outcome.FAILED
    assert result.reason.startswith("wrong move")
    assert env.task.moves[0] == 2


def test_a_target_that_never_registers_fails_within_the_step_limit(mujoxo):
    """A target off the pads (beside the board) cannot register: the skill gives up."""
    env = mujoxo
    timestep = env.reset()
    description = moved(env.description(), shift=(0.3, 0.0, 0.0))
    skill = ArmTouchSkill()
    result = run_touch(env, skill, 5, timestep, description=description, t_abs=200)
    assert result.outcome is Outcome.FAILED
    assert env.task.moves_registered == 0
    assert result.duration <= skill.config.max_steps + 1  # (+ the hold on which it gave up)


def test_the_episode_ending_first_is_a_failure(mujoxo):
    env = mujoxo
    timestep = env.reset()
    scene = scene_of(env, timestep)
    skill = ArmTouchSkill()
    skill.reset(env.description(), Subgoal(4, scene.state.child(4)), scene)
    skill.act(timestep._replace(step_type=dm_env.StepType.LAST), scene)
    assert skill.status is Status.FAILURE
    assert skill.failure_reason.startswith("episode ended")


def test_the_skill_does_not_change_the_simulation(mujoxo):
    env = mujoxo
    timestep = env.reset()
    data = env.physics.data
    qpos, qvel = data.qpos.copy(), data.qvel.copy()
    skill = ArmTouchSkill()
    scene = scene_of(env, timestep)
    skill.reset(env.description(), Subgoal(4, scene.state.child(4)), scene)
    skill.act(timestep, scene)
    np.testing.assert_array_equal(data.qpos, qpos)
    np.testing.assert_array_equal(data.qvel, qvel)
    assert skill.name == "arm-touch"
