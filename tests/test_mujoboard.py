"""MuJoBoard: OpenSpiel games beyond tic-tac-toe and Go, played by touch
(`envs.boards.games`, `envs.boards.mujoboard`), and the agent as either player."""

from __future__ import annotations

import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env

import envs
from fast_cover import cover, family_and_game
from abstract_planners.openspiel_bots import AlphaBetaPlanner, make_bot
from arm_driving import central_action, hold_action, touch_point
from envs.boards import arena as arena_lib
from envs.boards.games import GAMES, BoardGame, GameRules, register_game
from envs.boards.mujoboard import REGISTERED

NO_CAMERA = {"front_camera": None}
NAMES = [f"mujoboard/{name}" for name, _, _ in REGISTERED]
GAME_SIZES = [(game, size) for _, game, size in REGISTERED]


def test_at_least_six_games_are_registered_two_of_them_move_games():
    assert set(NAMES) <= set(envs.names())
    games = {game for game, _ in GAME_SIZES}
    assert len(games - {"tic_tac_toe", "go"}) >= 6
    assert len({g for g in games if GAMES[g].input == "move"}) >= 2


def _playouts(game: BoardGame, seed: int, games: int = 3, plies: int = 60):
    """States along random games (the states where a player must move)."""
    rng = np.random.default_rng(seed)
    spiel = game.load()
    for _ in range(games):
        state = spiel.new_initial_state()
        for _ in range(plies):
            if state.is_terminal():
                break
            yield state
            legal = state.legal_actions()
            state = state.child(int(legal[rng.integers(len(legal))]))


@pytest.mark.parametrize("game_name, size", GAME_SIZES + [("tic_tac_toe", 3), ("go", 7)])
def test_every_legal_action_is_played_by_its_touches_and_shown_for_its_mover(game_name, size):
    """The rules' touches for each legal action play exactly that action, and
    the mover's piece appears on the touched point (column: in the column)."""
    game = BoardGame(game_name, size)
    for state in _playouts(game, seed=1):
        if game.forced_pass(state) is not None:
            continue
        mover = state.current_player()
        for action in state.legal_actions():
            if action >= game.num_zones:
                continue
            zones = game.touches(state, action)
            selected = -1
            for zone in zones[:-1]:
                assert game.touch_effect(state, zone, selected) == ("select", zone)
                selected = zone
            assert game.touch_effect(state, zones[-1], selected) == ("move", action)
            if zones[-1] >= game.num_points:
                continue  # Go's pass
            players = game.players(state.child(action))
            if game.rules.input == "column":
                column = players.reshape(game.rows, game.cols)[:, action]
                before = game.players(state).reshape(game.rows, game.cols)[:, action]
                assert ((column == mover) & (before != mover)).sum() == 1
            else:
                assert players[zones[-1]] == mover


@pytest.mark.parametrize("game_name, size", GAME_SIZES)
def test_touches_that_play_nothing_are_exactly_the_illegal_ones(game_name, size):
    game = BoardGame(game_name, size)
    for state in list(_playouts(game, seed=2, games=2))[::5]:
        act, select = game.zone_effects(state)
        legal = set(state.legal_actions())
        if game.rules.input == "point":
            assert {int(a) for a in act if a >= 0} == {a for a in legal if a < game.num_zones}
            assert not select.any()
        elif game.rules.input == "column":
            assert set(act[act >= 0].tolist()) == legal
        else:  # only the mover's movable pieces do something before a selection
            assert (act < 0).all()
            players = game.players(state)
            assert (players[select[: game.num_points]] == state.current_player()).all()
            sources = {src for src, _ in game.move_points(state).values()}
            assert set(np.flatnonzero(select).tolist()) == sources


@pytest.mark.parametrize("game_name, size", GAME_SIZES + [("tic_tac_toe", 3), ("go", 7)])
def test_players_reads_each_point_from_its_owner_planes(game_name, size):
    game = BoardGame(game_name, size)
    for state in _playouts(game, seed=1, games=3, plies=60):
        tensor = np.asarray(state.observation_tensor(0)).reshape(-1, game.num_points)
        expected = np.full(game.num_points, -1)
        for player, planes in enumerate(game.rules.owner_planes):
            expected[(tensor[list(planes)] > 0.5).any(axis=0)] = player
        players = game.players(state)
        assert players.dtype == np.int8 and players.shape == (game.num_points,)
        np.testing.assert_array_equal(players, expected)


