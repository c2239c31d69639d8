"""Board-game planners: random moves, epsilon-greedy wrapper, tic-tac-toe minimax."""

from __future__ import annotations

import math

import numpy as np
import pyspiel
import pytest

from abstract_planners.base import Planner, Subgoal
from abstract_planners.board_random import RandomMovePlanner
from abstract_planners.epsilon_greedy import EpsilonGreedy
from abstract_planners.tictactoe import MinimaxPlanner, action_values, minimax_value

TTT = pyspiel.load_game("tic_tac_toe")


def play(game, planners, seed):
    """Plays one game; planners[p] moves for player p. Returns the final state."""
    for index, planner in enumerate(planners):
        planner.reset(seed * 7 + index)
    state = game.new_initial_state()
    while not state.is_terminal():
        before = state.history()
        subgoal = planners[state.current_player()].plan(state)
        assert state.history() == before, "a planner mutated its input state"
        assert subgoal.action in state.legal_actions()
        assert subgoal.state.history() == before + [subgoal.action]
        state = subgoal.state
    return state


def ttt_state(moves):
    state = TTT.new_initial_state()
    for move in moves:
        state.apply_action(move)
    return state


# -- random ------------------------------------------------------------------------


def test_random_planner_plays_legal_seeded_moves_of_any_game():
    planner = RandomMovePlanner(seed=3)
    assert planner.name == "random"
    go = pyspiel.load_game("go", {"board_size": 5, "komi": 5.5})
    for game in (TTT, go):
        state = play(game, [planner, planner], seed=1)
        assert state.is_terminal()
    first = [RandomMovePlanner(seed=5).plan(TTT.new_initial_state()).action for _ in range(3)]
    assert len(set(first)) == 1
    planner.reset(5)
    assert planner.plan(TTT.new_initial_state()).action == first[0]
    seen = {planner.plan(TTT.new_initial_state()).action for _ in range(200)}
    assert seen == set(range(9))


def test_planners_reject_terminal_states():
    finished = ttt_state([0, 3, 1, 4, 2])  # x wins on the top row
    assert finished.is_terminal()
    for planner in (RandomMovePlanner(), MinimaxPlanner(), EpsilonGreedy(MinimaxPlanner(), 0.5)):
        with pytest.raises(ValueError, match="terminal"):
            planner.plan(finished)


# -- minimax -----------------------------------------------------------------------


def test_minimax_values():
    assert minimax_value(TTT.new_initial_state()) == 0
    # x: 0, 1; o: 3, 4; x to move wins by playing 2.
    state = ttt_state([0, 3, 1, 4])
    subgoal = MinimaxPlanner(seed=0).plan(state)
    assert subgoal.action == 2 and subgoal.info["value"] == 1
    assert subgoal.state.is_terminal() and subgoal.state.returns()[0] == 1
    # o to move must block x's top row (x: 0, 1; o: 4); every other move loses.
    values = action_values(ttt_state([0, 4, 1]))
    assert values[2] == 0 and all(v == -1 for a, v in values.items() if a != 2)
    assert MinimaxPlanner().plan(ttt_state([0, 4, 1])).action == 2


def test_minimax_breaks_ties_uniformly_and_seeded():
    empty = TTT.new_initial_state()
    subgoal = MinimaxPlanner(seed=0).plan(empty)
    assert subgoal.info["value"] == 0 and subgoal.info["optimal_actions"] == tuple(range(9))
    firsts = {MinimaxPlanner(seed=s).plan(empty).action for s in range(40)}
    assert len(firsts) > 3
    planner = MinimaxPlanner(seed=11)
    a = [planner.plan(empty).action]
    for seed in range(12, 16):
        planner.reset(seed)  # a new episode draws again
        a.append(planner.plan(empty).action)
    assert len(set(a)) > 1
    planner.reset(11)
    assert planner.plan(empty).action == a[0]


