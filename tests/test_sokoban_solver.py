"""The Sokoban solver, its deadlock checks, and the Sokoban planners."""

from __future__ import annotations

import random
from collections import deque

import pytest

from abstract_planners.base import NoPlanError, Planner, Subgoal
from abstract_planners.sokoban import SokobanState, replay
from abstract_planners.sokoban_random import RandomPlanner
from abstract_planners.sokoban_solver import (
    SokobanSolverPlanner,
    SolveResult,
    dead_squares,
    frozen_deadlock,
    pi_corral_pushes,
    solve,
)
from envs.mujoban.generator import generate_level
from envs.mujoban.levels import BOXOBAN_DIR, read_levels

#: Unsolvable, though no box starts on a dead square or frozen: found by
#: random play on generated levels and confirmed by exhaustive search.
UNSOLVABLE_AFTER_SEARCH = [
    "\n".join(
        [
            "########",
            "####  ##",
            "#### .##",
            "####  ##",
            "# *#$ ##",
            "#   @ ##",
            "#    *##",
            "########",
        ]
    ),
    "\n".join(
        [
            "########",
            "#   ####",
            "#*  ####",
            "#  #####",
            "#  #####",
            "# @# * #",
            "#.$    #",
            "########",
        ]
    ),
]


def board(*rows: str) -> SokobanState:
    return SokobanState.from_text("\n".join(rows))


def levels(name: str, count: int = 20) -> list[SokobanState]:
    """``count`` levels spread evenly over a shipped Boxoban file."""
    all_levels = read_levels(BOXOBAN_DIR / name)
    stride = len(all_levels) // count
    return [SokobanState.from_level(all_levels[i * stride]) for i in range(count)]


def exhaustive_solvable(state: SokobanState) -> bool:
    """Breadth-first search over every (player, boxes) state: the ground truth."""
    seen = {state}
    queue = deque([state])
    while queue:
        s = queue.popleft()
        if s.is_solved():
            return True
        for move in s.legal_moves():
            t = s.apply(move)
            if t not in seen:
                seen.add(t)
                queue.append(t)
    return False


def check_solution(state: SokobanState, result: SolveResult) -> None:
    assert result.solved and result.reason == "solved"
    assert all(m in "UDLR" for m in result.moves)
    assert replay(state, result.moves).is_solved()
    pushes, s = 0, state
    for move in result.moves:
        pushes += s.is_push(move)
        s = s.apply(move)
    assert pushes == result.pushes


# -- dead squares and frozen boxes ---------------------------------------------------------


def test_dead_squares_of_a_hand_made_room():
    s = board("######", "#    #", "# .  #", "#   @#", "#  $ #", "######")
    dead = dead_squares(s)
    # Corners, and the cells along walls without a target, are dead.
    for cell in [
        (1, 1),
        (1, 4),
        (4, 1),
        (4, 4),
        (1, 2),
        (1, 3),
        (4, 2),
        (4, 3),
        (2, 1),
        (3, 1),
        (2, 4),
        (3, 4),
    ]:
        assert cell in dead, cell
    # Interior cells can be pushed to the target; the target is never dead.
    for cell in [(2, 2), (2, 3), (3, 2), (3, 3)]:
        assert cell not in dead, cell


def test_a_wall_cell_next_to_a_target_is_live():
    s = board("#######", "#.    #", "#  $ @#", "#######")
    dead = dead_squares(s)
    assert (1, 2) not in dead and (1, 5) in dead  # top row: pushed left onto the target
    assert (2, 2) in dead  # bottom row: no target along it
    assert (2, 3) in dead


def test_solver_rejects_a_box_on_a_dead_square_at_once():
    s = board("######", "#$  .#", "#  @ #", "######")
    r = solve(s)
    assert (r.solved, r.reason, r.nodes) == (False, "unsolvable", 0)


def test_frozen_box_in_a_corner():
    s = board("#####", "#$ .#", "# @ #", "#####")
    assert frozen_deadlock(s, (1, 1))


def test_box_in_a_corner_on_its_target_is_not_a_deadlock():
    s = board("#####", "#* .#", "# @$#", "#####")
    assert not frozen_deadlock(s, (1, 1))


def test_two_boxes_side_by_side_against_a_wall_are_frozen():
    s = board("########", "#  $$  #", "#  ..@ #", "########")
    assert frozen_deadlock(s, (1, 3)) and frozen_deadlock(s, (1, 4))
    # The same pair away from the wall can still move.
    t = board("########", "#      #", "#  $$ @#", "#  ..  #", "#      #", "########")
    assert not frozen_deadlock(t, (2, 3))


def test_a_frozen_pair_is_fine_only_with_both_boxes_on_targets():
    on_targets = board("#######", "#  ** #", "#   @ #", "#######")
    assert not frozen_deadlock(on_targets, (1, 3))
    one_off = board("#######", "#  *$ #", "#  .@ #", "#######")
    assert frozen_deadlock(one_off, (1, 3))  # on target, but frozen with an off-target box


