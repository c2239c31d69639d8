"""The Level type and the Boxoban text format (envs.mujoban.levels)."""

from __future__ import annotations

import io
import pickle

import numpy as np
import pytest

from envs.mujoban.levels import (
    BOXOBAN_DIR,
    Level,
    LevelError,
    parse_levels,
    read_levels,
    write_levels,
)

BOXOBAN_FILES = ["unfiltered-valid-000.txt", "medium-valid-000.txt"]
VALID = "(valid: '#', ' ', '@', '$', '.', '*', '+')"


@pytest.fixture(scope="module")
def unfiltered() -> list[Level]:
    return read_levels(BOXOBAN_DIR / "unfiltered-valid-000.txt")


# -- the real Boxoban files --------------------------------------------------------


@pytest.mark.parametrize("filename", BOXOBAN_FILES)
def test_real_boxoban_files_hold_1000_10x10_levels_with_4_boxes(filename):
    levels = read_levels(BOXOBAN_DIR / filename)
    assert len(levels) == 1000
    assert [lvl.name for lvl in levels] == [str(i) for i in range(1000)]
    for lvl in levels:
        assert (lvl.height, lvl.width) == (10, 10)
        assert len(lvl.boxes) == 4 and len(lvl.targets) == 4
        assert lvl.player not in lvl.walls
        assert lvl.path == str(BOXOBAN_DIR / filename)


def test_entity_layers_of_the_first_unfiltered_level(unfiltered):
    # ; 0
    # ##########
    # #####  ..#
    # ##### $  #
    # ####    .#
    # ###  $   #
    # ###     .#
    # #     ####
    # # $ $ @###
    # ##       #
    # ##########
    layers = unfiltered[0].entity_layers()
    assert layers.shape == (10, 10, 4) and layers.dtype == bool
    wall, target, player, box = (layers[..., k] for k in range(4))
    assert player[7, 6] and player.sum() == 1
    assert box[2, 6] and box[7, 2] and box[7, 4] and box[4, 5] and box.sum() == 4
    assert target[1, 7] and target[1, 8] and target[3, 8] and target[5, 8]
    assert target.sum() == 4
    assert wall[0, 0] and wall[1, 4] and wall[7, 7] and not wall[1, 5]
    assert not layers[1, 5].any()  # plain floor
    assert (
        wall.sum()
        == len(unfiltered[0].walls)
        == 100
        - sum(
            row.count(" ") + row.count("$") + row.count(".") + row.count("@")
            for row in unfiltered[0].to_text().split("\n")
        )
    )


def test_grid_shows_the_level_characters(unfiltered):
    grid = unfiltered[0].grid()
    assert grid.shape == (10, 10)
    assert grid[7, 6] == "@" and grid[2, 6] == "$" and grid[1, 7] == "." and grid[0, 0] == "#"
    assert grid[1, 5] == " "


def test_write_then_read_round_trips_the_whole_real_file(unfiltered, tmp_path):
    path = tmp_path / "copy.txt"
    write_levels(unfiltered, path)
    again = read_levels(path)
    assert again == unfiltered
    assert [lvl.name for lvl in again] == [lvl.name for lvl in unfiltered]
    # Same layout as the shipped file, byte for byte.
    assert path.read_text() == (BOXOBAN_DIR / "unfiltered-valid-000.txt").read_text()


def test_write_levels_to_a_text_stream_and_unnamed_levels_get_their_position():
    levels = [
        Level.from_text("#####\n#@$.#\n#####"),
        Level.from_text("#####\n#.$@#\n#####", name="hard one"),
    ]
    buffer = io.StringIO()
    write_levels(levels, buffer)
    again = parse_levels(buffer.getvalue())
    assert again == levels
    assert [lvl.name for lvl in again] == ["0", "hard one"]


def test_to_text_round_trips_real_levels(unfiltered):
    for lvl in unfiltered[:50]:
        assert Level.from_text(lvl.to_text()) == lvl


# -- characters -------------------------------------------------------------------------