def test_a_checkers_king_is_shown_on_its_own_plane():
    game = BoardGame("checkers", 8)
    for state in _playouts(game, seed=0, games=40, plies=400):
        if game.kings(state).any():
            planes = game.board_planes(state, 0)
            assert planes.shape == (8, 8, 4)
            kings = planes[..., 3].ravel()
            assert (game.players(state)[kings] >= 0).all()
            return
    pytest.fail("no king in 40 random games")


def test_rules_and_sizes_are_checked():
    with pytest.raises(ValueError, match="unknown board game"):
        BoardGame("chess", 8)
    with pytest.raises(ValueError, match="6x7"):
        BoardGame("connect_four", 7)
    with pytest.raises(ValueError, match="board_size"):
        BoardGame("hex", 20)
    with pytest.raises(ValueError, match="input"):
        GameRules("hex", input="slide")
    with pytest.raises(ValueError, match="already registered"):
        register_game("hex", GAMES["hex"])
    with pytest.raises(ValueError, match="OpenSpiel has no game"):
        register_game("no_such", GameRules("no_such_game"))
    with pytest.raises(ValueError, match="agent_player"):
        envs.load("mujoboard/hex-7x7", agent_player=2)
    with pytest.raises(ValueError, match="unknown bot"):
        envs.load("mujoboard/hex-7x7", opponent="stockfish")


# -- played with the arm ------------------------------------------------------


def _env(name, **kwargs):
    env = envs.load(name, seed=0, **NO_CAMERA, **kwargs)
    env.reset()
    return env


def assert_board_matches_openspiel(env, timestep):
    task, game = env.task, env.task.game
    obs = timestep.observation
    np.testing.assert_array_equal(obs["board_state"], game.board_planes(task.state, task.agent))
    players = game.players(task.state)
    model = env.physics.model
    for point, player in enumerate(players):
        geom = task._piece_ids[point]
        shown = model.geom_group[geom] != arena_lib.HIDDEN_GROUP
        assert shown == (player >= 0), f"point {point}"
        if shown:
            np.testing.assert_allclose(model.geom_rgba[geom], task.arena.colours[player])
    played = list(task.state.history())
    history = obs["move_history"]
    assert list(history[: len(played)]) == played and (history[len(played) :] == -1).all()
    assert int(obs["agent_player"][0]) == task.agent


def _touch(env, point, **kwargs):
    return touch_point(env, env.task.point_position(point), **kwargs)


@pytest.mark.parametrize("name", cover(NAMES, family_and_game))
def test_each_game_plays_an_opening_by_touch_as_openspiel_does(name):
    """Two moves of the agent, touched with the arm (a move game's as piece
    then destination), each answered by the opponent: the record, the board
    observation and the pieces shown agree with OpenSpiel after each."""
    env = _env(name, opponent="random")
    task = env.task
    for turn in range(2):
        action = central_action(task)
        before = len(task.moves)
        zones = task.game.touches(task.state, action)
        if len(zones) == 2:
            _touch(env, zones[0], until=lambda zone=zones[0]: task._selected == zone)
        timestep = _touch(env, zones[-1])
        assert task.moves[before] == action, f"turn {turn}"
        assert_board_matches_openspiel(env, timestep)
        assert timestep.reward == (
            task.game.final_reward(task.state, task.agent) if task.state.is_terminal() else 0.0
        )
    env.close()


def test_connect_four_a_touch_anywhere_on_a_column_drops_a_piece_in_it():
    env = _env("mujoboard/connect_four", opponent="random")
    task = env.task
    timestep = _touch(env, 2 * 7 + 3)  # column 3, a middle row
    assert task.moves[0] == 3 and task.moves_registered == 1
    # It fell to OpenSpiel's bottom row, the row farthest from the arm.
    assert task.game.players(task.state)[0 * 7 + 3] == 0
    assert_board_matches_openspiel(env, timestep)
    env.close()


def test_othello_flips_are_shown_and_the_opponents_first_move_is_seen():
    env = envs.load("mujoboard/othello-8x8", seed=0, agent_player=1, opponent="random", **NO_CAMERA)
    timestep = env.reset()
    task = env.task
    assert task.agent == 1 and len(task.moves) == 1  # black moved first
    assert_board_matches_openspiel(env, timestep)
    assert timestep.observation["board_state"][..., 2].sum() == 4  # 3 + 1 flipped
    action = task.state.legal_actions()[0]
    timestep = _touch(env, action)
    assert task.moves[1] == action
    assert_board_matches_openspiel(env, timestep)
    env.close()


