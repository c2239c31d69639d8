"""Go planners (GNU Go over GTP, OpenSpiel MCTS) and the action <-> vertex conventions."""

from __future__ import annotations

import os
import signal

import pyspiel
import pytest

from abstract_planners import gtp
from abstract_planners.board_random import RandomMovePlanner
from abstract_planners.go import (
    GnuGoPlanner,
    MCTSPlanner,
    action_to_vertex,
    go_game,
    pass_action,
    vertex_to_action,
)
from abstract_planners.gtp import GnuGoNotFoundError

needs_gnugo = pytest.mark.usefixtures("gnugo")  # conftest decides whether GNU Go is there


def state_after(game, vertices):
    state = game.new_initial_state()
    n = game.get_parameters()["board_size"]
    for vertex in vertices:
        state.apply_action(vertex_to_action(vertex, n))
    return state


def play(game, planners, seed=0, check=None):
    for index, planner in enumerate(planners):
        planner.reset(seed + index)
    state = game.new_initial_state()
    while not state.is_terminal():
        before = state.history()
        subgoal = planners[state.current_player()].plan(state)
        assert state.history() == before, "a planner mutated its input state"
        assert subgoal.action in state.legal_actions()
        assert subgoal.state.history() == before + [subgoal.action]
        if check:
            check(state, subgoal)
        state = subgoal.state
    return state


# -- coordinates -------------------------------------------------------------------


def printed_stone(state):
    """(column letter, row number) of the single stone in OpenSpiel's board printout."""
    for line in str(state).splitlines():
        words = line.split()
        if len(words) == 2 and words[0].isdigit() and "X" in words[1]:
            letters = str(state).splitlines()[-1].split()[0]
            return letters[words[1].index("X")], int(words[0])
    raise AssertionError(f"no stone in\n{state}")


@pytest.mark.parametrize("n", [5, 7, 9, 19])
def test_coordinates_round_trip_and_match_the_openspiel_printout(n):
    game = go_game(n)
    assert pass_action(n) == n * n == game.num_distinct_actions() - 1
    assert action_to_vertex(0, n) == "A1"  # action 0 is the bottom-left corner
    assert action_to_vertex(n, n) == "A2"
    assert action_to_vertex(n * n, n) == "pass"
    vertices = set()
    for action in range(n * n + 1):
        vertex = action_to_vertex(action, n)
        vertices.add(vertex)
        assert "I" not in vertex
        assert vertex_to_action(vertex, n) == action
        assert vertex_to_action(vertex.lower(), n) == action
        text = game.new_initial_state().action_to_string(0, action)
        assert text.split()[1].upper() == vertex.upper()
        if action < n * n and (n <= 9 or action % 7 == 0 or action in (n - 1, n * n - n)):
            state = game.new_initial_state()
            state.apply_action(action)
            letter, row = printed_stone(state)
            assert f"{letter}{row}" == vertex
    assert len(vertices) == n * n + 1


def test_bad_coordinates():
    for vertex in ("I1", "resign", "Z9", "A0", "A20", "", "11", "A"):
        with pytest.raises(ValueError, match="vertex"):
            vertex_to_action(vertex, 19)
    assert vertex_to_action("J1", 19) == 8
    with pytest.raises(ValueError, match="not a GTP vertex"):
        vertex_to_action("F1", 5)
    with pytest.raises(ValueError, match=r"action .*0\.\.25"):
        action_to_vertex(26, 5)


@pytest.mark.parametrize("size", [4, 20, 7.0, "7", True])
def test_go_game_validates_board_size(size):
    with pytest.raises(ValueError, match=r"board_size.*5\.\.19"):
        go_game(size)


def test_go_game():
    game = go_game(9, 7.5)
    assert game.get_parameters()["board_size"] == 9 and game.get_parameters()["komi"] == 7.5
    with pytest.raises(ValueError, match="komi"):
        go_game(7, float("nan"))


# -- MCTS --------------------------------------------------------------------------


