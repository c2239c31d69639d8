"""The option runner (`hier_agents.modular.options`): every outcome, and every
skill family through the same runner."""

from __future__ import annotations

import types

import dm_env
import numpy as np
import pytest

from abstract_planners.base import Subgoal
from hier_agents.modular.families import FAMILIES
from hier_agents.modular.options import Outcome, OptionRunner, T_ABS, run_option
from skills.base import Skill, Status


class _Scripted(Skill):
    """Succeeds (or fails) after ``after`` calls of act; actions count up."""

    def __init__(self, after=None, fail=False):
        super().__init__()
        self.after, self.fail, self.calls = after, fail, 0

    def reset(self, description, subgoal, scene):
        self.status, self.failure_reason, self.calls = Status.RUNNING, None, 0

    def act(self, timestep, scene):
        self.calls += 1
        if self.after is not None and self.calls > self.after:
            if self.fail:
                self._fail("blocked: by a wall")
            else:
                self.status = Status.SUCCESS
        return np.array([float(self.calls)])

    def hold(self):
        return np.zeros(1)


def _drive(runner, rewards, *, last_at=None, blind=(), scene=None):
    """Runs the started option; the k-th step returns reward ``rewards[k]``,
    discount 0.5, the episode ends at step ``last_at``; scenes of steps in
    ``blind`` cannot be estimated. Returns the actions."""
    scene = scene or types.SimpleNamespace(state=None)
    timestep, actions, k = dm_env.restart(None), [], 0
    current = scene
    while (action := runner.act(timestep, current)) is not None:
        actions.append(action)
        k += 1
        if last_at is not None and k >= last_at:
            timestep = dm_env.termination(rewards[k - 1], None)
        else:
            timestep = dm_env.transition(rewards[k - 1], None, discount=0.5)
        current = None if k in blind else scene
    return actions


def _runner(skill, **kw):
    runner = OptionRunner(skill, **kw)
    runner.start(None, Subgoal("a", None), types.SimpleNamespace(state=None))
    return runner


def test_reached_with_reward_sum_and_discount_product():
    runner = _runner(_Scripted(after=3), gamma=0.9)
    actions = _drive(runner, [1.0, 2.0, 4.0, 8.0])
    result = runner.result
    assert result.outcome is Outcome.REACHED and result.reason is None
    assert result.duration == 3 == len(actions)
    assert result.reward == pytest.approx(1.0 + 0.9 * 2.0 + 0.81 * 4.0)
    assert result.discount == pytest.approx((0.9 * 0.5) ** 3)


def test_failed_carries_the_skills_reason():
    runner = _runner(_Scripted(after=2, fail=True))
    _drive(runner, [0.0] * 5)
    assert runner.result.outcome is Outcome.FAILED
    assert runner.result.reason == "blocked: by a wall" and runner.result.duration == 2


def test_cut_off_at_t_abs():
    runner = _runner(_Scripted(), t_abs=7)
    _drive(runner, [0.0] * 10)
    assert runner.result.outcome is Outcome.CUT_OFF and runner.result.duration == 7


def test_interrupted_by_the_episodes_end():
    runner = _runner(_Scripted())
    _drive(runner, [0.0, 0.0, 1.0], last_at=3)
    result = runner.result
    assert result.outcome is Outcome.INTERRUPTED and result.reason == "episode ended"
    assert result.duration == 3 and result.discount == 0.0 and result.reward == 1.0


def test_interrupt_from_outside():
    runner = _runner(_Scripted())
    runner.act(dm_env.restart(None), types.SimpleNamespace(state=None))
    result = runner.interrupt("the user stopped it", dm_env.transition(2.0, None))
    assert result.outcome is Outcome.INTERRUPTED and result.reason == "the user stopped it"
    assert result.reward == 2.0 and not runner.running
    with pytest.raises(RuntimeError):
        runner.act(dm_env.restart(None), None)


def test_a_missing_estimate_holds_still_and_counts():
    skill = _Scripted(after=3)
    runner = _runner(skill)
    actions = _drive(runner, [0.0] * 6, blind=(1, 2))
    # steps 2 and 3 follow frames that could not be estimated: the hold action
    assert [a[0] for a in actions] == [1.0, 0.0, 0.0, 2.0, 3.0]
    assert runner.result.outcome is Outcome.REACHED and runner.result.duration == 5


def test_bad_arguments():
    with pytest.raises(ValueError):
        OptionRunner(_Scripted(), t_abs=0)
    with pytest.raises(ValueError):
        OptionRunner(_Scripted(), gamma=0.0)
    assert OptionRunner(_Scripted()).t_abs == T_ABS