@pytest.mark.parametrize(
    "name", ["mujoboard/breakthrough-6x6", "mujoboard/checkers", "mujoboard/clobber-5x6"]
)
def test_a_move_game_plays_a_piece_then_its_destination(name):
    env = _env(name, opponent="random")
    task, game = env.task, env.task.game
    action = central_action(task)
    src, dst = game.touches(task.state, action)
    selected = lambda: task._selected == src  # noqa: E731
    timestep = _touch(env, src, until=selected)
    assert selected() and task.moves == ()
    assert int(timestep.observation["selected_point"][0]) == src
    assert env.physics.model.geom_group[task._selection_id] == 0  # the disc shows
    timestep = _touch(env, dst)
    assert task.moves[0] == action and task.moves_registered == 1
    assert int(timestep.observation["selected_point"][0]) == -1
    assert env.physics.model.geom_group[task._selection_id] == arena_lib.HIDDEN_GROUP
    assert_board_matches_openspiel(env, timestep)
    env.close()


def test_a_half_move_times_out_and_its_destination_then_does_nothing():
    env = _env("mujoboard/breakthrough-6x6", opponent="random", half_move_timeout=1.0)
    task, game = env.task, env.task.game
    action = central_action(task)
    src, dst = game.touches(task.state, action)
    _touch(env, src, until=lambda: task._selected == src)
    for _ in range(int(1.0 / 0.05) + 1):
        timestep = env.step(hold_action(env))
    assert task._selected == -1 and int(timestep.observation["selected_point"][0]) == -1
    _touch(env, dst, steps=60)
    assert task.moves == () and task.moves_registered == 0
    env.close()


def test_touching_an_opponents_piece_or_an_empty_point_changes_nothing():
    env = _env("mujoboard/breakthrough-6x6", opponent="random")
    task, game = env.task, env.task.game
    players = game.players(task.state)
    distance = np.abs(task.arena.point_xy - np.array(task.arena.centre)).max(axis=1)
    opponent_piece, empty = (
        int(min(np.flatnonzero(mask), key=lambda p: distance[p]))
        for mask in (players == 1, players < 0)
    )
    for point in (opponent_piece, empty):
        _touch(env, point, steps=60)
        assert task._selected == -1 and task.moves == ()
    env.close()


@pytest.mark.parametrize("name", ["mujoxo/optimal", "mujogo/7x7", "mujoboard/hex-7x7"])
def test_as_second_player_the_agent_first_sees_the_opponents_move(name):
    env = envs.load(name, seed=3, agent_player=1, **NO_CAMERA)
    timestep = env.reset()
    task = env.task
    assert len(task.moves) == 1 and task.state.current_player() == 1
    planes = timestep.observation["board_state"]
    assert planes[..., 2].sum() == 1 and planes[..., 1].sum() == 0  # the opponent's piece
    assert_board_matches_openspiel(env, timestep)
    env.close()


def test_agent_player_random_draws_both_sides_and_rewards_the_agents_result():
    env = envs.load("mujoxo/optimal", seed=0, agent_player="random", **NO_CAMERA)
    sides = {int(env.reset().observation["agent_player"][0]) for _ in range(8)}
    assert sides == {0, 1}
    env.close()
    # As noughts (player 1): set up a position where one touch wins.
    env = envs.load("mujoxo/random", seed=0, agent_player=1, **NO_CAMERA)
    env.reset()
    task = env.task
    moves, win = _a_win_in_one_for(task.state, player=1, points=range(6))
    task.play_moves(moves)
    timestep = _touch(env, win)
    assert task.state.is_terminal() and task.outcome == "win"
    assert timestep.reward == 1.0 and timestep.last()
    env.close()


def _a_win_in_one_for(state, player, points, depth=4):
    """(moves, winning action): moves from ``state`` after which ``player``
    is to move and wins with an action among ``points`` (depth-first, the
    first found; the test helper's IK reaches the rows far from the arm best)."""
    if not state.is_terminal() and state.current_player() == player:
        for a in set(state.legal_actions()) & set(points):
            child = state.child(a)
            if child.is_terminal() and child.returns()[player] > 0:
                return [], a
    if depth == 0 or state.is_terminal():
        return None, None
    for a in state.legal_actions():
        child = state.child(a)
        if child.is_terminal():
            continue
        moves, win = _a_win_in_one_for(child, player, points, depth - 1)
        if win is not None:
            return [a] + moves, win
    return None, None