def test_mcts_beats_random_play_on_5x5():
    game = go_game(5, 5.5)
    wins = 0
    for seed in range(4):
        mcts_player = seed % 2
        planners = [RandomMovePlanner(), RandomMovePlanner()]
        planners[mcts_player] = MCTSPlanner(150, seed=seed)
        state = play(game, planners, seed=seed)
        wins += state.returns()[mcts_player] > 0
    assert wins >= 3


def test_mcts_is_seeded_and_reports_its_search():
    state = state_after(go_game(5), ["C3", "B2"])
    a = [MCTSPlanner(60, seed=4).plan(state) for _ in range(2)]
    assert a[0].action == a[1].action
    assert a[0].info["simulations"] == 60 and 1 <= a[0].info["visits"] <= 60
    assert -1 <= a[0].info["value"] <= 1
    planner = MCTSPlanner(60, seed=9)
    first = [planner.plan(state).action for _ in range(3)]
    planner.reset(9)
    assert [planner.plan(state).action for _ in range(3)] == first


def test_mcts_plays_other_games_and_solves_tic_tac_toe():
    ttt = pyspiel.load_game("tic_tac_toe")
    state = ttt.new_initial_state()
    for move in (0, 3, 1, 4):
        state.apply_action(move)
    subgoal = MCTSPlanner(200, seed=0, solve=True).plan(state)
    assert subgoal.action == 2


@pytest.mark.parametrize(
    "kwargs, name",
    [
        (dict(simulations=0), "simulations"),
        (dict(simulations=2.5), "simulations"),
        (dict(rollouts=0), "rollouts"),
        (dict(uct_c=0), "uct_c"),
        (dict(uct_c=float("inf")), "uct_c"),
        (dict(seed=-1), "seed"),
    ],
)
def test_mcts_validates_arguments(kwargs, name):
    with pytest.raises(ValueError, match=name):
        MCTSPlanner(**kwargs)


def test_mcts_rejects_terminal_states():
    state = state_after(go_game(5), ["pass", "pass"])
    assert state.is_terminal()
    with pytest.raises(ValueError, match="terminal"):
        MCTSPlanner(10).plan(state)


# -- GNU Go ------------------------------------------------------------------------


@pytest.mark.parametrize("level", [0, 11, 5.5, None])
def test_gnugo_level_is_validated(level):
    with pytest.raises(ValueError, match=r"level.*1\.\.10"):
        GnuGoPlanner(level)


def test_gnugo_missing_executable():
    with pytest.raises(GnuGoNotFoundError, match="sudo apt-get install gnugo"):
        GnuGoPlanner(command=["/nonexistent/gnugo", "--mode", "gtp"])


@needs_gnugo
def test_gnugo_plays_legal_moves_against_random_and_wins():
    game = go_game(5, 5.5)
    with GnuGoPlanner(5, board_size=5, seed=1) as gnugo:
        assert gnugo.name == "gnugo"
        for seed, gnugo_player in ((0, 0), (1, 1)):
            planners = [RandomMovePlanner(), RandomMovePlanner()]
            planners[gnugo_player] = gnugo
            state = play(game, planners, seed=seed)
            assert state.returns()[gnugo_player] == 1
        assert gnugo.client.starts == 1


@needs_gnugo
def test_gnugo_reset_starts_a_fresh_engine_so_a_game_does_not_depend_on_those_before():
    """GNU Go keeps what it read across ``clear_board``: a MuJoGo episode
    played after another lost where played alone it won. `reset` stops the
    engine, and the next plan starts a fresh one with the seed."""
    game = go_game(5, 5.5)
    with GnuGoPlanner(5, board_size=5, seed=1) as gnugo:
        state = game.new_initial_state()
        gnugo.plan(state)
        first = gnugo.client.pid
        gnugo.reset(seed=7)
        assert gnugo._client is None
        subgoal = gnugo.plan(state)
        assert gnugo.client.pid != first and gnugo._seed == 7
        assert subgoal.action in state.legal_actions()