def test_box_on_target_and_player_on_target_parse_and_round_trip():
    text = "######\n#+*.$#\n#$   #\n######"
    lvl = Level.from_text(text)
    assert lvl.player == (1, 1) and lvl.player in lvl.targets
    assert (1, 2) in lvl.boxes and (1, 2) in lvl.targets
    assert lvl.boxes == {(1, 2), (1, 4), (2, 1)}
    assert lvl.targets == {(1, 1), (1, 2), (1, 3)}
    assert lvl.to_text() == text
    assert Level.from_text(lvl.to_text()) == lvl
    layers = lvl.entity_layers()
    assert layers[1, 1].tolist() == [False, True, True, False]
    assert layers[1, 2].tolist() == [False, True, False, True]


def test_dash_and_underscore_are_floor():
    assert Level.from_text("#####\n#@$.#\n#-_ #\n#####") == Level.from_text(
        "#####\n#@$.#\n#   #\n#####"
    )


def test_interior_and_trailing_spaces_are_kept_and_crlf_is_accepted():
    lvl = Level.from_text("######\r\n#@$.  \r\n######\r\n")
    assert (lvl.height, lvl.width) == (3, 6)
    assert (1, 4) not in lvl.walls and (1, 5) not in lvl.walls
    assert lvl.to_text() == "######\n#@$.  \n######"


def test_a_floor_only_row_survives_a_file_round_trip(tmp_path):
    lvl = Level.from_text("     \n#@$.#\n#####")
    write_levels([lvl], tmp_path / "open.txt")
    assert read_levels(tmp_path / "open.txt") == [lvl]


def test_a_single_level_file_without_header(tmp_path):
    path = tmp_path / "one.txt"
    path.write_text("\n#####\n#@$.#\n#####\n\n")
    (lvl,) = read_levels(path)
    assert lvl.name is None and lvl.player == (1, 1)


# -- the Level type ----------------------------------------------------------------------


def test_levels_are_equal_and_hash_by_content_not_name():
    a = Level.from_text("#####\n#@$.#\n#####", name="a")
    b = Level.from_text("#####\n#@$.#\n#####", name="b")
    c = Level.from_text("#####\n#.$@#\n#####")
    assert a == b and hash(a) == hash(b) and len({a, b, c}) == 2
    assert a != c
    with pytest.raises(AttributeError):
        a.player = (1, 2)  # frozen


def test_direct_construction_is_validated():
    walls = frozenset((0, c) for c in range(4))
    good = dict(walls=walls, targets={(1, 1)}, boxes={(1, 2)}, player=(1, 3), height=2, width=4)
    assert Level(**good).boxes == frozenset({(1, 2)})
    bad = [
        dict(good, boxes={(0, 2)}),  # box on a wall
        dict(good, targets={(1, 4)}),  # target outside
        dict(good, player=(1, 2)),  # player on the box
        dict(good, player=(0, 3)),  # player on a wall
        dict(good, boxes=set(), targets=set()),  # no box
        dict(good, boxes={(1, 2), (1, 0)}),
    ]  # 2 boxes, 1 target
    for kwargs in bad:
        with pytest.raises(LevelError):
            Level(**kwargs)


def test_padding_a_5x5_level_to_10x10_centres_it_in_walls():
    text = "#####\n#@  #\n# $ #\n#  .#\n#####"
    lvl = Level.from_text(text, name="small")
    big = lvl.padded(10, 10)
    assert (big.height, big.width) == (10, 10) and big.name == "small"
    assert big.player == (3, 3) and big.boxes == {(4, 4)} and big.targets == {(5, 5)}
    grid = big.grid()
    assert "\n".join("".join(row) for row in grid[2:7, 2:7]) == text
    outside = np.ones((10, 10), bool)
    outside[2:7, 2:7] = False
    assert (grid[outside] == "#").all()
    assert lvl.padded(5, 5) == lvl
    odd = lvl.padded(8, 9)  # offset ((8-5)//2, (9-5)//2) = (1, 2)
    assert odd.player == (2, 3)