@pytest.mark.parametrize("name", cover(NAMES, family_and_game))
def test_every_mujoboard_name_passes_gymnasium_check_env(name):
    import gymnasium

    env = gymnasium.make(name, front_camera=(32, 32), agent_player="random")
    check_env(env.unwrapped, skip_render_check=True)
    env.close()


# -- the opponents --------------------------------------------------------------


def test_alpha_beta_takes_a_win_and_blocks_a_loss():
    import pyspiel

    game = pyspiel.load_game("tic_tac_toe")
    state = game.new_initial_state()
    for a in (0, 3, 1):  # X threatens 2
        state.apply_action(a)
    assert AlphaBetaPlanner(9, seed=0).plan(state).action == 2  # O blocks
    state = game.new_initial_state()
    for a in (0, 3, 1, 4):
        state.apply_action(a)
    subgoal = AlphaBetaPlanner(2, seed=0).plan(state)
    assert subgoal.action == 2 and subgoal.info["value"] > 0.9


def test_alpha_beta_breaks_ties_by_its_seed():
    import pyspiel

    state = pyspiel.load_game("connect_four").new_initial_state()
    picks = {AlphaBetaPlanner(2, seed=s).plan(state).action for s in range(12)}
    assert len(picks) > 1
    assert (
        AlphaBetaPlanner(2, seed=5).plan(state).action
        == AlphaBetaPlanner(2, seed=5).plan(state).action
    )


@pytest.mark.parametrize(
    "spec, word",
    [
        ("mcts:x", "not an integer"),
        ("minimax", "unknown"),
        ("mcts:0", "simulations"),
        ("alphabeta:0", "depth"),
        (3, "string"),
    ],
)
def test_bad_bot_names_raise(spec, word):
    with pytest.raises(ValueError, match=word):
        make_bot(spec)


# -- the agent and the task's pass rule ------------------------------------------


class _AlwaysPass:
    def plan(self, state):
        from abstract_planners.base import Subgoal

        action = state.get_game().num_distinct_actions() - 1
        return Subgoal(action, state.child(action))


def test_the_agent_plays_a_stone_where_the_task_would_ignore_its_second_pass():
    import types

    import pyspiel

    from hier_agents.modular.families import adapter

    state = pyspiel.load_game("go", {"board_size": 5, "komi": 5.5}).new_initial_state()
    # Black (the agent) surrounds point 0 (an eye: 1 and 5 are black), passes;
    # White plays elsewhere; Black's planner wants to pass again.
    for action in (1, 24, 5, 23, 25, 22):
        state.apply_action(action)
    positions = tuple((c * 0.1, r * 0.1, 0.02) for r in range(5) for c in range(5))
    rules = dict(
        game="go",
        board_size=5,
        komi=5.5,
        pass_action=25,
        board_centre=(0.2, 0.2),
        point_positions=positions,
    )
    refused = types.SimpleNamespace(**rules, allow_double_pass=False)
    allowed = types.SimpleNamespace(**rules, allow_double_pass=True)
    go = adapter("mujogo/7x7")
    subgoal = go.next_subgoal(_AlwaysPass(), state, refused)
    assert subgoal.action == 12  # the centre, not the eye at 0 nor a pass
    assert subgoal.info["replaced_pass"]
    assert go.next_subgoal(_AlwaysPass(), state, allowed).action == 25
    state.apply_action(2)
    state.apply_action(21)  # the agent's last move is a stone: a pass is fine
    assert go.next_subgoal(_AlwaysPass(), state, refused).action == 25


def test_the_description_says_whether_a_second_pass_counts():
    env = envs.load("mujogo/7x7", **NO_CAMERA)
    assert env.description().allow_double_pass is False
    env.close()
    env = envs.load("mujogo/7x7", allow_double_pass=True, **NO_CAMERA)
    assert env.description().allow_double_pass is True
    env.close()


def test_mcts_keeps_its_move_for_a_position_until_reset():
    """A re-plan of the same position (after an option was cut off) returns
    the move the arm may already be pressing; a new episode searches again."""
    import pyspiel

    from abstract_planners.openspiel_bots import MCTSPlanner

    state = pyspiel.load_game("breakthrough", {"rows": 6, "columns": 6}).new_initial_state()
    planner = MCTSPlanner(8, seed=0)  # a small search: its picks vary with the seed stream
    first = planner.plan(state).action
    assert all(planner.plan(state.clone()).action == first for _ in range(20))
    picks = set()
    for _ in range(20):
        planner.reset()
        picks.add(planner.plan(state).action)
    assert len(picks) > 1
