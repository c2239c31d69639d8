"""The covering subset the README's test command runs (`fast_cover.cover`)."""

from __future__ import annotations

import itertools

import pytest

from fast_cover import cover, family_and_game


def _is_slow(case) -> bool:
    return any(mark.name == "slow" for mark in getattr(case, "marks", ()))


def test_every_facet_value_is_in_a_fast_case_and_the_rest_are_slow():
    cases = list(itertools.product("ab", "xyz", (0, 1)))
    marked = cover(cases, lambda first, second, third: [(1, first), (2, second), (3, third)])
    assert len(marked) == len(cases)
    fast = [case.values for case in marked if not _is_slow(case)]
    assert len(fast) == 3  # "xyz" needs three cases, which also hold both of the others
    for position, values in ((0, "ab"), (1, "xyz"), (2, (0, 1))):
        assert {case[position] for case in fast} == set(values)
    slow = [case.values for case in marked if _is_slow(case)]
    assert sorted(slow + fast) == sorted(cases)


def test_ids_and_marks_are_kept_and_the_choice_repeats():
    cases = [
        pytest.param("mujoban/level1", id="one"),
        pytest.param("mujoban/level2", id="two", marks=pytest.mark.xfail),
        pytest.param("mujoban/level1-pegs", id="pegs"),
    ]
    first = cover(cases, family_and_game)
    assert [case.id for case in first] == ["one", "two", "pegs"]
    assert [_is_slow(case) for case in first] == [False, True, False]
    assert {mark.name for mark in first[1].marks} == {"xfail", "slow"}
    assert [_is_slow(case) for case in cover(cases, family_and_game)] == [False, True, False]


def test_board_games_are_told_apart_by_their_rules():
    assert ("input", "move") in family_and_game("mujoboard/checkers")
    assert ("layout", "hex") in family_and_game("mujoboard/hex-7x7")
    assert family_and_game("mujogo/7x7") == [("family", "mujogo")]
    with pytest.raises(ValueError):
        cover([], family_and_game)
