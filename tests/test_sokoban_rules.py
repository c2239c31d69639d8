"""SokobanState: the push rules, parsing, and value semantics."""

from __future__ import annotations

import copy
import pickle

import pytest

from abstract_planners.sokoban import MOVES, SokobanState, replay
from envs.mujoban.levels import BOXOBAN_DIR, Level, read_levels


def board(*rows: str) -> SokobanState:
    return SokobanState.from_text("\n".join(rows))


# -- moves and pushes ---------------------------------------------------------------


def test_walking_moves_the_player_only():
    s = board("#####", "# @ #", "#$ .#", "#####")
    t = s.apply("L")
    assert t.player == (1, 1)
    assert t.boxes == s.boxes
    assert s.player == (1, 2)  # the original is unchanged


def test_player_cannot_walk_into_walls():
    s = board("###", "#@#", "#$#", "#.#", "# #", "###")
    for move in "ULR":
        assert not s.is_legal(move)
        with pytest.raises(ValueError, match=f"illegal move '{move}'.*wall"):
            s.apply(move)
    assert s.legal_moves() == ["D"]


def test_push_moves_exactly_one_box_one_cell():
    s = board("######", "#@$ .#", "######")
    t = s.apply("R")
    assert t.player == (1, 2)
    assert t.boxes == frozenset({(1, 3)})
    assert s.is_push("R")
    assert not t.is_push("L")  # walking back is a plain move
    assert t.apply("R").is_solved()


def test_no_pulls():
    s = board("######", "# $@.#", "######")
    t = s.apply("R")  # step away from the box
    assert t.boxes == s.boxes
    assert t.player == (1, 4)


def test_box_cannot_be_pushed_into_a_wall():
    s = board("#####", "#@$#.", "#####")
    assert not s.is_legal("R")
    with pytest.raises(ValueError, match=r"'R'.*box at \(1, 2\).*\(1, 3\), a wall"):
        s.apply("R")


def test_no_double_box_pushes():
    s = board("#######", "#@$$ .#", "#    .#", "#######")
    assert not s.is_legal("R")
    assert "R" not in s.legal_moves()
    with pytest.raises(ValueError, match=r"blocked by the box at \(1, 3\)"):
        s.apply("R")


def test_the_grid_edge_blocks_like_a_wall():
    s = SokobanState(walls=(), targets={(0, 2)}, boxes={(0, 1)}, player=(0, 0), height=1, width=3)
    assert s.legal_moves() == ["R"]
    assert s.apply("R").is_solved()
    edge = SokobanState(
        walls=(), targets={(0, 0)}, boxes={(0, 2)}, player=(0, 1), height=1, width=3
    )
    assert not edge.is_legal("R")  # would push the box off the grid
    assert edge.legal_moves() == ["L"]


def test_unknown_move_letter_is_an_error():
    s = board("####", "#@$.", "####")
    with pytest.raises(ValueError, match="unknown move 'X'"):
        s.apply("X")
    with pytest.raises(ValueError, match="unknown move"):
        s.is_legal("up")


def test_legal_moves_are_in_udlr_order():
    s = board("#####", "#   #", "# @ #", "#$. #", "#####")
    assert s.legal_moves() == list(MOVES)


def test_replay_and_its_errors():
    s = board("#######", "#@ $ .#", "#######")
    assert replay(s, "RRR").is_solved()
    assert replay(s, ["R", "R", "R"]).is_solved()
    assert replay(s, "") == s
    with pytest.raises(ValueError, match="move 1: illegal move 'U'"):
        replay(s, "RUR")


def test_solved_only_with_every_box_on_a_target():
    s = board("#######", "#@$*  #", "#   . #", "#######")
    assert not s.is_solved()
    assert board("####", "#@*#", "####").is_solved()


# -- construction and parsing -----------------------------------------------------------