def test_minimax_asked_twice_in_one_episode_repeats_its_choice():
    empty = TTT.new_initial_state()
    planner = MinimaxPlanner(seed=3)
    first = planner.plan(empty).action
    assert all(planner.plan(empty).action == first for _ in range(20))
    later = ttt_state([first, 4 if first != 4 else 0])
    assert planner.plan(later).action == planner.plan(later).action


@pytest.mark.parametrize("minimax_player", [0, 1])
def test_minimax_never_loses_against_random_play(minimax_player):
    results = []
    for seed in range(150):
        planners = [RandomMovePlanner(), RandomMovePlanner()]
        planners[minimax_player] = MinimaxPlanner()
        state = play(TTT, planners, seed)
        results.append(state.returns()[minimax_player])
    assert min(results) >= 0
    assert results.count(1) > 50  # and it punishes random play


def test_minimax_against_itself_always_draws():
    for seed in range(30):
        state = play(TTT, [MinimaxPlanner(), MinimaxPlanner()], seed)
        assert state.returns() == [0.0, 0.0]


def test_minimax_rejects_other_games():
    go = pyspiel.load_game("go", {"board_size": 5, "komi": 5.5}).new_initial_state()
    with pytest.raises(ValueError, match="tic_tac_toe"):
        MinimaxPlanner().plan(go)
    with pytest.raises(ValueError, match="OpenSpiel"):
        MinimaxPlanner().plan("x..\n...\n...")


# -- epsilon-greedy ----------------------------------------------------------------


class Recorder(Planner):
    """A stub planner: records calls, optionally refuses to plan."""

    name = "stub"

    def __init__(self, refuse=False):
        self.refuse, self.seeds, self.closed, self.calls = refuse, [], 0, 0

    def reset(self, seed=None):
        self.seeds.append(seed)

    def plan(self, state):
        self.calls += 1
        if self.refuse:
            raise AssertionError("the inner planner must not be asked")
        action = state.legal_actions()[0]
        return Subgoal(action, state.child(action), info={"inner": True})

    def close(self):
        self.closed += 1


def test_epsilon_zero_is_the_inner_planner():
    for seed in range(20):
        greedy = EpsilonGreedy(MinimaxPlanner(seed=seed), 0.0, seed=99)
        plain = MinimaxPlanner(seed=seed)
        state = TTT.new_initial_state()
        while not state.is_terminal():
            subgoal = greedy.plan(state)
            assert subgoal.action == plain.plan(state).action
            assert subgoal.info["random"] is False and "value" in subgoal.info
            state = subgoal.state
        assert state.returns() == [0.0, 0.0]


def test_epsilon_one_is_random_play():
    planner = EpsilonGreedy(Recorder(refuse=True), 1, seed=0)
    assert planner.name == "stub-eps1"
    seen = set()
    for _ in range(300):
        subgoal = planner.plan(TTT.new_initial_state())
        assert subgoal.info == {"random": True}
        seen.add(subgoal.action)
    assert seen == set(range(9))


def test_epsilon_mixes_reseeds_and_closes():
    inner = Recorder()
    planner = EpsilonGreedy(inner, 0.3, seed=1)
    assert planner.name == "stub-eps0.3"
    flags = [planner.plan(TTT.new_initial_state()).info["random"] for _ in range(400)]
    assert 0.2 < np.mean(flags) < 0.4
    planner.reset(7)
    again = [planner.plan(TTT.new_initial_state()).info["random"] for _ in range(50)]
    planner.reset(7)
    assert [planner.plan(TTT.new_initial_state()).info["random"] for _ in range(50)] == again
    assert len(inner.seeds) == 2 and inner.seeds[0] == inner.seeds[1] is not None
    assert inner.seeds[0] != 7
    planner.reset()
    assert inner.seeds[-1] is None
    with planner:
        pass
    assert inner.closed == 1


@pytest.mark.parametrize("epsilon", [-0.1, 1.5, math.nan, math.inf, "0.5", None, True])
def test_bad_epsilon_raises(epsilon):
    with pytest.raises(ValueError, match=r"epsilon.*\[0, 1\]"):
        EpsilonGreedy(MinimaxPlanner(), epsilon)