def test_square_of_four_boxes_is_frozen_in_open_floor():
    s = board("########", "#      #", "# $$   #", "# $$ @ #", "# .... #", "#      #", "########")
    assert frozen_deadlock(s, (2, 2))


def test_box_blocked_on_one_axis_only_is_not_frozen():
    s = board("#######", "# $  .#", "#  @  #", "#######")
    assert not frozen_deadlock(s, (1, 2))  # can still be pushed sideways
    # Along a wall with no target, both sideways cells are dead: frozen.
    t = board("#######", "# $   #", "#  @ .#", "#######")
    assert frozen_deadlock(t, (1, 2))
    u = board("#####", "# # #", "#.$ #", "#@# #", "#   #", "#####")
    assert not frozen_deadlock(u, (2, 2))  # walls above and below, free sideways


def test_frozen_deadlock_needs_a_box():
    with pytest.raises(ValueError, match=r"no box on \(1, 2\)"):
        frozen_deadlock(board("#####", "#$ .#", "# @ #", "#####"), (1, 2))


# -- PI corrals ------------------------------------------------------------------------


def test_pi_corral_restricts_to_pushes_into_the_corral():
    # The player, on the left, cannot reach the pocket behind the boxes;
    # the only pushes of the barrier boxes are into it.
    s = board("########", "#   #  #", "# @ $ .#", "#   #. #", "#   $  #", "########")
    pushes = pi_corral_pushes(s)
    assert pushes is not None
    assert set(pushes) <= {((2, 4), "R"), ((4, 4), "R")}
    assert ((2, 4), "R") in pushes


def test_no_corral_when_everything_is_reachable():
    s = board("#######", "#     #", "# $@. #", "#     #", "#######")
    assert pi_corral_pushes(s) is None


def test_corral_pruning_agrees_with_exhaustive_search():
    """Random play on small generated levels: solver verdicts are the truth."""
    rng = random.Random(7)
    verdicts = {True: 0, False: 0}
    for _ in range(60):
        level = generate_level(rng.choice([1, 2, 3, 3]), seed=rng.randrange(10**6))
        s = SokobanState.from_level(level)
        for _ in range(rng.randrange(60)):
            s = s.apply(rng.choice(s.legal_moves()))
        if s.is_solved():
            continue
        truth = exhaustive_solvable(s)
        result = solve(s, time_limit=None)
        assert result.solved == truth, s.to_text()
        assert result.reason == ("solved" if truth else "unsolvable")
        if truth:
            check_solution(s, result)
        verdicts[truth] += 1
    assert verdicts[True] > 5 and verdicts[False] > 5


# -- the solver ----------------------------------------------------------------------


@pytest.mark.parametrize("name", ["unfiltered-valid-000.txt", "medium-valid-000.txt"])
def test_solves_real_boxoban_levels(name):
    for state in levels(name, 20):
        result = solve(state, time_limit=30.0)
        check_solution(state, result)
        assert result.nodes >= 1 and result.ms > 0


@pytest.mark.parametrize("difficulty", [1, 2, 3, 4, 5])
def test_solves_generated_levels(difficulty):
    for seed in range(4):
        level = generate_level(difficulty, seed=seed)
        state = SokobanState.from_level(level)
        check_solution(state, solve(state, time_limit=30.0))


def test_solve_accepts_a_level_object():
    level = read_levels(BOXOBAN_DIR / "unfiltered-valid-000.txt")[3]
    result = solve(level)
    check_solution(SokobanState.from_level(level), result)


def test_already_solved_state():
    result = solve(board("####", "#@*#", "####"))
    assert result.solved and result.moves == () and result.pushes == 0


def test_player_walled_off_from_the_box_is_unsolvable_quickly():
    s = board("#########", "#@#  $ .#", "#########")
    result = solve(s)
    assert (result.solved, result.reason) == (False, "unsolvable")
    assert result.nodes <= 1 and result.moves == ()


@pytest.mark.parametrize("text", UNSOLVABLE_AFTER_SEARCH)
def test_unsolvable_after_search(text):
    s = SokobanState.from_text(text)
    assert not exhaustive_solvable(s)
    result = solve(s, time_limit=None)
    assert (result.solved, result.reason) == (False, "unsolvable")
    assert 1 <= result.nodes < 1000


def test_node_budget():
    hard = SokobanState.from_level(read_levels(BOXOBAN_DIR / "medium-valid-000.txt")[0])
    result = solve(hard, max_nodes=3)
    assert (result.solved, result.reason) == (False, "budget")
    assert result.nodes == 3


def test_time_budget():
    # A level that needs thousands of expansions, with a microscopic time limit.
    hard = SokobanState.from_level(read_levels(BOXOBAN_DIR / "unfiltered-valid-000.txt")[859])
    result = solve(hard, time_limit=1e-6)
    assert (result.solved, result.reason) == (False, "budget")


def test_bad_budgets_are_rejected():
    s = board("####", "#@$.", "####")
    with pytest.raises(ValueError, match="time_limit"):
        solve(s, time_limit=0)
    with pytest.raises(ValueError, match="max_nodes"):
        solve(s, max_nodes=0)