@needs_gnugo
def test_gnugo_self_play_ends_with_two_passes():
    game = go_game(5, 5.5)
    with GnuGoPlanner(3, board_size=5) as gnugo:
        state = play(game, [gnugo, gnugo])
    history = state.history()
    assert history[-2:] == [25, 25]
    assert len(history) < game.max_game_length()


@needs_gnugo
def test_gnugo_passes_when_pass_is_the_only_legal_move():
    game = go_game(5, 5.5)
    eyes = {"A1", "C3", "E5", "A5", "E1"}
    blacks = [f"{c}{r}" for r in range(1, 6) for c in "ABCDE" if f"{c}{r}" not in eyes]
    moves = []
    for vertex in blacks:
        moves += [vertex, "pass"]
    state = state_after(game, moves[:-1])  # White to move, every empty point is suicide
    assert state.current_player() == 1 and state.legal_actions() == [25]
    with GnuGoPlanner(board_size=5) as gnugo:
        subgoal = gnugo.plan(state)
    assert subgoal.action == 25 and subgoal.info["vertex"] == "pass"
    assert subgoal.state.history() == state.history() + [25]


@needs_gnugo
def test_default_gnugo_plays_the_original_rules():
    # The original MuJoGo ran GNU Go with area scoring and dead-stone capture.
    assert gtp.default_gnugo_command()[1:] == [
        "--mode",
        "gtp",
        "--chinese-rules",
        "--capture-all-dead",
    ]


@needs_gnugo
def test_gnugo_with_territory_scoring_passes_at_a_settled_position():
    # Black owns columns A-C, White D-E: nothing left to play. (Under area
    # scoring, the default, GNU Go may also fill its own area at no cost.)
    walls = []
    for row in range(1, 6):
        walls += [f"C{row}", f"D{row}"]
    state = state_after(go_game(5, 5.5), walls)
    territory = [gtp.find_gnugo(), "--mode", "gtp"]
    with GnuGoPlanner(board_size=5, cleanup=False, command=territory) as gnugo:
        assert gnugo.plan(state).action == 25
        after_pass = state.child(25)
        assert gnugo.plan(after_pass).action == 25  # and White passes back


@needs_gnugo
def test_gnugo_resyncs_to_any_history_and_survives_a_kill():
    game = go_game(7, 5.5)
    with GnuGoPlanner(1, seed=2) as gnugo:
        first = state_after(game, ["D4", "C3", "pass"])
        gnugo.plan(first)
        assert gnugo.client.list_stones("b") == ["D4"]
        # a different game: the engine is cleared and replayed
        other = state_after(game, ["B2", "F6", "C5"])
        subgoal = gnugo.plan(other)
        assert gnugo.client.list_stones("b") == ["B2", "C5"]
        assert gnugo.client.list_stones("w") == sorted(["F6", subgoal.info["vertex"]])
        # the continuation of the same game: only the new moves are played
        follow = subgoal.state.child(vertex_to_action("E4", 7))
        pid = gnugo.client.pid
        os.kill(pid, signal.SIGKILL)
        subgoal = gnugo.plan(follow)
        assert gnugo.client.pid != pid
        assert subgoal.action in follow.legal_actions()
        assert gnugo.client.list_stones("b") == ["B2", "C5", "E4"]


@needs_gnugo
def test_gnugo_rejects_states_it_cannot_play():
    with GnuGoPlanner(board_size=7, komi=5.5) as gnugo:
        with pytest.raises(ValueError, match="board_size=7"):
            gnugo.plan(go_game(9, 5.5).new_initial_state())
        with pytest.raises(ValueError, match="komi"):
            gnugo.plan(go_game(7, 7.5).new_initial_state())
        with pytest.raises(ValueError, match="go"):
            gnugo.plan(pyspiel.load_game("tic_tac_toe").new_initial_state())
        with pytest.raises(ValueError, match="terminal"):
            gnugo.plan(state_after(go_game(7, 5.5), ["pass", "pass"]))
