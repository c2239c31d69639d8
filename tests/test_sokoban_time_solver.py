"""The time-cost Sokoban planner: valid plans, never slower (by the estimate)
than the push solver's, usable by name."""

from __future__ import annotations

import pytest

from abstract_planners.sokoban import SokobanState, replay
from abstract_planners.sokoban_solver import SokobanSolverPlanner, solve
from abstract_planners.sokoban_time import estimate_steps, plan_features
from abstract_planners.sokoban_time_solver import TimeSolverPlanner, solve_for_time
from envs.mujoban.levels import BOXOBAN_DIR, read_levels

LEVELS = read_levels(BOXOBAN_DIR / "medium-valid-000.txt")[:12]


@pytest.mark.parametrize("level", LEVELS, ids=lambda level: f"medium-{level.name}")
def test_time_plans_solve_and_are_never_estimated_slower_than_push_plans(level):
    state = SokobanState.from_level(level)
    timed = solve_for_time(state, time_limit=5.0)
    assert timed.solved and replay(state, timed.moves).is_solved()
    planner = TimeSolverPlanner(time_limit=10.0)
    chosen = planner.search(state)
    pushed = solve(state, time_limit=10.0)
    estimate = lambda moves: estimate_steps(plan_features(state, moves))  # noqa: E731
    assert replay(state, chosen.moves).is_solved()
    assert estimate(chosen.moves) <= estimate(pushed.moves)
    assert estimate(chosen.moves) <= estimate(timed.moves)


def test_time_search_saves_estimated_time_over_the_first_medium_levels():
    total_time = total_push = 0.0
    for level in LEVELS:
        state = SokobanState.from_level(level)
        total_push += estimate_steps(plan_features(state, solve(state).moves))
        total_time += estimate_steps(plan_features(state, solve_for_time(state).moves))
    assert total_time < 0.95 * total_push


def test_the_time_planner_follows_its_plan_and_reports_deadlocks():
    state = SokobanState.from_text("#######\n#     #\n# @$ .#\n#     #\n#######")
    planner = TimeSolverPlanner()
    subgoal = planner.next_push(state)
    assert subgoal.action == ("R",) and subgoal.state.boxes == {(2, 4)}
    assert planner.plan(subgoal.state).info["cached"]
    dead = SokobanState.from_text("#######\n#$    #\n# @  .#\n#     #\n#######")
    from abstract_planners.base import NoPlanError

    with pytest.raises(NoPlanError) as err:
        planner.next_push(dead)
    assert err.value.reason == "unsolvable"
    assert isinstance(planner, SokobanSolverPlanner)