# -- SokobanSolverPlanner --------------------------------------------------------------


def test_solver_planner_follows_and_caches_its_plan():
    state = levels("unfiltered-valid-000.txt", 5)[1]
    planner = SokobanSolverPlanner(time_limit=10.0)
    assert isinstance(planner, Planner) and planner.name == "sokoban-solver"
    first = planner.plan(state)
    assert isinstance(first, Subgoal)
    assert first.state == state.apply(first.action)
    assert replay(state, (first.action, *first.plan)).is_solved()
    assert first.info["cached"] is False and first.info["nodes"] >= 1
    assert first.info["pushes"] >= 1 and first.info["ms"] > 0

    s, step, steps = state, first, 0
    while True:
        assert step.state == s.apply(step.action)
        s = step.state
        steps += 1
        if s.is_solved():
            break
        step = planner.plan(s)
        assert step.info["cached"] is True and step.info["nodes"] == 0
    assert steps == 1 + len(first.plan)
    with pytest.raises(ValueError, match="already solved"):
        planner.plan(s)


def test_solver_planner_replans_off_its_plan():
    state = board("#########", "#       #", "# $   . #", "#   @   #", "#########")
    planner = SokobanSolverPlanner()
    step = planner.plan(state)
    detour = next(m for m in state.legal_moves() if m != step.action and not state.is_push(m))
    off = state.apply(detour)
    again = planner.plan(off)
    assert again.info["cached"] is False
    assert replay(off, (again.action, *again.plan)).is_solved()
    planner.reset()
    assert planner.plan(off).info["cached"] is False


def test_solver_planner_next_push():
    state = levels("medium-valid-000.txt", 5)[2]
    planner = SokobanSolverPlanner()
    s, pushes = state, 0
    while not s.is_solved():
        sub = planner.next_push(s)
        moves = sub.action
        assert isinstance(moves, tuple) and moves
        before_push = replay(s, moves[:-1])
        assert all(
            not t for t in [replay(s, moves[:k]).is_push(moves[k]) for k in range(len(moves) - 1)]
        )
        assert before_push.is_push(moves[-1])
        assert sub.state == before_push.apply(moves[-1])
        assert replay(sub.state, sub.plan).is_solved()
        s = sub.state
        pushes += 1
    assert pushes >= 1


def test_solver_planner_errors():
    planner = SokobanSolverPlanner()
    unsolvable = board("#########", "#@#  $ .#", "#########")
    with pytest.raises(NoPlanError, match="unsolvable") as caught:
        planner.plan(unsolvable)
    assert caught.value.reason == "unsolvable"
    with pytest.raises(NoPlanError) as caught:
        planner.next_push(unsolvable)
    assert caught.value.reason == "unsolvable"

    hard = SokobanState.from_level(read_levels(BOXOBAN_DIR / "medium-valid-000.txt")[0])
    with pytest.raises(NoPlanError, match="budget") as caught:
        SokobanSolverPlanner(max_nodes=2).plan(hard)
    assert caught.value.reason == "budget"

    with pytest.raises(ValueError, match="already solved"):
        planner.plan(board("####", "#@*#", "####"))
    with pytest.raises(ValueError, match="already solved"):
        planner.next_push(board("####", "#@*#", "####"))
    with pytest.raises(ValueError, match="time_limit"):
        SokobanSolverPlanner(time_limit=-1)


# -- RandomPlanner ---------------------------------------------------------------------


def test_random_planner_moves_are_legal():
    state = levels("unfiltered-valid-000.txt", 5)[0]
    planner = RandomPlanner(seed=0)
    assert isinstance(planner, Planner) and planner.name == "random"
    s = state
    for _ in range(200):
        if s.is_solved():
            break
        step = planner.plan(s)
        assert step.action in s.legal_moves()
        assert step.state == s.apply(step.action)
        assert step.info["legal_moves"] == len(s.legal_moves())
        s = step.state


def run_random(planner: RandomPlanner, state: SokobanState, n: int = 60) -> list[str]:
    moves = []
    for _ in range(n):
        step = planner.plan(state)
        moves.append(step.action)
        state = step.state
    return moves


def test_random_planner_is_reproducible_by_seed():
    state = board("########", "#      #", "#  $   #", "#   @  #", "#  .   #", "########")
    a = run_random(RandomPlanner(seed=3), state)
    assert a == run_random(RandomPlanner(seed=3), state)
    assert a != run_random(RandomPlanner(seed=4), state)
    planner = RandomPlanner(seed=11)
    first = run_random(planner, state)
    planner.reset(seed=11)
    assert run_random(planner, state) == first
    # All four directions turn up: the choice is not stuck on one move.
    assert set(a) == {"U", "D", "L", "R"}


def test_random_planner_errors():
    stuck = board("#####", "#@$$#", "#####", "#..##", "#####")
    assert stuck.legal_moves() == []
    with pytest.raises(ValueError, match="no legal move"):
        RandomPlanner(seed=0).plan(stuck)
    with pytest.raises(ValueError, match="already solved"):
        RandomPlanner(seed=0).plan(board("####", "#@*#", "####"))