def test_sokoban_deviation_and_the_solving_push():
    from abstract_planners.sokoban import SokobanState

    state = SokobanState.from_text("#####\n#@$.#\n#####")
    subgoal = Subgoal(("R",), state.apply("R"))
    adapter = FAMILIES["mujoban"]
    expected = adapter.expected(state, subgoal)
    assert expected == frozenset({state.boxes, subgoal.state.boxes})
    elsewhere = types.SimpleNamespace(state=types.SimpleNamespace(boxes=frozenset({(9, 9)})))
    assert adapter.deviates(expected, elsewhere)
    assert adapter.done_at_end(subgoal, types.SimpleNamespace(state=subgoal.state))
    runner = OptionRunner(_Scripted(), adapter, check_every=1)
    runner.start(None, subgoal, types.SimpleNamespace(state=state))
    assert runner.act(dm_env.restart(None), types.SimpleNamespace(state=state)) is not None
    assert runner.act(dm_env.transition(0.0, None), elsewhere) is None
    assert runner.result.outcome is Outcome.FAILED and runner.result.reason == "deviation"
    runner.start(None, subgoal, types.SimpleNamespace(state=state))
    runner.act(dm_env.restart(None), types.SimpleNamespace(state=state))
    runner.act(dm_env.termination(1.0, None), types.SimpleNamespace(state=subgoal.state))
    assert runner.result.outcome is Outcome.REACHED


def test_a_board_subgoal_planned_on_a_rewritten_estimate_deviates():
    """Go: a move planned after the opponent's pass, then the estimate finds
    the reply the pass stood for: the option fails as a deviation (the agent
    plans again); the agent's own move extending the record does not."""
    import pyspiel

    state = pyspiel.load_game("go", {"board_size": 7}).new_initial_state()
    for action in (24, 49):  # the agent's stone, the opponent's pass
        state.apply_action(action)
    subgoal = Subgoal(25, state.child(25))
    adapter = FAMILIES["mujogo"]
    expected = adapter.expected(state, subgoal)
    revised = state.clone()
    revised.undo_action(1, 49)  # the pass was a reply at 37
    revised.apply_action(37)
    assert adapter.deviates(expected, types.SimpleNamespace(state=revised))
    assert not adapter.deviates(expected, types.SimpleNamespace(state=subgoal.state))
    runner = OptionRunner(_Scripted(), adapter, check_every=1)
    runner.start(None, subgoal, types.SimpleNamespace(state=state))
    assert runner.act(dm_env.restart(None), types.SimpleNamespace(state=state)) is not None
    assert runner.act(dm_env.transition(0.0, None), types.SimpleNamespace(state=revised)) is None
    assert runner.result.outcome is Outcome.FAILED and runner.result.reason == "deviation"


def _ball_case(skill_name):
    import envs
    from abstract_planners.sokoban_solver import SokobanSolverPlanner
    from hier_agents.modular.components import SKILLS

    env = envs.load("mujoban/level1", seed=3, **envs.no_cameras("mujoban/level1"))
    from hier_agents.estimators import OracleEstimator

    estimator = OracleEstimator(env)
    timestep = env.reset()
    estimator.reset(env.description(), timestep)
    scene = estimator.estimate(timestep)
    subgoal = SokobanSolverPlanner().next_push(scene.state)
    return (
        env,
        estimator,
        SKILLS["mujoban"][skill_name](env.description(), 0),
        subgoal,
        timestep,
        scene,
    )


def _arm_case(skill_name):
    import envs
    from hier_agents.estimators import BoardEstimator
    from hier_agents.modular.components import SKILLS

    env = envs.load("mujoxo/optimal", seed=1, **envs.no_cameras("mujoxo/optimal"))
    estimator = BoardEstimator()
    timestep = env.reset()
    estimator.reset(env.description(), timestep)
    scene = estimator.estimate(timestep)
    subgoal = Subgoal(4, scene.state.child(4))
    return (
        env,
        estimator,
        SKILLS["mujoxo"][skill_name](env.description(), 0),
        subgoal,
        timestep,
        scene,
    )


@pytest.mark.parametrize(
    "family,skill_name",
    [
        ("mujoban", "ball"),
        ("mujoban", "learned-ball"),
        ("mujoxo", "arm-touch"),
        ("mujoxo", "learned-arm"),
    ],
)
def test_every_skill_family_runs_through_the_runner(family, skill_name):
    from hier_agents.modular.components import SKILLS

    if skill_name not in SKILLS[family]:
        pytest.skip(f"no {skill_name} skill registered")
    make = _ball_case if family == "mujoban" else _arm_case
    env, estimator, skill, subgoal, timestep, scene = make(skill_name)
    try:
        result = run_option(
            env,
            estimator,
            skill,
            subgoal,
            timestep,
            scene=scene,
            adapter=FAMILIES[family],
            t_abs=150,
        )
    finally:
        env.close()
    assert result.outcome is Outcome.REACHED, (result.outcome, result.reason)
    assert 0 < result.duration <= 150
    assert result.scene is not None