# -- malformed input ----------------------------------------------------------------------

GOOD = "#####\n#@$.#\n#####\n"


def bad_file(tmp_path, level_text: str, header: str = "; 7"):
    """A file whose second level (lines 6 on, header `header`) is `level_text`."""
    path = tmp_path / "levels.txt"
    path.write_text(f"; 0\n{GOOD}\n{header}\n{level_text}\n")
    return path


def raised(path) -> LevelError:
    with pytest.raises(LevelError) as info:
        read_levels(path)
    return info.value


@pytest.mark.parametrize(
    "text, line, column, words",
    [
        ("#####\n#@$x#\n#.###", 8, 4, "unknown character 'x' " + VALID),
        ("#####\n#@$.\n#####", 8, 5, "ragged rows"),  # short row
        ("#####\n#@$.##\n#####", 8, 6, "ragged rows"),  # long row
        ("#####\n# $.#\n#####", 7, None, "no player"),
        ("######\n#@$.@#\n######", 8, 5, "more than one player"),
        ("######\n#@$$.#\n######", 7, None, "2 boxes but 1 targets"),
        ("#####\n#@ .#\n#####", 7, None, "no box"),
    ],
)
def test_malformed_levels_raise_with_file_line_column_and_index(
    tmp_path, text, line, column, words
):
    path = bad_file(tmp_path, text)
    error = raised(path)
    assert isinstance(error, ValueError)
    assert (error.path, error.index, error.line, error.column) == (str(path), 7, line, column)
    assert words in error.reason
    assert "levels.txt" in str(error) and words in str(error)


def test_error_message_layout(tmp_path):
    path = bad_file(tmp_path, "#####\n#@$x#\n#.###")
    assert str(raised(path)) == f"{path}: level 7, line 8, column 4: unknown character 'x' {VALID}"
    assert str(LevelError("oops")) == "oops"
    assert str(LevelError("oops", index=2)) == "level 2: oops"


def test_index_is_the_position_when_the_header_is_not_a_number(tmp_path):
    path = bad_file(tmp_path, "#####\n#@$x#\n#.###", header="; the hard one")
    assert raised(path).index == 1


def test_unknown_character_error_in_a_text_without_file():
    with pytest.raises(LevelError) as info:
        Level.from_text("####\n#@$\t\n#.##")
    assert (info.value.path, info.value.line, info.value.column) == (None, 2, 4)
    assert str(info.value).startswith("line 2, column 4: unknown character '\\t'")


def test_a_blank_line_inside_a_level_splits_it(tmp_path):
    path = tmp_path / "split.txt"
    path.write_text("; 0\n#####\n#@$.#\n\n#####\n")
    error = raised(path)
    assert (error.index, error.line) == (1, 5) and "no player" in error.reason


def test_level_larger_than_the_arena_is_a_level_error_naming_the_file(tmp_path):
    path = tmp_path / "big.txt"
    path.write_text("; 3\n" + "\n".join(["#" * 12, "#@$.       #", "#" * 12]) + "\n")
    (lvl,) = read_levels(path)
    with pytest.raises(LevelError) as info:
        lvl.padded(10, 10)
    error = info.value
    assert error.path == str(path) and error.index == 3
    assert "level is 3x12, larger than the arena's 10x10" in str(error)
    assert "big.txt" in str(error)


def test_missing_file_is_an_os_error(tmp_path):
    with pytest.raises(OSError):
        read_levels(tmp_path / "nope.txt")


def test_level_error_pickles():
    error = LevelError("bad", path="a.txt", index=1, line=2, column=3)
    again = pickle.loads(pickle.dumps(error))
    assert (again.reason, again.path, again.index, again.line, again.column) == (
        "bad",
        "a.txt",
        1,
        2,
        3,
    )
    assert str(again) == str(error)


def test_names_that_cannot_round_trip_are_refused():
    lvl = Level.from_text("#####\n#@$.#\n#####", name="two\nlines")
    with pytest.raises(ValueError, match="name"):
        write_levels([lvl], io.StringIO())