def test_text_roundtrip_and_characters():
    text = "\n".join(["#######", "#+ $  #", "# *.$ #", "#######"])
    s = SokobanState.from_text(text)
    assert s.player == (1, 1)
    assert s.targets == frozenset({(1, 1), (2, 2), (2, 3)})
    assert s.boxes == frozenset({(1, 3), (2, 2), (2, 4)})
    assert s.to_text() == text
    assert SokobanState.from_text(s.to_text()) == s
    assert SokobanState.from_text("#-_@$.#") == SokobanState.from_text("#  @$.#")


@pytest.mark.parametrize(
    "text, message",
    [
        ("#@$.x#", "unknown character 'x'"),
        ("#$.#", "exactly one player"),
        ("#@@$..#", "exactly one player"),
        ("#@$$.#", "2 boxes but 1 targets"),
        ("", "empty board"),
    ],
)
def test_bad_text_is_rejected(text, message):
    with pytest.raises(ValueError, match=message):
        SokobanState.from_text(text)


def test_bad_boards_are_rejected():
    with pytest.raises(ValueError, match="player at .* is on a wall"):
        SokobanState({(0, 0)}, {(0, 2)}, {(0, 1)}, (0, 0), 1, 3)
    with pytest.raises(ValueError, match="player at .* is on a box"):
        SokobanState((), {(0, 2)}, {(0, 1)}, (0, 1), 1, 3)
    with pytest.raises(ValueError, match="outside the 1x3 grid"):
        SokobanState((), {(0, 3)}, {(0, 1)}, (0, 0), 1, 3)


def test_from_level_matches_the_boxoban_level():
    level = read_levels(BOXOBAN_DIR / "unfiltered-valid-000.txt")[0]
    s = SokobanState.from_level(level)
    assert (s.walls, s.targets, s.boxes, s.player) == (
        level.walls,
        level.targets,
        level.boxes,
        level.player,
    )
    assert (s.height, s.width) == (level.height, level.width)
    assert s == SokobanState.from_text(level.to_text())
    assert Level.from_text(s.to_text()) == level
    with pytest.raises(TypeError, match="walls, targets, boxes"):
        SokobanState.from_level("not a level")


def test_moves_agree_with_a_generator_solution():
    from envs.mujoban.generator import generate_level

    level, solution = generate_level(4, seed=3, return_solution=True)
    assert replay(SokobanState.from_level(level), solution).is_solved()


# -- value semantics --------------------------------------------------------------------


def test_equal_by_content_and_hashable():
    a = board("#####", "#@$.#", "#####")
    b = SokobanState(
        walls=set(a.walls),
        targets=list(a.targets),
        boxes=tuple(a.boxes),
        player=[1, 1],
        height=3,
        width=5,
    )
    assert a == b and hash(a) == hash(b)
    assert len({a, b}) == 1
    # Reaching the same board by different paths gives equal states.
    s = board("######", "#    #", "#@$. #", "######")
    assert replay(s, "UD") == s and hash(replay(s, "UD")) == hash(s)
    assert replay(s, "URRDL") == replay(s, "URRDLUD")


def test_states_differing_in_anything_are_unequal():
    a = board("######", "#@$ .#", "######")
    assert a != a.apply("R")  # player and box
    assert a != a.with_player((1, 3))  # player only
    assert a != board("######", "#@$. #", "######")  # targets
    assert a != board("######", "#@$#.#", "######")  # walls
    assert a != "not a state"


def test_states_are_immutable():
    s = board("####", "#@$.", "####")
    with pytest.raises(AttributeError, match="immutable"):
        s.player = (1, 2)
    with pytest.raises(AttributeError):
        s.boxes.add((1, 1))
    assert copy.deepcopy(s) is s
    t = pickle.loads(pickle.dumps(s))
    assert t == s and hash(t) == hash(s)


def test_successors_share_walls_and_targets():
    s = board("######", "#@$ .#", "######")
    t = s.apply("R")
    assert t.walls is s.walls and t.targets is s.targets
